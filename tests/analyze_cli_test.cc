// End-to-end tests of `heatwave analyze`: spots, images and analyze.json from a PLY, and what
// bad meshes, configs and options do.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "analyze/test_scene.h"
#include "core/ply.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::TestFolder;
using Result = hw::test::CommandResult;

Result Heatwave(const std::string& args) {
  return hw::test::RunCommand(HW_HEATWAVE_EXE " " + args);
}

hw::core::PlyMesh Plate(bool with_temperature = true) { return hw::analyze::test::HotDiscPlate(with_temperature); }

// Small images so the test stays fast.
const std::string kConfig =
    "version: 1\n"
    "images:\n"
    "  width: 160\n"
    "  height: 120\n"
    "  samples_per_pixel: 1\n"
    "  overviews: 1\n";

fs::path Write(const fs::path& folder, const std::string& name, const std::string& text) {
  hw::core::WriteFileAtomically(folder / name, text);
  return folder / name;
}

TEST(AnalyzeCliTest, MeasuresTheDiscAndWritesImagesAndJson) {
  const fs::path dir = TestFolder();
  hw::core::WritePly(dir / "plate.ply", Plate());
  const fs::path config = Write(dir, "analyze.yaml", kConfig);
  const Result r = Heatwave("analyze " + (dir / "plate.ply").string() + " --out " + (dir / "out").string() +
                            " --config " + config.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("spots: 1"), std::string::npos) << r.output;
  const std::string json = hw::core::ReadFile(dir / "out" / "analyze.json", 1 << 24);
  EXPECT_NE(json.find("\"id\": \"H1\""), std::string::npos);
  EXPECT_NE(json.find("\"severity\": \"major\""), std::string::npos);
  // One overview + top + the close-up, four modes each; one float image per view.
  for (const std::string view : {"overview-1", "top", "H1"}) {
    for (const std::string mode : {"thermal", "colour", "ih", "highlight"}) {
      EXPECT_TRUE(fs::exists(dir / "out" / "images" / (view + "-" + mode + ".png"))) << view << " " << mode;
    }
    EXPECT_TRUE(fs::exists(dir / "out" / "images" / (view + "-temperature_c.exr"))) << view;
  }
  EXPECT_FALSE(fs::exists(dir / "out" / ".heatwave-run"));

  // A second run into the same folder needs --overwrite (usage error otherwise).
  const Result again = Heatwave("analyze " + (dir / "plate.ply").string() + " --out " + (dir / "out").string() +
                                " --config " + config.string() + " -q");
  EXPECT_EQ(again.exit_code, 2) << again.output;
  EXPECT_NE(again.output.find("--overwrite"), std::string::npos);
}

// A model that says how coarse the thermal image was (reconstruct's temperature_footprint_m):
// a 20 cm disc seen with 10 cm pixels is 2 pixels across, under-resolved and warned about;
// with 5 mm pixels it is 40 across.
TEST(AnalyzeCliTest, ASpotFewerThanThreeThermalPixelsAcrossIsWarnedAbout) {
  const fs::path dir = TestFolder();
  const fs::path config = Write(dir, "analyze.yaml", kConfig);
  for (const double footprint_m : {0.1, 0.005}) {
    hw::core::PlyMesh plate = Plate();
    plate.AddProperty("temperature_footprint_m", hw::core::PlyType::kFloat32,
                      std::vector<double>(plate.NumVertices(), footprint_m));
    const fs::path ply = dir / ("plate-" + std::to_string(footprint_m) + ".ply");
    hw::core::WritePly(ply, plate);
    const fs::path out = dir / ("out-" + std::to_string(footprint_m));
    const Result r = Heatwave("analyze " + ply.string() + " --out " + out.string() + " --config " + config.string() +
                              " --no-images");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const std::string json = hw::core::ReadFile(out / "analyze.json", 1 << 24);
    const bool coarse = footprint_m > 0.05;
    EXPECT_EQ(r.output.find("thermal pixels across (one covers 100.0 mm of its surface): under-resolved") !=
                  std::string::npos,
              coarse)
        << r.output;
    EXPECT_NE(json.find(coarse ? "\"resolved\": false" : "\"resolved\": true"), std::string::npos) << json;
    const size_t at = json.find("\"width_px\": ");
    ASSERT_NE(at, std::string::npos) << json;
    EXPECT_NEAR(std::strtod(json.c_str() + at + 12, nullptr), 0.2 / footprint_m, 0.02 / footprint_m);
  }
}

// The plate's 50 °C disc seen head-on from 1.5 m (view vectors as reconstruct writes
// them): flagged as the thermographer's reflection only when the config lets a person look
// 60 °C; analyze.json carries the check either way, and --no-images still checks.
TEST(AnalyzeCliTest, ASpotSeenHeadOnOnAShinySurfaceIsFlaggedAsAPossibleReflection) {
  const fs::path dir = TestFolder();
  hw::core::PlyMesh plate = Plate();
  const std::vector<Eigen::Vector3d> points = plate.Positions();
  for (int axis = 0; axis < 3; ++axis) {
    std::vector<double> component;
    for (const Eigen::Vector3d& p : points) component.push_back(Eigen::Vector3d(0, 0, 1.5)[axis] - p[axis]);
    plate.AddProperty(std::string("temperature_view_") + "xyz"[axis], hw::core::PlyType::kFloat32, component);
  }
  hw::core::WritePly(dir / "plate.ply", plate);
  for (const double max_c : {37.0, 60.0}) {
    const fs::path config = Write(dir, "analyze.yaml", kConfig + "reflections:\n  operator_max_c: " + std::to_string(max_c) + "\n");
    const fs::path out = dir / ("out-" + std::to_string(max_c));
    const Result r = Heatwave("analyze " + (dir / "plate.ply").string() + " --out " + out.string() + " --config " +
                              config.string() + " --no-images");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const std::string json = hw::core::ReadFile(out / "analyze.json", 1 << 24);
    EXPECT_NE(json.find("\"incidence_deg\": "), std::string::npos) << json;
    const bool flagged = max_c > 50;
    EXPECT_NE(json.find(flagged ? "\"possible_reflection\": true" : "\"possible_reflection\": false"), std::string::npos)
        << json;
    EXPECT_EQ(r.output.find("(reflection?)") != std::string::npos, flagged) << r.output;
    EXPECT_EQ(r.output.find("H1 may be a reflection: over 100 % of it the mirror direction of the views meets the "
                            "thermographer's body") != std::string::npos,
              flagged)
        << r.output;
  }
  // A bad value: exit 2 naming it.
  const fs::path bad = Write(dir, "bad.yaml", kConfig + "reflections:\n  min_fraction: 0\n");
  const Result r = Heatwave("analyze " + (dir / "plate.ply").string() + " --out " + (dir / "bad-out").string() +
                            " --config " + bad.string());
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("reflections.min_fraction"), std::string::npos) << r.output;
}

TEST(AnalyzeCliTest, WithoutTemperatureItRendersColourAndSaysSo) {
  const fs::path dir = TestFolder();
  hw::core::WritePly(dir / "plate.ply", Plate(false));
  const fs::path config = Write(dir, "analyze.yaml", kConfig);
  const Result r = Heatwave("analyze " + (dir / "plate.ply").string() + " --out " + (dir / "out").string() +
                            " --config " + config.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("no temperature_c"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(dir / "out" / "images" / "overview-1-colour.png"));
  EXPECT_FALSE(fs::exists(dir / "out" / "images" / "overview-1-thermal.png"));
  const std::string json = hw::core::ReadFile(dir / "out" / "analyze.json", 1 << 24);
  EXPECT_NE(json.find("\"has_temperature\": false"), std::string::npos);
}

TEST(AnalyzeCliTest, BadMeshesAreOneLineErrorsOrWarnings) {
  const fs::path dir = TestFolder();
  hw::core::PlyMesh cloud;
  cloud.SetPositions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  hw::core::WritePly(dir / "cloud.ply", cloud);
  Result r = Heatwave("analyze " + (dir / "cloud.ply").string() + " --out " + (dir / "o1").string() + " -q");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("cloud.ply: no triangles"), std::string::npos) << r.output;

  // NaN positions and temperatures, a degenerate triangle: warnings, still a result.
  hw::core::PlyMesh plate = Plate();
  plate.Get("x").values[5] = std::nan("");
  plate.Get("temperature_c").values[7] = INFINITY;
  plate.faces.emplace_back(0, 0, 1);
  hw::core::WritePly(dir / "bad.ply", plate);
  const fs::path config = Write(dir, "analyze.yaml", kConfig);
  r = Heatwave("analyze " + (dir / "bad.ply").string() + " --out " + (dir / "o2").string() + " --config " +
               config.string() + " --no-images");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("non-finite x y z dropped"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("degenerate triangles"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("infinite temperature_c"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("spots: 1"), std::string::npos) << r.output;

  r = Heatwave("analyze " + (dir / "missing.ply").string() + " --out " + (dir / "o3").string() + " -q");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
}

TEST(AnalyzeCliTest, BadConfigsNameKeyAndLine) {
  const fs::path dir = TestFolder();
  hw::core::WritePly(dir / "plate.ply", Plate());
  struct Case {
    std::string yaml, expected;
  };
  const Case cases[] = {
      {"version: 1\nspots:\n  min_delta: 2\n", "unknown key 'min_delta' (line 3)"},
      {"version: 1\nimages:\n  highlight_band_c: [30, 20]\n", "inverted band"},
      {"version: 1\nimages:\n  span_c: [30, 20]\n", "inverted span"},
      {"version: 1\nspots:\n  reference: ambient\n", "ambient_c"},
      {"version: 1\nseverity:\n  - {name: a, min_delta_k: 5}\n  - {name: b, min_delta_k: 1}\n", "severity[1].min_delta_k"},
      {"version: 1\nimages:\n  palette: jet\n", "images.palette"},
      {"version: 2\n", "version"},
  };
  int i = 0;
  for (const Case& c : cases) {
    const fs::path config = Write(dir, "c" + std::to_string(i) + ".yaml", c.yaml);
    const Result r = Heatwave("analyze " + (dir / "plate.ply").string() + " --out " +
                              (dir / ("o" + std::to_string(i++))).string() + " --config " + config.string() + " -q");
    EXPECT_EQ(r.exit_code, 1) << c.yaml << r.output;
    EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
    EXPECT_NE(r.output.find(c.expected), std::string::npos) << c.yaml << " → " << r.output;
    EXPECT_NE(r.output.find(config.filename().string()), std::string::npos) << r.output;
  }
  const Result usage = Heatwave("analyze " + (dir / "plate.ply").string() + " --out " + (dir / "u").string() +
                                " --truth-observed-only -q");
  EXPECT_EQ(usage.exit_code, 2) << usage.output;
}

}  // namespace
