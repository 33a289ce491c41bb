#include "analyze/render.h"

#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

namespace hw::analyze {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

// An axis-aligned square in the plane z = depth_m, centred on (cx, cy), half side h; its
// counter-clockwise normal faces −z (towards a camera at the origin) unless `facing_away`.
void AddSquare(ThermalMesh* mesh, double cx, double cy, double h, double depth_m, bool facing_away = false) {
  const int base = mesh->NumVertices();
  mesh->points_in_world.push_back({cx - h, cy - h, depth_m});
  mesh->points_in_world.push_back({cx + h, cy - h, depth_m});
  mesh->points_in_world.push_back({cx + h, cy + h, depth_m});
  mesh->points_in_world.push_back({cx - h, cy + h, depth_m});
  if (facing_away) {
    mesh->faces.push_back({base, base + 1, base + 2});
    mesh->faces.push_back({base, base + 2, base + 3});
  } else {
    mesh->faces.push_back({base, base + 2, base + 1});
    mesh->faces.push_back({base, base + 3, base + 2});
  }
}

// A fan polygon of `segments` sides, radius r, centre (0, 0, depth_m), facing −z.
ThermalMesh Disc(double r, double depth_m, int segments) {
  ThermalMesh mesh;
  mesh.points_in_world.push_back({0, 0, depth_m});
  for (int k = 0; k < segments; ++k) {
    const double a = 2 * M_PI * k / segments;
    mesh.points_in_world.push_back({r * std::cos(a), r * std::sin(a), depth_m});
  }
  for (int k = 0; k < segments; ++k) mesh.faces.push_back({0, 1 + (k + 1) % segments, 1 + k});
  return mesh;
}

Camera SmallCamera(bool orthographic) {
  Camera camera;
  camera.width = 64;
  camera.height = 48;
  camera.orthographic = orthographic;
  camera.ortho_height_m = 1.5;
  return camera;
}

TEST(RenderTest, UnitSquareGivesExactFacesDepthAndBarycentrics) {
  ThermalMesh mesh;
  AddSquare(&mesh, 0, 0, 0.5, 2.0);
  const MeshRenderer renderer(mesh);
  const Camera camera = SmallCamera(false);
  RenderOptions options;
  options.samples_per_pixel = 1;
  const SampleBuffer samples = renderer.Render(camera, options);
  ASSERT_EQ(samples.NumSamples(), 64u * 48u);
  int hits = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      // The pixel centre's ray meets z = 2 at p.
      Vector3d origin, direction;
      camera.Ray(x + 0.5, y + 0.5, &origin, &direction);
      const Vector3d p = origin + direction * (2.0 / direction.z());
      const size_t i = samples.Index(x, y, 0);
      const double margin = 1e-4;  // skip centres on an edge or the diagonal
      if (std::abs(std::abs(p.x()) - 0.5) < margin || std::abs(std::abs(p.y()) - 0.5) < margin ||
          std::abs(p.x() - p.y()) < margin) {
        continue;
      }
      if (std::abs(p.x()) > 0.5 || std::abs(p.y()) > 0.5) {
        EXPECT_EQ(samples.face[i], -1);
        EXPECT_TRUE(std::isinf(samples.depth_m[i]));
        continue;
      }
      ++hits;
      // Face 0 = (v0, v2, v1) holds y < x, face 1 = (v0, v3, v2) y > x.
      const int face = p.y() < p.x() ? 0 : 1;
      ASSERT_EQ(samples.face[i], face) << x << " " << y;
      const Vector3d a = mesh.points_in_world[static_cast<size_t>(mesh.faces[face][0])];
      const Vector3d b = mesh.points_in_world[static_cast<size_t>(mesh.faces[face][1])];
      const Vector3d c = mesh.points_in_world[static_cast<size_t>(mesh.faces[face][2])];
      Eigen::Matrix2d m;
      m << (b - a).x(), (c - a).x(), (b - a).y(), (c - a).y();
      const Vector2d uv = m.inverse() * (p - a).head<2>();
      // float rays over a 2 m lever: a few 1e-7 relative.
      EXPECT_NEAR(samples.bary_u[i], uv.x(), 1e-5);
      EXPECT_NEAR(samples.bary_v[i], uv.y(), 1e-5);
      EXPECT_NEAR(samples.depth_m[i], 2.0, 1e-5);
      EXPECT_NEAR(samples.cos_incidence[i], std::abs(direction.z()), 1e-5);
    }
  }
  // The square spans 2 · f · 0.25 px ≈ 33 px vertically: hundreds of pixels.
  EXPECT_GT(hits, 500);
}

TEST(RenderTest, ProjectAndRayRoundTripForBothProjections) {
  for (const bool orthographic : {false, true}) {
    const Camera camera =
        LookAt(Vector3d(1, -2, 0.5), Vector3d(0.2, 0.3, 0.1), Vector3d::UnitZ(), SmallCamera(orthographic));
    ASSERT_EQ(camera.Check(), "");
    for (const Vector2d& pixel : {Vector2d(0, 0), Vector2d(10.25, 40.5), Vector2d(63.9, 0.1), Vector2d(32, 24)}) {
      Vector3d origin, direction;
      camera.Ray(pixel.x(), pixel.y(), &origin, &direction);
      EXPECT_NEAR(direction.norm(), 1.0, 1e-12);
      const Vector3d point = origin + 3.7 * direction;
      double depth_m = 0;
      const Vector2d back = camera.Project(point, &depth_m);
      EXPECT_NEAR((back - pixel).norm(), 0.0, 1e-9) << orthographic;
      // Depth along the optical axis: the full 3.7 m for the orthographic ray (origin on the
      // camera plane), 3.7 · cos(off-axis angle) for the perspective one.
      const Vector3d axis = camera.world_from_camera.linear().col(2);
      EXPECT_NEAR(depth_m, orthographic ? 3.7 : 3.7 * direction.dot(axis), 1e-9);
    }
    // The image centre looks along +z of the camera, i.e. at the target.
    EXPECT_NEAR((camera.Project(Vector3d(0.2, 0.3, 0.1)) - Vector2d(32, 24)).norm(), 0.0, 1e-9);
  }
}

TEST(RenderTest, LookAtKeepsUpUpAndHandlesAViewStraightDown) {
  const Camera camera = LookAt(Vector3d(0, -5, 0), Vector3d::Zero(), Vector3d::UnitZ(), SmallCamera(false));
  // A point above the target is above the image centre (smaller y).
  EXPECT_LT(camera.Project(Vector3d(0, 0, 1)).y(), 24.0);
  EXPECT_GT(camera.Project(Vector3d(1, 0, 0)).x(), 32.0);  // +x is to the right looking along +y
  const Camera down = LookAt(Vector3d(0, 0, 5), Vector3d::Zero(), Vector3d::UnitZ(), SmallCamera(false));
  EXPECT_EQ(down.Check(), "");
  EXPECT_NEAR(down.world_from_camera.linear().col(2).z(), -1.0, 1e-12);
}

// Area of a fan of n sides inscribed in radius r.
double PolygonArea(double r, int n) { return 0.5 * n * r * r * std::sin(2 * M_PI / n); }

TEST(RenderTest, CoverageOfADiscAndAnEdgeMatchesTheAnalyticFraction) {
  // Orthographic, 1 px = 1 cm: a disc of radius 50 px.
  Camera camera = SmallCamera(true);
  camera.width = 160;
  camera.height = 160;
  camera.ortho_height_m = 1.6;
  const ThermalMesh disc = Disc(0.5, 3.0, 256);
  const MeshRenderer disc_renderer(disc);
  const double disc_px2 = PolygonArea(50, 256);
  // Half-plane x < 0.003 m: its edge 30 % into column 80 (the camera's centre is x = 80 px).
  ThermalMesh half;
  half.points_in_world = {{-2, -2, 3}, {0.003, -2, 3}, {0.003, 2, 3}, {-2, 2, 3}};
  half.faces = {{0, 2, 1}, {0, 3, 2}};
  const MeshRenderer half_renderer(half);
  for (const int spp : {4, 16}) {
    RenderOptions options;
    options.samples_per_pixel = spp;
    const SampleBuffer d = disc_renderer.Render(camera, options);
    size_t covered = 0;
    for (const int f : d.face) covered += f >= 0;
    const double area_px2 = static_cast<double>(covered) / spp;
    // n×n strata: a boundary pixel's estimate has variance <= 2n · (1/4) / n⁴ (at most 2n
    // strata cross the edge, each a Bernoulli); ~314 boundary pixels; 4 σ.
    const double n = std::sqrt(spp);
    const double sigma_px2 = std::sqrt(314 * 2 * n * 0.25 / std::pow(n, 4));
    EXPECT_NEAR(area_px2, disc_px2, 4 * sigma_px2) << spp;

    const SampleBuffer h = half_renderer.Render(camera, options);
    double column_sum = 0;
    for (int y = 0; y < camera.height; ++y) {
      double pixel = 0;
      for (int s = 0; s < spp; ++s) pixel += h.face[h.Index(80, y, s)] >= 0;
      column_sum += pixel / spp;
      // Whole pixels either side are fully in or out.
      for (int s = 0; s < spp; ++s) {
        EXPECT_GE(h.face[h.Index(79, y, s)], 0);
        EXPECT_EQ(h.face[h.Index(81, y, s)], -1);
      }
    }
    // Per-pixel variance: n strata per crossing column cell, each Bernoulli(p); p = 0.6 of
    // the [0, 0.5) cell (n = 2), 0.2 of the [0.25, 0.5) cell (n = 4); mean of 160 rows, 4 σ.
    const double p = spp == 4 ? 0.6 : 0.2;
    const double sigma = std::sqrt(n * p * (1 - p) / std::pow(n, 4) / camera.height);
    EXPECT_NEAR(column_sum / camera.height, 0.3, 4 * sigma) << spp;
  }
}

TEST(RenderTest, SampleOffsetsAreStratified) {
  for (const int spp : {4, 9, 16}) {
    const int n = static_cast<int>(std::lround(std::sqrt(spp)));
    for (int s = 0; s < spp; ++s) {
      const Vector2d o = SampleOffset(7, 11, s, spp);
      EXPECT_EQ(static_cast<int>(o.x() * n), s % n);
      EXPECT_EQ(static_cast<int>(o.y() * n), s / n);
    }
  }
  EXPECT_EQ(SampleOffset(3, 4, 0, 1), Vector2d(0.5, 0.5));
  EXPECT_NE(SampleOffset(3, 4, 0, 4), SampleOffset(4, 4, 0, 4));  // not the same in every pixel
}

TEST(RenderTest, InterpolatesALinearFieldAndAppliesTheNanRule) {
  ThermalMesh mesh;
  AddSquare(&mesh, 0.1, -0.05, 0.5, 2.0);
  std::vector<double> field;
  auto linear = [](const Vector3d& p) { return 3 * p.x() + 2 * p.y() + 1; };
  for (const Vector3d& p : mesh.points_in_world) field.push_back(linear(p));
  const MeshRenderer renderer(mesh);
  const Camera camera = SmallCamera(false);
  RenderOptions options;
  options.samples_per_pixel = 4;
  const SampleBuffer samples = renderer.Render(camera, options);
  int checked = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      for (int s = 0; s < 4; ++s) {
        const size_t i = samples.Index(x, y, s);
        const float value = InterpolateAtSample(mesh, field, samples, i);
        if (samples.face[i] < 0) {
          EXPECT_TRUE(std::isnan(value));
          continue;
        }
        const Vector2d pixel = Vector2d(x, y) + SampleOffset(x, y, s, 4);
        Vector3d origin, direction;
        camera.Ray(pixel.x(), pixel.y(), &origin, &direction);
        const Vector3d p = origin + direction * (2.0 / direction.z());
        EXPECT_NEAR(value, linear(p), 1e-4);  // float barycentrics, field values ~ 3
        ++checked;
      }
    }
  }
  EXPECT_GT(checked, 2000);

  // By hand: face 0 = (v0, v2, v1) with vertex 0 unobserved.
  std::vector<double> partial = field;
  partial[0] = std::numeric_limits<double>::quiet_NaN();
  SampleBuffer hand;
  hand.width = 1;
  hand.height = 1;
  hand.samples_per_pixel = 3;
  hand.face = {0, 0, -1};
  hand.bary_u = {0.3f, 0.2f, 0};
  hand.bary_v = {0.3f, 0.2f, 0};
  hand.depth_m = {1, 1, std::numeric_limits<float>::infinity()};
  hand.cos_incidence = {1, 1, 0};
  // Weights (0.4, 0.3, 0.3): 0.6 observed → renormalised mean of v2 and v1.
  EXPECT_NEAR(InterpolateAtSample(mesh, partial, hand, 0), 0.5 * (field[2] + field[1]), 1e-6);
  // Weights (0.6, 0.2, 0.2): only 0.4 observed → NaN.
  EXPECT_TRUE(std::isnan(InterpolateAtSample(mesh, partial, hand, 1)));
  EXPECT_TRUE(std::isnan(InterpolateAtSample(mesh, field, hand, 2)));  // a miss
}

TEST(RenderTest, CullsBackFacesOnlyWhenAsked) {
  ThermalMesh mesh;
  AddSquare(&mesh, 0, 0, 0.5, 1.0, /*facing_away=*/true);  // its back towards the camera
  AddSquare(&mesh, 0, 0, 1.0, 2.0);                        // its front towards the camera
  const MeshRenderer renderer(mesh);
  const Camera camera = SmallCamera(false);
  RenderOptions options;
  options.samples_per_pixel = 1;
  const SampleBuffer plain = renderer.Render(camera, options);
  options.cull_back_faces = true;
  const SampleBuffer culled = renderer.Render(camera, options);
  const size_t centre = plain.Index(32, 24, 0);
  EXPECT_NEAR(plain.depth_m[centre], 1.0, 1e-6);
  EXPECT_LT(plain.face[centre], 2);
  EXPECT_NEAR(culled.depth_m[centre], 2.0, 1e-6);
  EXPECT_GE(culled.face[centre], 2);
  // Occlusion ignores culling: the near square still blocks.
  EXPECT_FALSE(renderer.Unoccluded(Vector3d::Zero(), Vector3d(0, 0, 2)));
}

TEST(RenderTest, UnoccludedSeesBlockers) {
  ThermalMesh mesh;
  AddSquare(&mesh, 0, 0, 0.5, 1.0);
  const MeshRenderer renderer(mesh);
  EXPECT_FALSE(renderer.Unoccluded(Vector3d(0, 0, 0), Vector3d(0, 0, 2)));
  EXPECT_FALSE(renderer.Unoccluded(Vector3d(0, 0, 2), Vector3d(0.2, 0.1, 0)));  // either way
  EXPECT_TRUE(renderer.Unoccluded(Vector3d(2, 0, 0), Vector3d(2, 0, 2)));      // passes beside it
  EXPECT_TRUE(renderer.Unoccluded(Vector3d(0, 0, 0), Vector3d(0, 0, 0.9)));    // stops short
  EXPECT_TRUE(renderer.Unoccluded(Vector3d(0, 0, 0), Vector3d(0.1, 0, 1.0)));  // ends on it
  EXPECT_FALSE(renderer.Unoccluded(Vector3d(0, 0, 0), Vector3d(0.1, 0, 1.01)));
}

TEST(RenderTest, OutputDoesNotDependOnThreadsOrTiles) {
  // A bumpy 60×60 grid: thousands of faces, edges everywhere.
  ThermalMesh mesh;
  const int n = 60;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const double x = -1 + 2.0 * i / n, y = -1 + 2.0 * j / n;
      mesh.points_in_world.push_back({x, y, 3 + 0.2 * std::sin(7 * x) * std::cos(5 * y)});
    }
  }
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i;
      mesh.faces.push_back({a, a + n + 2, a + 1});
      mesh.faces.push_back({a, a + n + 1, a + n + 2});
    }
  }
  const MeshRenderer renderer(mesh);
  EXPECT_GT(renderer.build_seconds(), 0.0);
  Camera camera = LookAt(Vector3d(0.3, -0.4, 0), Vector3d(0, 0, 3), -Vector3d::UnitY(), SmallCamera(false));
  camera.width = 101;  // not a multiple of the tile or packet size
  camera.height = 77;
  RenderOptions one;
  one.samples_per_pixel = 4;
  one.num_threads = 1;
  RenderOptions two = one;
  two.num_threads = 2;
  two.tile_px = 8;
  const SampleBuffer a = renderer.Render(camera, one);
  const SampleBuffer b = renderer.Render(camera, two);
  EXPECT_EQ(a.face, b.face);
  EXPECT_EQ(a.bary_u, b.bary_u);
  EXPECT_EQ(a.bary_v, b.bary_v);
  EXPECT_EQ(a.depth_m, b.depth_m);
  EXPECT_EQ(a.cos_incidence, b.cos_incidence);
  size_t hits = 0;
  for (const int f : a.face) hits += f >= 0;
  EXPECT_GT(hits, a.NumSamples() / 2);
}

TEST(RenderTest, OptionChecksNameTheField) {
  RenderOptions options;
  EXPECT_EQ(options.Check(), "");
  options.samples_per_pixel = 3;
  EXPECT_NE(options.Check().find("samples_per_pixel"), std::string::npos);
  options = {};
  options.tile_px = 2;
  EXPECT_NE(options.Check().find("tile_px"), std::string::npos);
  Camera camera;
  EXPECT_EQ(camera.Check(), "");
  camera.fov_y_deg = 180;
  EXPECT_NE(camera.Check().find("fov_y_deg"), std::string::npos);
  camera = {};
  camera.world_from_camera.linear() *= 2;
  EXPECT_NE(camera.Check().find("world_from_camera"), std::string::npos);
}

}  // namespace
}  // namespace hw::analyze
