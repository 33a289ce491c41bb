#include "analyze/spot_reflection.h"

#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "analyze/test_scene.h"
#include "core/ply.h"

namespace hw::analyze {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kSpotRadiusM = 0.05;

// A 1 m plate (z = 0, facing +z, 2 cm grid) at 20 °C with a 5 cm disc at `spot_c` round
// the origin, seen from `camera_in_world` (every vertex's view vector points there), and
// optionally a 0.4 m square at `source_c` centred at `source_at`, facing the plate's
// centre. Returns the mesh; *spot gets the disc's faces, peak and kind.
ThermalMesh Scene(const Eigen::Vector3d& camera_in_world, double spot_c, Spot* spot, bool with_views = true,
                  const Eigen::Vector3d& source_at = Eigen::Vector3d::Constant(NAN), double source_c = NAN) {
  test::SceneMesh scene;
  test::AddGrid(&scene, {-0.5, -0.5, 0}, {1, 0, 0}, {0, 1, 0}, 0.02);
  const size_t plate_vertices = scene.points.size();
  if (source_at.allFinite()) {
    const Eigen::Vector3d facing = -source_at.normalized();
    const Eigen::Vector3d u = facing.unitOrthogonal() * 0.4, v = facing.cross(u).normalized() * 0.4;
    test::AddGrid(&scene, source_at - 0.5 * u - 0.5 * v, u, v, 0.05);
  }
  std::vector<double> temperature, vx, vy, vz;
  for (size_t i = 0; i < scene.points.size(); ++i) {
    const Eigen::Vector3d& p = scene.points[i];
    temperature.push_back(i >= plate_vertices ? source_c : p.head<2>().norm() <= kSpotRadiusM ? spot_c : 20.0);
    const Eigen::Vector3d view = camera_in_world - p;
    vx.push_back(view.x());
    vy.push_back(view.y());
    vz.push_back(view.z());
  }
  core::PlyMesh ply;
  ply.SetPositions(scene.points, core::PlyType::kFloat64);
  ply.AddProperty("temperature_c", core::PlyType::kFloat64, temperature);
  if (with_views) {
    ply.AddProperty("temperature_view_x", core::PlyType::kFloat32, vx);
    ply.AddProperty("temperature_view_y", core::PlyType::kFloat32, vy);
    ply.AddProperty("temperature_view_z", core::PlyType::kFloat32, vz);
  }
  ply.faces = scene.faces;
  ThermalMesh mesh = MakeThermalMesh(ply, "scene.ply");
  *spot = Spot();
  spot->id = "H1";
  spot->hot = spot_c > 20;
  spot->peak_c = spot_c;
  spot->action = "Repair";
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const Eigen::Vector3i& face = mesh.faces[static_cast<size_t>(f)];
    const Eigen::Vector3d centroid =
        (mesh.points_in_world[face[0]] + mesh.points_in_world[face[1]] + mesh.points_in_world[face[2]]) / 3;
    if (std::abs(centroid.z()) < 1e-9 && centroid.head<2>().norm() <= kSpotRadiusM) spot->faces.push_back(f);
  }
  return mesh;
}

// The camera 1.5 m from the plate's centre at `angle_deg` from its normal (in the x-z plane).
Eigen::Vector3d CameraAt(double angle_deg) {
  const double a = angle_deg * kPi / 180;
  return 1.5 * Eigen::Vector3d(std::sin(a), 0, std::cos(a));
}

Spot Checked(const ThermalMesh& mesh, Spot spot, const ReflectionOptions& options = {}) {
  const MeshRenderer renderer(mesh);
  std::vector<Spot> spots = {spot};
  CheckReflections(mesh, renderer, options, &spots);
  return spots[0];
}

// Head-on, a shiny plate shows the thermographer: the mirror ray of every face returns to
// within 7.5 cm (the disc's radius at twice its slope) of the camera.
TEST(SpotReflectionTest, AWarmSpotSeenHeadOnIsTheOperatorsReflection) {
  Spot spot;
  const ThermalMesh mesh = Scene(CameraAt(0), 30, &spot);
  ASSERT_FALSE(mesh.view_m.empty());
  const Spot s = Checked(mesh, spot);
  EXPECT_TRUE(s.possible_reflection);
  EXPECT_EQ(s.reflection_source, "operator");
  EXPECT_DOUBLE_EQ(s.reflection_fraction, 1.0);
  EXPECT_LT(s.incidence_deg, 2.0);  // ≤ atan(5 cm / 1.5 m) = 1.9°
  EXPECT_LT((s.reflection_source_in_world - CameraAt(0)).norm(), 1e-6);
  EXPECT_TRUE(std::isnan(s.reflection_source_c));
  EXPECT_NE(s.action.find("Verify first"), std::string::npos) << s.action;
  EXPECT_NE(s.action.find("If it stays: Repair"), std::string::npos) << s.action;
}

// The operator's reach: at 10° the mirror ray passes 1.5 m · sin 20° = 0.51 m from the
// camera — inside the default 0.6 m, outside 0.4 m; at 20°, 0.96 m: outside.
TEST(SpotReflectionTest, TheOperatorIsWithinItsRadiusOfTheCamera) {
  Spot spot;
  const ThermalMesh at10 = Scene(CameraAt(10), 30, &spot);
  EXPECT_TRUE(Checked(at10, spot).possible_reflection);
  ReflectionOptions narrow;
  narrow.operator_radius_m = 0.4;
  const Spot s = Checked(at10, spot, narrow);
  EXPECT_FALSE(s.possible_reflection);
  EXPECT_DOUBLE_EQ(s.reflection_fraction, 0.0);
  EXPECT_EQ(s.reflection_source, "");
  EXPECT_EQ(s.action, "Repair");
  EXPECT_NEAR(s.incidence_deg, 10, 2);
  const ThermalMesh at20 = Scene(CameraAt(20), 30, &spot);
  EXPECT_FALSE(Checked(at20, spot).possible_reflection);
}

// A spot warmer than a person cannot be one; a cold spot is never the operator.
TEST(SpotReflectionTest, SpotsWarmerThanAPersonOrColdAreNotTheOperator) {
  Spot spot;
  const ThermalMesh hot = Scene(CameraAt(0), 45, &spot);
  Spot s = Checked(hot, spot);
  EXPECT_FALSE(s.possible_reflection);
  EXPECT_LT(s.incidence_deg, 2.0);
  ReflectionOptions warm;
  warm.operator_max_c = 50;
  EXPECT_TRUE(Checked(hot, spot, warm).possible_reflection);
  const ThermalMesh cold = Scene(CameraAt(0), 10, &spot);
  ASSERT_FALSE(spot.hot);
  EXPECT_FALSE(Checked(cold, spot).possible_reflection);
}

// Seen at 40°, the mirror ray leaves at 40° on the other side of the normal. A 60 °C panel
// there, 0.5 m away, is the source of a 30 °C spot (and is reported); a 25 °C one is not
// (cooler than the spot) and hides the rest of the room.
TEST(SpotReflectionTest, AHotterSurfaceInTheMirrorDirectionIsTheSource) {
  Spot spot;
  const Eigen::Vector3d mirror = CameraAt(-40).normalized();
  const ThermalMesh mesh = Scene(CameraAt(40), 30, &spot, true, 0.5 * mirror, 60);
  const Spot s = Checked(mesh, spot);
  EXPECT_TRUE(s.possible_reflection);
  EXPECT_EQ(s.reflection_source, "surface");
  EXPECT_DOUBLE_EQ(s.reflection_fraction, 1.0);
  EXPECT_NEAR(s.reflection_source_c, 60, 1e-9);
  // Every face's mirror ray is parallel (a far camera) within 2°: hits within 2 cm of the
  // panel's centre plus the face's own offset (≤ 5 cm).
  EXPECT_LT((s.reflection_source_in_world - 0.5 * mirror).norm(), 0.03);
  EXPECT_NEAR(s.incidence_deg, 40, 2);
  EXPECT_NE(s.action.find("60.0 °C surface"), std::string::npos) << s.action;
  const ThermalMesh cool = Scene(CameraAt(40), 30, &spot, true, 0.5 * mirror, 25);
  EXPECT_FALSE(Checked(cool, spot).possible_reflection);
  // A cold spot reflects a colder surface: 10 °C spot, 0 °C panel.
  const ThermalMesh cold = Scene(CameraAt(40), 10, &spot, true, 0.5 * mirror, 0);
  const Spot c = Checked(cold, spot);
  EXPECT_TRUE(c.possible_reflection);
  EXPECT_EQ(c.reflection_source, "surface");
}

// A panel that blocks the mirror ray before it reaches the camera hides the operator.
TEST(SpotReflectionTest, ASurfaceBetweenHidesTheOperator) {
  Spot spot;
  const ThermalMesh mesh = Scene(CameraAt(0), 30, &spot, true, Eigen::Vector3d(0, 0, 0.5), 20);
  // The panel is also between the camera and the plate: what the check sees is geometry
  // only (the views say the camera was there).
  EXPECT_FALSE(Checked(mesh, spot).possible_reflection);
}

TEST(SpotReflectionTest, WithoutViewVectorsOrWhenOffNothingIsChecked) {
  Spot spot;
  const ThermalMesh mesh = Scene(CameraAt(0), 30, &spot, false);
  EXPECT_TRUE(mesh.view_m.empty());
  Spot s = Checked(mesh, spot);
  EXPECT_FALSE(s.possible_reflection);
  EXPECT_TRUE(std::isnan(s.reflection_fraction));
  EXPECT_TRUE(std::isnan(s.incidence_deg));
  const ThermalMesh with = Scene(CameraAt(0), 30, &spot);
  ReflectionOptions off;
  off.check = false;
  s = Checked(with, spot, off);
  EXPECT_FALSE(s.possible_reflection);
  EXPECT_TRUE(std::isnan(s.reflection_fraction));
}

TEST(SpotReflectionTest, OptionsAreChecked) {
  const auto fails = [](const std::function<void(ReflectionOptions&)>& change, const std::string& field) {
    ReflectionOptions o;
    change(o);
    EXPECT_NE(o.Check().find(field), std::string::npos) << field << ": " << o.Check();
  };
  EXPECT_EQ(ReflectionOptions().Check(), "");
  fails([](ReflectionOptions& o) { o.operator_radius_m = 0; }, "operator_radius_m");
  fails([](ReflectionOptions& o) { o.operator_max_c = NAN; }, "operator_max_c");
  fails([](ReflectionOptions& o) { o.min_fraction = 1.5; }, "min_fraction");
  fails([](ReflectionOptions& o) { o.max_faces = 0; }, "max_faces");
}

}  // namespace
}  // namespace hw::analyze
