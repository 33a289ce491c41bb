#include "analyze/thermal_mesh.h"

#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "core/error.h"

namespace hw::analyze {
namespace {

// Two unit squares side by side in z = 0, the second with its own copies of the shared
// edge's vertices (a seam), and temperatures 10..70.
core::PlyMesh TwoSquares() {
  core::PlyMesh ply;
  ply.SetPositions({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},  // left
                    {1, 0, 0}, {2, 0, 0}, {2, 1, 0}, {1, 1, 0}});  // right, seam copies 4 and 7
  ply.AddProperty("temperature_c", core::PlyType::kFloat32, {10, 20, 30, 40, 20, 50, 60, 30});
  ply.faces = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}};
  return ply;
}

TEST(ThermalMeshTest, ReadsAreaNormalsAndTemperature) {
  const ThermalMesh mesh = MakeThermalMesh(TwoSquares(), "two.ply");
  EXPECT_EQ(mesh.NumVertices(), 8);
  EXPECT_EQ(mesh.NumFaces(), 4);
  EXPECT_NEAR(mesh.TotalArea(), 2.0, 1e-12);
  EXPECT_TRUE(mesh.HasTemperature());
  EXPECT_FALSE(mesh.HasColour());
  EXPECT_EQ(mesh.temperature_c[5], 50);
  for (const auto& n : mesh.normals) EXPECT_NEAR(n.z(), 1.0, 1e-12);
}

// View vectors load as a triple (NaN kept where unobserved); one or two of the three alone
// are not a vector: warned about, not used.
TEST(ThermalMeshTest, ViewVectorsLoadAsATriple) {
  core::PlyMesh ply = TwoSquares();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  ply.AddProperty("temperature_view_x", core::PlyType::kFloat32, {1, 1, 1, 1, 1, 1, 1, nan});
  ply.AddProperty("temperature_view_y", core::PlyType::kFloat32, {0, 0, 0, 0, 0, 0, 0, 0});
  const ThermalMesh partial = MakeThermalMesh(ply, "two.ply");
  EXPECT_TRUE(partial.view_m.empty());
  ASSERT_EQ(partial.report.warnings.size(), 1u);
  EXPECT_NE(partial.report.warnings[0].find("temperature_view_x/_y/_z"), std::string::npos);
  ply.AddProperty("temperature_view_z", core::PlyType::kFloat32, {2, 2, 2, 2, 2, 2, 2, 2});
  const ThermalMesh full = MakeThermalMesh(ply, "two.ply");
  ASSERT_EQ(full.view_m.size(), 8u);
  EXPECT_EQ(full.view_m[0], Eigen::Vector3d(1, 0, 2));
  EXPECT_TRUE(std::isnan(full.view_m[7].x()));
  EXPECT_TRUE(full.report.warnings.empty());
}

TEST(ThermalMeshTest, GraphJoinsSeamVertices) {
  const ThermalMesh mesh = MakeThermalMesh(TwoSquares(), "two.ply");
  const VertexGraph graph = BuildVertexGraph(mesh);
  // Vertex 1 and its copy 4 are linked; without welding the halves would be disconnected.
  bool linked = false;
  for (int i = graph.offsets[4]; i < graph.offsets[5]; ++i) linked |= graph.neighbours[i] == 1;
  EXPECT_TRUE(linked);
  const std::vector<int> weld = WeldMap(mesh.points_in_world);
  EXPECT_EQ(weld[4], 1);
  EXPECT_EQ(weld[7], 2);
  EXPECT_EQ(weld[5], 5);
}

TEST(ThermalMeshTest, DropsNonFiniteAndDegenerate) {
  core::PlyMesh ply = TwoSquares();
  std::vector<double>& x = ply.Get("x").values;
  x[6] = std::numeric_limits<double>::quiet_NaN();  // kills face {4,5,6} and {4,6,7}
  ply.faces.push_back({0, 0, 1});                    // repeated index
  ply.faces.push_back({0, 1, 1});
  std::vector<double>& t = ply.Get("temperature_c").values;
  t[0] = std::numeric_limits<double>::infinity();
  const ThermalMesh mesh = MakeThermalMesh(ply, "bad.ply");
  EXPECT_EQ(mesh.NumFaces(), 2);
  EXPECT_EQ(mesh.report.vertices_non_finite, 1);
  EXPECT_EQ(mesh.report.faces_degenerate, 2);
  EXPECT_EQ(mesh.report.temperatures_non_finite, 1);
  EXPECT_TRUE(std::isnan(mesh.temperature_c[0]));
  EXPECT_EQ(mesh.report.warnings.size(), 3u);
}

TEST(ThermalMeshTest, RejectsEmptyAndPointClouds) {
  core::PlyMesh cloud;
  cloud.SetPositions({{0, 0, 0}, {1, 0, 0}});
  EXPECT_THROW(MakeThermalMesh(cloud, "cloud.ply"), core::InputError);
  core::PlyMesh flat = TwoSquares();
  flat.Get("y").values.assign(8, 0.0);  // every triangle collapses onto a line
  try {
    MakeThermalMesh(flat, "flat.ply");
    FAIL();
  } catch (const core::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("flat.ply"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("degenerate"), std::string::npos);
  }
}

TEST(ThermalMeshTest, WithoutTemperatureLoadsAndWarns) {
  core::PlyMesh ply = TwoSquares();
  ply.RemoveProperty("temperature_c");
  ply.SetColors(std::vector<core::Rgb8>(8, core::Rgb8(255, 128, 0)));
  const ThermalMesh mesh = MakeThermalMesh(ply, "c.ply");
  EXPECT_FALSE(mesh.HasTemperature());
  ASSERT_TRUE(mesh.HasColour());
  EXPECT_NEAR(mesh.colour_linear[0].x(), 1.0f, 1e-6f);
  EXPECT_NEAR(mesh.colour_linear[0].y(), 0.2158605f, 1e-5f);  // sRGB 128 decoded
  EXPECT_EQ(mesh.report.warnings.size(), 1u);
  EXPECT_THROW(MakeThermalMesh(ply, "c.ply", "temperature_apparent_c"), core::InputError);
}

}  // namespace
}  // namespace hw::analyze
