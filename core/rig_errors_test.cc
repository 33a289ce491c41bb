#include "core/rig.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "tests/support.h"
#include "core/rig_test_support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using hw::test::LineOf;
using hw::test::Replace;
using ::testing::HasSubstr;
using ::testing::StartsWith;
using namespace rig_test;

// ---------------------------------------------------------------------------------------
// Malformed rig.yaml.

struct BadRig {
  std::string name;
  std::string text;
  std::string expected;  // substring of what()
};

std::vector<BadRig> BadRigs() {
  const std::string full = kFullRig;
  const std::string no_rgb = Replace(full, kRgbBlock, "");
  const std::string no_thermal_camera = Replace(full, kThermalCameraBlock, "");
  return {
      // Values out of range.
      {"negative focal", Replace(full, "fx: 180.5", "fx: -3"),
       "cameras.thermal.fx: must be in [1, 1e6] px, got -3"},
      {"zero focal", Replace(full, "fy: 526.0", "fy: 0"),
       "cameras.depth.fy: must be in [1, 1e6] px, got 0"},
      {"zero width", Replace(full, "width: 640", "width: 0"),
       "cameras.depth.width: must be in [1, 16384] px, got 0"},
      {"negative height", Replace(full, "height: 720", "height: -720"),
       "cameras.rgb.height: must be in [1, 16384] px, got -720"},
      {"non-unit quaternion", Replace(full, "[0, 0, 0, 1]", "[0, 0, 0, 1.2]"),
       "extrinsics.depth_from_rgb.q_xyzw: not a unit quaternion (norm 1.2)"},
      {"quaternion off by 2e-6",
       Replace(full, "[0.0, 0.0, 0.6, 0.8]", "[0.0, 0.0, 0.6, 0.8000016]"),
       "extrinsics.depth_from_thermal.q_xyzw: not a unit quaternion (norm 1.00000128)"},
      {"zero quaternion", Replace(full, "[0.0, 0.0, 0.6, 0.8]", "[0, 0, 0, 0]"),
       "extrinsics.depth_from_thermal.q_xyzw: not a unit quaternion (norm 0)"},
      {"unknown model", Replace(full, "model: pinhole", "model: fisheye"),
       "cameras.depth.model: must be pinhole, opencv or splined, got 'fisheye'"},
      {"opencv with 3 coefficients",
       Replace(full, "[0.1, -0.25, 0.001, -0.002, 0.05]", "[0.1, 0, 0]"),
       "cameras.rgb.distortion: opencv needs 4, 5 or 8 coefficients, got 3"},
      {"opencv with none", Replace(full, "[-0.3, 0.12, 0.0005, 0.0007]", "[]"),
       "cameras.thermal.distortion: opencv needs 4, 5 or 8 coefficients, got 0"},
      {"pinhole with coefficients", Replace(full, "distortion: []", "distortion: [0.1, 0, 0, 0]"),
       "cameras.depth.distortion: pinhole needs 0 coefficients, got 4"},
      {"band decreasing", Replace(full, "[7.5, 14.0]", "[14.0, 7.5]"),
       "thermal.spectral_band_um: must be [lo, hi] with 0.1 <= lo < hi <= 1000 µm, got [14, 7.5]"},
      {"band from zero", Replace(full, "[7.5, 14.0]", "[0, 14.0]"),
       "thermal.spectral_band_um: must be [lo, hi] with 0.1 <= lo < hi <= 1000 µm, got [0, 14]"},
      {"band negative", Replace(full, "[7.5, 14.0]", "[-8, -7.5]"),
       "thermal.spectral_band_um: must be [lo, hi] with 0.1 <= lo < hi <= 1000 µm, got [-8, -7.5]"},
      {"band equal", Replace(full, "[7.5, 14.0]", "[7.5, 7.5]"),
       "thermal.spectral_band_um: must be [lo, hi] with 0.1 <= lo < hi <= 1000 µm, got [7.5, 7.5]"},
      {"emissivity 0", Replace(full, "emissivity: 0.95", "emissivity: 0"),
       "thermal.emissivity: must be in [0.01, 1], got 0"},
      {"emissivity above 1", Replace(full, "emissivity: 0.95", "emissivity: 1.01"),
       "thermal.emissivity: must be in [0.01, 1], got 1.01"},
      {"negative netd", Replace(full, "netd_k: 0.04", "netd_k: -0.01"),
       "thermal.netd_k: must be in [0, 10] K, got -0.01"},
      {"zero raw scale", Replace(full, "raw_scale: 0.01", "raw_scale: 0"),
       "thermal.raw_scale: |raw_scale| must be in [1e-6, 10] °C per count (either sign), got 0"},
      {"reflected below absolute zero", Replace(full, "reflected_c: 20.0", "reflected_c: -300"),
       "thermal.reflected_c: must be in (-273.15, 3000] °C (above absolute zero), got -300"},
      {"zero depth scale", Replace(full, "depth_scale: 1000.0", "depth_scale: 0"),
       "depth_scale: must be in [1, 1e6] raw units per metre, got 0"},
      {"negative depth scale", Replace(full, "depth_scale: 1000.0", "depth_scale: -1000"),
       "depth_scale: must be in [1, 1e6] raw units per metre, got -1000"},
      {"depth clock offset", Replace(full, "  rgb: 0.0\n", "  rgb: 0.0\n  depth: 0.1\n"),
       "time_offset_s.depth: must be 0 (depth is the reference clock), got 0.1"},
      {"version 2", Replace(full, "version: 1", "version: 2"), "version: unsupported version 2"},
      {"version 2 with new keys", Replace(full, "version: 1", "version: 2\nnew_key: 3"),
       "version: unsupported version 2"},
      {"version 0", Replace(full, "version: 1", "version: 0"), "version: unsupported version 0"},
      {"version float", Replace(full, "version: 1", "version: 1.0"),
       "version: must be an integer, got '1.0'"},
      {"version quoted", Replace(full, "version: 1", "version: \"1\""),
       "version: must be an integer, got string \"1\""},

      // Unknown keys at every level.
      {"unknown top key", full + "colour: red\n", "top level: unknown key 'colour'"},
      {"unknown camera key", Replace(full, "    fx: 525.0\n", "    fx: 525.0\n    fxx: 525.0\n"),
       "cameras.depth: unknown key 'fxx'"},
      {"misspelt camera key", Replace(full, "    fx: 910.25\n", "    f_x: 910.25\n"),
       "cameras.rgb: unknown key 'f_x'"},
      {"unknown camera", Replace(full, "cameras:\n", "cameras:\n  ir:\n    width: 1\n"),
       "cameras: unknown key 'ir'"},
      {"unknown extrinsics", Replace(full, "extrinsics:\n", "extrinsics:\n  depth_from_ir: {}\n"),
       "extrinsics: unknown key 'depth_from_ir'"},
      {"unknown transform key", Replace(full, "t_m: [-0.025", "scale: 1, t_m: [-0.025"),
       "extrinsics.depth_from_rgb: unknown key 'scale'"},
      {"unknown time offset", Replace(full, "  rgb: 0.0\n", "  rgb: 0.0\n  ir: 0.1\n"),
       "time_offset_s: unknown key 'ir'"},
      {"unknown thermal key", Replace(full, "  netd_k: 0.04\n", "  netd_k: 0.04\n  gain: 2\n"),
       "thermal: unknown key 'gain'"},
      {"duplicate key", Replace(full, "    fx: 525.0\n", "    fx: 525.0\n    fx: 530.0\n"),
       "cameras.depth: duplicate key 'fx'"},
      {"duplicate top key", full + "version: 1\n", "top level: duplicate key 'version'"},
      {"duplicate flow key",
       Replace(full, "t_m: [-0.025, 0.0, 0.0]", "t_m: [1, 2, 3], t_m: [1, 2, 3]"),
       "extrinsics.depth_from_rgb: duplicate key 't_m'"},
      {"non-scalar key", full + "? [a, b]\n: 1\n", "top level: keys must be plain names"},

      // Missing keys.
      {"missing version", Replace(full, "version: 1\n", ""), "version: missing required key"},
      {"missing depth scale", Replace(full, "depth_scale: 1000.0\n", ""),
       "depth_scale: missing required key"},
      {"missing fy", Replace(full, "    fy: 911.5\n", ""), "cameras.rgb.fy: missing required key"},
      {"missing model", Replace(full, "    model: pinhole\n", ""),
       "cameras.depth.model: missing required key"},
      {"missing distortion", Replace(full, "    distortion: []\n", ""),
       "cameras.depth.distortion: missing required key"},
      {"missing depth camera",
       Replace(full,
               "  depth:\n    width: 640\n    height: 480\n    model: pinhole\n"
               "    fx: 525.0\n    fy: 526.0\n    cx: 319.5\n    cy: 239.5\n"
               "    distortion: []\n",
               ""),
       "cameras.depth: missing required key"},
      {"missing cameras", "version: 1\ndepth_scale: 1000\n", "cameras: missing required key"},
      {"missing netd", Replace(full, "  netd_k: 0.04\n", ""),
       "thermal.netd_k: missing required key"},
      {"missing thermal block", Replace(full, kThermalBlock, ""), "thermal: missing required key"},
      {"missing thermal offset", Replace(full, "  thermal: -0.04\n", ""),
       "time_offset_s.thermal: missing required key"},
      {"missing time offsets", Replace(full, "time_offset_s:\n  rgb: 0.0\n  thermal: -0.04\n", ""),
       "time_offset_s.rgb: missing required key"},
      {"missing rgb extrinsics",
       Replace(full, "  depth_from_rgb: { q_xyzw: [0, 0, 0, 1], t_m: [-0.025, 0.0, 0.0] }\n", ""),
       "extrinsics.depth_from_rgb: missing required key"},
      {"missing t_m", Replace(full, ", t_m: [-0.025, 0.0, 0.0]", ""),
       "extrinsics.depth_from_rgb.t_m: missing required key"},

      // Blocks for cameras that are absent.
      {"rgb extrinsics without rgb", no_rgb,
       "extrinsics.depth_from_rgb: given but cameras.rgb is absent"},
      {"rgb offset without rgb",
       Replace(no_rgb, "  depth_from_rgb: { q_xyzw: [0, 0, 0, 1], t_m: [-0.025, 0.0, 0.0] }\n", ""),
       "time_offset_s.rgb: given but cameras.rgb is absent"},
      {"thermal extrinsics without thermal", no_thermal_camera,
       "extrinsics.depth_from_thermal: given but cameras.thermal is absent"},
      {"thermal block without thermal",
       Replace(Replace(no_thermal_camera,
                       "  depth_from_thermal: { q_xyzw: [0.0, 0.0, 0.6, 0.8], t_m: [0.03, 0.01, "
                       "-0.002] }\n",
                       ""),
               "  thermal: -0.04\n", ""),
       "thermal: given but cameras.thermal is absent"},

      // Wrong types.
      {"quoted number", Replace(full, "fx: 525.0", "fx: \"525.0\""),
       "cameras.depth.fx: must be a number, got string \"525.0\""},
      {"word for number", Replace(full, "fx: 525.0", "fx: five"),
       "cameras.depth.fx: must be a number, got 'five'"},
      {"number with unit", Replace(full, "cx: 319.5", "cx: 319.5px"),
       "cameras.depth.cx: must be a number, got '319.5px'"},
      {"list for number", Replace(full, "fx: 525.0", "fx: [525.0]"),
       "cameras.depth.fx: must be a number, got a list"},
      {"mapping for number", Replace(full, "fx: 525.0", "fx: {value: 525.0}"),
       "cameras.depth.fx: must be a number, got a mapping"},
      {"nothing for number", Replace(full, "fx: 525.0", "fx:"),
       "cameras.depth.fx: must be a number, got nothing"},
      {"infinite number", Replace(full, "cy: 239.5", "cy: .inf"),
       "cameras.depth.cy: must be finite, got '.inf'"},
      {"nan", Replace(full, "cy: 239.5", "cy: nan"), "cameras.depth.cy: must be finite, got 'nan'"},
      {"overflowing number", Replace(full, "depth_scale: 1000.0", "depth_scale: 1e999"),
       "depth_scale: number out of range"},
      {"double sign", Replace(full, "fx: 525.0", "fx: +-525.0"),
       "cameras.depth.fx: must be a number, got '+-525.0'"},
      {"fractional width", Replace(full, "width: 640", "width: 640.5"),
       "cameras.depth.width: must be an integer, got '640.5'"},
      {"huge width", Replace(full, "width: 640", "width: 99999999999"),
       "cameras.depth.width: integer out of range"},
      {"list for model", Replace(full, "model: pinhole", "model: [pinhole]"),
       "cameras.depth.model: must be a name, got a list"},
      {"scalar distortion", Replace(full, "distortion: []", "distortion: 0"),
       "cameras.depth.distortion: must be a list of numbers, got '0'"},
      {"word in distortion", Replace(full, "[0.1, -0.25, 0.001, -0.002, 0.05]", "[0.1, x, 0, 0]"),
       "cameras.rgb.distortion[1]: must be a number, got 'x'"},
      {"short quaternion", Replace(full, "[0, 0, 0, 1]", "[0, 0, 1]"),
       "extrinsics.depth_from_rgb.q_xyzw: must be a list of 4 numbers, got 3"},
      {"long translation", Replace(full, "[0.03, 0.01, -0.002]", "[0.03, 0.01, -0.002, 1]"),
       "extrinsics.depth_from_thermal.t_m: must be a list of 3 numbers, got 4"},
      {"short band", Replace(full, "[7.5, 14.0]", "[7.5]"),
       "thermal.spectral_band_um: must be a list of 2 numbers, got 1"},
      {"scalar transform",
       Replace(full, "{ q_xyzw: [0, 0, 0, 1], t_m: [-0.025, 0.0, 0.0] }", "identity"),
       "extrinsics.depth_from_rgb: must be a mapping of keys, got 'identity'"},
      {"list for cameras", "version: 1\ndepth_scale: 1000\ncameras: [depth]\n",
       "cameras: must be a mapping of keys, got a list"},
      {"empty camera", Replace(full, kThermalCameraBlock, "  thermal:\n"),
       "cameras.thermal: must be a mapping of keys, got nothing"},

      // Not YAML, or not one mapping.
      {"empty", "", "rig.yaml: empty file"},
      {"only comments", "# nothing here\n\n", "rig.yaml: empty file"},
      {"empty document", "---\n...\n", "rig.yaml: empty file"},
      {"top-level list", "- version\n- 1\n",
       "expected a mapping of keys at the top level, got a list"},
      {"top-level scalar", "rig", "expected a mapping of keys at the top level, got 'rig'"},
      {"two documents", full + "---\nversion: 1\n",
       "more than one YAML document (the second starts on line 44)"},
      {"two empty documents", "---\n---\n", "more than one YAML document"},
      // yaml-cpp 0.7's LoadAll would loop, allocating without bound, on these.
      {"leading comma", "," + full, "rig.yaml: line 1: YAML syntax error: unexpected ','"},
      {"lone comma", ",", "rig.yaml: line 1: YAML syntax error: unexpected ','"},
      {"comma after document end", "...\n,\n",
       "rig.yaml: line 2: YAML syntax error: unexpected ','"},
      {"second document a comma", full + "---\n,\n", "more than one YAML document"},
      {"syntax error in a second document", full + "---\n[\n",
       "rig.yaml: line 46: YAML syntax error"},
      {"deep nesting", "version: " + std::string(3000, '[') + std::string(3000, ']') + "\n",
       "rig.yaml: line 1: YAML nesting deeper than 32 levels"},
      {"unclosed flow list", Replace(full, "[7.5, 14.0]", "[7.5, 14.0"), "YAML syntax error"},
      {"bad indentation", Replace(full, "    fy: 526.0\n", "   fy: 526.0\n"), "YAML syntax error"},
      {"tab indentation", Replace(full, "    fy: 526.0\n", "\tfy: 526.0\n"), "YAML syntax error"},
      // yaml-cpp reads an unclosed quote to the end of the file: caught all the same.
      {"unclosed quote", Replace(full, "model: pinhole", "model: \"pinhole"),
       "cameras.depth.model: must be pinhole, opencv or splined, got string \"pinhole fx: 525.0 fy: 526.0 "
       "cx: 319.5 cy...\""},
      {"multi-line name", Replace(full, "model: pinhole", "model: |\n      pin\n      hole"),
       "cameras.depth.model: must be pinhole, opencv or splined, got string \"pin\\nhole\\n\""},
      {"negative infinity", Replace(full, "cy: 239.5", "cy: -.Inf"),
       "cameras.depth.cy: must be finite"},
  };
}

TEST(RigTest, EveryMalformedRigThrowsOneClearInputError) {
  for (const BadRig& bad : BadRigs()) {
    SCOPED_TRACE(bad.name);
    const std::string error = RigError(bad.text);
    EXPECT_THAT(error, StartsWith("rig.yaml: "));
    EXPECT_THAT(error, HasSubstr(bad.expected));
    EXPECT_EQ(error.find('\n'), std::string::npos) << error;
  }
}

TEST(RigTest, ErrorsGiveTheLineNumber) {
  const std::string full = kFullRig;
  EXPECT_EQ(RigError(Replace(full, "fx: 180.5", "fx: -3")),
            "rig.yaml: cameras.thermal.fx: must be in [1, 1e6] px, got -3 (line " +
                std::to_string(LineOf(full, "fx: 180.5")) + ")");
  EXPECT_EQ(RigError(Replace(full, "    fx: 525.0\n", "    fxx: 525.0\n")),
            "rig.yaml: cameras.depth: unknown key 'fxx' (line " +
                std::to_string(LineOf(full, "fx: 525.0")) + ")");
  EXPECT_EQ(RigError(Replace(full, "[0, 0, 0, 1]", "[0, 0, 0, 1.2]")),
            "rig.yaml: extrinsics.depth_from_rgb.q_xyzw: not a unit quaternion (norm 1.2) (line " +
                std::to_string(LineOf(full, "[0, 0, 0, 1]")) + ")");
  // A missing key points at the mapping it is missing from.
  EXPECT_EQ(RigError(Replace(full, "  netd_k: 0.04\n", "")),
            "rig.yaml: thermal.netd_k: missing required key (line " +
                std::to_string(LineOf(full, "raw_scale")) + ")");
  EXPECT_THAT(RigError(Replace(full, "[7.5, 14.0]", "[7.5, 14.0")), StartsWith("rig.yaml: line "));
  const std::string syntax = RigError(Replace(full, "    fy: 526.0\n", "   fy: 526.0\n"));
  EXPECT_THAT(syntax, StartsWith("rig.yaml: line " + std::to_string(LineOf(full, "fy: 526.0")) +
                                 ": YAML syntax error: "));
}

TEST(RigTest, MissingFileIsAnInputError) {
  const fs::path dir = hw::test::TestFolder();
  EXPECT_THROW(ReadRig(dir / "rig.yaml"), InputError);
  EXPECT_THROW(ReadRig(dir), InputError);  // a folder
  WriteFileAtomically(dir / "rig.yaml", "version: 1\n");
  try {
    ReadRig(dir / "rig.yaml");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), dir / "rig.yaml");
    EXPECT_EQ(e.reason(), "depth_scale: missing required key (line 1)");
  }
}

// Returns or throws InputError on every input; when it returns, the rig is valid and
// survives a round trip.
void ExpectParsesOrInputError(const std::string& text, int* accepted) {
  try {
    const Rig rig = ParseRig(text, "rig.yaml");
    ASSERT_EQ(rig.Check(), "");
    ExpectSameRig(rig, ParseRig(FormatRig(rig), "rig.yaml"));
    ++*accepted;
  } catch (const InputError& e) {
    ASSERT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
  } catch (const std::exception& e) {
    FAIL() << "unexpected exception " << e.what() << " on:\n" << text;
  }
}

TEST(RigTest, FuzzTruncationsMutationsAndDeletions) {
  const std::string full = kFullRig;
  int cases = 0, accepted = 0;
  // Every prefix.
  for (size_t n = 0; n <= full.size(); ++n, ++cases) {
    ExpectParsesOrInputError(full.substr(0, n), &accepted);
  }
  // Random byte edits: overwrite, insert or delete, 1-3 per case, biased to YAML syntax.
  std::mt19937 rng(12345);
  const std::string specials = ":-[]{},#'\"&*!|>?%@` \n\t0123456789.eE+";
  for (int i = 0; i < 2000; ++i, ++cases) {
    std::string text = full;
    const int edits = 1 + static_cast<int>(rng() % 3);
    for (int e = 0; e < edits && !text.empty(); ++e) {
      const size_t at = rng() % text.size();
      const char c =
          (rng() % 4 == 0) ? static_cast<char>(rng() % 256) : specials[rng() % specials.size()];
      switch (rng() % 3) {
        case 0:
          text[at] = c;
          break;
        case 1:
          text.insert(text.begin() + static_cast<std::ptrdiff_t>(at), c);
          break;
        default:
          text.erase(at, 1);
          break;
      }
    }
    ExpectParsesOrInputError(text, &accepted);
  }
  // Deleting lines (keys, whole blocks' headers), one and several at a time.
  std::vector<std::string> lines;
  for (size_t start = 0; start < full.size();) {
    const size_t end = full.find('\n', start);
    lines.push_back(full.substr(start, end - start + 1));
    start = end + 1;
  }
  for (int i = 0; i < 400; ++i, ++cases) {
    std::vector<std::string> kept = lines;
    const int deletions = i < static_cast<int>(lines.size()) ? 1 : 1 + static_cast<int>(rng() % 4);
    for (int d = 0; d < deletions && !kept.empty(); ++d) {
      const size_t at =
          i < static_cast<int>(lines.size()) ? static_cast<size_t>(i) : rng() % kept.size();
      kept.erase(kept.begin() + static_cast<std::ptrdiff_t>(at));
    }
    std::string text;
    for (const std::string& line : kept) text += line;
    ExpectParsesOrInputError(text, &accepted);
  }
  // The fuzz must reach both outcomes, or it tested nothing.
  EXPECT_GT(accepted, 10);
  EXPECT_LT(accepted, cases / 2);
  RecordProperty("cases", cases);
  RecordProperty("accepted", accepted);
}

}  // namespace
}  // namespace hw::core
