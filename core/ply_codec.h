#pragma once

// Internals of the PLY reader and writer (core/ply.h), shared by core/ply*.cc: the scalar
// type table, byte order, number text and name checks. Not an API of its own.

#include <algorithm>
#include <array>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numeric>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "core/ply.h"

namespace hw::core::ply_internal {

// ---------------------------------------------------------------------------------------
// Types

struct TypeInfo {
  PlyType type;
  std::string_view name;   // written
  std::string_view alias;  // also accepted on read
  size_t size;
};

inline constexpr std::array<TypeInfo, 8> kTypes = {{
    {PlyType::kInt8, "char", "int8", 1},
    {PlyType::kUInt8, "uchar", "uint8", 1},
    {PlyType::kInt16, "short", "int16", 2},
    {PlyType::kUInt16, "ushort", "uint16", 2},
    {PlyType::kInt32, "int", "int32", 4},
    {PlyType::kUInt32, "uint", "uint32", 4},
    {PlyType::kFloat32, "float", "float32", 4},
    {PlyType::kFloat64, "double", "float64", 8},
}};

inline const TypeInfo& Info(PlyType type) {
  const auto index = static_cast<size_t>(type);
  assert(index < kTypes.size());
  return kTypes[index];
}

// Calls f(T{}) with T the C++ type of `type`.
template <typename F>
decltype(auto) Dispatch(PlyType type, F&& f) {
  switch (type) {
    case PlyType::kInt8:
      return f(int8_t{});
    case PlyType::kUInt8:
      return f(uint8_t{});
    case PlyType::kInt16:
      return f(int16_t{});
    case PlyType::kUInt16:
      return f(uint16_t{});
    case PlyType::kInt32:
      return f(int32_t{});
    case PlyType::kUInt32:
      return f(uint32_t{});
    case PlyType::kFloat32:
      return f(float{});
    case PlyType::kFloat64:
      return f(double{});
  }
  assert(false && "bad PlyType");
  return f(double{});
}

// Largest double that still rounds to a finite float (FLT_MAX plus half an ulp is a tie,
// which rounds to even: infinity).
inline constexpr double kFloatOverflow = 0x1.ffffffp+127;

template <typename T>
T Convert(double value) {
  if constexpr (std::is_same_v<T, double>) {
    return value;
  } else if constexpr (std::is_same_v<T, float>) {
    // Out-of-range double-to-float casts are undefined behaviour: saturate to infinity as
    // IEEE rounding would.
    if (value >= kFloatOverflow) return std::numeric_limits<float>::infinity();
    if (value <= -kFloatOverflow) return -std::numeric_limits<float>::infinity();
    return static_cast<float>(value);
  } else {
    if (std::isnan(value)) return T{0};
    const double rounded = std::round(value);
    // Every limit of an integer type up to 32 bits is exact in double.
    if (rounded <= static_cast<double>(std::numeric_limits<T>::min())) {
      return std::numeric_limits<T>::min();
    }
    if (rounded >= static_cast<double>(std::numeric_limits<T>::max())) {
      return std::numeric_limits<T>::max();
    }
    return static_cast<T>(rounded);
  }
}

// ---------------------------------------------------------------------------------------
// Byte order

template <size_t N>
struct UIntOfSize;
template <>
struct UIntOfSize<2> {
  using Type = uint16_t;
  static Type Swap(Type v) { return __builtin_bswap16(v); }
};
template <>
struct UIntOfSize<4> {
  using Type = uint32_t;
  static Type Swap(Type v) { return __builtin_bswap32(v); }
};
template <>
struct UIntOfSize<8> {
  using Type = uint64_t;
  static Type Swap(Type v) { return __builtin_bswap64(v); }
};

template <typename T, bool kSwap>
inline T Load(const char* p) {
  T value;
  if constexpr (kSwap && sizeof(T) > 1) {
    using U = UIntOfSize<sizeof(T)>;
    typename U::Type bits;
    std::memcpy(&bits, p, sizeof(bits));
    bits = U::Swap(bits);
    std::memcpy(&value, &bits, sizeof(value));
  } else {
    std::memcpy(&value, p, sizeof(value));
  }
  return value;
}

template <typename T, bool kSwap>
inline void Store(T value, char* p) {
  if constexpr (kSwap && sizeof(T) > 1) {
    using U = UIntOfSize<sizeof(T)>;
    typename U::Type bits;
    std::memcpy(&bits, &value, sizeof(bits));
    bits = U::Swap(bits);
    std::memcpy(p, &bits, sizeof(bits));
  } else {
    std::memcpy(p, &value, sizeof(value));
  }
}

// Whether a file in `format` needs its bytes swapped on this machine.
inline bool NeedsSwap(PlyFormat format) {
  static_assert(std::endian::native == std::endian::little ||
                std::endian::native == std::endian::big);
  const bool file_big = format == PlyFormat::kBinaryBigEndian;
  return file_big != (std::endian::native == std::endian::big);
}

inline double LoadAsDouble(PlyType type, const char* p, bool swap) {
  return Dispatch(type, [&](auto tag) -> double {
    using T = decltype(tag);
    return static_cast<double>(swap ? Load<T, true>(p) : Load<T, false>(p));
  });
}

// ---------------------------------------------------------------------------------------
// Text

// Splits on spaces and tabs.
std::vector<std::string_view> SplitFields(std::string_view line);
// `text` in quotes, cut to 40 characters, non-printable bytes as '?': keeps messages one
// short printable line even for binary garbage.
std::string Quoted(std::string_view text);
// A decimal number of digits only; false for anything else or on overflow.
bool ParseUInt64(std::string_view text, uint64_t* value);
// Shortest text of `value` that reads back to it.
std::string ToText(double value);
// Parses a PLY ASCII number into what `type` holds. Returns "" or why it is not valid.
std::string ParseAsciiValue(std::string_view token, PlyType type, double* value);
// Appends the shortest text that reads back to `value` converted to `type`.
void AppendAsciiValue(PlyType type, double value, std::string* out);
// Non-empty, no whitespace or control characters.
bool IsValidName(std::string_view name);

// ---------------------------------------------------------------------------------------
// Names

// The position of the first name, in order, that equals an earlier one, or `n` when all
// `n` names (name_at(0) .. name_at(n - 1)) differ. Sorts positions instead of comparing
// every pair (headers are written by whoever made the file: 100k property names must not
// take 10^10 comparisons) and instead of hashing (crafted names cannot collide a sort into
// quadratic time). O(n log n) comparisons and 8 bytes per name.
template <typename NameAt>
size_t FirstRepeated(size_t n, NameAt&& name_at) {
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    const std::string_view name_a = name_at(a);
    const std::string_view name_b = name_at(b);
    return name_a != name_b ? name_a < name_b : a < b;
  });
  // Within a run of equal names positions ascend: every one after the run's first repeats.
  size_t first = n;
  for (size_t k = 1; k < n; ++k) {
    if (name_at(order[k]) == name_at(order[k - 1])) first = std::min(first, order[k]);
  }
  return first;
}

}  // namespace hw::core::ply_internal
