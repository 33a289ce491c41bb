#include "reconstruct/surface_eval.h"

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
