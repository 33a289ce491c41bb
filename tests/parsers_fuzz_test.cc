// Feeds truncated and randomly mutated bytes to every parser of an input file the project
// reads, and expects each call to return or throw hw::core::InputError: never a crash, an
// abort, a hang, or another exception type escaping (yaml-cpp, std::stod, bad_alloc, ...).
// Deterministic (fixed seeds). The unit tests beside each parser check the error messages.
#include <sys/stat.h>
#include <zlib.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "core/atomic_file.h"
#include "core/cameramodel_io.h"
#include "core/error.h"
#include "core/image_io.h"
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
  return ReadFile(path, kMaxMeshFileBytes);
}

// Runs `parse` on the valid input (must succeed), every truncated prefix (all for small
// inputs, a stride for big ones), and `mutations` random mutations: byte flips, insertions
// of structural characters, deletions and duplications of spans.
void Fuzz(const std::string& name, const std::string& valid, const Parser& parse,
          int mutations = 3000, bool expect_some_accepted = true) {
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
  if (expect_some_accepted) {
    EXPECT_GT(accepted, 0);
  }
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


// The same input with a UTF-8 BOM and with CRLF or CR-only line ends: what Windows and
// classic-Mac tools write. Each variant must parse, and survive the fuzzer too.
std::vector<std::pair<std::string, std::string>> LineEndingVariants(const std::string& text) {
  std::string crlf, cr;
  for (const char c : text) {
    crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
    cr += c == '\n' ? '\r' : c;
  }
  return {{"bom", "\xEF\xBB\xBF" + text}, {"crlf", crlf}, {"cr", cr},
          {"bom+crlf", "\xEF\xBB\xBF" + crlf}};
}

TEST(ParsersFuzz, LineEndingVariantsParseAndFuzz) {
  const std::vector<std::tuple<std::string, std::string, Parser>> inputs = {
      {"rig.yaml", kRig, [](const std::string& s) { ParseRig(s, "rig.yaml"); }},
      {"target.yaml", kTarget, [](const std::string& s) { ParseTarget(s, "target.yaml"); }},
      {"groundtruth.txt", kTum,
       [](const std::string& s) { ParseTumTrajectory(s, "groundtruth.txt"); }},
      {"rgb.txt", kIndex, [](const std::string& s) { ParseStreamIndex(s, "rgb.txt"); }},
      {"ffc.txt", kFfc, [](const std::string& s) { ParseFfcEvents(s, "ffc.txt"); }},
  };
  for (const auto& [name, text, parse] : inputs) {
    for (const auto& [variant, bytes] : LineEndingVariants(text)) {
      Fuzz(name + "/" + variant, bytes, parse, 400);
    }
  }
  // Not only parsed: read the same.
  for (const auto& [variant, bytes] : LineEndingVariants(kTum)) {
    EXPECT_EQ(ParseTumTrajectory(bytes, "t").size(), 3u) << variant;
  }
  for (const auto& [variant, bytes] : LineEndingVariants(kIndex)) {
    const std::vector<IndexEntry> entries = ParseStreamIndex(bytes, "rgb.txt");
    ASSERT_EQ(entries.size(), 3u) << variant;
    EXPECT_EQ(entries[2].line, 6) << variant;
    EXPECT_EQ(entries[2].path, "rgb/1305031102.243211.png") << variant;
  }
  for (const auto& [variant, bytes] : LineEndingVariants(kRig)) {
    EXPECT_EQ(ParseRig(bytes, "rig.yaml").thermal_time_offset_s, -0.04) << variant;
  }
}

// Recomputes the CRC of every chunk whose length still fits, so that mutations reach
// libpng's header checks and inflate rather than stopping at the first CRC check.
std::string FixPngCrcs(std::string png) {
  size_t pos = 8;
  while (pos + 12 <= png.size()) {
    const auto byte = [&](size_t i) { return static_cast<uint32_t>(static_cast<uint8_t>(png[i])); };
    const uint32_t length = byte(pos) << 24 | byte(pos + 1) << 16 | byte(pos + 2) << 8 | byte(pos + 3);
    if (length > png.size() - pos - 12) break;
    const uint32_t crc = static_cast<uint32_t>(
        crc32(0, reinterpret_cast<const Bytef*>(png.data() + pos + 4), length + 4));
    for (int k = 0; k < 4; ++k) png[pos + 8 + length + k] = static_cast<char>(crc >> (24 - 8 * k));
    pos += 12 + length;
  }
  return png;
}

// Image decoders (libpng, OpenImageIO's TIFF and JPEG) on mutated files: InputError only,
// and nothing printed by the libraries.
TEST(ParsersFuzz, ImageDecoders) {
  cv::Mat depth(24, 32, CV_16UC1);
  cv::randu(depth, 0, 4000);
  cv::Mat apparent_c(12, 16, CV_32FC1);
  cv::randu(apparent_c, 10.0, 40.0);
  cv::Mat colour(24, 32, CV_8UC3);
  cv::randu(colour, 0, 255);
  ::testing::internal::CaptureStderr();
  for (const auto& [name, bytes] : std::vector<std::pair<std::string, std::string>>{
           {"depth.png", EncodeImage(depth, ".png", "depth.png")},
           {"thermal.tiff", EncodeImage(apparent_c, ".tiff", "thermal.tiff")},
           {"rgb.jpg", EncodeImage(colour, ".jpg", "rgb.jpg")}}) {
    Fuzz(name, bytes, [&](const std::string& s) {
      DecodeImage(name == "depth.png" ? FixPngCrcs(s) : s, name, [&](const ImageHeader& header) {
        // As a scan reader would: a frame is small; a mutated header must not cost more.
        if (header.width > 64 || header.height > 64) throw InputError(name, "too large");
      });
      // PNG's checksums (chunk CRCs, recomputed above, and the zlib stream's Adler-32)
      // reject nearly every mutation: that is the format working, not a fuzzer stuck.
    }, 600, name != "depth.png");
  }
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
}

// Every reader given something that is not a regular file: a clear InputError in bounded
// time, never a hang (FIFO), an endless read (/dev/zero) or "no such file" for a link.
TEST(ParsersFuzz, SpecialFilesForEveryReader) {
  namespace fs = std::filesystem;
  const fs::path dir = hw::test::TestFolder();
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0644), 0);
  fs::create_symlink("/dev/zero", dir / "zero");
  fs::create_symlink("absent", dir / "dangling");
  fs::create_symlink("loop", dir / "loop");
  fs::create_directories(dir / "folder");
  const std::vector<std::pair<std::string, std::function<void(const fs::path&)>>> readers = {
      {"ReadRig", [](const fs::path& p) { ReadRig(p); }},
      {"ReadTarget", [](const fs::path& p) { ReadTarget(p); }},
      {"ReadTumTrajectory", [](const fs::path& p) { ReadTumTrajectory(p); }},
      {"ReadStreamIndex", [](const fs::path& p) { ReadStreamIndex(p); }},
      {"ReadFfcEvents", [](const fs::path& p) { ReadFfcEvents(p); }},
      {"ReadPly", [](const fs::path& p) { ReadPly(p); }},
      {"ReadMrcalCameraModel", [](const fs::path& p) { ReadMrcalCameraModel(p); }},
      {"ReadImage", [](const fs::path& p) { ReadImage(p); }},
  };
  for (const auto& [reader, read] : readers) {
    for (const std::string special : {"fifo", "zero", "dangling", "loop", "folder"}) {
      const int code = hw::test::RunInChild(
          [&] {
            try {
              read(dir / special);
            } catch (const InputError& e) {
              return std::string(e.what()).find((dir / special).string()) == 0 ? 0 : 1;
            } catch (...) {
              return 2;
            }
            return 3;
          },
          10);
      EXPECT_EQ(code, 0) << reader << " on " << special
                         << (code == hw::test::kTimedOut ? ": hung" : "");
    }
  }
}

}  // namespace
}  // namespace hw::core
