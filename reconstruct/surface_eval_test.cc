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

}  // namespace
}  // namespace hw::reconstruct
