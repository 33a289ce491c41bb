#pragma once

// Eight floats at a time with GCC/Clang vector extensions, for the per-pixel loops that -O2
// does not vectorise by itself (the bilateral filter, normals, ICP's association): two SSE
// halves in a plain x86-64 build, one AVX register in the functions cloned for AVX2 and
// AVX-512 (`__attribute__((target_clones(...)))`), into which these helpers are inlined.
// The same operations in the same order in every clone (no FMA contraction in ISO C++), so
// results do not depend on the CPU.
//
// GCC warns that passing 32-byte vectors without AVX changes the ABI between translation
// units; the helpers are inline and never cross one, so the warning is off for the files
// that include this (a diagnostic pragma lasts to the end of the translation unit).

#include <cmath>
#include <cstdint>
#include <cstring>

#pragma GCC diagnostic ignored "-Wpsabi"

namespace hw::reconstruct::internal {

using Float8 = float __attribute__((vector_size(32)));
using Int8 = std::int32_t __attribute__((vector_size(32)));

inline Float8 Load8(const float* p) {
  Float8 v;
  std::memcpy(&v, p, sizeof(v));
  return v;
}
inline void Store8(float* p, Float8 v) { std::memcpy(p, &v, sizeof(v)); }
inline Float8 Splat8(float f) { return Float8{f, f, f, f, f, f, f, f}; }
// `v` where mask is all ones, else +0 (also where v is NaN).
inline Float8 Masked8(Float8 v, Int8 mask) { return reinterpret_cast<Float8>(reinterpret_cast<Int8>(v) & mask); }
// a where mask is all ones, else b.
inline Float8 Select8(Int8 mask, Float8 a, Float8 b) {
  return reinterpret_cast<Float8>((reinterpret_cast<Int8>(a) & mask) | (reinterpret_cast<Int8>(b) & ~mask));
}
inline Float8 Abs8(Float8 v) { return reinterpret_cast<Float8>(reinterpret_cast<Int8>(v) & (Int8{} + 0x7fffffff)); }
inline Float8 Max8(Float8 a, Float8 b) { return a > b ? a : b; }
// Lanes are floor(v) for |v| < 2³¹ (conversion truncates towards zero).
inline Int8 Floor8(Float8 v) {
  const Int8 t = __builtin_convertvector(v, Int8);
  return t + (__builtin_convertvector(t, Float8) > v);  // a true comparison is -1
}

// Correctly rounded square roots (as std::sqrt), by halves: SSE's sqrtps is in every
// x86-64 clone.
inline Float8 Sqrt8(Float8 v) {
#if defined(__SSE__)
  using Float4 = float __attribute__((vector_size(16)));
  Float4 half[2];
  std::memcpy(half, &v, sizeof(v));
  half[0] = __builtin_ia32_sqrtps(half[0]);
  half[1] = __builtin_ia32_sqrtps(half[1]);
  std::memcpy(&v, half, sizeof(v));
  return v;
#else
  return Float8{std::sqrt(v[0]), std::sqrt(v[1]), std::sqrt(v[2]), std::sqrt(v[3]),
                std::sqrt(v[4]), std::sqrt(v[5]), std::sqrt(v[6]), std::sqrt(v[7])};
#endif
}

// Eight packed float triples (24 floats from `xyz`: points or normals as Eigen::Vector3f)
// as three registers of x, y and z: three loads, a blend and a permute per component. Lane
// l of register i holds float 8i + l, component (8i + l) % 3 of triple (8i + l) / 3; each
// component is in exactly one register per lane (blend), then in triple order (permute).
// Setting lanes one by one instead goes through the stack, and the load of the whole vector
// waits for the eight stores (it was a third of ICP's association).
inline void LoadTriples8(const float* xyz, Float8 (&out)[3]) {
  const Float8 r0 = Load8(xyz), r1 = Load8(xyz + 8), r2 = Load8(xyz + 16);
  constexpr Int8 from_r1[3] = {{0, -1, 0, 0, -1, 0, 0, -1}, {0, 0, -1, 0, 0, -1, 0, 0}, {-1, 0, 0, -1, 0, 0, -1, 0}};
  constexpr Int8 from_r2[3] = {{0, 0, -1, 0, 0, -1, 0, 0}, {-1, 0, 0, -1, 0, 0, -1, 0}, {0, -1, 0, 0, -1, 0, 0, -1}};
  constexpr Int8 order[3] = {{0, 3, 6, 1, 4, 7, 2, 5}, {1, 4, 7, 2, 5, 0, 3, 6}, {2, 5, 0, 3, 6, 1, 4, 7}};
#pragma GCC unroll 3
  for (int c = 0; c < 3; ++c) {
    const Float8 blend = from_r2[c] ? r2 : (from_r1[c] ? r1 : r0);
    out[c] = __builtin_shuffle(blend, order[c]);
  }
}

// The inverse of LoadTriples8: x, y and z of eight triples stored packed at `xyz`.
inline void StoreTriples8(const Float8 (&in)[3], float* xyz) {
  // Register i lane l takes component (8i + l) % 3 of triple (8i + l) / 3: each component
  // first permuted so that each lane holds the triple whose component lands there (the
  // inverse permutations of LoadTriples8's), then blended into place.
  constexpr Int8 inverse[3] = {{0, 3, 6, 1, 4, 7, 2, 5}, {5, 0, 3, 6, 1, 4, 7, 2}, {2, 5, 0, 3, 6, 1, 4, 7}};
  Float8 spread[3];
#pragma GCC unroll 3
  for (int c = 0; c < 3; ++c) spread[c] = __builtin_shuffle(in[c], inverse[c]);
  constexpr Int8 component_of[3] = {{0, 1, 2, 0, 1, 2, 0, 1}, {2, 0, 1, 2, 0, 1, 2, 0}, {1, 2, 0, 1, 2, 0, 1, 2}};
#pragma GCC unroll 3
  for (int i = 0; i < 3; ++i) {
    const Int8 k = component_of[i];
    Store8(xyz + 8 * i, k == 0 ? spread[0] : (k == 1 ? spread[1] : spread[2]));
  }
}

// base[offset[k]] in lane k: eight scalar loads assembled in registers (a vector built with
// one initialiser; see LoadTriples8 for why not lane by lane).
inline Float8 Gather8(const float* base, Int8 offset) {
  return Float8{base[offset[0]], base[offset[1]], base[offset[2]], base[offset[3]],
                base[offset[4]], base[offset[5]], base[offset[6]], base[offset[7]]};
}

}  // namespace hw::reconstruct::internal
