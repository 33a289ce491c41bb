#include "core/ply.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <limits>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "tests/support.h"
#include "core/ply_test_support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using namespace ply_test;

// Malformed, truncated and absurd PLY input; atomic output; fuzzing; speed.

TEST(PlyRead, HeaderErrors) {
  const std::string v = "element vertex 1\nproperty float x\n";
  ExpectInputError("", "not a PLY file");
  ExpectInputError("plx\nformat ascii 1.0\nend_header\n", "not a PLY file");
  ExpectInputError("PLY\nformat ascii 1.0\nend_header\n", "not a PLY file");
  ExpectInputError("ply", "not a PLY file");
  ExpectInputError("ply\nformat binary_middle_endian 1.0\n" + v + "end_header\n",
                   "line 2: unknown format 'binary_middle_endian'");
  ExpectInputError("ply\nformat ascii 2.0\nend_header\n", "line 2: unsupported PLY version '2.0'");
  ExpectInputError("ply\nformat ascii\nend_header\n", "line 2: expected 'format");
  ExpectInputError("ply\nformat ascii 1.0\nformat ascii 1.0\nend_header\n",
                   "line 3: second format line");
  ExpectInputError("ply\nelement vertex 1\nformat ascii 1.0\nend_header\n",
                   "line 2: element before the format line");
  ExpectInputError("ply\nend_header\n", "line 2: end_header before the format line");
  ExpectInputError("ply\nformat ascii 1.0\nelement vertex 1\nproperty flaot x\nend_header\n0\n",
                   "line 4: unknown property type 'flaot'");
  ExpectInputError("ply\nformat ascii 1.0\nelement vertex 1\nproperty list uchar flaot x\n",
                   "line 4: unknown property type 'flaot'");
  ExpectInputError("ply\nformat ascii 1.0\n" + v, "no end_header line");
  ExpectInputError("ply\nformat ascii 1.0\n" + v + "end_header", "no end_header line");
  ExpectInputError("ply\nformat ascii 1.0\n" + v + "comment a\rb\nend_header\n0\n",
                   "line 5: control character 0x0d in the header");
  ExpectInputError("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x" +
                       std::string(1, '\0') + "y\nend_header\n0\n",
                   "line 4: control character 0x00 in the header");
  ExpectInputError("ply\nformat ascii 1.0\n" + v + "end_header now\n0\n",
                   "line 5: text after end_header");
  ExpectInputError("ply\nformat ascii 1.0\n" + v + "vertices 3\nend_header\n",
                   "line 5: unknown header keyword 'vertices'");
  ExpectInputError("ply\nformat ascii 1.0\nproperty float x\n" + v + "end_header\n",
                   "line 3: property before any element");
  ExpectInputError("ply\nformat ascii 1.0\n" + v + "property float x\nend_header\n",
                   "line 5: duplicate property 'x' in element vertex");
  ExpectInputError("ply\nformat ascii 1.0\n" + v + v + "end_header\n",
                   "line 5: duplicate element 'vertex'");
  ExpectInputError("ply\nformat ascii 1.0\nelement vertex\nend_header\n",
                   "line 3: expected 'element <name> <count>'");
  ExpectInputError("ply\nformat ascii 1.0\nelement vertex -3\nend_header\n",
                   "line 3: element 'vertex': count is not a non-negative integer: '-3'");
  ExpectInputError("ply\nformat ascii 1.0\nelement vertex 3.5\nend_header\n",
                   "count is not a non-negative integer: '3.5'");
  ExpectInputError("ply\nformat ascii 1.0\nelement vertex 99999999999999999999\nend_header\n",
                   "count is not a non-negative integer");
  ExpectInputError("ply\nformat ascii 1.0\nelement vertex 1\nproperty float\nend_header\n",
                   "line 4: expected 'property <type> <name>'");
  ExpectInputError("ply\nformat ascii 1.0\nelement vertex 1\nproperty list uchar x\n",
                   "line 4: expected 'property list <count type> <item type> <name>'");
  ExpectInputError("ply\nformat ascii 1.0\n" + v +
                       "element face 1\nproperty list float int vertex_indices\nend_header\n",
                   "line 6: list count type must be an integer type, got 'float'");
  ExpectInputError("ply\nformat ascii 1.0\n" + v +
                       "element face 1\nproperty list uchar float vertex_indices\nend_header\n",
                   "line 6: vertex indices must be of an integer type, got float");
  ExpectInputError(
      "ply\nformat ascii 1.0\n" + v + "element face 1\nproperty int vertex_indices\nend_header\n",
      "line 6: face property vertex_indices must be a list");
  ExpectInputError("ply\nformat ascii 1.0\n" + v +
                       "element face 1\nproperty list uchar int corners\nend_header\n",
                   "element face has no list property vertex_indices");
  ExpectInputError("ply\nformat ascii 1.0\n" + v +
                       "element face 1\nproperty list uchar int vertex_indices\n"
                       "property list uchar int vertex_index\nend_header\n",
                   "element face has both vertex_indices and vertex_index");
  ExpectInputError(
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty list uchar float x\n"
      "end_header\n",
      "element vertex has 3 vertices but no scalar property");
  ExpectInputError(
      "ply\nformat binary_little_endian 1.0\nelement vertex 3000000000\n"
      "property float x\nend_header\n",
      "element vertex: 3000000000 vertices, more than the 2147483647 supported");
}

TEST(PlyRead, BinaryDataErrors) {
  const std::string head =
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nelement face 2\n"
      "property list uchar int vertex_indices\nend_header\n";
  std::string vertices;
  for (int i = 0; i < 9; ++i) vertices += Bytes<float>(static_cast<float>(i));
  auto face = [](std::vector<int32_t> indices) {
    std::string out = Bytes<uint8_t>(static_cast<uint8_t>(indices.size()));
    for (const int32_t index : indices) out += Bytes<int32_t>(index);
    return out;
  };
  const std::string good = head + vertices + face({0, 1, 2}) + face({2, 1, 0});
  EXPECT_EQ(ParsePly(good, "good.ply").faces.size(), 2u);

  ExpectInputError(head + vertices.substr(0, 20),
                   "truncated: expected 36 bytes of vertex data, got 20");
  ExpectInputError(head + vertices, "truncated: expected at least 26 bytes of face data, got 0");
  ExpectInputError(head + vertices + face({0, 1, 2, 0}) + face({2, 1, 0}).substr(0, 12),
                   "truncated: face 1: list vertex_indices of 3 items needs 12 bytes, got 11");
  ExpectInputError(head + vertices + face({0, 1, 2}) + face({2, 7, 0}),
                   "face 1: vertex index 7 out of range (3 vertices)");
  ExpectInputError(head + vertices + face({0, -1, 2}) + face({2, 1, 0}),
                   "face 0: vertex index -1 out of range (3 vertices)");
  ExpectInputError(head + vertices + face({0, 1}) + face({2, 1, 0}) + Bytes<int32_t>(0),
                   "face 0: 2 vertex indices, a face needs at least 3");
  ExpectInputError(head + vertices + face({}) + face({2, 1, 0}) + std::string(12, '\0'),
                   "face 0: 0 vertex indices, a face needs at least 3");
  ExpectInputError(good + "\n", "1 bytes of unexpected data after the last element");
  // A list of 200 items with the data for far fewer.
  ExpectInputError(head + vertices + Bytes<uint8_t>(200) + std::string(30, '\0'),
                   "truncated: face 0: list vertex_indices of 200 items needs 800 bytes, got 30");
  // Negative list lengths (signed count types).
  const std::string signed_head =
      "ply\nformat binary_little_endian 1.0\nelement things 1\n"
      "property list char float values\nend_header\n";
  ExpectInputError(signed_head + Bytes<int8_t>(-1) + std::string(8, '\0'),
                   "things 0: list values has negative length -1");
  // The file ends inside a scalar of a row of variable length.
  const std::string mixed_head =
      "ply\nformat binary_little_endian 1.0\nelement extra 2\nproperty list uchar int a\n"
      "property int b\nend_header\n";
  ExpectInputError(
      mixed_head + Bytes<uint8_t>(3) + std::string(16, '\0') + Bytes<uint8_t>(0) + "\x01\x02",
      "truncated: the file ends inside extra 1 of 2");
}

TEST(PlyRead, AbsurdCountsFailBeforeAllocating) {
  // If any of these allocated what the header claims, the test would run out of memory or
  // take far too long; they must fail at once on the size of the data.
  ExpectInputError(
      "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\n"
      "property double x\nproperty double y\nend_header\n" +
          std::string(64, 'a'),
      "truncated: expected 32000000000 bytes of vertex data, got 64");
  ExpectInputError(
      "ply\nformat ascii 1.0\nelement vertex 2000000000\n"
      "property double x\nproperty double y\nend_header\n0 0\n",
      "truncated: 2000000000 vertex rows need at least 4000000000 values, but "
      "only 4 bytes of text follow");
  ExpectInputError(
      "ply\nformat binary_big_endian 1.0\nelement vertex 0\nproperty float x\n"
      "element face 1000000000000\nproperty list uchar int vertex_indices\n"
      "end_header\n" +
          std::string(100, '\0'),
      "truncated: expected at least 13000000000000 bytes of face data, got 100");
  ExpectInputError(
      "ply\nformat binary_little_endian 1.0\nelement edge 18446744073709551615\n"
      "property list uchar int a\nend_header\n" +
          std::string(10, '\0'),
      "truncated: expected at least 18446744073709551615 bytes of edge data, "
      "got 10");
  ExpectInputError(
      "ply\nformat binary_little_endian 1.0\nelement edge 18446744073709551615\n"
      "property double a\nend_header\n",
      "truncated: expected 18446744073709551615 x 8 bytes of edge data, got 0");
  ExpectInputError(
      "ply\nformat ascii 1.0\nelement edge 18446744073709551615\n"
      "property list uchar int a\nend_header\n1 2\n",
      "truncated: 18446744073709551615 edge rows need at least");
  // A count of 4 billion in a list of a binary file.
  ExpectInputError(
      "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty uchar x\n"
      "element face 1\nproperty list uint int vertex_indices\nend_header\n"
      "\x01\x02\x03" +
          Bytes<uint32_t>(4000000000u) + std::string(12, '\0'),
      "truncated: face 0: list vertex_indices of 4000000000 items needs "
      "16000000000 bytes, got 12");
  // An element without properties takes no bytes whatever its count: no endless loop.
  const PlyMesh mesh = ParsePly(
      "ply\nformat ascii 1.0\nelement nothing 18446744073709551615\nend_header\n", "nothing.ply");
  EXPECT_EQ(mesh.NumVertices(), 0u);
}

TEST(PlyRead, AsciiDataErrors) {
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
      "property uchar red\nelement face 1\nproperty list uchar int vertex_indices\n"
      "end_header\n";  // data starts on line 10
  const std::string v = "0.5 0.5 1\n1.5 0.5 2\n0.5 1.5 3\n";
  EXPECT_EQ(ParsePly(head + v + "3 0 1 2\n", "good.ply").faces.size(), 1u);
  ExpectInputError(head + "0.5 0.5 1\n1.5 2\n0.5 1.5 3\n3 0 1 2\n",
                   "line 11 (vertex 1): too few values: red missing");
  ExpectInputError(head + "0.5 0.5 1 7\n1.5 0.5 2\n0.5 1.5 3\n3 0 1 2\n",
                   "line 10 (vertex 0): more values than the element's properties, starting "
                   "with '7'");
  ExpectInputError(head + "0.5 abc 1\n1.5 0.5 2\n0.5 1.5 3\n3 0 1 2\n",
                   "line 10 (vertex 0): y: not a number: 'abc'");
  ExpectInputError(head + "0.5 0.5 1\n1.5 0.5 300\n0.5 1.5 3\n3 0 1 2\n",
                   "line 11 (vertex 1): red: '300' is out of range for uchar");
  ExpectInputError(head + "0.5 0.5 1\n1.5 0.5 -1\n0.5 1.5 3\n3 0 1 2\n",
                   "line 11 (vertex 1): red: '-1' is out of range for uchar");
  ExpectInputError(head + "0.5 0.5 1.5\n1.5 0.5 2\n0.5 1.5 3\n3 0 1 2\n",
                   "line 10 (vertex 0): red: expected an integer (uchar), got '1.5'");
  ExpectInputError(head + "0.5 1e39 1\n1.5 0.5 2\n0.5 1.5 3\n3 0 1 2\n",
                   "line 10 (vertex 0): y: '1e39' is out of range for float");
  ExpectInputError(head + "0.5 0x10 1\n1.5 0.5 2\n0.5 1.5 3\n3 0 1 2\n", "y: not a number: '0x10'");
  ExpectInputError(head + "0.5 0.5 1\n1.5 0.5 2\n0.5 1.5 3\n",
                   "truncated: 1 face rows need at least 4 values, but only 0 bytes of text "
                   "follow");
  ExpectInputError(head + "0.5 0.5 1\n1.5 0.5 2\n0.5 1.5 3\n\n\n\n\n\n\n\n",
                   "truncated: the file ends after 0 of 1 face rows");
  ExpectInputError(head + "0.5 0.5 1\n1.5 0.5 2\n\n\n\n\n",
                   "truncated: the file ends after 2 of 3 vertex rows");
  ExpectInputError(head + v + "3 0 1 3\n",
                   "line 13 (face 0): vertex index 3 out of range (3 vertices)");
  ExpectInputError(head + v + "3 0 -1 2\n",
                   "line 13 (face 0): vertex index -1 out of range (3 vertices)");
  // (Blank lines after the last row keep the data long enough for the minimum-size check.)
  ExpectInputError(head + v + "2 0 1\n\n\n", "line 13 (face 0): 2 vertex indices, a face needs");
  ExpectInputError(head + v + "3 0 1\n\n\n", "line 13 (face 0): too few values: vertex_indices");
  ExpectInputError(head + v + "3 0 1 2 0\n", "line 13 (face 0): more values than");
  ExpectInputError(head + v + "3 0 1.5 2\n", "vertex_indices: expected an integer (int)");
  ExpectInputError(head + v + "256 0 1 2\n", "vertex_indices: '256' is out of range for uchar");
  ExpectInputError(head + v + "255 0 1 2\n",
                   "line 13 (face 0): list vertex_indices of 255 items is longer than its line");
  ExpectInputError(head + v + "3 0 1 2\n0 0 0\n",
                   "line 14: unexpected data after the last element: '0 0 0'");
  ExpectInputError(
      "ply\nformat ascii 1.0\nelement a 1\nproperty list char int v\nend_header\n-2 1 1\n",
      "line 6 (a 0): list v has negative length -2");
}

TEST(PlyRead, MissingOrUnreadableFile) {
  const fs::path dir = hw::test::TestFolder("missing");
  try {
    ReadPly(dir / "none.ply");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), dir / "none.ply");
  }
  EXPECT_THROW(ReadPly(dir), InputError);  // a folder
}

TEST(PlyWrite, AtomicWriteLeavesNoTemporaryFile) {
  const fs::path dir = hw::test::TestFolder("atomic");
  const fs::path path = dir / "scene.ply";
  PlyMesh mesh = EveryTypeMesh();
  for (const PlyFormat format :
       {PlyFormat::kAscii, PlyFormat::kBinaryLittleEndian, PlyFormat::kBinaryBigEndian}) {
    WritePly(path, mesh, format);  // the second and third overwrite
    EXPECT_EQ(ListDir(dir), std::vector<fs::path>{"scene.ply"});
    EXPECT_EQ(ReadFile(path, kMaxMeshFileBytes), SerializePly(mesh, format));
    ExpectSameMesh(mesh, ReadPly(path));
  }
  // A folder in the way: OutputError, and still no temporary file left.
  fs::create_directories(dir / "blocked.ply" / "x");
  EXPECT_THROW(WritePly(dir / "blocked.ply", mesh), OutputError);
  std::vector<fs::path> files = ListDir(dir);
  std::sort(files.begin(), files.end());
  EXPECT_EQ(files, (std::vector<fs::path>{"blocked.ply", "scene.ply"}));
}

// Every proper prefix and a few thousand deterministic mutations of valid files either
// parse into a consistent mesh or throw InputError; nothing else (crash, other exception,
// huge allocation).
TEST(PlyRead, FuzzPrefixesAndMutations) {
  PlyMesh mesh = EveryTypeMesh();
  mesh.faces.emplace_back(0, 1, 2);
  std::mt19937 rng(12345);
  const std::string special =
      std::string(" \n\r\t0123456789-+.e", 18) + std::string(1, '\0') + "\xff\x7f\x80";
  for (const PlyFormat format :
       {PlyFormat::kAscii, PlyFormat::kBinaryLittleEndian, PlyFormat::kBinaryBigEndian}) {
    std::string valid = SerializePly(mesh, format);
    // A skipped element with a list, so that mutations reach that code too.
    const std::string marker = "end_header\n";
    if (format == PlyFormat::kAscii) {
      valid.insert(valid.find(marker), "element extra 2\nproperty list uchar short s\n");
      valid += "2 -1 7\n0\n";
    } else {
      const bool big = format == PlyFormat::kBinaryBigEndian;
      valid.insert(valid.find(marker), "element extra 2\nproperty list uchar short s\n");
      valid +=
          Bytes<uint8_t>(2) + Bytes<int16_t>(-1, big) + Bytes<int16_t>(7, big) + Bytes<uint8_t>(0);
    }
    ASSERT_NO_THROW(ParsePly(valid, "valid.ply"));
    const size_t last_line_start = valid.rfind('\n', valid.size() - 2) + 1;

    int parsed = 0, rejected = 0;
    for (size_t length = 0; length < valid.size(); ++length) {
      try {
        const PlyMesh read = ParsePly(valid.substr(0, length), "prefix.ply");
        EXPECT_EQ(read.Check(), "");
        // An ASCII file cut inside its last line can still be valid; anything shorter not.
        EXPECT_TRUE(format == PlyFormat::kAscii && length >= last_line_start) << length;
        ++parsed;
      } catch (const InputError&) {
        ++rejected;
      }
    }
    EXPECT_GT(rejected, 100);

    for (int trial = 0; trial < 1500; ++trial) {
      std::string data = valid;
      const int edits = 1 + static_cast<int>(rng() % 3);
      for (int e = 0; e < edits; ++e) {
        const size_t at = rng() % data.size();
        switch (rng() % 3) {
          case 0:
            data[at] = static_cast<char>(data[at] ^ (1 << (rng() % 8)));
            break;
          case 1:
            data[at] = special[rng() % special.size()];
            break;
          default:
            data.erase(at, 1 + rng() % 4);
            break;
        }
        if (data.empty()) data = "p";
      }
      try {
        const PlyMesh read = ParsePly(data, "mutated.ply");
        EXPECT_EQ(read.Check(), "") << "trial " << trial;
        ++parsed;
      } catch (const InputError&) {
        ++rejected;
      }
    }
    std::printf("[ PLY fuzz ] %s: %zu prefixes and 1500 mutated files: %d parsed, %d rejected\n",
                format == PlyFormat::kAscii ? "ascii" : "binary", valid.size(), parsed, rejected);
    // Both outcomes occur: the mutations are neither all harmless nor all fatal.
    EXPECT_GT(parsed, 50);
    EXPECT_GT(rejected, 500);
  }
}

// A mesh like reconstruction writes: positions, normals, colour, temperature, confidence
// (11 properties) on a strip of 2n - 4 triangles.
PlyMesh StripMesh(size_t n) {
  std::vector<Eigen::Vector3d> positions(n), normals(n);
  std::vector<Rgb8> colors(n);
  std::vector<double> temperature_c(n), confidence(n);
  for (size_t i = 0; i < n; ++i) {
    const double a = static_cast<double>(i) * 1e-3;
    positions[i] = Eigen::Vector3d(std::sin(a), std::cos(a), a * 1e-3);
    normals[i] = Eigen::Vector3d(std::cos(a), -std::sin(a), 0.0);
    colors[i] = Rgb8(static_cast<uint8_t>(i), static_cast<uint8_t>(i >> 8), 7);
    temperature_c[i] = 20.0 + std::sin(a * 7.0);
    confidence[i] = std::fmod(a, 1.0);
  }
  PlyMesh mesh;
  mesh.SetPositions(positions);
  mesh.SetNormals(normals);
  mesh.SetColors(colors);
  mesh.AddProperty("temperature_c", PlyType::kFloat32, std::move(temperature_c));
  mesh.AddProperty("confidence", PlyType::kFloat32, std::move(confidence));
  mesh.faces.resize(2 * n - 4);
  for (size_t f = 0; f < mesh.faces.size(); ++f) {
    const int i = static_cast<int>(f / 2);
    mesh.faces[f] = f % 2 ? Eigen::Vector3i(i, i + 2, i + 1) : Eigen::Vector3i(i, i + 1, i + 2);
  }
  return mesh;
}

// Measures (and prints) read and write speed: binary for 1M vertices and 2M faces, ASCII
// for 200k vertices (it is slower, and the test must stay fast). No timing assertion:
// machines and their load differ; the numbers go to the log, as wall and CPU time.
TEST(PlySpeed, OneMillionVertices) {
  const fs::path dir = hw::test::TestFolder("speed");
  using Clock = std::chrono::steady_clock;
  struct Timer {
    Clock::time_point wall = Clock::now();
    std::clock_t cpu = std::clock();
    std::string Stop(double per) const {
      const double wall_s = std::chrono::duration<double>(Clock::now() - wall).count();
      const double cpu_s = static_cast<double>(std::clock() - cpu) / CLOCKS_PER_SEC;
      char text[96];
      std::snprintf(text, sizeof(text), "%.3f s (cpu %.3f s; %.2f s per 1M vertices)", wall_s,
                    cpu_s, cpu_s * per);
      return text;
    }
  };
  for (const auto& [format, n] : {std::pair{PlyFormat::kBinaryLittleEndian, size_t{1000000}},
                                  std::pair{PlyFormat::kAscii, size_t{200000}}}) {
    const PlyMesh mesh = StripMesh(n);
    const double per = 1e6 / static_cast<double>(n);
    const fs::path path = dir / "big.ply";
    Timer timer;
    WritePly(path, mesh, format);
    const std::string write = timer.Stop(per);
    timer = Timer();
    const PlyMesh read = ReadPly(path);
    const std::string read_text = timer.Stop(per);
    std::printf(
        "[ PLY speed ] %s, %zu vertices (11 properties), %zu faces, %.1f MB:\n"
        "[ PLY speed ]   write %s\n[ PLY speed ]   read  %s\n",
        format == PlyFormat::kAscii ? "ascii" : "binary_little_endian", n, mesh.faces.size(),
        static_cast<double>(fs::file_size(path)) / 1e6, write.c_str(), read_text.c_str());
    ASSERT_EQ(read.NumVertices(), n);
    ASSERT_EQ(read.faces.size(), mesh.faces.size());
    EXPECT_EQ(read.faces.back(), mesh.faces.back());
    EXPECT_EQ(read.Get("temperature_c").values[n / 2],
              PlyRepresentable(PlyType::kFloat32, mesh.Get("temperature_c").values[n / 2]));
    EXPECT_EQ(read.Colors()[12345], mesh.Colors()[12345]);
  }
  fs::remove_all(dir);  // tens of MB
}

}  // namespace
}  // namespace hw::core
