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

class PlyFormatTest : public ::testing::TestWithParam<PlyFormat> {};

INSTANTIATE_TEST_SUITE_P(AllFormats, PlyFormatTest,
                         ::testing::Values(PlyFormat::kAscii, PlyFormat::kBinaryLittleEndian,
                                           PlyFormat::kBinaryBigEndian));

TEST(PlyType, NamesAliasesAndSizes) {
  const std::vector<std::pair<PlyType, std::vector<std::string>>> expected = {
      {PlyType::kInt8, {"char", "int8"}},        {PlyType::kUInt8, {"uchar", "uint8"}},
      {PlyType::kInt16, {"short", "int16"}},     {PlyType::kUInt16, {"ushort", "uint16"}},
      {PlyType::kInt32, {"int", "int32"}},       {PlyType::kUInt32, {"uint", "uint32"}},
      {PlyType::kFloat32, {"float", "float32"}}, {PlyType::kFloat64, {"double", "float64"}}};
  const std::vector<size_t> sizes = {1, 1, 2, 2, 4, 4, 4, 8};
  for (size_t k = 0; k < expected.size(); ++k) {
    const auto& [type, names] = expected[k];
    EXPECT_EQ(PlyTypeName(type), names[0]);
    for (const std::string& name : names) EXPECT_EQ(ParsePlyType(name), type) << name;
    EXPECT_EQ(PlyTypeSize(type), sizes[k]);
    EXPECT_EQ(PlyTypeIsInteger(type), k < 6);
  }
  EXPECT_EQ(ParsePlyType("flaot"), std::nullopt);
  EXPECT_EQ(ParsePlyType("Float"), std::nullopt);
  EXPECT_EQ(ParsePlyType(""), std::nullopt);
  EXPECT_EQ(ParsePlyType("int64"), std::nullopt);
}

TEST(PlyType, RepresentableRoundsAndSaturates) {
  EXPECT_EQ(PlyRepresentable(PlyType::kUInt8, 300), 255);
  EXPECT_EQ(PlyRepresentable(PlyType::kUInt8, -5), 0);
  EXPECT_EQ(PlyRepresentable(PlyType::kUInt8, 2.5), 3);
  EXPECT_EQ(PlyRepresentable(PlyType::kUInt8, 2.49), 2);
  EXPECT_EQ(PlyRepresentable(PlyType::kInt8, -128.4), -128);
  EXPECT_EQ(PlyRepresentable(PlyType::kInt8, -1e300), -128);
  EXPECT_EQ(PlyRepresentable(PlyType::kInt16, std::nan("")), 0);
  EXPECT_EQ(PlyRepresentable(PlyType::kUInt32, 1e20), 4294967295.0);
  EXPECT_EQ(PlyRepresentable(PlyType::kInt32, -1e20), -2147483648.0);
  EXPECT_EQ(PlyRepresentable(PlyType::kInt32, std::numeric_limits<double>::infinity()),
            2147483647.0);
  EXPECT_EQ(PlyRepresentable(PlyType::kFloat32, 0.1), static_cast<double>(0.1f));
  EXPECT_EQ(PlyRepresentable(PlyType::kFloat32, 1e39), std::numeric_limits<double>::infinity());
  EXPECT_EQ(PlyRepresentable(PlyType::kFloat32, -1e39), -std::numeric_limits<double>::infinity());
  EXPECT_EQ(PlyRepresentable(PlyType::kFloat32, 3.4028235e38), 3.4028234663852886e38);
  EXPECT_EQ(PlyRepresentable(PlyType::kFloat64, 0.1), 0.1);
}

TEST_P(PlyFormatTest, EveryTypeAtItsLimitsRoundTripsExactly) {
  PlyMesh mesh = EveryTypeMesh();
  mesh.comments = {"made in a test", "second comment"};
  const std::string bytes = SerializePly(mesh, GetParam());
  const PlyMesh read = ParsePly(bytes, "every_type.ply");
  ExpectSameMesh(mesh, read);
  EXPECT_EQ(read.comments,
            (std::vector<std::string>{"written by heatwave", "made in a test", "second comment"}));
  // Writing what was read gives the same bytes: nothing drifts, comments do not pile up.
  EXPECT_EQ(SerializePly(read, GetParam()), bytes);
}

TEST_P(PlyFormatTest, OutOfRangeValuesAreWrittenSaturated) {
  PlyMesh mesh;
  mesh.AddProperty("u8", PlyType::kUInt8, {-3, 255.6, 17.4});
  mesh.AddProperty("f32", PlyType::kFloat32, {1e300, 0.1, -1e300});
  const PlyMesh read = ParsePly(SerializePly(mesh, GetParam()), "saturated.ply");
  EXPECT_EQ(read.Get("u8").values, (std::vector<double>{0, 255, 17}));
  EXPECT_EQ(read.Get("f32").values[0], std::numeric_limits<double>::infinity());
  EXPECT_EQ(read.Get("f32").values[1], static_cast<double>(0.1f));
  EXPECT_EQ(read.Get("f32").values[2], -std::numeric_limits<double>::infinity());
}

TEST_P(PlyFormatTest, MixedPropertiesThroughAccessorsAndFiles) {
  const fs::path dir = hw::test::TestFolder("mixed" + std::to_string(static_cast<int>(GetParam())));
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uniform(-2.0, 2.0);
  const size_t n = 500;
  std::vector<Eigen::Vector3d> positions(n), normals(n);
  std::vector<Rgba8> colors(n);
  std::vector<double> temperature_c(n), confidence(n);
  for (size_t i = 0; i < n; ++i) {
    positions[i] = Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng));
    normals[i] = Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng)).normalized();
    colors[i] = Rgba8(static_cast<uint8_t>(i), static_cast<uint8_t>(255 - i % 256),
                      static_cast<uint8_t>(i * 7), static_cast<uint8_t>(i * 13));
    temperature_c[i] = 20.0 + 10.0 * uniform(rng);
    confidence[i] = 0.25 * (uniform(rng) + 2.0);
  }
  PlyMesh mesh;
  mesh.AddProperty("temperature_c", PlyType::kFloat32, temperature_c);
  mesh.SetPositions(positions);  // goes first
  mesh.SetNormals(normals);
  mesh.SetColorsWithAlpha(colors);
  mesh.AddProperty("confidence", PlyType::kFloat64, confidence);
  for (size_t f = 0; f + 2 < n; f += 3) {
    mesh.faces.emplace_back(static_cast<int>(f), static_cast<int>(f + 1), static_cast<int>(f + 2));
  }
  std::vector<std::string> names;
  for (const PlyProperty& p : mesh.vertex_properties) names.push_back(p.name);
  EXPECT_EQ(names, (std::vector<std::string>{"x", "y", "z", "temperature_c", "nx", "ny", "nz",
                                             "red", "green", "blue", "alpha", "confidence"}));

  const fs::path path = dir / "sub" / "mesh.ply";
  WritePly(path, mesh, GetParam());
  const PlyMesh read = ReadPly(path);
  ExpectSameMesh(mesh, read);
  EXPECT_EQ(ListDir(path.parent_path()), std::vector<fs::path>{"mesh.ply"});

  // Float properties come back as the nearest float: within half a float ulp.
  const std::vector<Eigen::Vector3d> p = read.Positions();
  const std::vector<Eigen::Vector3d> nrm = read.Normals();
  const std::vector<Rgba8> c = read.ColorsWithAlpha();
  ASSERT_EQ(p.size(), n);
  for (size_t i = 0; i < n; ++i) {
    EXPECT_LE((p[i] - positions[i]).cwiseAbs().maxCoeff(), 0x1p-24) << i;
    EXPECT_LE((nrm[i] - normals[i]).cwiseAbs().maxCoeff(), 0x1p-24) << i;
    EXPECT_EQ(c[i], colors[i]) << i;
    EXPECT_EQ(read.Get("confidence").values[i], confidence[i]);  // double: exact
  }
}

TEST_P(PlyFormatTest, EmptyMeshAndPointCloud) {
  const PlyMesh empty = ParsePly(SerializePly(PlyMesh(), GetParam()), "empty.ply");
  EXPECT_EQ(empty.NumVertices(), 0u);
  EXPECT_TRUE(empty.vertex_properties.empty());
  EXPECT_TRUE(empty.faces.empty());

  PlyMesh cloud;
  cloud.SetPositions({{1, 2, 3}, {4, 5, 6}}, PlyType::kFloat64);
  const std::string bytes = SerializePly(cloud, GetParam());
  EXPECT_THAT(bytes, HasSubstr("element face 0\n"));
  const PlyMesh read = ParsePly(bytes, "cloud.ply");
  ExpectSameMesh(cloud, read);
  EXPECT_EQ(read.Positions()[1], Eigen::Vector3d(4, 5, 6));
}

TEST(PlyWrite, ExactAsciiText) {
  PlyMesh mesh;
  mesh.SetPositions({{0, 0, 0}, {1, 0, 0}, {0, 0.1, 0}}, PlyType::kFloat32);
  mesh.AddProperty("temperature_c", PlyType::kFloat32, {21.5, -3.25, 1e-7});
  mesh.SetColors({{255, 0, 0}, {0, 255, 0}, {0, 0, 255}});
  mesh.faces = {{0, 1, 2}};
  EXPECT_EQ(SerializePly(mesh, PlyFormat::kAscii),
            "ply\n"
            "format ascii 1.0\n"
            "comment written by heatwave\n"
            "element vertex 3\n"
            "property float x\n"
            "property float y\n"
            "property float z\n"
            "property float temperature_c\n"
            "property uchar red\n"
            "property uchar green\n"
            "property uchar blue\n"
            "element face 1\n"
            "property list uchar int vertex_indices\n"
            "end_header\n"
            "0 0 0 21.5 255 0 0\n"
            "1 0 0 -3.25 0 255 0\n"
            "0 0.1 0 1e-07 0 0 255\n"
            "3 0 1 2\n");
}

TEST(PlyWrite, ExactBinaryBytes) {
  PlyMesh mesh;
  mesh.AddProperty("x", PlyType::kFloat32, {1.0, -2.0});
  mesh.AddProperty("s", PlyType::kInt16, {-2, 258});
  mesh.AddProperty("c", PlyType::kUInt8, {7, 200});
  mesh.faces = {{1, 0, 1}};
  const std::string header_tail =
      " 1.0\ncomment written by heatwave\nelement vertex 2\nproperty float x\n"
      "property short s\nproperty uchar c\nelement face 1\n"
      "property list uchar int vertex_indices\nend_header\n";
  const std::string le = std::string("\x00\x00\x80\x3f", 4) + "\xfe\xff" + "\x07" +
                         std::string("\x00\x00\x00\xc0", 4) + "\x02\x01" + "\xc8" + "\x03" +
                         std::string("\x01\x00\x00\x00\x00\x00\x00\x00\x01\x00\x00\x00", 12);
  const std::string be = std::string("\x3f\x80\x00\x00", 4) + "\xff\xfe" + "\x07" +
                         std::string("\xc0\x00\x00\x00", 4) + "\x01\x02" + "\xc8" + "\x03" +
                         std::string("\x00\x00\x00\x01\x00\x00\x00\x00\x00\x00\x00\x01", 12);
  EXPECT_EQ(SerializePly(mesh, PlyFormat::kBinaryLittleEndian),
            "ply\nformat binary_little_endian" + header_tail + le);
  EXPECT_EQ(SerializePly(mesh, PlyFormat::kBinaryBigEndian),
            "ply\nformat binary_big_endian" + header_tail + be);
}

TEST(PlyRead, MeshLabStyleAscii) {
  // As MeshLab (VCG) writes: obj_info-free header, trailing spaces on every data line.
  const std::string text =
      "ply\n"
      "format ascii 1.0\n"
      "comment VCGLIB generated\n"
      "element vertex 4\n"
      "property float x\n"
      "property float y\n"
      "property float z\n"
      "property float nx\n"
      "property float ny\n"
      "property float nz\n"
      "property uchar red\n"
      "property uchar green\n"
      "property uchar blue\n"
      "property uchar alpha\n"
      "element face 2\n"
      "property list uchar int vertex_indices\n"
      "end_header\n"
      "0 0 0 0 0 1 255 0 0 255 \n"
      "1.5 0 0 0 0 1 0 255 0 255 \n"
      "1.5 2.25 0 0 0 1 0 0 255 128 \n"
      "0 2.25 -0.125 0 0 1 10 20 30 0 \n"
      "3 0 1 2 \n"
      "3 0 2 3 \n";
  const PlyMesh mesh = ParsePly(text, "meshlab.ply");
  EXPECT_EQ(mesh.comments, std::vector<std::string>{"VCGLIB generated"});
  ASSERT_EQ(mesh.NumVertices(), 4u);
  EXPECT_EQ(mesh.vertex_properties.size(), 10u);
  EXPECT_EQ(mesh.Positions()[2], Eigen::Vector3d(1.5, 2.25, 0));
  EXPECT_EQ(mesh.Positions()[3], Eigen::Vector3d(0, 2.25, -0.125));
  EXPECT_EQ(mesh.Normals()[1], Eigen::Vector3d(0, 0, 1));
  EXPECT_EQ(mesh.Get("red").type, PlyType::kUInt8);
  EXPECT_EQ(mesh.ColorsWithAlpha()[2], Rgba8(0, 0, 255, 128));
  EXPECT_EQ(mesh.Colors()[3], Rgb8(10, 20, 30));
  ASSERT_EQ(mesh.faces.size(), 2u);
  EXPECT_EQ(mesh.faces[0], Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(mesh.faces[1], Eigen::Vector3i(0, 2, 3));
}

TEST(PlyRead, CrlfLineEndingsBlankLinesAndAliases) {
  const std::string text =
      "ply\r\nformat ascii 1.0\r\nobj_info scanner 1\r\nelement vertex 3\r\n"
      "property float32 x\r\nproperty float32 y\r\nproperty float32 z\r\n"
      "property int8 label\r\nelement face 1\r\nproperty list uint8 uint32 vertex_index\r\n"
      "end_header\r\n"
      "0 0 0 -7\r\n\r\n1e0 +2 0.5 +3\r\n  0\t1 2   4  \r\n3 2 1 0\r\n\r\n";
  const PlyMesh mesh = ParsePly(text, "crlf.ply");
  EXPECT_EQ(mesh.Get("label").values, (std::vector<double>{-7, 3, 4}));
  EXPECT_EQ(mesh.Get("label").type, PlyType::kInt8);
  EXPECT_EQ(mesh.Positions()[1], Eigen::Vector3d(1, 2, 0.5));
  ASSERT_EQ(mesh.faces.size(), 1u);
  EXPECT_EQ(mesh.faces[0], Eigen::Vector3i(2, 1, 0));

  // A binary file whose header has CRLF line ends: the data starts after the '\n'.
  const std::string binary =
      "ply\r\nformat binary_little_endian 1.0\r\nelement vertex 1\r\n"
      "property ushort v\r\nend_header\r\n" +
      Bytes<uint16_t>(0x0d0a);
  EXPECT_EQ(ParsePly(binary, "crlf_binary.ply").Get("v").values[0], 0x0d0a);
}

TEST(PlyRead, FaceElementBeforeVertexAndNumberForms) {
  // Element order is free; indices are checked against the vertex count of the header.
  const std::string text =
      "ply\nformat ascii 1.0\nelement face 1\nproperty list uchar int vertex_indices\n"
      "element vertex 3\nproperty double x\nproperty short s\nend_header\n"
      "3 2 0 1\n.5 1.0e1\n-1. +7\n1.5e-3 -0\n";
  const PlyMesh mesh = ParsePly(text, "order.ply");
  EXPECT_EQ(mesh.faces, (std::vector<Eigen::Vector3i>{{2, 0, 1}}));
  EXPECT_EQ(mesh.Get("x").values, (std::vector<double>{0.5, -1.0, 1.5e-3}));
  EXPECT_EQ(mesh.Get("s").values, (std::vector<double>{10, 7, 0}));
}

TEST(PlyRead, PolygonsAreFanTriangulated) {
  const std::string header =
      "element vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 3\nproperty list uchar int vertex_indices\nend_header\n";
  const std::vector<Eigen::Vector3i> expected = {{0, 1, 2}, {0, 2, 3},              // quad
                                                 {3, 4, 5},                         // triangle
                                                 {5, 4, 3}, {5, 3, 2}, {5, 2, 1}};  // pentagon
  std::string ascii = "ply\nformat ascii 1.0\n" + header;
  for (int i = 0; i < 6; ++i) ascii += std::to_string(i) + " 0 0\n";
  ascii += "4 0 1 2 3\n3 3 4 5\n5 5 4 3 2 1\n";
  EXPECT_EQ(ParsePly(ascii, "fan.ply").faces, expected);

  std::string binary = "ply\nformat binary_little_endian 1.0\n" + header;
  for (int i = 0; i < 6; ++i) binary += Bytes<float>(i) + Bytes<float>(0) + Bytes<float>(0);
  for (const std::vector<int>& polygon :
       std::vector<std::vector<int>>{{0, 1, 2, 3}, {3, 4, 5}, {5, 4, 3, 2, 1}}) {
    binary += Bytes<uint8_t>(static_cast<uint8_t>(polygon.size()));
    for (const int index : polygon) binary += Bytes<int32_t>(index);
  }
  EXPECT_EQ(ParsePly(binary, "fan.ply").faces, expected);
}

TEST(PlyRead, UnknownElementsAndListsAreSkipped) {
  // Elements before, between and after the known ones; list properties in an unknown
  // element, in the vertex element (skipped) and face properties after the index list
  // (per-face colour, as some writers emit).
  const std::string header_tail =
      " 1.0\n"
      "element material 2\nproperty list ushort float coefficients\nproperty uchar kind\n"
      "element vertex 3\nproperty double x\nproperty list uchar int neighbours\n"
      "property short t\n"
      "element edge 1\nproperty int vertex1\nproperty int vertex2\n"
      "element face 2\nproperty uchar flags\nproperty list uchar uint vertex_indices\n"
      "property uchar red\nproperty list int short ids\n"
      "element camera 1\nproperty list uint double matrix\n"
      "end_header\n";
  const std::string ascii = "ply\nformat ascii 1.0\ncomment c\n" + header_tail.substr(5) +
                            "3 0.5 1.5 2.5 9\n0 1\n"
                            "0.25 2 1 2 -1\n1.25 0 -2\n2.25 1 0 -3\n"
                            "0 2\n"
                            "1 3 0 1 2 255 2 7 8\n0 4 2 1 0 1 0 0\n"
                            "2 1 2\n";
  auto check = [](const PlyMesh& mesh) {
    ASSERT_EQ(mesh.vertex_properties.size(), 2u);
    EXPECT_EQ(mesh.Get("x").values, (std::vector<double>{0.25, 1.25, 2.25}));
    EXPECT_EQ(mesh.Get("t").values, (std::vector<double>{-1, -2, -3}));
    EXPECT_EQ(mesh.Get("t").type, PlyType::kInt16);
    EXPECT_EQ(mesh.faces, (std::vector<Eigen::Vector3i>{{0, 1, 2}, {2, 1, 0}, {2, 0, 1}}));
  };
  check(ParsePly(ascii, "skip.ply"));

  for (const bool big : {false, true}) {
    std::string binary = std::string("ply\nformat ") +
                         (big ? "binary_big_endian" : "binary_little_endian") + header_tail;
    // material
    binary += Bytes<uint16_t>(3, big) + Bytes<float>(0.5f, big) + Bytes<float>(1.5f, big) +
              Bytes<float>(2.5f, big) + Bytes<uint8_t>(9);
    binary += Bytes<uint16_t>(0, big) + Bytes<uint8_t>(1);
    // vertex
    binary += Bytes<double>(0.25, big) + Bytes<uint8_t>(2) + Bytes<int32_t>(1, big) +
              Bytes<int32_t>(2, big) + Bytes<int16_t>(-1, big);
    binary += Bytes<double>(1.25, big) + Bytes<uint8_t>(0) + Bytes<int16_t>(-2, big);
    binary += Bytes<double>(2.25, big) + Bytes<uint8_t>(1) + Bytes<int32_t>(0, big) +
              Bytes<int16_t>(-3, big);
    // edge
    binary += Bytes<int32_t>(0, big) + Bytes<int32_t>(2, big);
    // face
    binary += Bytes<uint8_t>(1) + Bytes<uint8_t>(3) + Bytes<uint32_t>(0, big) +
              Bytes<uint32_t>(1, big) + Bytes<uint32_t>(2, big) + Bytes<uint8_t>(255) +
              Bytes<int32_t>(2, big) + Bytes<int16_t>(7, big) + Bytes<int16_t>(8, big);
    binary += Bytes<uint8_t>(0) + Bytes<uint8_t>(4) + Bytes<uint32_t>(2, big) +
              Bytes<uint32_t>(1, big) + Bytes<uint32_t>(0, big) + Bytes<uint32_t>(1, big) +
              Bytes<uint8_t>(0) + Bytes<int32_t>(0, big);
    // camera
    binary += Bytes<uint32_t>(2, big) + Bytes<double>(1, big) + Bytes<double>(2, big);
    SCOPED_TRACE(big ? "big-endian" : "little-endian");
    check(ParsePly(binary, "skip.ply"));
  }
}

TEST(PlyRead, BigEndianFileBuiltByteByByte) {
  std::string file =
      "ply\nformat binary_big_endian 1.0\nelement vertex 2\nproperty float x\n"
      "property float y\nproperty float z\nproperty short s\nproperty uint u\n"
      "property double temperature_c\nelement face 1\nproperty list uchar int vertex_indices\n"
      "end_header\n";
  const unsigned char data[] = {
      0x3f, 0x80, 0x00, 0x00,                          // x = 1.0f
      0xc0, 0x00, 0x00, 0x00,                          // y = -2.0f
      0x3e, 0x80, 0x00, 0x00,                          // z = 0.25f
      0xff, 0xfe,                                      // s = -2
      0x01, 0x02, 0x03, 0x04,                          // u = 0x01020304
      0x40, 0x35, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 21.0
      0x00, 0x00, 0x00, 0x00,                          // x = 0
      0x7f, 0x80, 0x00, 0x00,                          // y = +inf
      0x80, 0x00, 0x00, 0x01,                          // z = -denorm_min
      0x80, 0x00,                                      // s = -32768
      0xff, 0xff, 0xff, 0xff,                          // u = 4294967295
      0xc0, 0x71, 0x13, 0x33, 0x33, 0x33, 0x33, 0x33,  // -273.2
      0x03, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01,  // 1 0 1
  };
  file.append(reinterpret_cast<const char*>(data), sizeof(data));
  const PlyMesh mesh = ParsePly(file, "be.ply");
  EXPECT_EQ(mesh.Positions()[0], Eigen::Vector3d(1.0, -2.0, 0.25));
  EXPECT_EQ(mesh.Get("x").values[1], 0.0);
  EXPECT_EQ(mesh.Get("y").values[1], std::numeric_limits<double>::infinity());
  EXPECT_EQ(mesh.Get("z").values[1],
            -static_cast<double>(std::numeric_limits<float>::denorm_min()));
  EXPECT_EQ(mesh.Get("s").values, (std::vector<double>{-2, -32768}));
  EXPECT_EQ(mesh.Get("u").values, (std::vector<double>{0x01020304, 4294967295.0}));
  EXPECT_EQ(mesh.Get("temperature_c").values, (std::vector<double>{21.0, -273.2}));
  EXPECT_EQ(mesh.faces, (std::vector<Eigen::Vector3i>{{1, 0, 1}}));
}

TEST(PlyMeshTest, Accessors) {
  PlyMesh mesh;
  EXPECT_EQ(mesh.NumVertices(), 0u);
  EXPECT_EQ(mesh.Find("x"), nullptr);
  EXPECT_FALSE(mesh.HasPositions());
  mesh.AddProperty("emissivity", PlyType::kFloat32, {0.9, 0.95});
  mesh.SetPositions({{1, 2, 3}, {4, 5, 6}});
  EXPECT_EQ(mesh.vertex_properties[0].name, "x");
  EXPECT_EQ(mesh.vertex_properties[3].name, "emissivity");
  EXPECT_EQ(mesh.NumVertices(), 2u);
  EXPECT_TRUE(mesh.HasPositions());
  EXPECT_FALSE(mesh.HasNormals());
  EXPECT_FALSE(mesh.HasColors());
  // Replacing keeps the place and changes the type.
  mesh.SetPositions({{7, 8, 9}, {1, 1, 1}}, PlyType::kFloat64);
  EXPECT_EQ(mesh.vertex_properties[2].name, "z");
  EXPECT_EQ(mesh.Get("z").type, PlyType::kFloat64);
  EXPECT_EQ(mesh.Positions()[0], Eigen::Vector3d(7, 8, 9));
  mesh.SetProperty("emissivity", PlyType::kFloat64, {0.5, 0.6});
  mesh.SetProperty("confidence", PlyType::kUInt8, {1, 2});
  EXPECT_EQ(mesh.vertex_properties.back().name, "confidence");
  EXPECT_EQ(mesh.Get("emissivity").values[1], 0.6);
  mesh.Get("confidence").values[0] = 9;
  EXPECT_EQ(mesh.Find("confidence")->values[0], 9);
  EXPECT_TRUE(mesh.RemoveProperty("confidence"));
  EXPECT_FALSE(mesh.RemoveProperty("confidence"));
  EXPECT_EQ(mesh.Check(), "");

  // Colours: alpha defaults to 255; float colour is 0..1, scaled and clamped.
  mesh.SetColorsWithAlpha({{1, 2, 3, 4}, {5, 6, 7, 8}});
  EXPECT_EQ(mesh.ColorsWithAlpha()[1], Rgba8(5, 6, 7, 8));
  mesh.SetColors({{1, 2, 3}, {5, 6, 7}});
  EXPECT_EQ(mesh.Find("alpha"), nullptr);
  EXPECT_EQ(mesh.ColorsWithAlpha()[0], Rgba8(1, 2, 3, 255));
  mesh.SetProperty("red", PlyType::kFloat32, {0.5, 2.0});
  mesh.SetProperty("green", PlyType::kInt16, {-4, 1000});
  EXPECT_EQ(mesh.Colors()[0], Rgb8(128, 0, 3));
  EXPECT_EQ(mesh.Colors()[1], Rgb8(255, 255, 7));
}

TEST(PlyMeshTest, CheckNamesWhatIsWrong) {
  PlyMesh mesh;
  mesh.SetPositions({{0, 0, 0}, {1, 0, 0}, {0, 1, 0}});
  mesh.faces = {{0, 1, 2}};
  EXPECT_EQ(mesh.Check(), "");
  PlyMesh bad = mesh;
  bad.faces.emplace_back(0, 3, 1);
  EXPECT_EQ(bad.Check(), "face 1: vertex index 3 out of range (3 vertices)");
  bad = mesh;
  bad.faces.emplace_back(-1, 0, 1);
  EXPECT_THAT(bad.Check(), HasSubstr("vertex index -1 out of range"));
  bad = mesh;
  bad.vertex_properties[1].values.pop_back();
  EXPECT_EQ(bad.Check(), "property y has 2 values, property x has 3");
  bad = mesh;
  bad.vertex_properties[2].name = "x";
  EXPECT_EQ(bad.Check(), "duplicate property x");
  bad = mesh;
  bad.vertex_properties[2].name = "two words";
  EXPECT_THAT(bad.Check(), HasSubstr("invalid PLY name"));
  bad = mesh;
  bad.vertex_properties[2].name = "";
  EXPECT_THAT(bad.Check(), HasSubstr("invalid PLY name"));
  bad = mesh;
  bad.comments = {"two\nlines"};
  EXPECT_THAT(bad.Check(), HasSubstr("line break"));
}

TEST(PlyMeshDeathTest, MisuseAsserts) {
  PlyMesh mesh;
  mesh.SetPositions({{0, 0, 0}, {1, 0, 0}});
  EXPECT_DEATH(mesh.AddProperty("t", PlyType::kFloat32, {1.0}), "size");
  EXPECT_DEATH(mesh.AddProperty("x", PlyType::kFloat32, {1.0, 2.0}), "already");
  EXPECT_DEATH(mesh.Get("nope"), "nope");
  mesh.faces = {{0, 1, 2}};
  EXPECT_DEATH(SerializePly(mesh), "out of range");
}

}  // namespace
}  // namespace hw::core
