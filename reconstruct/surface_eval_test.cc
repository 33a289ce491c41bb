#include "reconstruct/surface_eval.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

namespace hw::reconstruct {
namespace {

using Eigen::Vector3d;

TEST(ClosestPointOnTriangle, EveryVoronoiRegion) {
  const Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  // Face interior: straight down.
  EXPECT_TRUE(ClosestPointOnTriangle({0.2, 0.3, 0.7}, a, b, c).isApprox(Vector3d(0.2, 0.3, 0)));
  // Vertices.
  EXPECT_TRUE(ClosestPointOnTriangle({-1, -1, 0.5}, a, b, c).isApprox(a));
  EXPECT_TRUE(ClosestPointOnTriangle({2, -0.5, 0}, a, b, c).isApprox(b));
  EXPECT_TRUE(ClosestPointOnTriangle({-0.5, 2, 1}, a, b, c).isApprox(c));
  // Edges: ab, ac, and the hypotenuse bc (closest point (0.5, 0.5) from (1, 1)).
  EXPECT_TRUE(ClosestPointOnTriangle({0.5, -1, 0}, a, b, c).isApprox(Vector3d(0.5, 0, 0)));
  EXPECT_TRUE(ClosestPointOnTriangle({-1, 0.25, 3}, a, b, c).isApprox(Vector3d(0, 0.25, 0)));
  EXPECT_TRUE(ClosestPointOnTriangle({1, 1, 0}, a, b, c).isApprox(Vector3d(0.5, 0.5, 0)));
}

TEST(ClosestPointOnTriangle, MatchesDenseSampling) {
  // Against a brute-force minimum over a fine barycentric grid of a skewed 3D triangle.
  const Vector3d a(0.1, -0.2, 0.3), b(1.2, 0.4, -0.1), c(-0.3, 0.9, 0.5);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (int trial = 0; trial < 20; ++trial) {
    const Vector3d p(u(rng), u(rng), u(rng));
    double brute = 1e9;
    constexpr int kN = 400;
    for (int i = 0; i <= kN; ++i)
      for (int j = 0; i + j <= kN; ++j) {
        const Vector3d q = a + (b - a) * (double(i) / kN) + (c - a) * (double(j) / kN);
        brute = std::min(brute, (q - p).norm());
      }
    const double exact = (ClosestPointOnTriangle(p, a, b, c) - p).norm();
    // The grid's spacing is ~1.5/400 m: its minimum is above the exact one by at most that.
    EXPECT_LE(exact, brute + 1e-12);
    EXPECT_GT(exact, brute - 0.004);
  }
}

TEST(ClosestPointOnTriangle, WeightsReproduceThePoint) {
  const Vector3d a(0.1, -0.2, 0.3), b(1.2, 0.4, -0.1), c(-0.3, 0.9, 0.5);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  for (int trial = 0; trial < 200; ++trial) {
    const Vector3d p(u(rng), u(rng), u(rng));
    const TrianglePoint q = ClosestPointOnTriangleWithWeights(p, a, b, c);
    EXPECT_EQ(q.point, ClosestPointOnTriangle(p, a, b, c));
    EXPECT_GE(q.weights.minCoeff(), 0);
    EXPECT_NEAR(q.weights.sum(), 1, 1e-12);
    EXPECT_LT((q.weights.x() * a + q.weights.y() * b + q.weights.z() * c - q.point).norm(), 1e-12);
  }
}

TEST(PointToMeshDistances, MatchesBruteForceOnLargeSlantedTriangles) {
  // Triangles of up to 1 m in every orientation in a grid of 5 cm cells: each is binned only
  // in the cells it comes near, which must not lose any query within the search radius.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  std::vector<Vector3d> vertices;
  std::vector<Eigen::Vector3i> faces;
  for (int f = 0; f < 20; ++f) {
    for (int k = 0; k < 3; ++k) vertices.emplace_back(u(rng), u(rng), u(rng));
    faces.emplace_back(3 * f, 3 * f + 1, 3 * f + 2);
  }
  std::vector<Vector3d> points;
  for (int i = 0; i < 2000; ++i) points.emplace_back(u(rng), u(rng), u(rng));
  constexpr double kMax = 0.05;
  const auto d = PointToMeshDistances(points, vertices, faces, kMax);
  int within = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    double brute = INFINITY;
    for (const auto& f : faces) {
      brute = std::min(brute, (ClosestPointOnTriangle(points[i], vertices[f[0]], vertices[f[1]], vertices[f[2]]) -
                               points[i]).norm());
    }
    if (brute <= kMax) {
      ++within;
      ASSERT_TRUE(d[i]) << i;
      EXPECT_EQ(*d[i], brute);
    } else {
      EXPECT_FALSE(d[i]) << i;
    }
  }
  EXPECT_GT(within, 200);  // the test exercises the search
}

TEST(PointToMeshDistances, PlaneOfTwoTrianglesAndSearchRadius) {
  const std::vector<Vector3d> vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  const std::vector<Eigen::Vector3i> faces = {{0, 1, 2}, {0, 2, 3}};
  const std::vector<Vector3d> points = {{0.5, 0.5, 0.003}, {0.9, 0.1, -0.01}, {0.5, 0.5, 0.2},
                                        {1.02, 0.5, 0}};
  const auto d = PointToMeshDistances(points, vertices, faces, 0.05);
  ASSERT_TRUE(d[0] && d[1] && d[3]);
  EXPECT_NEAR(*d[0], 0.003, 1e-12);
  EXPECT_NEAR(*d[1], 0.01, 1e-12);
  EXPECT_FALSE(d[2]);  // 0.2 m away: beyond the search radius
  EXPECT_NEAR(*d[3], 0.02, 1e-12);
  const SurfaceDistanceStats s = SummarizeDistances(d);
  EXPECT_EQ(s.points, 4);
  EXPECT_EQ(s.beyond_search, 1);
  EXPECT_NEAR(s.median_m, 0.01, 1e-12);
  EXPECT_NEAR(s.max_m, 0.02, 1e-12);
  EXPECT_NEAR(s.mean_m, 0.011, 1e-12);
}

// A square of side 1 m meshed in 2 cm cells, placed by `frame` (its own x, y span the square,
// z is its normal), appended to (vertices, faces).
void AddSquare(const core::Rigid3d& frame, std::vector<Vector3d>& vertices, std::vector<Eigen::Vector3i>& faces) {
  constexpr int kCells = 50;
  const int base = static_cast<int>(vertices.size());
  for (int j = 0; j <= kCells; ++j)
    for (int i = 0; i <= kCells; ++i) vertices.push_back(frame * Vector3d(double(i) / kCells, double(j) / kCells, 0));
  for (int j = 0; j < kCells; ++j)
    for (int i = 0; i < kCells; ++i) {
      const int a = base + j * (kCells + 1) + i;
      faces.emplace_back(a, a + 1, a + kCells + 2);
      faces.emplace_back(a, a + kCells + 2, a + kCells + 1);
    }
}

// Points drawn on a square of AddSquare's (inside a 5 cm margin), with isotropic noise of
// standard deviation noise_m (m; 0: none).
void SampleSquare(const core::Rigid3d& frame, int count, double noise_m, std::mt19937& rng,
                  std::vector<Vector3d>& points) {
  std::uniform_real_distribution<double> u(0.05, 0.95);
  std::normal_distribution<double> n(0, 1);
  for (int k = 0; k < count; ++k) {
    points.push_back(frame * Vector3d(u(rng), u(rng), 0) + noise_m * Vector3d(n(rng), n(rng), n(rng)));
  }
}

// A room's corner: floor and two walls, which fix all six directions of a rigid motion.
struct Corner {
  std::vector<Vector3d> vertices;
  std::vector<Eigen::Vector3i> faces;
  std::vector<core::Rigid3d> frames;
  Corner() {
    const auto about = [](const Vector3d& axis, double deg) {
      return Eigen::Quaterniond(Eigen::AngleAxisd(deg * M_PI / 180, axis));
    };
    frames = {core::Rigid3d(),                                                         // floor z = 0
              core::Rigid3d(about(Vector3d::UnitY(), -90), Vector3d::Zero()),         // wall x = 0
              core::Rigid3d(about(Vector3d::UnitX(), 90), Vector3d::Zero())};         // wall y = 0
    for (const auto& f : frames) AddSquare(f, vertices, faces);
  }
};

core::Rigid3d SmallMotion() {
  return core::Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.5 * M_PI / 180, Vector3d(1, 2, 3).normalized())),
                       Vector3d(0.006, -0.004, 0.008));
}

TEST(RegisterToMesh, RecoversAKnownMotionExactlyWithoutNoise) {
  const Corner corner;
  std::mt19937 rng(11);
  std::vector<Vector3d> points;
  for (const auto& f : corner.frames) SampleSquare(f, 3000, 0, rng, points);
  const core::Rigid3d truth = SmallMotion();
  for (Vector3d& p : points) p = truth * p;
  const TriangleGrid grid(corner.vertices, corner.faces, 0.05);
  const MeshRegistration r = RegisterToMesh(points, grid, MeshRegistrationOptions{});
  EXPECT_TRUE(r.converged);
  EXPECT_EQ(r.constrained_directions, 6);
  const core::PoseError e = core::ComparePoses(r.reference_from_points, truth.Inverse());
  EXPECT_LT(e.rotation_rad * 180 / M_PI, 1e-5);
  EXPECT_LT(e.translation_m, 1e-6);
  EXPECT_NEAR(r.rotation_deg, 0.5, 1e-5);
  std::vector<Vector3d> registered;
  for (const Vector3d& p : points) registered.push_back(r.reference_from_points * p);
  EXPECT_LT(SummarizeDistances(PointToMeshDistances(registered, corner.vertices, corner.faces, 0.05)).max_m, 1e-6);
}

TEST(RegisterToMesh, NoiseLeavesTheMotionWithinItsStandardError) {
  // 1 mm of isotropic noise on 9000 points: the translation's standard error is about
  // σ / sqrt(N / 3) = 0.02 mm, the rotation's σ / (sqrt(N) · 0.3 m) = 0.002°; the bounds are
  // five of those. After registration the distances are |N(0, σ)|, median 0.674 σ.
  const Corner corner;
  std::mt19937 rng(13);
  std::vector<Vector3d> points;
  constexpr double kSigma = 0.001;
  for (const auto& f : corner.frames) SampleSquare(f, 3000, kSigma, rng, points);
  const core::Rigid3d truth = SmallMotion();
  for (Vector3d& p : points) p = truth * p;
  const TriangleGrid grid(corner.vertices, corner.faces, 0.05);
  const double before = SummarizeDistances(PointToMeshDistances(points, corner.vertices, corner.faces, 0.05)).median_m;
  const MeshRegistration r = RegisterToMesh(points, grid, MeshRegistrationOptions{});
  const core::PoseError e = core::ComparePoses(r.reference_from_points, truth.Inverse());
  EXPECT_LT(e.rotation_rad * 180 / M_PI, 0.01);
  EXPECT_LT(e.translation_m, 1e-4);
  std::vector<Vector3d> registered;
  for (const Vector3d& p : points) registered.push_back(r.reference_from_points * p);
  const double after = SummarizeDistances(PointToMeshDistances(registered, corner.vertices, corner.faces, 0.05)).median_m;
  EXPECT_GT(before, 3 * kSigma);
  EXPECT_NEAR(after, 0.674 * kSigma, 0.05 * kSigma);
}

TEST(RegisterToMesh, APlaneMovesOnlyAlongWhatItFixes) {
  // One plane fixes its offset and its two tilts; sliding in it and turning about its normal
  // are left as they were, not guessed.
  std::vector<Vector3d> vertices;
  std::vector<Eigen::Vector3i> faces;
  AddSquare(core::Rigid3d(), vertices, faces);
  std::mt19937 rng(17);
  std::vector<Vector3d> points;
  SampleSquare(core::Rigid3d(), 3000, 0, rng, points);
  const core::Rigid3d in_plane(Eigen::Quaterniond(Eigen::AngleAxisd(1.0 * M_PI / 180, Vector3d::UnitZ())),
                               Vector3d(0.02, 0.01, 0));
  for (Vector3d& p : points) p = in_plane * p + Vector3d(0, 0, 0.005);
  const TriangleGrid grid(vertices, faces, 0.05);
  const MeshRegistration r = RegisterToMesh(points, grid, MeshRegistrationOptions{});
  EXPECT_EQ(r.constrained_directions, 3);
  EXPECT_NEAR(r.reference_from_points.translation.z(), -0.005, 1e-9);
  EXPECT_LT(r.reference_from_points.translation.head<2>().norm(), 1e-9);
  EXPECT_LT(r.rotation_deg, 1e-6);
}

TEST(RegisterToMesh, NothingWithinReachIsTheIdentity) {
  std::vector<Vector3d> vertices;
  std::vector<Eigen::Vector3i> faces;
  AddSquare(core::Rigid3d(), vertices, faces);
  const TriangleGrid grid(vertices, faces, 0.05);
  const MeshRegistration r = RegisterToMesh({{0.5, 0.5, 1.0}, {0.2, 0.2, 2.0}}, grid, MeshRegistrationOptions{});
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(r.rotation_deg, 0);
  EXPECT_EQ(r.translation_m, 0);
}

TEST(MeshRegistrationOptions, CheckNamesTheField) {
  EXPECT_EQ(MeshRegistrationOptions{}.Check(), "");
  MeshRegistrationOptions o;
  o.outlier_median_ratio = 0.5;
  EXPECT_NE(o.Check().find("outlier_median_ratio"), std::string::npos);
  o = {};
  o.min_eigenvalue_ratio = 1;
  EXPECT_NE(o.Check().find("min_eigenvalue_ratio"), std::string::npos);
  o = {};
  o.max_distance_m = NAN;
  EXPECT_NE(o.Check().find("max_distance_m"), std::string::npos);
}

}  // namespace
}  // namespace hw::reconstruct
