// End-to-end tests of `heatwave compare`: two scans of one small scene (an L of floor and
// wall plates with a box: every rigid motion is constrained), the second moved and with
// its spots changed; alignment, spot changes, images and compare.json, and bad inputs.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "core/ply.h"
#include "tests/support.h"

namespace {

namespace fs = std::filesystem;
using hw::test::TestFolder;
using Result = hw::test::CommandResult;

Result Heatwave(const std::string& args) { return hw::test::RunCommand(HW_HEATWAVE_EXE " " + args); }

// A disc of temperature on the surface: `peak_c` inside radius_m of centre, a smooth
// 8 mm-scale logistic edge (iso-line at the half level on the radius: the half-ΔT boundary
// of the detector, whatever the tessellation).
struct Disc {
  Eigen::Vector3d centre;
  double radius_m;
  double peak_c;
};

constexpr double kBackgroundC = 20;

double Temperature(const Eigen::Vector3d& p, const std::vector<Disc>& discs) {
  double t = kBackgroundC;
  for (const Disc& d : discs) t += (d.peak_c - kBackgroundC) / (1 + std::exp(((p - d.centre).norm() - d.radius_m) / 0.008));
  return t;
}

// The scene in BEFORE's frame, tessellated at `step_m`, with the discs' temperature, its
// vertices mapped by `transform`: floor z = 0 over [-0.6, 0.6]², wall x = −0.6 up to 1 m,
// a 0.3 m box on the floor (only the box: `only_box`); faces counter-clockwise seen from the open side.
hw::core::PlyMesh Scene(double step_m, const std::vector<Disc>& discs, const Eigen::Isometry3d& transform,
                        bool with_temperature = true, bool only_box = false) {
  std::vector<Eigen::Vector3d> points;
  std::vector<double> t;
  std::vector<hw::core::Rgb8> colours;
  hw::core::PlyMesh ply;
  auto rectangle = [&](const Eigen::Vector3d& origin, const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
    const int nu = static_cast<int>(std::lround(u.norm() / step_m)), nv = static_cast<int>(std::lround(v.norm() / step_m));
    const int first = static_cast<int>(points.size());
    for (int j = 0; j <= nv; ++j) {
      for (int i = 0; i <= nu; ++i) {
        const Eigen::Vector3d p = origin + u * i / nu + v * j / nv;
        points.push_back(transform * p);
        t.push_back(Temperature(p, discs));
        colours.emplace_back(150, 140, 120);
      }
    }
    for (int j = 0; j < nv; ++j) {
      for (int i = 0; i < nu; ++i) {
        const int a = first + j * (nu + 1) + i;
        ply.faces.emplace_back(a, a + 1, a + nu + 2);
        ply.faces.emplace_back(a, a + nu + 2, a + nu + 1);
      }
    }
  };
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX(), y = Eigen::Vector3d::UnitY(), z = Eigen::Vector3d::UnitZ();
  if (!only_box) {
    rectangle({-0.6, -0.6, 0}, 1.2 * x, 1.2 * y);  // floor, +z
    rectangle({-0.6, -0.6, 0}, 1.2 * y, 1.0 * z);  // wall, +x
  }
  const double b0 = 0.15, s = 0.3;
  rectangle({b0, b0, s}, s * x, s * y);             // top, +z
  rectangle({b0, b0, 0}, s * x, s * z);             // −y
  rectangle({b0, b0 + s, 0}, s * z, s * x);         // +y
  rectangle({b0, b0, 0}, s * z, s * y);             // −x
  rectangle({b0 + s, b0, 0}, s * y, s * z);         // +x
  ply.SetPositions(points);
  if (with_temperature) ply.AddProperty("temperature_c", hw::core::PlyType::kFloat32, t);
  ply.SetColors(colours);
  return ply;
}

// The discs: A on the floor heats from 30 to 38 °C, B on the wall (32 °C) is gone in AFTER,
// C on the floor (12 °C, cold) is new in AFTER.
const Disc kA{{0.2, -0.25, 0}, 0.08, 30}, kAHeated{{0.2, -0.25, 0}, 0.08, 38};
const Disc kB{{-0.6, 0.1, 0.6}, 0.08, 32};
const Disc kC{{-0.25, 0.25, 0}, 0.08, 12};

// AFTER's frame from BEFORE's: 4° about a tilted axis and 10 cm.
Eigen::Isometry3d Motion() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(4 * M_PI / 180, Eigen::Vector3d(0.2, 0.3, 1).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.06, -0.08, 0);
  return T;
}

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

// The number after "key": at or after `from` in `text` (the first element when an array).
double NumberAfter(const std::string& text, const std::string& key, size_t from = 0) {
  const size_t at = text.find("\"" + key + "\": ", from);
  if (at == std::string::npos) {
    ADD_FAILURE() << "no " << key;
    return NAN;
  }
  size_t p = at + key.size() + 4;
  while (p < text.size() && text[p] == '[') ++p;
  return std::strtod(text.c_str() + p, nullptr);
}

// The line of the changes array whose kinds are exactly `kinds` (e.g. "[\"heated\"]"), or "".
std::string ChangeLine(const std::string& json, const std::string& kinds) {
  const size_t changes = json.find("\"changes\": [");
  const size_t end = json.find("\n  ], \"images\": [", changes);  // the top-level list after it
  size_t at = json.find("\"kinds\": " + kinds, changes);
  if (changes == std::string::npos || at == std::string::npos || at > end) return "";
  const size_t begin = json.rfind('\n', at);
  return json.substr(begin, json.find('\n', at) - begin);
}

TEST(CompareCliTest, AlignsAndListsTheSpotChanges) {
  const fs::path dir = TestFolder();
  hw::core::WritePly(dir / "before.ply", Scene(0.02, {kA, kB}, Eigen::Isometry3d::Identity()));
  hw::core::WritePly(dir / "after.ply", Scene(0.018, {kAHeated, kC}, Motion()));
  const fs::path config = Write(dir, "analyze.yaml", kConfig);
  const Result r = Heatwave("compare " + (dir / "before.ply").string() + " " + (dir / "after.ply").string() +
                            " --out " + (dir / "out").string() + " --config " + config.string() + " --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("spots: 2 before, 2 after"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("verify"), std::string::npos) << r.output;
  const std::string json = hw::core::ReadFile(dir / "out" / "compare.json", 1 << 24);
  EXPECT_NE(json.find("\"before_checked_reflections\": false, \"after_checked_reflections\": false"),
            std::string::npos);

  // The alignment: both tessellations sample the same planes, so the pose is exact to well
  // below a millimetre and 0.05° (align_test's noiseless bound on a room).
  const size_t alignment = json.find("\"alignment\": {");
  ASSERT_NE(alignment, std::string::npos);
  const Eigen::Quaterniond truth(Motion().linear());
  Eigen::Quaterniond q;
  const size_t qat = json.find("\"q_xyzw\": [", alignment);
  ASSERT_EQ(std::sscanf(json.c_str() + qat, "\"q_xyzw\": [%lf, %lf, %lf, %lf]", &q.x(), &q.y(), &q.z(), &q.w()), 4);
  EXPECT_LT(q.angularDistance(truth) * 180 / M_PI, 0.05);
  Eigen::Vector3d translation;
  const size_t tat = json.find("\"translation_m\": [", alignment);
  ASSERT_EQ(std::sscanf(json.c_str() + tat, "\"translation_m\": [%lf, %lf, %lf]", &translation.x(), &translation.y(),
                        &translation.z()),
            3);
  EXPECT_LT((translation - Motion().translation()).norm(), 1e-3) << translation.transpose();
  EXPECT_GT(NumberAfter(json, "inlier_fraction", alignment), 0.9);
  EXPECT_LT(NumberAfter(json, "rms_residual_m", alignment), 1e-3);

  // A heated by 8 K at the same place and size; B vanished with its ΔT of 12 K; C appeared
  // 8 K below the floor. Peaks are vertex values of the smooth disc: within 0.5 K (the
  // logistic is within 5e-5 of its plateau at the centre; the tessellations differ).
  const std::string heated = ChangeLine(json, "[\"heated\"]");
  ASSERT_FALSE(heated.empty()) << json;
  EXPECT_NEAR(NumberAfter(heated, "peak_change_k"), 8, 0.5);
  EXPECT_NEAR(NumberAfter(heated, "peak_before_c"), 30, 0.5);
  EXPECT_NEAR(NumberAfter(heated, "peak_after_c"), 38, 0.5);
  EXPECT_LT(NumberAfter(heated, "distance_m"), 0.01);
  // Area π·0.08² = 201 cm²; tessellation error of the half-level line below 10 %.
  EXPECT_NEAR(NumberAfter(heated, "area_after_m2"), M_PI * 0.08 * 0.08, 0.1 * M_PI * 0.08 * 0.08);
  const std::string vanished = ChangeLine(json, "[\"vanished\"]");
  ASSERT_FALSE(vanished.empty()) << json;
  EXPECT_NEAR(NumberAfter(vanished, "peak_before_c"), 32, 0.5);
  EXPECT_NEAR(NumberAfter(vanished, "delta_before_k"), 12, 0.5);
  const std::string appeared = ChangeLine(json, "[\"appeared\"]");
  ASSERT_FALSE(appeared.empty()) << json;
  EXPECT_NEAR(NumberAfter(appeared, "peak_after_c"), 12, 0.5);
  EXPECT_NEAR(NumberAfter(appeared, "delta_after_k"), -8, 0.5);

  // The difference: most of the surface did not change; the symmetric span covers B's
  // vanished excess, rounded out to the ticks' step (5 K for ±12: ±15).
  EXPECT_NEAR(NumberAfter(json, "median_k"), 0, 0.05);
  EXPECT_NEAR(NumberAfter(json, "span_k"), -15, 1e-9);

  // Images: the overview and top of AFTER, and one close-up per change.
  for (const std::string view : {"overview-1", "top", "H1", "C1"}) {
    for (const std::string kind : {"difference", "difference-highlight", "thermal"}) {
      EXPECT_TRUE(fs::exists(dir / "out" / "images" / (view + "-" + kind + ".png"))) << view << " " << kind;
    }
    EXPECT_TRUE(fs::exists(dir / "out" / "images" / (view + "-difference_k.exr"))) << view;
  }
  EXPECT_NE(vanished.find("\"name\": \"before-H1\""), std::string::npos) << vanished;
  EXPECT_TRUE(fs::exists(dir / "out" / "images" / "before-H1-difference.png"));
  EXPECT_FALSE(fs::exists(dir / "out" / ".heatwave-run"));

  // A second run into the same folder needs --overwrite.
  const Result again = Heatwave("compare " + (dir / "before.ply").string() + " " + (dir / "after.ply").string() +
                                " --out " + (dir / "out").string() + " -q --no-images");
  EXPECT_EQ(again.exit_code, 2) << again.output;
  EXPECT_NE(again.output.find("--overwrite"), std::string::npos) << again.output;
  const Result replaced = Heatwave("compare " + (dir / "before.ply").string() + " " + (dir / "after.ply").string() +
                                   " --out " + (dir / "out").string() + " -q --no-images --overwrite");
  EXPECT_EQ(replaced.exit_code, 0) << replaced.output;
  EXPECT_FALSE(fs::exists(dir / "out" / "images"));
}

// Every vertex's view vector (temperature_view_x/_y/_z, what reconstruct writes: to the
// thermal camera, world frame, m) towards `camera` (BEFORE's frame, carried by `transform`
// as the scene's vertices are).
void AddViews(hw::core::PlyMesh* ply, const Eigen::Vector3d& camera, const Eigen::Isometry3d& transform) {
  std::vector<double> view[3];
  const hw::core::PlyProperty* x = ply->Find("x");
  const hw::core::PlyProperty* y = ply->Find("y");
  const hw::core::PlyProperty* z = ply->Find("z");
  for (size_t i = 0; i < x->values.size(); ++i) {
    const Eigen::Vector3d v = transform * camera - Eigen::Vector3d(x->values[i], y->values[i], z->values[i]);
    for (int k = 0; k < 3; ++k) view[k].push_back(v[k]);
  }
  ply->AddProperty("temperature_view_x", hw::core::PlyType::kFloat32, view[0]);
  ply->AddProperty("temperature_view_y", hw::core::PlyType::kFloat32, view[1]);
  ply->AddProperty("temperature_view_z", hw::core::PlyType::kFloat32, view[2]);
}

// Two scans of shiny surfaces, each flagging a spot as the thermographer's reflection: BEFORE
// looked straight down at A (30 °C, no warmer than a person: its mirror ray returns to the
// camera), AFTER straight down at D, a 31 °C disc that "appeared" on the floor (AFTER's H1:
// its ΔT is the larger; A is H2). Both flags are in the warnings and compare.json; D's
// appearance is marked for a second view, A's unchanged pair is not (AFTER read it the same
// from 29° off head-on, where its mirror ray leaves the scene: the second view was taken).
// Without view vectors (the first test) nothing is checked.
TEST(CompareCliTest, ChangesThatMayBeReflectionsAreMarkedForVerification) {
  const fs::path dir = TestFolder();
  const Disc d{{-0.25, 0.25, 0}, 0.08, 31};
  hw::core::PlyMesh before = Scene(0.02, {kA}, Eigen::Isometry3d::Identity());
  AddViews(&before, kA.centre + Eigen::Vector3d(0, 0, 1.2), Eigen::Isometry3d::Identity());
  hw::core::PlyMesh after = Scene(0.018, {kA, d}, Motion());
  AddViews(&after, d.centre + Eigen::Vector3d(0, 0, 1.2), Motion());
  hw::core::WritePly(dir / "before.ply", before);
  hw::core::WritePly(dir / "after.ply", after);
  const Result r = Heatwave("compare " + (dir / "before.ply").string() + " " + (dir / "after.ply").string() +
                            " --out " + (dir / "out").string() + " --no-images --threads 2");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("appeared (refl.?)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("verify: H1 (AFTER) may be a reflection in that scan"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("warning: BEFORE: H1 may be a reflection: over 100 % of it"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("warning: AFTER: H1 may be a reflection: over 100 % of it"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("AFTER: H2 may be"), std::string::npos) << r.output;
  const std::string json = hw::core::ReadFile(dir / "out" / "compare.json", 1 << 24);
  const std::string appeared = ChangeLine(json, "[\"appeared\"]");
  ASSERT_FALSE(appeared.empty()) << json;
  EXPECT_NEAR(NumberAfter(appeared, "peak_after_c"), 31, 0.5);
  EXPECT_NE(appeared.find("\"before_possible_reflection\": false, \"after_possible_reflection\": true, "
                          "\"needs_second_view\": true"),
            std::string::npos)
      << appeared;
  const std::string unchanged = ChangeLine(json, "[]");
  ASSERT_FALSE(unchanged.empty()) << json;
  EXPECT_NE(unchanged.find("\"before_possible_reflection\": true, \"after_possible_reflection\": false, "
                           "\"needs_second_view\": false"),
            std::string::npos)
      << unchanged;
  EXPECT_NE(json.find("\"before_checked_reflections\": true, \"after_checked_reflections\": true"),
            std::string::npos);

  // The check off (analyze.yaml): the same changes, nothing flagged.
  const fs::path config = Write(dir, "off.yaml", "version: 1\nreflections:\n  check: false\n");
  const Result off = Heatwave("compare " + (dir / "before.ply").string() + " " + (dir / "after.ply").string() +
                              " --out " + (dir / "off").string() + " --no-images --config " + config.string());
  ASSERT_EQ(off.exit_code, 0) << off.output;
  EXPECT_EQ(off.output.find("refl"), std::string::npos) << off.output;
  EXPECT_NE(off.output.find("appeared"), std::string::npos) << off.output;
}

TEST(CompareCliTest, BadInputsAreOneLineErrors) {
  const fs::path dir = TestFolder();
  hw::core::WritePly(dir / "before.ply", Scene(0.04, {kA}, Eigen::Isometry3d::Identity()));
  hw::core::WritePly(dir / "bare.ply", Scene(0.04, {kA}, Eigen::Isometry3d::Identity(), false));
  Result r = Heatwave("compare " + (dir / "before.ply").string() + " " + (dir / "bare.ply").string() + " --out " +
                      (dir / "o1").string() + " -q");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("bare.ply: no temperature_c: nothing to compare"), std::string::npos) << r.output;

  r = Heatwave("compare " + (dir / "missing.ply").string() + " " + (dir / "before.ply").string() + " --out " +
               (dir / "o2").string() + " -q");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(hw::test::CountLines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("missing.ply"), std::string::npos) << r.output;

  r = Heatwave("compare " + (dir / "before.ply").string() + " --out " + (dir / "o3").string() + " -q");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  r = Heatwave("compare " + (dir / "before.ply").string() + " " + (dir / "before.ply").string() + " --out " +
               (dir / "o4").string() + " --threads -1 -q");
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

// AFTER holds only the box (0.45 m² of BEFORE's 3.09 m²): at most 15 % of BEFORE's samples
// can find AFTER's surface, below the 50 % the warning asks for; still a result.
TEST(CompareCliTest, WarnsWhenTheModelsOverlapLittle) {
  const fs::path dir = TestFolder();
  hw::core::WritePly(dir / "before.ply", Scene(0.04, {kA}, Eigen::Isometry3d::Identity()));
  hw::core::WritePly(dir / "box.ply", Scene(0.04, {}, Eigen::Isometry3d::Identity(), true, true));
  const Result r = Heatwave("compare " + (dir / "before.ply").string() + " " + (dir / "box.ply").string() +
                            " --out " + (dir / "out").string() + " --no-images");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("warning: alignment: only"), std::string::npos) << r.output;
  const std::string json = hw::core::ReadFile(dir / "out" / "compare.json", 1 << 24);
  EXPECT_LT(NumberAfter(json, "inlier_fraction"), 0.2);
  EXPECT_NE(json.find("\"warnings\": [\n    \"alignment: only"), std::string::npos) << json;
}

}  // namespace
