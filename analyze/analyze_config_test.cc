#include "analyze/analyze_config.h"

#include <gtest/gtest.h>

#include "core/error.h"

namespace hw::analyze {
namespace {

std::string ErrorOf(const std::string& yaml) {
  try {
    ParseAnalyzeConfig(yaml, "analyze.yaml");
  } catch (const core::InputError& e) {
    return e.what();
  }
  return "";
}

TEST(AnalyzeConfigTest, ReadsEveryKey) {
  const AnalyzeConfig c = ParseAnalyzeConfig(
      "version: 1\n"
      "field: temperature_apparent_c\n"
      "spots:\n"
      "  detect: absolute\n"
      "  reference: ambient\n"
      "  ambient_c: 21.5\n"
      "  min_delta_k: 3\n"
      "  hot_above_c: 60\n"
      "  cold_below_c: 12\n"
      "  kinds: [hot]\n"
      "  boundary_fraction: 0.4\n"
      "  min_area_m2: 0.001\n"
      "  max_area_m2: 1\n"
      "  background_radius_m: 0.5\n"
      "  min_ring_coverage: 0.2\n"
      "  min_ring_area_ratio: 3\n"
      "severity:\n"
      "  - {name: minor, min_delta_k: 1, action: Monitor}\n"
      "  - {name: serious, min_delta_k: 10}\n"
      "reflections:\n"
      "  check: false\n"
      "  operator_radius_m: 0.8\n"
      "  operator_max_c: 35\n"
      "  min_fraction: 0.7\n"
      "  max_faces: 500\n"
      "images:\n"
      "  width: 640\n"
      "  height: 480\n"
      "  samples_per_pixel: 9\n"
      "  palette: rainbow-inverted\n"
      "  span_c: [20, 80]\n"
      "  highlight_band_c: [15, 35]\n"
      "  overviews: 2\n"
      "  closeups: false\n"
      "  max_closeups: 3\n"
      "  float_format: tiff\n"
      "  up: [0, -1, 0]\n"
      "  views:\n"
      "    - {name: front, eye: [0, -3, 1.5], target: [0, 0, 1], fov_y_deg: 50}\n"
      "    - {name: plan, eye: [0, 0, 5], target: [0, 0, 0], up: [0, 1, 0], ortho_height_m: 4}\n",
      "analyze.yaml");
  EXPECT_EQ(c.field, "temperature_apparent_c");
  EXPECT_EQ(c.spots.detect, SpotOptions::Detect::kAbsolute);
  EXPECT_EQ(c.spots.reference, SpotOptions::Reference::kAmbient);
  EXPECT_EQ(c.spots.ambient_c, 21.5);
  EXPECT_EQ(c.spots.min_delta_k, 3);
  EXPECT_TRUE(c.spots.find_hot);
  EXPECT_FALSE(c.spots.find_cold);
  EXPECT_EQ(c.spots.boundary_fraction, 0.4);
  EXPECT_EQ(c.spots.min_ring_coverage, 0.2);
  EXPECT_EQ(c.spots.min_ring_area_ratio, 3);
  ASSERT_EQ(c.spots.severity.size(), 2u);
  EXPECT_EQ(c.spots.severity[0].action, "Monitor");
  EXPECT_EQ(c.spots.severity[1].name, "serious");
  EXPECT_FALSE(c.reflections.check);
  EXPECT_EQ(c.reflections.operator_radius_m, 0.8);
  EXPECT_EQ(c.reflections.operator_max_c, 35);
  EXPECT_EQ(c.reflections.min_fraction, 0.7);
  EXPECT_EQ(c.reflections.max_faces, 500);
  EXPECT_EQ(c.width, 640);
  EXPECT_EQ(c.samples_per_pixel, 9);
  EXPECT_EQ(c.palette, "rainbow-inverted");
  EXPECT_EQ(c.span_max_c, 80);
  EXPECT_EQ(c.highlight_low_c, 15);
  EXPECT_FALSE(c.closeups);
  EXPECT_EQ(c.max_closeups, 3);
  EXPECT_EQ(c.float_format, "tiff");
  EXPECT_EQ(c.up_in_world, Eigen::Vector3d(0, -1, 0));
  ASSERT_EQ(c.views.size(), 2u);
  EXPECT_EQ(c.views[1].ortho_height_m, 4);
  EXPECT_EQ(c.views[1].up_in_world, Eigen::Vector3d(0, 1, 0));
}

TEST(AnalyzeConfigTest, DefaultsAreValid) {
  EXPECT_EQ(AnalyzeConfig().Check(), "");
  EXPECT_EQ(ParseAnalyzeConfig("version: 1\n", "a.yaml").width, 1280);
}

TEST(AnalyzeConfigTest, ErrorsNameKeyAndLine) {
  EXPECT_NE(ErrorOf("version: 1\nspot:\n  detect: delta\n").find("spot"), std::string::npos);
  EXPECT_NE(ErrorOf("version: 1\nspots:\n  detect: maybe\n").find("spots.detect"), std::string::npos);
  EXPECT_NE(ErrorOf("version: 1\nspots:\n  min_delta_k: -1\n").find("spots.min_delta_k"), std::string::npos);
  EXPECT_NE(ErrorOf("version: 1\nspots:\n  kinds: [warm]\n").find("spots.kinds"), std::string::npos);
  EXPECT_NE(ErrorOf("version: 1\nimages:\n  highlight_band_c: [30, 20]\n").find("inverted band"), std::string::npos);
  EXPECT_NE(ErrorOf("version: 1\nimages:\n  samples_per_pixel: 3\n").find("samples_per_pixel"), std::string::npos);
  EXPECT_NE(ErrorOf("version: 1\nimages:\n  views:\n    - {name: a, eye: [0, 0, 0], target: [0, 0, 0]}\n")
                .find("differ from eye"),
            std::string::npos);
  EXPECT_NE(ErrorOf("version: 1\nimages:\n  closeups: maybe\n").find("images.closeups"), std::string::npos);
  EXPECT_NE(ErrorOf("version: 1\nreflections:\n  mirror: true\n").find("mirror"), std::string::npos);
  EXPECT_NE(ErrorOf("version: 1\nreflections:\n  operator_radius_m: -1\n").find("reflections.operator_radius_m"),
            std::string::npos);
  const std::string e = ErrorOf("version: 1\nspots:\n  detect: absolute\n  hot_above_c: 50\n");
  EXPECT_NE(e.find("cold_below_c"), std::string::npos) << e;
  EXPECT_NE(e.find("analyze.yaml"), std::string::npos) << e;
}

}  // namespace
}  // namespace hw::analyze
