// The PLY reader against files made to exhaust it: headers of hundreds of thousands of
// names must read in linear time, and no file may make the reader allocate much more than
// the mesh it describes. Memory is measured exactly, by counting this program's heap
// (operator new is replaced below), not from the resident set size: the numbers depend
// neither on the machine's load nor on what the process did before.

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <malloc.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <new>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/ply.h"

namespace {

std::atomic<int64_t> g_heap_bytes{0};  // live bytes from operator new
std::atomic<int64_t> g_heap_peak{0};   // highest g_heap_bytes since the last reset

void CountAllocation(void* p) {
  const auto size = static_cast<int64_t>(malloc_usable_size(p));
  const int64_t now = g_heap_bytes.fetch_add(size, std::memory_order_relaxed) + size;
  int64_t peak = g_heap_peak.load(std::memory_order_relaxed);
  while (now > peak && !g_heap_peak.compare_exchange_weak(peak, now, std::memory_order_relaxed)) {
  }
}

}  // namespace

// libstdc++'s array, nothrow and sized forms call these two; aligned forms (which nothing
// here uses) bypass them on both sides, so the count stays balanced.
void* operator new(std::size_t size) {
  void* p = std::malloc(size == 0 ? 1 : size);
  if (p == nullptr) throw std::bad_alloc();
  CountAllocation(p);
  return p;
}
void* operator new[](std::size_t size) { return ::operator new(size); }
void operator delete(void* p) noexcept {
  if (p == nullptr) return;
  g_heap_bytes.fetch_sub(static_cast<int64_t>(malloc_usable_size(p)), std::memory_order_relaxed);
  // GCC sees a pointer from operator new reach free(); here it came from malloc above.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
  std::free(p);
#pragma GCC diagnostic pop
}
void operator delete[](void* p) noexcept { ::operator delete(p); }
void operator delete(void* p, std::size_t) noexcept { ::operator delete(p); }
void operator delete[](void* p, std::size_t) noexcept { ::operator delete(p); }

namespace hw::core {
namespace {

using ::testing::HasSubstr;

// Highest heap growth while `f` runs, bytes, counting what it allocates and frees again.
template <typename F>
int64_t PeakHeapGrowth(F&& f) {
  const int64_t base = g_heap_bytes.load();
  g_heap_peak.store(base);
  f();
  return g_heap_peak.load() - base;
}

void ExpectInputError(const std::string& data, const std::string& message) {
  try {
    ParsePly(data, "bad.ply");
    ADD_FAILURE() << "no error; expected: " << message;
  } catch (const InputError& e) {
    EXPECT_THAT(e.reason(), HasSubstr(message));
  }
}

template <typename T>
void Append(std::string* out, T value) {
  out->append(reinterpret_cast<const char*>(&value), sizeof(value));
}

// The test of the tests: without a working hook every memory bound would hold trivially.
TEST(PlyLimits, HeapCounterSeesAllocations) {
  const int64_t growth = PeakHeapGrowth([] {
    std::vector<char> buffer(int64_t{8} << 20);
    buffer[12345] = 1;
    EXPECT_EQ(buffer[12345], 1);
  });
  EXPECT_GE(growth, int64_t{8} << 20);
  EXPECT_LT(growth, int64_t{9} << 20);
}

// Property and element names are checked for duplicates: that must not compare every
// name with every other (100k properties took 15 s to read and 13 s more to Check; 200k,
// 29 s and 34 s). Each step gets 3 s of this process's CPU time, so that other programs
// on the machine do not count; linear, each takes a small fraction of that.
TEST(PlyLimits, ManyPropertiesAndElementsTakeLinearTime) {
  constexpr size_t kN = 200000;
  constexpr double kMaxSeconds = 3.0;
  const auto cpu_seconds = [](auto&& f) {
    const std::clock_t start = std::clock();
    f();
    const double seconds = static_cast<double>(std::clock() - start) / CLOCKS_PER_SEC;
    std::printf("[ PLY limits ]   %.3f s of CPU\n", seconds);
    return seconds;
  };

  std::string header = "ply\nformat binary_little_endian 1.0\nelement vertex 1\n";
  for (size_t i = 0; i < kN; ++i) header += "property uchar p" + std::to_string(i) + "\n";
  const std::string data = header + "end_header\n" + std::string(kN, '\x07');
  std::printf("[ PLY limits ] reading %zu properties, checking, writing, reading again:\n", kN);
  PlyMesh mesh;
  // ASSERT: when it is slow, stop here rather than minutes later.
  ASSERT_LT(cpu_seconds([&] { mesh = ParsePly(data, "wide.ply"); }), kMaxSeconds);
  ASSERT_EQ(mesh.vertex_properties.size(), kN);
  EXPECT_EQ(mesh.vertex_properties.back().name, "p199999");
  EXPECT_EQ(mesh.vertex_properties.back().values, std::vector<double>{7});
  ASSERT_LT(cpu_seconds([&] { EXPECT_EQ(mesh.Check(), ""); }), kMaxSeconds);
  // Writing checks the mesh too.
  EXPECT_LT(cpu_seconds([&] {
              EXPECT_EQ(ParsePly(SerializePly(mesh), "again.ply").vertex_properties.size(), kN);
            }),
            kMaxSeconds);

  // A repeat at the very end is found, on its line.
  const std::string repeat =
      header + "property uchar p123456\nend_header\n" + std::string(kN + 1, '\0');
  std::printf("[ PLY limits ] a repeated property, in a file and in a mesh:\n");
  EXPECT_LT(cpu_seconds([&] {
              ExpectInputError(repeat,
                               "line " + std::to_string(kN + 4) + ": duplicate property 'p123456'");
            }),
            kMaxSeconds);
  mesh.vertex_properties.push_back(mesh.vertex_properties[4321]);
  EXPECT_LT(cpu_seconds([&] { EXPECT_EQ(mesh.Check(), "duplicate property p4321"); }), kMaxSeconds);

  std::string elements = "ply\nformat ascii 1.0\n";
  for (size_t i = 0; i < kN; ++i) elements += "element e" + std::to_string(i) + " 0\n";
  const std::string many = elements + "end_header\n";
  const std::string repeated = elements + "element e777 0\nend_header\n";
  std::printf("[ PLY limits ] %zu elements, then with a repeated one:\n", kN);
  EXPECT_LT(cpu_seconds([&] { EXPECT_EQ(ParsePly(many, "long.ply").NumVertices(), 0u); }),
            kMaxSeconds);
  EXPECT_LT(cpu_seconds([&] {
              ExpectInputError(repeated,
                               "line " + std::to_string(kN + 3) + ": duplicate element 'e777'");
            }),
            kMaxSeconds);
}

// Repeated names are found by sorting once the header is read; the error reported is
// still the one on the earliest line, as when every line was checked in turn.
TEST(PlyLimits, RepeatedNamesAreReportedInFileOrder) {
  const std::string head = "ply\nformat ascii 1.0\n";
  // Before a later error of another kind, or a missing end_header.
  ExpectInputError(head + "element v 0\nproperty int x\nproperty int x\nnonsense\nend_header\n",
                   "line 5: duplicate property 'x' in element v");
  ExpectInputError(head + "element v 0\nproperty int x\nproperty int x\n",
                   "line 5: duplicate property 'x' in element v");
  ExpectInputError(head + "element v 0\nelement v 0\nelement w 0\nelement w\n",
                   "line 4: duplicate element 'v'");
  // Before the checks of the whole header.
  ExpectInputError(head + "element vertex 3000000000\nproperty int x\nproperty int x\nend_header\n",
                   "line 5: duplicate property 'x' in element vertex");
  // Before what is wrong with the same line.
  ExpectInputError(head + "element face 0\nproperty list uchar int vertex_indices\n" +
                       "property int vertex_indices\nend_header\n",
                   "line 5: duplicate property 'vertex_indices' in element face");
  // The earlier of a repeated element and a repeated property, either way round.
  ExpectInputError(head + "element a 0\nproperty int x\nproperty int x\nelement a 0\nend_header\n",
                   "line 5: duplicate property 'x' in element a");
  ExpectInputError(head + "element a 0\nelement a 0\nproperty int x\nproperty int x\nend_header\n",
                   "line 4: duplicate element 'a'");
  ExpectInputError(head + "element a 0\nproperty int y\nelement b 0\nproperty int x\n" +
                       "property int y\nproperty int x\nproperty int y\nend_header\n",
                   "line 8: duplicate property 'x' in element b");
  // Line numbers count blank, comment and CRLF lines.
  ExpectInputError(
      "ply\r\nformat ascii 1.0\r\ncomment a\r\n\r\nelement v 0\r\nproperty int p\r\n"
      "obj_info x\r\n  \r\nproperty int p\r\nend_header\r\n",
      "line 9: duplicate property 'p' in element v");
  // The same name in two elements is no repeat.
  const PlyMesh mesh = ParsePly(head + "element vertex 1\nproperty int x\nelement b 1\n" +
                                    "property int x\nend_header\n1\n2\n",
                                "fine.ply");
  EXPECT_EQ(mesh.Get("x").values, std::vector<double>{1});

  // PlyMesh::Check reports the first problem in property order, a repeat or another.
  PlyMesh bad;
  bad.AddProperty("x", PlyType::kFloat32, {1, 2});
  bad.AddProperty("y", PlyType::kFloat32, {1, 2});
  bad.AddProperty("z", PlyType::kFloat32, {1, 2});
  bad.vertex_properties[1].name = "x";
  bad.vertex_properties[2].values.pop_back();
  EXPECT_EQ(bad.Check(), "duplicate property x");
  bad.vertex_properties[1].name = "y";
  bad.vertex_properties[2].name = "x";
  bad.vertex_properties[1].values.pop_back();
  EXPECT_EQ(bad.Check(), "property y has 1 values, property x has 2");
}

// A face with `num_indices` vertex indices of type `index_type` over 256 vertices.
std::string SinglePolygonFile(PlyFormat format, PlyType index_type, size_t num_indices) {
  const std::string type_name(PlyTypeName(index_type));
  if (format == PlyFormat::kAscii) {
    std::string data =
        "ply\nformat ascii 1.0\nelement vertex 10\nproperty uchar x\nelement face 1\n"
        "property list uint " +
        type_name + " vertex_indices\nend_header\n";
    for (int i = 0; i < 10; ++i) data += "0\n";
    data += std::to_string(num_indices);
    for (size_t k = 0; k < num_indices; ++k) {
      data += ' ';
      data += static_cast<char>('0' + k % 10);
    }
    return data + "\n";
  }
  std::string data =
      "ply\nformat binary_little_endian 1.0\nelement vertex 256\nproperty uchar x\n"
      "element face 1\nproperty list uint " +
      type_name + " vertex_indices\nend_header\n" + std::string(256, '\0');
  Append(&data, static_cast<uint32_t>(num_indices));
  for (size_t k = 0; k < num_indices; ++k) {
    const auto index = static_cast<uint8_t>(k);
    switch (PlyTypeSize(index_type)) {
      case 1:
        Append(&data, index);
        break;
      case 2:
        Append(&data, static_cast<uint16_t>(index));
        break;
      default:
        Append(&data, static_cast<uint32_t>(index));
        break;
    }
  }
  return data;
}

// One polygon of millions of indices (a 50 MB file of one face took 1.3 GB): reading it
// may take what its fan triangulation needs, 12 bytes per triangle, and little more. That
// is 3x the file for int indices, 6x for ushort and ASCII, 12x for uchar: the triangles
// themselves, no temporary copy of the polygon and no vector growth slack.
TEST(PlyLimits, OneHugePolygonNeedsOnlyItsTriangles) {
  constexpr size_t kFileBytes = size_t{4} << 20;
  struct Case {
    PlyFormat format;
    PlyType index_type;
    double max_ratio;  // peak heap growth / file size
  };
  for (const Case& c : {Case{PlyFormat::kBinaryLittleEndian, PlyType::kInt32, 3.05},
                        Case{PlyFormat::kBinaryLittleEndian, PlyType::kUInt16, 6.05},
                        Case{PlyFormat::kBinaryLittleEndian, PlyType::kUInt8, 12.05},
                        Case{PlyFormat::kAscii, PlyType::kInt32, 6.05}}) {
    const size_t item_bytes = c.format == PlyFormat::kAscii ? 2 : PlyTypeSize(c.index_type);
    const size_t num_indices = kFileBytes / item_bytes;
    const std::string data = SinglePolygonFile(c.format, c.index_type, num_indices);
    const int modulus = c.format == PlyFormat::kAscii ? 10 : 256;
    size_t num_triangles = 0;
    Eigen::Vector3i last;
    const int64_t growth = PeakHeapGrowth([&] {
      const PlyMesh mesh = ParsePly(data, "polygon.ply");
      num_triangles = mesh.faces.size();
      last = mesh.faces.back();
    });
    const std::string name = std::string(c.format == PlyFormat::kAscii ? "ascii " : "binary ") +
                             std::string(PlyTypeName(c.index_type));
    EXPECT_EQ(num_triangles, num_indices - 2) << name;
    EXPECT_EQ(last, Eigen::Vector3i(0, static_cast<int>((num_indices - 2) % modulus),
                                    static_cast<int>((num_indices - 1) % modulus)))
        << name;
    const double ratio = static_cast<double>(growth) / static_cast<double>(data.size());
    std::printf("[ PLY limits ] one polygon, %s, %.1f MB: peak heap %.1f MB = %.2fx the file\n",
                name.c_str(), static_cast<double>(data.size()) / 1e6,
                static_cast<double>(growth) / 1e6, ratio);
    const auto triangle_bytes = static_cast<int64_t>(num_triangles * sizeof(Eigen::Vector3i));
    EXPECT_LE(growth, triangle_bytes + (int64_t{64} << 10)) << name;
    EXPECT_LE(ratio, c.max_ratio) << name;
  }
}

// An ordinary mesh reads into its arrays, 8 bytes per value and 12 per triangle, without
// temporary copies or vector growth slack.
TEST(PlyLimits, MeshNeedsOnlyItsArrays) {
  constexpr size_t kN = 200000;
  PlyMesh mesh;
  std::vector<double> xs(kN), reds(kN);
  for (size_t i = 0; i < kN; ++i) {
    xs[i] = static_cast<double>(i) * 0.25;
    reds[i] = static_cast<double>(i % 256);
  }
  mesh.AddProperty("x", PlyType::kFloat32, xs);
  mesh.AddProperty("y", PlyType::kFloat32, xs);
  mesh.AddProperty("z", PlyType::kFloat64, std::move(xs));
  mesh.AddProperty("red", PlyType::kUInt8, std::move(reds));
  for (size_t i = 0; i + 2 < kN; ++i) {
    mesh.faces.emplace_back(static_cast<int>(i), static_cast<int>(i + 1), static_cast<int>(i + 2));
  }
  const int64_t arrays =
      static_cast<int64_t>(4 * kN * sizeof(double) + mesh.faces.size() * sizeof(Eigen::Vector3i));
  for (const PlyFormat format : {PlyFormat::kBinaryBigEndian, PlyFormat::kAscii}) {
    const std::string data = SerializePly(mesh, format);
    const int64_t growth = PeakHeapGrowth(
        [&] { EXPECT_EQ(ParsePly(data, "mesh.ply").faces.size(), mesh.faces.size()); });
    EXPECT_LE(growth, arrays + (int64_t{64} << 10)) << (format == PlyFormat::kAscii);
  }
}

// Counts in the header and in list rows are checked against the bytes that follow before
// anything is allocated for them.
TEST(PlyLimits, CountsAreCheckedBeforeAllocating) {
  struct Case {
    std::string data;
    std::string message;
  };
  const std::string binary = "ply\nformat binary_little_endian 1.0\n";
  const std::string ascii = "ply\nformat ascii 1.0\n";
  const std::string face = "element face 1\nproperty list uint int vertex_indices\n";
  std::string huge_list = binary + "element vertex 3\nproperty float x\n" + face + "end_header\n" +
                          std::string(12, '\0');
  Append(&huge_list, uint32_t{100000000});  // 100M indices in a 1 MB file
  huge_list += std::string(size_t{1} << 20, '\0');
  const std::vector<Case> cases = {
      // One byte short of 125000 vertices of a double each.
      {binary + "element vertex 125000\nproperty double x\nend_header\n" +
           std::string(999999, '\0'),
       "truncated: expected 1000000 bytes of vertex data, got 999999"},
      {binary + "element vertex 1099511627776\nproperty uchar x\nend_header\n",
       "more than the 2147483647 supported"},
      // 100000 faces need 1.7 MB at the least; 1 MB follows.
      {binary + "element vertex 0\nproperty float x\n" +
           "element face 100000\nproperty list uint int vertex_indices\nend_header\n" +
           std::string(size_t{1} << 20, '\0'),
       "truncated: expected at least 1600000 bytes of face data"},
      {huge_list, "list vertex_indices of 100000000 items needs 400000000 bytes"},
      // Each ASCII value takes two bytes: "0 ".
      {ascii + "element vertex 300000\nproperty float x\nproperty float y\nend_header\n" +
           std::string(size_t{1} << 20, '0'),
       "truncated: 300000 vertex rows need at least 600000 values"},
      {ascii + "element vertex 3\nproperty float x\n" + face + "end_header\n0\n0\n0\n" +
           "4000000000 0 1 2\n",
       "list vertex_indices of 4000000000 items is longer than its line"},
  };
  for (const Case& c : cases) {
    const int64_t growth = PeakHeapGrowth([&] { ExpectInputError(c.data, c.message); });
    EXPECT_LT(growth, int64_t{64} << 10) << c.message;
  }
}

// Headers of many short lines: every line becomes an object of a few dozen bytes (a
// comment a std::string, a property a PlyProperty), so these files take several times their
// size; the bound keeps that a small constant, without growth slack or duplicate copies.
TEST(PlyLimits, LongHeadersTakeAFewTimesTheirSize) {
  constexpr size_t kN = 200000;
  std::string properties = "ply\nformat binary_little_endian 1.0\nelement vertex 1\n";
  for (size_t i = 0; i < kN; ++i) properties += "property char " + std::to_string(i) + "\n";
  properties += "end_header\n" + std::string(kN, '\0');
  std::string elements = "ply\nformat ascii 1.0\n";
  for (size_t i = 0; i < kN; ++i) elements += "element " + std::to_string(i) + " 0\n";
  elements += "end_header\n";
  std::string comments = "ply\nformat ascii 1.0\n";
  for (size_t i = 0; i < kN; ++i) comments += "comment\n";
  comments += "end_header\n";
  std::string lists = "ply\nformat ascii 1.0\nelement vertex 1\n";
  for (size_t i = 0; i < kN; ++i) lists += "property list char char " + std::to_string(i) + "\n";
  lists += "property char x\nend_header\n";
  for (size_t i = 0; i < kN; ++i) lists += "0 ";
  lists += "0\n";
  struct Case {
    const char* name;
    const std::string& data;
    double max_ratio;
  };
  // Per line: a property is a PlyProperty (64 bytes), its one value (24) and 32 bytes while
  // reading; an element 40 bytes while reading; a comment a std::string (32 bytes).
  for (const Case& c : {Case{"properties", properties, 6.5}, Case{"elements", elements, 3.5},
                        Case{"comments", comments, 4.5}, Case{"skipped lists", lists, 1.5}}) {
    const int64_t growth = PeakHeapGrowth([&] { ParsePly(c.data, "header.ply"); });
    const double ratio = static_cast<double>(growth) / static_cast<double>(c.data.size());
    std::printf("[ PLY limits ] %zu %s, %.1f MB: peak heap %.1f MB = %.2fx the file\n", kN, c.name,
                static_cast<double>(c.data.size()) / 1e6, static_cast<double>(growth) / 1e6, ratio);
    EXPECT_LE(ratio, c.max_ratio) << c.name;
  }
}

}  // namespace
}  // namespace hw::core
