#include "reconstruct/tsdf_fill.h"

#include <algorithm>
#include <cstdint>

#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#include <immintrin.h>
#endif

#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct::internal {
namespace {

Voxel& At(Voxel* v, int x, int y, int z) { return v[x + kBlockSide * (y + kBlockSide * z)]; }

// `out` from its even neighbours a and b (tsdf_fill.h): the mean, or at a block's last index
// (face) the extrapolation 1.5 a − 0.5 b. The sums are exact (multiples of 2^-15 below 2), so
// the only rounding is set_sdf's, as in the SIMD code.
void Mix(const Voxel& a, const Voxel& b, bool face, Voxel& out) {
  if (a.observed() && b.observed()) {
    out.set_sdf(face ? 1.5f * a.sdf() - 0.5f * b.sdf() : 0.5f * a.sdf() + 0.5f * b.sdf());
    out.weight_count = std::min(a.weight_count, b.weight_count);
  } else if (a.observed() || b.observed()) {
    const Voxel& s = a.observed() ? a : b;
    out.sdf_steps = s.sdf_steps;
    out.weight_count = s.weight_count;
  }
  if (a.colour_weight != 0 && b.colour_weight != 0 && !face) {
    for (int k = 0; k < 3; ++k) out.colour[k] = static_cast<std::uint8_t>((a.colour[k] + b.colour[k] + 1) >> 1);
    out.colour_weight = std::min(a.colour_weight, b.colour_weight);
  } else if (a.colour_weight != 0 || b.colour_weight != 0) {
    const Voxel& s = a.colour_weight != 0 ? a : b;
    out.colour = s.colour;
    out.colour_weight = s.colour_weight;
  }
}

#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#define HW_FILL_AVX2 1

// Mix on 4 voxels at once (dwords: distance word, colour word, …): alpha and beta weigh a and
// b in the distance words, face (all ones per dword) takes a's colour instead of the mean.
__attribute__((target("avx2"), always_inline)) inline __m256i MixAvx2(__m256i a, __m256i b, __m256i old, __m256 alpha,
                                                                      __m256 beta, __m256i face) {
  const __m256i zero = _mm256_setzero_si256(), ones = _mm256_set1_epi32(-1);
  // Observed (distance words: weight in the high half) or painted (colour words: the top
  // byte) per dword.
  const __m256i has_a = _mm256_xor_si256(
      _mm256_cmpeq_epi32(_mm256_blend_epi32(_mm256_srli_epi32(a, 16), _mm256_srli_epi32(a, 24), 0xAA), zero), ones);
  const __m256i has_b = _mm256_xor_si256(
      _mm256_cmpeq_epi32(_mm256_blend_epi32(_mm256_srli_epi32(b, 16), _mm256_srli_epi32(b, 24), 0xAA), zero), ones);
  const __m256 unit = _mm256_set1_ps(Voxel::kSdfUnit);
  const __m256 sa = _mm256_cvtepi32_ps(_mm256_srai_epi32(_mm256_slli_epi32(a, 16), 16));
  const __m256 sb = _mm256_cvtepi32_ps(_mm256_srai_epi32(_mm256_slli_epi32(b, 16), 16));
  const __m256 s = _mm256_min_ps(
      _mm256_max_ps(_mm256_add_ps(_mm256_mul_ps(alpha, sa), _mm256_mul_ps(beta, sb)), _mm256_sub_ps(_mm256_setzero_ps(), unit)),
      unit);
  const __m256i distance =
      _mm256_or_si256(_mm256_and_si256(_mm256_cvtps_epi32(s), _mm256_set1_epi32(0xffff)),
                      _mm256_slli_epi32(_mm256_min_epu32(_mm256_srli_epi32(a, 16), _mm256_srli_epi32(b, 16)), 16));
  const __m256i top = _mm256_set1_epi32(static_cast<int>(0xff000000u));
  const __m256i mean = _mm256_blendv_epi8(_mm256_avg_epu8(a, b), _mm256_min_epu8(a, b), top);
  const __m256i mixed = _mm256_blend_epi32(distance, _mm256_blendv_epi8(mean, a, face), 0xAA);
  __m256i out = _mm256_blendv_epi8(old, b, has_b);
  out = _mm256_blendv_epi8(out, a, has_a);
  return _mm256_blendv_epi8(out, mixed, _mm256_and_si256(has_a, has_b));
}

// A row of 8 voxels (64 bytes) as two registers of 4.
struct Row {
  __m256i lo, hi;
};
__attribute__((target("avx2"), always_inline)) inline Row Load(const Voxel* v) {
  return {_mm256_load_si256(reinterpret_cast<const __m256i*>(v)),
          _mm256_load_si256(reinterpret_cast<const __m256i*>(v) + 1)};
}
__attribute__((target("avx2"), always_inline)) inline void Store(Voxel* v, const Row& r) {
  _mm256_store_si256(reinterpret_cast<__m256i*>(v), r.lo);
  _mm256_store_si256(reinterpret_cast<__m256i*>(v) + 1, r.hi);
}

// Row `out` from rows a and b (Mix on each voxel).
__attribute__((target("avx2"), always_inline)) inline void MixRows(Voxel* out, const Voxel* a, const Voxel* b,
                                                                   bool face) {
  const Row ra = Load(a), rb = Load(b), old = Load(out);
  const __m256 alpha = _mm256_set1_ps(face ? 1.5f : 0.5f), beta = _mm256_set1_ps(face ? -0.5f : 0.5f);
  const __m256i f = _mm256_set1_epi32(face ? -1 : 0);
  Store(out, {MixAvx2(ra.lo, rb.lo, old.lo, alpha, beta, f), MixAvx2(ra.hi, rb.hi, old.hi, alpha, beta, f)});
}

__attribute__((target("avx2"))) void FillOddVoxelsAvx2(Voxel* v) {
  const __m256 half = _mm256_set1_ps(0.5f);
  const __m256i no_face = _mm256_setzero_si256();
  // Within a row: voxels 1, 3 from (0, 2), (2, 4); 5 from (4, 6); 7 from (6, 4) at the face.
  const __m256 hi_alpha = _mm256_setr_ps(0.5f, 0.5f, 0.5f, 0.5f, 1.5f, 1.5f, 1.5f, 1.5f);
  const __m256 hi_beta = _mm256_setr_ps(0.5f, 0.5f, 0.5f, 0.5f, -0.5f, -0.5f, -0.5f, -0.5f);
  const __m256i hi_face = _mm256_setr_epi32(0, 0, 0, 0, -1, -1, -1, -1);
  for (int z = 0; z < kBlockSide; z += 2) {
    for (int y = 0; y < kBlockSide; y += 2) {
      Voxel* row = &At(v, 0, y, z);
      const Row r = Load(row);
      const __m256i a_lo = _mm256_permute4x64_epi64(r.lo, _MM_SHUFFLE(2, 2, 0, 0));
      const __m256i b_lo = _mm256_blend_epi32(_mm256_permute4x64_epi64(r.lo, _MM_SHUFFLE(0, 0, 2, 2)),
                                              _mm256_permute4x64_epi64(r.hi, _MM_SHUFFLE(0, 0, 0, 0)), 0xF0);
      const __m256i a_hi = _mm256_permute4x64_epi64(r.hi, _MM_SHUFFLE(2, 2, 0, 0));
      const __m256i b_hi = _mm256_permute4x64_epi64(r.hi, _MM_SHUFFLE(0, 0, 2, 2));
      // Odd voxels are the upper 64 bits of each 128-bit lane: dwords 2, 3, 6, 7.
      Store(row, {_mm256_blend_epi32(r.lo, MixAvx2(a_lo, b_lo, r.lo, half, half, no_face), 0xCC),
                  _mm256_blend_epi32(r.hi, MixAvx2(a_hi, b_hi, r.hi, hi_alpha, hi_beta, hi_face), 0xCC)});
    }
  }
  // Odd rows of the even slabs, then the odd slabs: whole rows from the rows beside them.
  for (int z = 0; z < kBlockSide; z += 2) {
    for (int y = 1; y < kBlockSide; y += 2) {
      const bool face = y == kBlockSide - 1;
      MixRows(&At(v, 0, y, z), &At(v, 0, y - 1, z), &At(v, 0, face ? y - 3 : y + 1, z), face);
    }
  }
  for (int z = 1; z < kBlockSide; z += 2) {
    const bool face = z == kBlockSide - 1;
    for (int y = 0; y < kBlockSide; ++y) {
      MixRows(&At(v, 0, y, z), &At(v, 0, y, z - 1), &At(v, 0, y, face ? z - 3 : z + 1), face);
    }
  }
}

#endif

}  // namespace

void FillOddVoxelsScalar(Voxel* v) {
  constexpr int last = kBlockSide - 1;
  for (int z = 0; z < kBlockSide; z += 2) {
    for (int y = 0; y < kBlockSide; y += 2) {
      for (int x = 1; x < last; x += 2) Mix(At(v, x - 1, y, z), At(v, x + 1, y, z), false, At(v, x, y, z));
      Mix(At(v, last - 1, y, z), At(v, last - 3, y, z), true, At(v, last, y, z));
    }
  }
  for (int z = 0; z < kBlockSide; z += 2) {
    for (int y = 1; y < kBlockSide; y += 2) {
      for (int x = 0; x < kBlockSide; ++x) {
        if (y < last) Mix(At(v, x, y - 1, z), At(v, x, y + 1, z), false, At(v, x, y, z));
        else Mix(At(v, x, last - 1, z), At(v, x, last - 3, z), true, At(v, x, y, z));
      }
    }
  }
  for (int z = 1; z < kBlockSide; z += 2) {
    for (int y = 0; y < kBlockSide; ++y) {
      for (int x = 0; x < kBlockSide; ++x) {
        if (z < last) Mix(At(v, x, y, z - 1), At(v, x, y, z + 1), false, At(v, x, y, z));
        else Mix(At(v, x, y, last - 1), At(v, x, y, last - 3), true, At(v, x, y, z));
      }
    }
  }
}

void FillOddVoxels(Voxel* voxels) {
#ifdef HW_FILL_AVX2
  if (UseAvx2Kernels()) {
    FillOddVoxelsAvx2(voxels);
    return;
  }
#endif
  FillOddVoxelsScalar(voxels);
}

}  // namespace hw::reconstruct::internal
