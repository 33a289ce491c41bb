#pragma once

// Meshes, byte builders and expectations shared by the PLY tests.

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

#include "core/ply.h"

namespace hw::core::ply_test {

namespace fs = std::filesystem;

inline std::vector<fs::path> ListDir(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir)) files.push_back(entry.path().filename());
  return files;
}

// Same bits, so that NaN equals NaN and -0 differs from +0.
inline bool SameBits(double a, double b) {
  return std::bit_cast<uint64_t>(a) == std::bit_cast<uint64_t>(b);
}

inline void ExpectSameMesh(const PlyMesh& expected, const PlyMesh& actual) {
  ASSERT_EQ(actual.vertex_properties.size(), expected.vertex_properties.size());
  for (size_t j = 0; j < expected.vertex_properties.size(); ++j) {
    const PlyProperty& e = expected.vertex_properties[j];
    const PlyProperty& a = actual.vertex_properties[j];
    EXPECT_EQ(a.name, e.name);
    EXPECT_EQ(a.type, e.type) << e.name;
    ASSERT_EQ(a.values.size(), e.values.size()) << e.name;
    for (size_t i = 0; i < e.values.size(); ++i) {
      // What the file holds is the value converted to the property's type, exactly.
      const double want = PlyRepresentable(e.type, e.values[i]);
      EXPECT_TRUE(SameBits(a.values[i], want))
          << e.name << "[" << i << "]: got " << a.values[i] << ", want " << want;
    }
  }
  ASSERT_EQ(actual.faces.size(), expected.faces.size());
  for (size_t f = 0; f < expected.faces.size(); ++f) {
    EXPECT_EQ(actual.faces[f], expected.faces[f]) << "face " << f;
  }
}

// Expects ParsePly(data) to throw InputError whose reason contains `message`.
inline void ExpectInputError(const std::string& data, const std::string& message) {
  try {
    ParsePly(data, "bad.ply");
    ADD_FAILURE() << "no error; expected: " << message;
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), fs::path("bad.ply"));
    EXPECT_THAT(e.reason(), ::testing::HasSubstr(message)) << "data:\n" << data.substr(0, 400);
    EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
  }
}

// Little- or big-endian bytes of a value, for building binary files by hand.
template <typename T>
inline std::string Bytes(T value, bool big_endian = false) {
  std::string out(sizeof(T), '\0');
  std::memcpy(out.data(), &value, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big)) {
    std::reverse(out.begin(), out.end());
  }
  return out;
}

// One property of every type, holding the type's extremes and awkward values.
inline PlyMesh EveryTypeMesh() {
  using F = std::numeric_limits<float>;
  using D = std::numeric_limits<double>;
  PlyMesh mesh;
  mesh.AddProperty("i8", PlyType::kInt8, {-128, 127, 0, -1, 1, 42, -100, 5});
  mesh.AddProperty("u8", PlyType::kUInt8, {0, 255, 1, 254, 128, 127, 7, 200});
  mesh.AddProperty("i16", PlyType::kInt16, {-32768, 32767, 0, -1, 1, 12345, -12345, 300});
  mesh.AddProperty("u16", PlyType::kUInt16, {0, 65535, 1, 65534, 32768, 256, 255, 40000});
  mesh.AddProperty("i32", PlyType::kInt32,
                   {-2147483648.0, 2147483647.0, 0, -1, 1, 123456789, -987654321, 65536});
  mesh.AddProperty("u32", PlyType::kUInt32,
                   {0, 4294967295.0, 1, 4294967294.0, 2147483648.0, 16777217, 3, 99});
  mesh.AddProperty("f32", PlyType::kFloat32,
                   {static_cast<double>(F::max()), static_cast<double>(F::lowest()),
                    static_cast<double>(F::min()), static_cast<double>(F::denorm_min()),
                    static_cast<double>(0.1f), -0.0, D::infinity(), D::quiet_NaN()});
  mesh.AddProperty("f64", PlyType::kFloat64,
                   {D::max(), D::lowest(), D::min(), D::denorm_min(), 0.1, -0.0, std::numbers::pi,
                    -D::infinity()});
  mesh.faces = {{0, 1, 2}, {7, 6, 5}, {2, 4, 3}};
  return mesh;
}

}  // namespace hw::core::ply_test
