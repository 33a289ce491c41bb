#include "analyze/view_select.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include <gtest/gtest.h>

namespace hw::analyze {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

// An axis-aligned box [lo, hi] as 12 triangles, outward normals.
void AddBox(ThermalMesh* mesh, const Vector3d& lo, const Vector3d& hi) {
  const int base = mesh->NumVertices();
  for (int k = 0; k < 8; ++k) {
    mesh->points_in_world.push_back({(k & 1) ? hi.x() : lo.x(), (k & 2) ? hi.y() : lo.y(), (k & 4) ? hi.z() : lo.z()});
  }
  const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& q : quads) {
    mesh->faces.push_back({base + q[0], base + q[1], base + q[2]});
    mesh->faces.push_back({base + q[0], base + q[2], base + q[3]});
  }
}

TEST(ViewSelectTest, OverviewsFrameTheWholeBoxTightly) {
  ThermalMesh mesh;
  const Vector3d lo(-2.5, -4, 0), hi(2.5, 0, 3);  // a room-sized box, z up
  AddBox(&mesh, lo, hi);
  ViewSelectOptions options;
  ASSERT_EQ(options.Check(), "");
  const std::vector<NamedView> views = OverviewViews(mesh, options);
  ASSERT_EQ(views.size(), 5u);
  const Vector3d centre = 0.5 * (lo + hi);
  for (size_t v = 0; v < views.size(); ++v) {
    const Camera& camera = views[v].camera;
    EXPECT_EQ(camera.Check(), "");
    EXPECT_EQ(views[v].name, v < 4 ? "overview-" + std::to_string(v + 1) : std::string("top"));
    EXPECT_EQ(camera.orthographic, v == 4);
    // Inside the margin everywhere, touching it somewhere (the nearest fitting distance).
    const double mx = options.margin_fraction * options.width, my = options.margin_fraction * options.height;
    double slack_px = 1e9;
    for (int k = 0; k < 8; ++k) {
      const Vector3d corner((k & 1) ? hi.x() : lo.x(), (k & 2) ? hi.y() : lo.y(), (k & 4) ? hi.z() : lo.z());
      double depth_m = 0;
      const Vector2d p = camera.Project(corner, &depth_m);
      EXPECT_GT(depth_m, 0);
      EXPECT_GE(p.x(), mx - 1e-6);
      EXPECT_LE(p.x(), options.width - mx + 1e-6);
      EXPECT_GE(p.y(), my - 1e-6);
      EXPECT_LE(p.y(), options.height - my + 1e-6);
      slack_px = std::min({slack_px, p.x() - mx, options.width - mx - p.x(), p.y() - my, options.height - my - p.y()});
    }
    EXPECT_NEAR(slack_px, 0.0, 1e-6) << views[v].name;
    // Looking at the centre, from above the horizon.
    EXPECT_NEAR((camera.Project(centre) - Vector2d(640, 480)).norm(), 0.0, 1e-6);
    const Vector3d forward = camera.world_from_camera.linear().col(2);
    if (v < 4) {
      EXPECT_NEAR(std::asin(-forward.z()) * 180 / M_PI, options.elevation_deg, 1e-9);
      // Evenly spaced azimuths from 45°: the eye lies at azimuth 45° + 90° v from the centre.
      const Vector3d to_eye = camera.world_from_camera.translation() - centre;
      const double azimuth_deg = std::atan2(to_eye.y(), to_eye.x()) * 180 / M_PI;
      EXPECT_NEAR(std::remainder(azimuth_deg - (45.0 + 90.0 * static_cast<double>(v)), 360.0), 0.0, 1e-9);
      // Up stays up in the image: the top of the box is above its bottom.
      EXPECT_LT(camera.Project(Vector3d(centre.x(), centre.y(), hi.z())).y(),
                camera.Project(Vector3d(centre.x(), centre.y(), lo.z())).y());
    } else {
      EXPECT_NEAR(forward.z(), -1.0, 1e-12);
      // A plan: +x right, +y up.
      EXPECT_GT(camera.Project(centre + Vector3d::UnitX()).x(), 640);
      EXPECT_LT(camera.Project(centre + Vector3d::UnitY()).y(), 480);
    }
  }
}

// A wall in the plane y = 0 facing −y, a spot on it at (0, 0, 1.5) of radius 0.1, and a box
// in front of it along the normal that hides it from straight ahead and from 25°.
TEST(ViewSelectTest, CloseUpLooksPastABlockerAndFramesTheSpot) {
  ThermalMesh mesh;
  mesh.points_in_world = {{-2, 0, 0}, {2, 0, 0}, {2, 0, 3}, {-2, 0, 3}};
  mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  AddBox(&mesh, Vector3d(-0.15, -0.45, 1.35), Vector3d(0.15, -0.25, 1.65));
  const MeshRenderer renderer(mesh);
  const Vector3d centroid(0, 0, 1.5), normal(0, -1, 0);
  std::vector<Vector3d> region;
  for (int k = 0; k < 16; ++k) {
    const double a = 2 * M_PI * k / 16;
    region.push_back(centroid + 0.1 * Vector3d(std::cos(a), 0, std::sin(a)));
  }
  region.push_back(centroid);
  ViewSelectOptions options;
  options.close_up_min_distance_m = 0.3;
  // Sanity of the set-up: straight ahead the box hides the centroid.
  EXPECT_FALSE(renderer.Unoccluded(centroid + 0.55 * normal, centroid, 1e-3));

  double fraction = -1;
  const NamedView view = CloseUpView(renderer, centroid, normal, 0.1, region, options, &fraction);
  EXPECT_EQ(view.name, "close-up");
  EXPECT_EQ(fraction, 1.0);
  const Camera& camera = view.camera;
  const Vector3d eye = camera.world_from_camera.translation();
  const double angle_deg = std::acos((eye - centroid).normalized().dot(normal)) * 180 / M_PI;
  EXPECT_NEAR(angle_deg, 50.0, 1e-6);  // 0° and 25° are blocked (see the geometry above)
  for (const Vector3d& p : region) EXPECT_TRUE(renderer.Unoccluded(eye, p, 1e-3));
  // Framing: the centroid in the image centre; distance r / (fill · tan(fov/2)) = 0.55 m
  // (or 60 % of it); the region's vertical extent, seen obliquely about a vertical or
  // horizontal axis, spans at most fill · height and at least cos 50° of it.
  EXPECT_NEAR((camera.Project(centroid) - Vector2d(640, 480)).norm(), 0.0, 1e-6);
  const double full_m = 0.1 / (0.5 * std::tan(20 * M_PI / 180));
  const double distance_m = (eye - centroid).norm();
  EXPECT_TRUE(std::abs(distance_m - full_m) < 1e-9 || std::abs(distance_m - 0.6 * full_m) < 1e-9) << distance_m;
  double y_min = 1e9, y_max = -1e9, x_min = 1e9, x_max = -1e9;
  for (const Vector3d& p : region) {
    const Vector2d q = camera.Project(p);
    x_min = std::min(x_min, q.x()), x_max = std::max(x_max, q.x());
    y_min = std::min(y_min, q.y()), y_max = std::max(y_max, q.y());
    EXPECT_TRUE(q.x() >= 0 && q.x() < 1280 && q.y() >= 0 && q.y() < 960);
  }
  const double span = std::max(x_max - x_min, y_max - y_min) / 960.0;
  const double expected_span = 0.5 * full_m / distance_m;
  EXPECT_GT(span, expected_span * std::cos(50 * M_PI / 180) * 0.9);
  EXPECT_LT(span, expected_span * 1.25);  // perspective enlarges the near side a little
}

TEST(ViewSelectTest, CloseUpPrefersTheNormalWhenNothingBlocks) {
  ThermalMesh mesh;
  mesh.points_in_world = {{-2, 0, 0}, {2, 0, 0}, {2, 0, 3}, {-2, 0, 3}};
  mesh.faces = {{0, 1, 2}, {0, 2, 3}};
  const MeshRenderer renderer(mesh);
  const Vector3d centroid(0.5, 0, 1.0), normal(0, -1, 0);
  ViewSelectOptions options;
  double fraction = -1;
  // A 1 cm spot: the distance floor applies.
  const NamedView view = CloseUpView(renderer, centroid, normal, 0.01, {}, options, &fraction);
  EXPECT_EQ(fraction, 1.0);
  const Vector3d eye = view.camera.world_from_camera.translation();
  EXPECT_NEAR((eye - (centroid + options.close_up_min_distance_m * normal)).norm(), 0.0, 1e-9);
}

TEST(ViewSelectTest, FirstOverviewLooksAtTheScannedSideOfAPartialScan) {
  // One wall x = 0 facing −x (a scan taken from x < 0): the first overview's eye is on that
  // side, whatever first_azimuth_deg says; a closed box keeps the configured azimuth.
  ThermalMesh wall;
  wall.points_in_world = {{0, -1, 0}, {0, 1, 0}, {0, 1, 2}, {0, -1, 2}};
  wall.faces = {{0, 2, 1}, {0, 3, 2}};  // normal −x
  ViewSelectOptions options;
  const std::vector<NamedView> views = OverviewViews(wall, options);
  EXPECT_LT(views[0].camera.world_from_camera.translation().x(), -0.5);
  EXPECT_NEAR(views[0].camera.world_from_camera.translation().y(), 0, 1e-9);
  options.face_scanned_side = false;  // 45°: +x, +y quadrant
  EXPECT_GT(OverviewViews(wall, options)[0].camera.world_from_camera.translation().x(), 0.5);
  ThermalMesh box;
  AddBox(&box, Vector3d(-1, -1, 0), Vector3d(1, 1, 2));
  const Vector3d eye = OverviewViews(box, ViewSelectOptions())[0].camera.world_from_camera.translation();
  EXPECT_GT(eye.x(), 0.5);
  EXPECT_GT(eye.y(), 0.5);
}

TEST(ViewSelectTest, OptionCheckNamesTheField) {
  ViewSelectOptions options;
  options.overview_count = 0;
  EXPECT_NE(options.Check().find("overview_count"), std::string::npos);
  options = {};
  options.up_in_world = Vector3d::Zero();
  EXPECT_NE(options.Check().find("up_in_world"), std::string::npos);
  options = {};
  options.margin_fraction = 0.5;
  EXPECT_NE(options.Check().find("margin_fraction"), std::string::npos);
}

}  // namespace
}  // namespace hw::analyze
