// Feeds truncated and randomly mutated bytes to every parser of an input file the project
// reads, and expects each call to return or throw hw::core::InputError: never a crash, an
// abort, a hang, or another exception type escaping (yaml-cpp, std::stod, bad_alloc, ...).
// Deterministic (fixed seeds). The unit tests beside each parser check the error messages.
#include <cstdint>
#include <functional>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "core/cameramodel_io.h"
#include "core/error.h"
#include "core/ply.h"
#include "core/rig.h"
#include "core/scan.h"
#include "core/trajectory.h"
#include "tests/support.h"

namespace hw::core {
namespace {

using Parser = std::function<void(const std::string&)>;

const char* const kRig = R"(version: 1
depth_scale: 1000.0
cameras:
  depth: {width: 640, height: 480, model: pinhole, fx: 525.0, fy: 525.0, cx: 319.5, cy: 239.5, distortion: []}
  rgb: {width: 640, height: 480, model: opencv, fx: 520.0, fy: 521.0, cx: 320.1, cy: 240.2, distortion: [0.1, -0.2, 0.001, 0.002]}
  thermal: {width: 160, height: 120, model: opencv, fx: 150.0, fy: 150.0, cx: 79.5, cy: 59.5, distortion: [-0.3, 0.1, 0.0, 0.0, -0.02]}
extrinsics:
  depth_from_rgb:     { q_xyzw: [0, 0, 0, 1], t_m: [0.025, 0.0, 0.0] }
  depth_from_thermal: { q_xyzw: [0.0087265, 0, 0, 0.9999619], t_m: [0.03, 0.01, 0.0] }
time_offset_s:
  rgb: 0.0
  thermal: -0.04
thermal:
  raw_scale: 0.01
  raw_offset: -273.15
  spectral_band_um: [7.5, 14.0]
  netd_k: 0.04
  emissivity: 0.95
  reflected_c: 20.0
)";

const char* const kTarget = "type: aprilgrid\nrows: 6\ncols: 6\nsquare_m: 0.088\npitch_m: 0.1144\n"
                            "family: tag36h11\n";

const char* const kTum =
    "# ground truth trajectory\n# timestamp tx ty tz qx qy qz qw\n"
    "1305031102.1758 1.3405 0.6266 1.6575 0.6574 0.6126 -0.2949 -0.3248\n"
    "1305031102.1858 1.3303 0.6256 1.6464 0.6579 0.6161 -0.2932 -0.3189\n"
    "1305031102.1958 1.3160 0.6254 1.6302 0.6609 0.6159 -0.2893 -0.3152\n";

const char* const kIndex = "# color images\n# file: 'rgbd_dataset'\n# timestamp filename\n"
                           "1305031102.175304 rgb/1305031102.175304.png\n"
                           "1305031102.211214 rgb/1305031102.211214.png\n"
                           "1305031102.243211 rgb/1305031102.243211.png\n";

const char* const kFfc = "# flat-field events\n12.5\n73.25\n140.0\n";

std::string PlyText(PlyFormat format) {
  PlyMesh mesh;
  mesh.SetPositions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0.5}});
  mesh.AddProperty("temperature_c", PlyType::kFloat32, {20, 21.5, 60, -5});
  mesh.AddProperty("confidence", PlyType::kFloat64, {0.1, 0.2, 0.3, 1});
  mesh.SetColors({{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {9, 9, 9}});
  mesh.faces = {{0, 1, 2}, {1, 3, 2}};
  const auto path =
      hw::test::TestFolder() / ("mesh" + std::to_string(static_cast<int>(format)) + ".ply");
  WritePly(path, mesh, format);
  return ReadFile(path);
}

// Runs `parse` on the valid input (must succeed), every truncated prefix (all for small
// inputs, a stride for big ones), and `mutations` random mutations: byte flips, insertions
// of structural characters, deletions and duplications of spans.
void Fuzz(const std::string& name, const std::string& valid, const Parser& parse,
          int mutations = 3000) {
  SCOPED_TRACE(name);
  ASSERT_NO_THROW(parse(valid)) << "the valid input must parse";
  int accepted = 0, rejected = 0;
  auto attempt = [&](const std::string& input) {
    try {
      parse(input);
      ++accepted;
    } catch (const InputError&) {
      ++rejected;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "escaped " << typeid(e).name() << ": " << e.what() << "\ninput:\n" << input;
    }
  };
  const size_t stride = std::max<size_t>(1, valid.size() / 400);
  for (size_t n = 0; n < valid.size(); n += stride) attempt(valid.substr(0, n));
  std::mt19937_64 rng(0xC0FFEE ^ std::hash<std::string>()(name));
  const std::string specials = std::string(":[]{},-#.\n\t \"'0123456789e+x") + '\0' + '\xff';
  for (int k = 0; k < mutations; ++k) {
    std::string s = valid;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits && !s.empty(); ++e) {
      const size_t pos = rng() % s.size();
      switch (rng() % 5) {
        case 0: s[pos] = static_cast<char>(rng() & 0xFF); break;
        case 1: s[pos] = specials[rng() % specials.size()]; break;
        case 2: s.insert(pos, 1, specials[rng() % specials.size()]); break;
        case 3: s.erase(pos, 1 + rng() % 16); break;
        case 4: {
          const size_t len = std::min<size_t>(1 + rng() % 32, s.size() - pos);
          s.insert(pos, s.substr(pos, len));
          break;
        }
      }
    }
    attempt(s);
  }
  // Both outcomes must occur: a fuzzer that never gets past the first check tests nothing.
  EXPECT_GT(rejected, 0);
  EXPECT_GT(accepted, 0);
}

TEST(ParsersFuzz, RigYaml) {
  Fuzz("rig.yaml", kRig, [](const std::string& s) { ParseRig(s, "rig.yaml"); });
}

TEST(ParsersFuzz, TargetYaml) {
  Fuzz("target.yaml", kTarget, [](const std::string& s) { ParseTarget(s, "target.yaml"); });
}

TEST(ParsersFuzz, TumTrajectory) {
  Fuzz("groundtruth.txt", kTum,
       [](const std::string& s) { ParseTumTrajectory(s, "groundtruth.txt"); });
}

TEST(ParsersFuzz, StreamIndex) {
  Fuzz("rgb.txt", kIndex, [](const std::string& s) { ParseStreamIndex(s, "rgb.txt"); });
}

TEST(ParsersFuzz, FfcEvents) {
  Fuzz("ffc.txt", kFfc, [](const std::string& s) { ParseFfcEvents(s, "ffc.txt"); });
}

TEST(ParsersFuzz, PlyAllFormats) {
  for (const PlyFormat format :
       {PlyFormat::kAscii, PlyFormat::kBinaryLittleEndian, PlyFormat::kBinaryBigEndian}) {
    Fuzz("mesh.ply/" + std::to_string(static_cast<int>(format)), PlyText(format),
         [](const std::string& s) { ParsePly(s, "mesh.ply"); });
  }
}

TEST(ParsersFuzz, MrcalCameraModel) {
  CameraModel camera;
  camera.width = 640;
  camera.height = 480;
  camera.type = CameraModelType::kOpenCV;
  camera.fx = 600;
  camera.fy = 601;
  camera.cx = 320;
  camera.cy = 240;
  camera.distortion = {-0.3, 0.1, 0.001, -0.002, 0.01};
  const std::string text = FormatMrcalCameraModel(camera);
  // libmrcal prints its own diagnostics on malformed input; keep the test log readable.
  ::testing::internal::CaptureStderr();
  Fuzz("camera.cameramodel", text,
       [](const std::string& s) { ParseMrcalCameraModel(s, "camera.cameramodel"); }, 1500);
  ::testing::internal::GetCapturedStderr();
}

}  // namespace
}  // namespace hw::core
