// TsdfVolume::Integrate: allocation of the blocks around the measured surface, then the
// projective TSDF update of every voxel of the blocks seen this frame (KinectFusion,
// Newcombe et al. 2011; block-wise as InfiniTAM, Prisacariu et al. 2017).
//
// The distance stored is the projective one: sdf = depth at the voxel's projection (bilinear
// between the four pixels around it when they lie on one surface, else the nearest pixel's)
// − z of the voxel, along the camera's optical axis. It is exact for a surface facing the camera and
// overestimates the Euclidean distance by 1 / cos(angle between the viewing ray and the
// surface normal) elsewhere; the zero crossing, the only thing raycasting and meshing read,
// stays exactly on the measured surface whatever the angle, and averaging over views with
// different angles only changes the slope of the field away from it. It needs one
// projection per voxel and no search for the nearest surface point, which is what keeps
// fusion at frame rate.
//
// Speed: the update runs a row of 8 voxels (along x) at once with AVX2 where the CPU has it
// (checked at run time: the binary stays portable), else the scalar row it was written from;
// both make the same floating-point operations in the same order and write the same bits
// (tsdf_volume_test). On eq3 (640×480, 5 mm voxels) 71 % of the 2.5 M voxels visited per
// frame are updated, so culling rows or blocks would save little: the work is the update.
// Far blocks never seen nearer (TsdfOptions::coarse_far) are updated on their even voxels
// and filled (tsdf_fill.h): there the work is mostly bringing the block's lines in.

#include <algorithm>
#include <array>
#include <atomic>
#include <cassert>
#include <cmath>
#include <cstdint>

#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#include <immintrin.h>
#endif

#include <Eigen/Geometry>

#include "reconstruct/tsdf_volume.h"
#include "reconstruct/tsdf_fill.h"
#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct {

using internal::KeyInRange;
using internal::PackKey;

namespace {

// Appends the keys of the blocks a segment (block units, a to b) passes through, in order
// (Amanatides & Woo 1987 grid traversal), skipping those already appended among a few
// recent ones: the segments of neighbouring pixels mostly cross the same blocks. The recent
// ones are kept in a direct-mapped table of 16 384 keys indexed by a multiplicative hash of
// the key, so a lookup is one comparison and the next row of pixels finds most of its
// blocks still there. (Stop 53: the table was 4096 keys, one per position of the key
// modulo 16 along each axis — a 64 cm cube; a far view's row of pixels spans metres, and
// on the 10 s `building` sweep 3.3 keys per visible block reached the serial pass, 1.1 now,
// which took it from 4.6 to 3.3 ms per integration. With 4×4×4 before that, 6× as many
// keys on eq3.) Only which duplicates reach the list depends on it; the serial pass drops
// the rest, keeping the order of first appearance.
class SegmentBlocks {
 public:
  explicit SegmentBlocks(std::vector<uint64_t>& out) : out_(out) { recent_.fill(~uint64_t{0}); }

  void Walk(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
    int cell[3], step[3];
    float t_max[3], t_delta[3];
    for (int i = 0; i < 3; ++i) {
      const float d = b[i] - a[i];
      cell[i] = FloorToInt(a[i]);
      if (d > 0) {
        step[i] = 1;
        t_delta[i] = 1.0f / d;
        t_max[i] = (static_cast<float>(cell[i]) + 1 - a[i]) / d;
      } else if (d < 0) {
        step[i] = -1;
        t_delta[i] = -1.0f / d;
        t_max[i] = (a[i] - static_cast<float>(cell[i])) / -d;
      } else {
        step[i] = 0;
        t_delta[i] = t_max[i] = std::numeric_limits<float>::infinity();
      }
    }
    // A segment crosses at most Σ_i (|b_i − a_i| + 1) + 1 blocks (23 for the default noise
    // model's band at 5 m and 4 cm blocks); the bound only guards against rounding.
    const int max_blocks = static_cast<int>(std::abs(b[0] - a[0]) + std::abs(b[1] - a[1]) + std::abs(b[2] - a[2])) + 5;
    for (int n = 0; n < max_blocks; ++n) {
      Add(cell[0], cell[1], cell[2]);
      const int axis = t_max[0] < t_max[1] ? (t_max[0] < t_max[2] ? 0 : 2) : (t_max[1] < t_max[2] ? 1 : 2);
      if (t_max[axis] > 1) break;
      cell[axis] += step[axis];
      t_max[axis] += t_delta[axis];
    }
  }

 private:
  void Add(int x, int y, int z) {
    if (!KeyInRange(x, y, z)) return;
    const uint64_t key = PackKey(x, y, z);
    uint64_t& slot = recent_[(key * 0x9E3779B97F4A7C15ull) >> (64 - kRecentBits)];  // Fibonacci hashing
    if (slot == key) return;
    slot = key;
    out_.push_back(key);
  }

  std::vector<uint64_t>& out_;
  static constexpr int kRecentBits = 14;
  std::array<uint64_t, size_t{1} << kRecentBits> recent_;  // ~0: no valid packed key has all 64 bits set
};

BlockKey Unpack(uint64_t key) {
  auto field = [](uint64_t v) {
    const int x = static_cast<int>(v & ((uint64_t{1} << 21) - 1));
    return x >= (1 << 20) ? x - (1 << 21) : x;
  };
  return {field(key >> 42), field(key >> 21), field(key)};
}

// What the per-voxel update needs of one frame (Integrate's constants).
struct FrameParams {
  const float* depth;  // depth_m's pixels, depth_step floats per row
  size_t depth_step;
  float fx, fy, cx, cy;
  float u_limit, v_limit;  // nearest pixel inside the image: u in (−0.5, u_limit)
  float u_inner, v_inner;  // the 2×2 pixels of bilinear depth inside: u in [0, u_inner)
  float min_depth_m, max_depth_m;
  float truncation_m, half_truncation_m;
  TsdfOptions::NoiseBand band;  // the band at a reading's depth: band.At(d)
  float edge_slope_per_m;
  float max_weight;
  const float* inv_count;  // 1 / (w + 1) for the weights 0 … max_weight
  // Colour (colour_rgb null: none).
  const std::uint8_t* colour_rgb;
  size_t colour_step;  // bytes per row
  int colour_width, colour_height;
  float colour_rotation[9];  // colour_from_camera, row-major
  float colour_translation[3];
  float colour_fx, colour_fy, colour_cx, colour_cy;
  float colour_u_limit, colour_v_limit;
  int max_colour_weight;
  // Rolling shutter (colour_bands 0: none): colour_from_camera of each band of rows, as
  // structures of arrays (band_rotation[i][k]: element i, row-major, of band k's rotation).
  int colour_bands;
  float colour_band_scale;  // bands / image height: a row's band is (v + 0.5) · this
  float band_rotation[9][kMaxColourBands];
  float band_translation[3][kMaxColourBands];
  // Voxel steps along the world axes, in the camera frame (m).
  float step_x[3], step_y[3], step_z[3];
};

// The camera-frame centres of one row of kBlockSide voxels (x, y, z of each).
struct RowPoints {
  alignas(32) float x[kBlockSide];
  alignas(32) float y[kBlockSide];
  alignas(32) float z[kBlockSide];
};

// Updates the voxels of one row of kBlockSide (consecutive in x) whose bit is set in `lanes`
// (bit x: voxel x) with the frame; returns how many were updated. The reference
// implementation: UpdateRowAvx2 must give the same bits.
int UpdateRowScalar(const FrameParams& f, const RowPoints& row, Voxel* voxel, unsigned lanes) {
  int count = 0;
  for (int x = 0; x < kBlockSide; ++x, ++voxel) {
    if ((lanes >> x & 1) == 0) continue;
    const float pz = row.z[x];
    if (!(pz > 0)) continue;
    const float inv_z = 1.0f / pz;
    const float u = f.fx * row.x[x] * inv_z + f.cx, v = f.fy * row.y[x] * inv_z + f.cy;
    if (!(u > -0.5f && u < f.u_limit && v > -0.5f && v < f.v_limit)) continue;
    float d = f.depth[static_cast<size_t>(v + 0.5f) * f.depth_step + static_cast<size_t>(u + 0.5f)];
    if (!(d >= f.min_depth_m && d <= f.max_depth_m)) continue;
    // The band of this measurement, from the nearest pixel's depth (the bilinear one differs
    // by at most the spread accepted below, over which the band hardly changes).
    const float band_m = f.band.At(d);
    // Bilinear depth can move d by at most the spread it accepts (below): beyond that margin
    // around the band the voxel is free space (tsdf 1) or hidden either way.
    const float margin_m = band_m + f.half_truncation_m + d * f.edge_slope_per_m;
    if (d - pz < -margin_m) continue;
    if (d - pz < margin_m && u >= 0 && v >= 0 && u < f.u_inner && v < f.v_inner) {
      // Bilinear depth where the four pixels around lie on one surface: the nearest pixel's
      // depth alone would be off by up to half a pixel times the depth slope (a quarter
      // voxel on a 45° wall). One surface: a spread below half a truncation plus what a
      // surface at up to 76° (slope 4) to the view spans over a pixel; a larger jump is a
      // depth edge, where interpolating would invent a surface between the two.
      const int x0 = static_cast<int>(u), y0 = static_cast<int>(v);
      const float* d0 = f.depth + static_cast<size_t>(y0) * f.depth_step + x0;
      const float* d1 = d0 + f.depth_step;
      const float lo = std::min(std::min(d0[0], d0[1]), std::min(d1[0], d1[1]));
      const float hi = std::max(std::max(d0[0], d0[1]), std::max(d1[0], d1[1]));
      // (NaN fails every comparison: such a pixel keeps the nearest depth.)
      if (lo >= f.min_depth_m && hi <= f.max_depth_m && hi - lo < f.half_truncation_m + lo * f.edge_slope_per_m &&
          d0[0] == d0[0] && d0[1] == d0[1] && d1[0] == d1[0] && d1[1] == d1[1]) {
        const float a = u - static_cast<float>(x0), c = v - static_cast<float>(y0);
        const float top = d0[0] + a * (d0[1] - d0[0]), bottom = d1[0] + a * (d1[1] - d1[0]);
        d = top + c * (bottom - top);
      }
    }
    const float sdf_m = d - pz;
    if (sdf_m < -band_m) continue;  // hidden behind the surface: unknown
    const float tsdf = std::min(1.0f, sdf_m * (1.0f / band_m));
    const float w = voxel->weight();
    voxel->set_sdf((voxel->sdf() * w + tsdf) * f.inv_count[voxel->weight_count]);
    voxel->set_weight(std::min(w + 1, f.max_weight));
    ++count;
    if (f.colour_rgb == nullptr || sdf_m >= band_m) continue;
    const float* r = f.colour_rotation;
    // Summed as Eigen's rotation * p + translation (which it replaced): the same pixel.
    const float qx = (r[0] * row.x[x] + (r[1] * row.y[x] + r[2] * pz)) + f.colour_translation[0];
    const float qy = (r[3] * row.x[x] + (r[4] * row.y[x] + r[5] * pz)) + f.colour_translation[1];
    const float qz = (r[6] * row.x[x] + (r[7] * row.y[x] + r[8] * pz)) + f.colour_translation[2];
    if (!(qz > 0)) continue;
    float inv_qz = 1.0f / qz;
    float cu = f.colour_fx * qx * inv_qz + f.colour_cx, cv = f.colour_fy * qy * inv_qz + f.colour_cy;
    if (f.colour_bands > 0) {
      // Projected again with the pose of the rows it landed on.
      // Clamped as a float (NaN to band 0), as the SIMD kernel does.
      float band = (cv + 0.5f) * f.colour_band_scale;
      band = band > 0 ? band : 0.0f;
      band = band < static_cast<float>(f.colour_bands - 1) ? band : static_cast<float>(f.colour_bands - 1);
      const int k = static_cast<int>(band);
      const float bx = (f.band_rotation[0][k] * row.x[x] + (f.band_rotation[1][k] * row.y[x] + f.band_rotation[2][k] * pz)) +
                       f.band_translation[0][k];
      const float by = (f.band_rotation[3][k] * row.x[x] + (f.band_rotation[4][k] * row.y[x] + f.band_rotation[5][k] * pz)) +
                       f.band_translation[1][k];
      const float bz = (f.band_rotation[6][k] * row.x[x] + (f.band_rotation[7][k] * row.y[x] + f.band_rotation[8][k] * pz)) +
                       f.band_translation[2][k];
      if (!(bz > 0)) continue;
      inv_qz = 1.0f / bz;
      cu = f.colour_fx * bx * inv_qz + f.colour_cx;
      cv = f.colour_fy * by * inv_qz + f.colour_cy;
    }
    if (!(cu > -0.5f && cu < f.colour_u_limit && cv > -0.5f && cv < f.colour_v_limit)) continue;
    const auto* rgb = f.colour_rgb + static_cast<size_t>(cv + 0.5f) * f.colour_step + 3 * static_cast<size_t>(cu + 0.5f);
    const int cw = voxel->colour_weight;
    const float inv_cw = f.inv_count[cw];  // cw <= min(max_weight, 255)
    for (int k = 0; k < 3; ++k) {
      const float mean = (static_cast<float>(voxel->colour[k]) * static_cast<float>(cw) + rgb[k]) * inv_cw;
      voxel->colour[k] = static_cast<std::uint8_t>(mean + 0.5f);
    }
    voxel->colour_weight = static_cast<std::uint8_t>(std::min(cw + 1, f.max_colour_weight));
  }
  return count;
}

// Updates the voxels of a block whose voxel (0, 0, 0) is at corner_in_camera (m) — when
// `coarse`, its even voxels, then fills the others from them (tsdf_fill.h); returns how many
// were updated. The reference for UpdateBlockAvx2.
int UpdateBlockScalar(const FrameParams& f, const Eigen::Vector3f& corner_in_camera, Voxel* voxel, bool coarse) {
  const Eigen::Vector3f step_x(f.step_x[0], f.step_x[1], f.step_x[2]);
  const Eigen::Vector3f step_y(f.step_y[0], f.step_y[1], f.step_y[2]);
  const Eigen::Vector3f step_z(f.step_z[0], f.step_z[1], f.step_z[2]);
  const int stride = coarse ? 2 : 1;
  const unsigned lanes = coarse ? 0x55u : 0xFFu;
  int count = 0;
  RowPoints row;
  for (int z = 0; z < kBlockSide; z += stride) {
    for (int y = 0; y < kBlockSide; y += stride) {
      // Voxel centres stepped along x one addition at a time (as they always were: the
      // SIMD kernel makes the same additions, so both see the same bits).
      Eigen::Vector3f p = corner_in_camera + static_cast<float>(y) * step_y + static_cast<float>(z) * step_z;
      for (int x = 0; x < kBlockSide; ++x, p += step_x) {
        row.x[x] = p.x();
        row.y[x] = p.y();
        row.z[x] = p.z();
      }
      count += UpdateRowScalar(f, row, voxel + kBlockSide * (y + kBlockSide * z), lanes);
    }
  }
  if (coarse) internal::FillOddVoxelsScalar(voxel);
  return count;
}

#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#define HW_TSDF_AVX2 1

// UpdateRowScalar on the 8 voxels at once (AVX2; the binary stays portable: called only
// where the CPU has it). Same operations in the same order, no FMA (the target has none, so
// the compiler cannot contract a·b + c): the same bits as the scalar row. The 8 voxels (64
// bytes, AoS) are loaded as two registers, split into distance words (sdf steps and weight)
// and colour words, merged back with unpacks and permutes, and stored whole (lanes not
// updated keep their bits).
__attribute__((target("avx2"))) inline __m256 EvenLanes(__m256 lo4, __m256 hi4) {
  // [l0 r0 l1 r1 | l2 r2 l3 r3], [l4 r4 … | …] → [l0 … l7]
  return _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(lo4, hi4, 0x88)), 0xD8));
}
__attribute__((target("avx2"))) inline __m256 OddLanes(__m256 lo4, __m256 hi4) {  // → [r0 … r7]
  return _mm256_castpd_ps(_mm256_permute4x64_pd(_mm256_castps_pd(_mm256_shuffle_ps(lo4, hi4, 0xDD)), 0xD8));
}

__attribute__((target("avx2"), always_inline)) inline int UpdateRowAvx2(const FrameParams& f, __m256 px, __m256 py,
                                                                        __m256 pz, __m256 lanes, Voxel* voxel) {
  const __m256 zero = _mm256_setzero_ps();
  const __m256 in_front = _mm256_and_ps(lanes, _mm256_cmp_ps(pz, zero, _CMP_GT_OQ));
  if (_mm256_movemask_ps(in_front) == 0) return 0;
  const __m256 inv_z = _mm256_div_ps(_mm256_set1_ps(1.0f), pz);
  const __m256 u = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(f.fx), px), inv_z), _mm256_set1_ps(f.cx));
  const __m256 v = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(f.fy), py), inv_z), _mm256_set1_ps(f.cy));
  const __m256 minus_half = _mm256_set1_ps(-0.5f), half = _mm256_set1_ps(0.5f);
  __m256 mask = _mm256_and_ps(in_front, _mm256_and_ps(_mm256_cmp_ps(u, minus_half, _CMP_GT_OQ),
                                                     _mm256_cmp_ps(u, _mm256_set1_ps(f.u_limit), _CMP_LT_OQ)));
  mask = _mm256_and_ps(mask, _mm256_and_ps(_mm256_cmp_ps(v, minus_half, _CMP_GT_OQ),
                                           _mm256_cmp_ps(v, _mm256_set1_ps(f.v_limit), _CMP_LT_OQ)));
  if (_mm256_movemask_ps(mask) == 0) return 0;
  // The 2×2 pixels around the projection, read as two pixel pairs per voxel (four 64-bit
  // gathers of 4 lanes: half the elements of eight 32-bit gathers), wherever they lie in the
  // image; the nearest pixel is one of them. Lanes outside a mask compute garbage indices
  // but load nothing (masked gathers).
  const __m256i step = _mm256_set1_epi32(static_cast<int>(f.depth_step));
  const __m256i nx = _mm256_cvttps_epi32(_mm256_add_ps(u, half)), ny = _mm256_cvttps_epi32(_mm256_add_ps(v, half));
  const __m256i x0 = _mm256_cvttps_epi32(u), y0 = _mm256_cvttps_epi32(v);
  const __m256 interior = _mm256_and_ps(
      mask, _mm256_and_ps(_mm256_and_ps(_mm256_cmp_ps(u, zero, _CMP_GE_OQ), _mm256_cmp_ps(v, zero, _CMP_GE_OQ)),
                          _mm256_and_ps(_mm256_cmp_ps(u, _mm256_set1_ps(f.u_inner), _CMP_LT_OQ),
                                        _mm256_cmp_ps(v, _mm256_set1_ps(f.v_inner), _CMP_LT_OQ))));
  const int interior_bits = _mm256_movemask_ps(interior);
  __m256 d00 = zero, d01 = zero, d10 = zero, d11 = zero, d = zero;
  if (interior_bits != 0) {
    const __m256i i00 = _mm256_add_epi32(_mm256_mullo_epi32(y0, step), x0);
    const __m128i i_lo = _mm256_castsi256_si128(i00), i_hi = _mm256_extracti128_si256(i00, 1);
    const __m256i m = _mm256_castps_si256(interior);
    const __m256d m_lo = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_castsi256_si128(m)));
    const __m256d m_hi = _mm256_castsi256_pd(_mm256_cvtepi32_epi64(_mm256_extracti128_si256(m, 1)));
    const double* top_row = reinterpret_cast<const double*>(f.depth);
    const double* bottom_row = reinterpret_cast<const double*>(f.depth + f.depth_step);
    const __m256d zero_d = _mm256_setzero_pd();
    // Scale 4: an index counts floats; each lane reads the pixel and its right neighbour.
    const __m256 t_lo = _mm256_castpd_ps(_mm256_mask_i32gather_pd(zero_d, top_row, i_lo, m_lo, 4));
    const __m256 t_hi = _mm256_castpd_ps(_mm256_mask_i32gather_pd(zero_d, top_row, i_hi, m_hi, 4));
    const __m256 b_lo = _mm256_castpd_ps(_mm256_mask_i32gather_pd(zero_d, bottom_row, i_lo, m_lo, 4));
    const __m256 b_hi = _mm256_castpd_ps(_mm256_mask_i32gather_pd(zero_d, bottom_row, i_hi, m_hi, 4));
    d00 = EvenLanes(t_lo, t_hi);
    d01 = OddLanes(t_lo, t_hi);
    d10 = EvenLanes(b_lo, b_hi);
    d11 = OddLanes(b_lo, b_hi);
    // The nearest pixel: (nx, ny) is (x0, y0) plus 0 or 1 along each axis.
    const __m256 right_x = _mm256_castsi256_ps(_mm256_cmpgt_epi32(nx, x0));
    const __m256 lower_y = _mm256_castsi256_ps(_mm256_cmpgt_epi32(ny, y0));
    d = _mm256_blendv_ps(_mm256_blendv_ps(d00, d01, right_x), _mm256_blendv_ps(d10, d11, right_x), lower_y);
  }
  if (interior_bits != _mm256_movemask_ps(mask)) {  // on the image's last row or column
    const __m256 border = _mm256_andnot_ps(interior, mask);
    const __m256i nearest = _mm256_add_epi32(_mm256_mullo_epi32(ny, step), nx);
    d = _mm256_blendv_ps(d, _mm256_mask_i32gather_ps(zero, f.depth, nearest, border, 4), border);
  }
  const __m256 min_depth = _mm256_set1_ps(f.min_depth_m), max_depth = _mm256_set1_ps(f.max_depth_m);
  mask = _mm256_and_ps(mask, _mm256_and_ps(_mm256_cmp_ps(d, min_depth, _CMP_GE_OQ),
                                           _mm256_cmp_ps(d, max_depth, _CMP_LE_OQ)));
  const __m256 slope = _mm256_set1_ps(f.edge_slope_per_m);
  // f.band.At(d) per lane, its operations in its order.
  const __m256 dz = _mm256_sub_ps(d, _mm256_set1_ps(f.band.reference_m));
  const __m256 band = _mm256_max_ps(
      _mm256_set1_ps(f.band.truncation_m),
      _mm256_mul_ps(_mm256_set1_ps(f.band.sigmas),
                    _mm256_add_ps(_mm256_set1_ps(f.band.base_m),
                                  _mm256_mul_ps(_mm256_set1_ps(f.band.quadratic_per_m), _mm256_mul_ps(dz, dz)))));
  const __m256 margin =
      _mm256_add_ps(_mm256_add_ps(band, _mm256_set1_ps(f.half_truncation_m)), _mm256_mul_ps(d, slope));
  const __m256 ahead = _mm256_sub_ps(d, pz);
  // !(ahead < −margin); the operands are finite on mask lanes.
  mask = _mm256_and_ps(mask, _mm256_cmp_ps(ahead, _mm256_sub_ps(zero, margin), _CMP_NLT_UQ));
  if (_mm256_movemask_ps(mask) == 0) return 0;
  const __m256 near = _mm256_and_ps(_mm256_and_ps(mask, interior), _mm256_cmp_ps(ahead, margin, _CMP_LT_OQ));
  if (_mm256_movemask_ps(near) != 0) {
    // min/max differ from std::min/max only with a NaN operand, which fails `one` anyway.
    const __m256 lo = _mm256_min_ps(_mm256_min_ps(d00, d01), _mm256_min_ps(d10, d11));
    const __m256 hi = _mm256_max_ps(_mm256_max_ps(d00, d01), _mm256_max_ps(d10, d11));
    __m256 one = _mm256_and_ps(near, _mm256_and_ps(_mm256_cmp_ps(lo, min_depth, _CMP_GE_OQ),
                                                   _mm256_cmp_ps(hi, max_depth, _CMP_LE_OQ)));
    one = _mm256_and_ps(one, _mm256_cmp_ps(_mm256_sub_ps(hi, lo),
                                           _mm256_add_ps(_mm256_set1_ps(f.half_truncation_m), _mm256_mul_ps(lo, slope)),
                                           _CMP_LT_OQ));
    one = _mm256_and_ps(one, _mm256_and_ps(_mm256_cmp_ps(d00, d01, _CMP_ORD_Q), _mm256_cmp_ps(d10, d11, _CMP_ORD_Q)));
    const __m256 a = _mm256_sub_ps(u, _mm256_cvtepi32_ps(x0)), c = _mm256_sub_ps(v, _mm256_cvtepi32_ps(y0));
    const __m256 top = _mm256_add_ps(d00, _mm256_mul_ps(a, _mm256_sub_ps(d01, d00)));
    const __m256 bottom = _mm256_add_ps(d10, _mm256_mul_ps(a, _mm256_sub_ps(d11, d10)));
    d = _mm256_blendv_ps(d, _mm256_add_ps(top, _mm256_mul_ps(c, _mm256_sub_ps(bottom, top))), one);
  }
  const __m256 sdf_m = _mm256_sub_ps(d, pz);
  mask = _mm256_and_ps(mask, _mm256_cmp_ps(sdf_m, _mm256_sub_ps(zero, band), _CMP_NLT_UQ));
  const int updated = _mm256_movemask_ps(mask);
  if (updated == 0) return 0;

  // Split the AoS row: voxel k is dwords 2k (sdf steps in the low half, weight count in the
  // high one) and 2k + 1 (colour word); the even dwords of the two registers are the first
  // words in voxel order, the odd ones the colour words.
  float* raw = reinterpret_cast<float*>(voxel);
  const __m256 r0 = _mm256_loadu_ps(raw), r1 = _mm256_loadu_ps(raw + 8);
  const __m256i distance_word = _mm256_castps_si256(EvenLanes(r0, r1));
  __m256i colour_word = _mm256_castps_si256(OddLanes(r0, r1));
  const __m256 sdf_unit = _mm256_set1_ps(Voxel::kSdfUnit);
  // Sign-extended steps times 2^-14 (exact), as Voxel::sdf().
  const __m256 old_sdf = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srai_epi32(_mm256_slli_epi32(distance_word, 16), 16)),
                                       _mm256_set1_ps(1.0f / Voxel::kSdfUnit));
  const __m256 weight = _mm256_cvtepi32_ps(_mm256_srli_epi32(distance_word, 16));

  const __m256 unit = _mm256_set1_ps(1.0f);
  const __m256 tsdf = _mm256_min_ps(_mm256_mul_ps(sdf_m, _mm256_div_ps(unit, band)), unit);
  const __m256 weight_1 = _mm256_add_ps(weight, unit);
  // 1 / (w + 1) rounded once: the value inv_count holds for a whole w.
  const __m256 inv = _mm256_div_ps(unit, weight_1);
  const __m256 new_sdf = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(old_sdf, weight), tsdf), inv);
  const __m256 new_weight = _mm256_min_ps(weight_1, _mm256_set1_ps(f.max_weight));
  // Voxel::set_sdf and set_weight: clamped to ±1 band, rounded to the nearest step (the
  // conversion rounds as std::lrint does, to nearest even); the weight is whole.
  const __m256 scaled = _mm256_min_ps(_mm256_max_ps(_mm256_mul_ps(new_sdf, sdf_unit), _mm256_sub_ps(zero, sdf_unit)), sdf_unit);
  const __m256i packed = _mm256_or_si256(_mm256_and_si256(_mm256_cvtps_epi32(scaled), _mm256_set1_epi32(0xffff)),
                                         _mm256_slli_epi32(_mm256_cvttps_epi32(new_weight), 16));
  const __m256i distance_out = _mm256_castps_si256(
      _mm256_blendv_ps(_mm256_castsi256_ps(distance_word), _mm256_castsi256_ps(packed), mask));

  if (f.colour_rgb != nullptr) {
    __m256 paint = _mm256_and_ps(mask, _mm256_cmp_ps(sdf_m, band, _CMP_LT_OQ));
    if (_mm256_movemask_ps(paint) != 0) {
      const float* r = f.colour_rotation;
      __m256 q[3];  // r · p + t, summed as UpdateRowScalar does
      for (int i = 0; i < 3; ++i) {
        const __m256 yz = _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(r[3 * i + 1]), py),
                                        _mm256_mul_ps(_mm256_set1_ps(r[3 * i + 2]), pz));
        q[i] = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(r[3 * i]), px), yz),
                             _mm256_set1_ps(f.colour_translation[i]));
      }
      const __m256 qx = q[0], qy = q[1], qz = q[2];
      paint = _mm256_and_ps(paint, _mm256_cmp_ps(qz, zero, _CMP_GT_OQ));
      __m256 inv_qz = _mm256_div_ps(unit, qz);
      __m256 cu = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(f.colour_fx), qx), inv_qz),
                                _mm256_set1_ps(f.colour_cx));
      __m256 cv = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(f.colour_fy), qy), inv_qz),
                                _mm256_set1_ps(f.colour_cy));
      if (f.colour_bands > 0 && _mm256_movemask_ps(paint) != 0) {
        // Each lane projected again with its band's pose (gathered), as UpdateRowScalar;
        // max_ps returns its second operand for a NaN: band 0, as there.
        const __m256 row_band = _mm256_min_ps(
            _mm256_max_ps(_mm256_mul_ps(_mm256_add_ps(cv, half), _mm256_set1_ps(f.colour_band_scale)), zero),
            _mm256_set1_ps(static_cast<float>(f.colour_bands - 1)));
        const __m256i k = _mm256_cvttps_epi32(row_band);
        // A row of voxels spans a few image rows, so its painted lanes mostly share one band
        // (32 bands of 15 rows at 480): then its pose is broadcast instead of gathered (twelve
        // gathers per row were a third of the update), the same values either way.
        const int paint_bits = _mm256_movemask_ps(paint);
        alignas(32) int band_of[8];
        _mm256_store_si256(reinterpret_cast<__m256i*>(band_of), k);
        const int first = band_of[__builtin_ctz(static_cast<unsigned>(paint_bits))];
        const int same = _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(k, _mm256_set1_epi32(first))));
        __m256 b[3];
        if ((same & paint_bits) == paint_bits) {
          for (int i = 0; i < 3; ++i) {
            const __m256 yz = _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(f.band_rotation[3 * i + 1][first]), py),
                                            _mm256_mul_ps(_mm256_set1_ps(f.band_rotation[3 * i + 2][first]), pz));
            b[i] = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(f.band_rotation[3 * i][first]), px), yz),
                                 _mm256_set1_ps(f.band_translation[i][first]));
          }
        } else {
          for (int i = 0; i < 3; ++i) {
            const __m256 bx = _mm256_i32gather_ps(f.band_rotation[3 * i], k, 4);
            const __m256 by = _mm256_i32gather_ps(f.band_rotation[3 * i + 1], k, 4);
            const __m256 bz = _mm256_i32gather_ps(f.band_rotation[3 * i + 2], k, 4);
            const __m256 yz = _mm256_add_ps(_mm256_mul_ps(by, py), _mm256_mul_ps(bz, pz));
            b[i] = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(bx, px), yz),
                                 _mm256_i32gather_ps(f.band_translation[i], k, 4));
          }
        }
        paint = _mm256_and_ps(paint, _mm256_cmp_ps(b[2], zero, _CMP_GT_OQ));
        inv_qz = _mm256_div_ps(unit, b[2]);
        cu = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(f.colour_fx), b[0]), inv_qz),
                           _mm256_set1_ps(f.colour_cx));
        cv = _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(f.colour_fy), b[1]), inv_qz),
                           _mm256_set1_ps(f.colour_cy));
      }
      paint = _mm256_and_ps(paint, _mm256_and_ps(_mm256_cmp_ps(cu, minus_half, _CMP_GT_OQ),
                                                 _mm256_cmp_ps(cu, _mm256_set1_ps(f.colour_u_limit), _CMP_LT_OQ)));
      paint = _mm256_and_ps(paint, _mm256_and_ps(_mm256_cmp_ps(cv, minus_half, _CMP_GT_OQ),
                                                 _mm256_cmp_ps(cv, _mm256_set1_ps(f.colour_v_limit), _CMP_LT_OQ)));
      if (_mm256_movemask_ps(paint) != 0) {
        // The pixel's 3 bytes read as one dword; the image's very last pixel from one byte
        // earlier (then shifted), so that no read passes the end of the image.
        const __m256i offset = _mm256_add_epi32(
            _mm256_mullo_epi32(_mm256_cvttps_epi32(_mm256_add_ps(cv, half)),
                               _mm256_set1_epi32(static_cast<int>(f.colour_step))),
            _mm256_mullo_epi32(_mm256_cvttps_epi32(_mm256_add_ps(cu, half)), _mm256_set1_epi32(3)));
        const int last = static_cast<int>(static_cast<size_t>(f.colour_height - 1) * f.colour_step) +
                         3 * (f.colour_width - 1) - 1;
        const __m256i safe = _mm256_min_epi32(offset, _mm256_set1_epi32(last));
        const __m256i shift = _mm256_slli_epi32(_mm256_sub_epi32(offset, safe), 3);
        const __m256i rgb = _mm256_srlv_epi32(
            _mm256_mask_i32gather_epi32(_mm256_setzero_si256(), reinterpret_cast<const int*>(f.colour_rgb), safe,
                                        _mm256_castps_si256(paint), 1),
            shift);
        const __m256i byte = _mm256_set1_epi32(0xff);
        const __m256i cw = _mm256_srli_epi32(colour_word, 24);
        const __m256 cw_f = _mm256_cvtepi32_ps(cw);
        const __m256 inv_cw = _mm256_div_ps(unit, _mm256_add_ps(cw_f, unit));  // = inv_count[cw]
        __m256i painted = _mm256_slli_epi32(
            _mm256_min_epi32(_mm256_add_epi32(cw, _mm256_set1_epi32(1)), _mm256_set1_epi32(f.max_colour_weight)), 24);
        for (int k = 0; k < 3; ++k) {
          const __m256 old_k = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(colour_word, 8 * k), byte));
          const __m256 new_k = _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(rgb, 8 * k), byte));
          const __m256 mean = _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(old_k, cw_f), new_k), inv_cw);
          const __m256i rounded = _mm256_cvttps_epi32(_mm256_add_ps(mean, half));
          painted = _mm256_or_si256(painted, _mm256_slli_epi32(rounded, 8 * k));
        }
        colour_word = _mm256_castps_si256(
            _mm256_blendv_ps(_mm256_castsi256_ps(colour_word), _mm256_castsi256_ps(painted), paint));
      }
    }
  }

  // Merge back: voxels 0, 1 | 4, 5 and 2, 3 | 6, 7 interleaved, then their halves paired.
  const __m256 lo = _mm256_unpacklo_ps(_mm256_castsi256_ps(distance_out), _mm256_castsi256_ps(colour_word));
  const __m256 hi = _mm256_unpackhi_ps(_mm256_castsi256_ps(distance_out), _mm256_castsi256_ps(colour_word));
  _mm256_storeu_ps(raw, _mm256_permute2f128_ps(lo, hi, 0x20));
  _mm256_storeu_ps(raw + 8, _mm256_permute2f128_ps(lo, hi, 0x31));
  return __builtin_popcount(static_cast<unsigned>(updated));
}

// r[i] lane j → out[j] lane i (8×8 transpose).
__attribute__((target("avx2"))) inline void Transpose8(const __m256 r[8], __m256 out[8]) {
  __m256 t[8], u[8];
  for (int i = 0; i < 4; ++i) {
    t[2 * i] = _mm256_unpacklo_ps(r[2 * i], r[2 * i + 1]);
    t[2 * i + 1] = _mm256_unpackhi_ps(r[2 * i], r[2 * i + 1]);
  }
  for (int i = 0; i < 2; ++i) {
    u[4 * i] = _mm256_shuffle_ps(t[4 * i], t[4 * i + 2], 0x44);
    u[4 * i + 1] = _mm256_shuffle_ps(t[4 * i], t[4 * i + 2], 0xEE);
    u[4 * i + 2] = _mm256_shuffle_ps(t[4 * i + 1], t[4 * i + 3], 0x44);
    u[4 * i + 3] = _mm256_shuffle_ps(t[4 * i + 1], t[4 * i + 3], 0xEE);
  }
  for (int i = 0; i < 4; ++i) {
    out[i] = _mm256_permute2f128_ps(u[i], u[i + 4], 0x20);
    out[i + 4] = _mm256_permute2f128_ps(u[i], u[i + 4], 0x31);
  }
}

// UpdateBlockScalar with UpdateRowAvx2. The voxel centres of a z slab are made 8 rows at
// once (lanes over y) with the scalar code's additions in the same order, then transposed
// into rows (lanes over x).
__attribute__((target("avx2"))) int UpdateBlockAvx2(const FrameParams& f, const Eigen::Vector3f& corner_in_camera,
                                                    Voxel* voxel, bool coarse) {
  const __m256 y_index = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
  const int stride = coarse ? 2 : 1;
  const __m256 lanes = _mm256_castsi256_ps(coarse ? _mm256_setr_epi32(-1, 0, -1, 0, -1, 0, -1, 0) : _mm256_set1_epi32(-1));
  int count = 0;
  for (int z = 0; z < kBlockSide; z += stride) {
    __m256 rows[3][kBlockSide];
    for (int i = 0; i < 3; ++i) {
      __m256 columns[kBlockSide];
      __m256 p = _mm256_add_ps(
          _mm256_add_ps(_mm256_set1_ps(corner_in_camera[i]), _mm256_mul_ps(y_index, _mm256_set1_ps(f.step_y[i]))),
          _mm256_set1_ps(static_cast<float>(z) * f.step_z[i]));
      const __m256 step = _mm256_set1_ps(f.step_x[i]);
      for (int x = 0; x < kBlockSide; ++x, p = _mm256_add_ps(p, step)) columns[x] = p;
      Transpose8(columns, rows[i]);
    }
    for (int y = 0; y < kBlockSide; y += stride) {
      count += UpdateRowAvx2(f, rows[0][y], rows[1][y], rows[2][y], lanes, voxel + kBlockSide * (y + kBlockSide * z));
    }
  }
  if (coarse) internal::FillOddVoxels(voxel);
  return count;
}

#endif

}  // namespace

IntegrateStats TsdfVolume::Integrate(const cv::Mat& depth_m, const PinholeCamera& camera,
                                     const core::Rigid3d& world_from_camera,
                                     const ColourView* colour) {
  assert(depth_m.type() == CV_32FC1 && depth_m.cols == camera.width && depth_m.rows == camera.height);
  assert(colour == nullptr || colour->rgb.empty() ||
         (colour->rgb.type() == CV_8UC3 && colour->rgb.cols == colour->camera.width &&
          colour->rgb.rows == colour->camera.height));
  IntegrateStats stats;
  Impl& impl = *impl_;
  const int num_threads = ResolveThreads(options_.num_threads);
  const float voxel_m = voxel_size_m();
  const float block_m = voxel_m * kBlockSide;
  const float truncation_m = static_cast<float>(options_.truncation_m);
  const float min_depth_m = static_cast<float>(options_.min_depth_m);
  const float max_depth_m = static_cast<float>(options_.max_depth_m);
  const TsdfOptions::NoiseBand noise_band = options_.Band();  // per reading: noise_band.At(d)
  const int width = camera.width, height = camera.height;

  // 1. Allocation. Every valid pixel's viewing ray between depth − truncation and depth +
  // truncation is walked through the block grid. Pixels are sampled every `stride` in x and
  // y, with the stride chosen so that neighbouring samples land at most half a block apart at
  // the farthest depth of the frame: a surface patch half a block wide is then always hit
  // (`TsdfIntegrate.PatchesHalfABlockWideAreAlwaysAllocated`), and what the sampling misses
  // is a sliver along a block's side whose voxels the next frames (a hand-held camera moves)
  // pick up. A quarter block (until stop 60) walked every pixel of a frame that reaches 4 m
  // with 5 mm voxels — 15 of its 117 ms of integration — for the same model: on the 10 s
  // sweeps ATE 1.51 / 1.66 → 1.61 / 1.65 mm, shape 1.70 / 1.93 → 1.69 / 1.93 mm, vertices
  // +0.7 / −1.0 %.
  float far_m = 0;
  for (int y = 0; y < height; ++y) {
    const float* row = depth_m.ptr<float>(y);
    for (int x = 0; x < width; ++x) {
      const float d = row[x];
      if (d >= min_depth_m && d <= max_depth_m && d > far_m) far_m = d;
    }
  }
  if (far_m == 0) return stats;  // nothing to fuse: no block allocated or touched
  const float pixel_m = far_m / std::min(camera.fx, camera.fy);  // footprint of a pixel
  const int stride = std::clamp(static_cast<int>(0.5f * block_m / pixel_m), 1, 8);

  const Eigen::Matrix3f rotation = world_from_camera.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f origin_m = world_from_camera.translation.cast<float>();
  std::vector<float>& ray_x = impl.ray_x;  // camera.Unproject(x, ·, 1).x(), per column
  ray_x.resize(width);
  for (int x = 0; x < width; ++x) ray_x[x] = (static_cast<float>(x) - camera.cx) / camera.fx;
  std::vector<std::vector<uint64_t>>& keys = impl.keys;  // kept: no allocation per frame
  keys.resize(num_threads);
  for (auto& chunk_keys : keys) chunk_keys.clear();
  internal::RunChunks(num_threads, [&](int chunk) {
    const int rows = (height + stride - 1) / stride;
    const int row_begin = rows * chunk / num_threads, row_end = rows * (chunk + 1) / num_threads;
    SegmentBlocks walker(keys[chunk]);
    const float inv_block = 1.0f / block_m;
    for (int r = row_begin; r < row_end; ++r) {
      const int y = r * stride;
      const float* row = depth_m.ptr<float>(y);
      const float ray_y = (static_cast<float>(y) - camera.cy) / camera.fy;  // camera.Unproject at z = 1
      for (int x = 0; x < width; x += stride) {
        const float d = row[x];
        if (!(d >= min_depth_m && d <= max_depth_m)) continue;
        const Eigen::Vector3f ray = rotation * Eigen::Vector3f(ray_x[x], ray_y, 1.0f);
        const float band_m = noise_band.At(d);
        const float near_m = std::max(d - band_m, 0.0f);
        walker.Walk((origin_m + near_m * ray) * inv_block, (origin_m + (d + band_m) * ray) * inv_block);
      }
    }
  });

  // Serial: the hash is never mutated concurrently. The visible list is deduplicated by the
  // stamp of this call.
  const uint32_t stamp = ++impl.integrate_count;
  // New blocks are constructed by the thread that updates them (below): in parallel, and
  // still in that core's cache when it does.
  std::vector<VoxelBlock*>& visible = impl.visible;
  std::vector<uint64_t>& fresh = impl.visible_fresh;
  visible.clear();
  fresh.clear();
  const size_t blocks_before = impl.blocks.size();
  // Each key's hash table entry is fetched a few keys ahead: the lookups are independent
  // (3.3 → 3.0 ms per integration on the 10 s `building` sweep).
  constexpr size_t kLookAhead = 8;
  for (const auto& chunk_keys : keys) {
    for (size_t k = 0; k < chunk_keys.size(); ++k) {
      if (k + kLookAhead < chunk_keys.size()) impl.index.prefetch(chunk_keys[k + kLookAhead]);
      const uint64_t key = chunk_keys[k];
      bool created = false;
      const int32_t index = impl.GetOrAllocate(key, created);
      if (impl.visit_stamp[index] == stamp) continue;
      impl.visit_stamp[index] = stamp;
      visible.push_back(impl.blocks[index]);
      fresh.push_back(created ? key : ~uint64_t{0});
    }
  }
  stats.blocks_allocated = static_cast<int>(impl.blocks.size() - blocks_before);
  stats.blocks_visible = static_cast<int>(visible.size());

  // 2. Update of the voxels of the visible blocks. Threads take chunks of blocks from a
  // shared counter (each block belongs to one chunk: no two threads write one voxel; the
  // result does not depend on which thread takes which): on 2 shared cores a fixed split
  // waits for the slower half.
  const core::Rigid3d camera_from_world = world_from_camera.Inverse();
  const Eigen::Matrix3f cw_rotation = camera_from_world.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f cw_translation = camera_from_world.translation.cast<float>();
  // 1 / (w + 1) for every weight a voxel can hold (integers up to max_weight): a
  // multiplication instead of a division per voxel.
  const float max_weight = static_cast<float>(options_.max_weight);
  if (impl.inv_count.empty()) {
    impl.inv_count.resize(static_cast<size_t>(max_weight) + 1);
    for (size_t w = 0; w < impl.inv_count.size(); ++w) impl.inv_count[w] = 1.0f / static_cast<float>(w + 1);
  }
  FrameParams f{};
  f.depth = depth_m.ptr<float>(0);
  f.depth_step = depth_m.step1();
  f.fx = camera.fx;
  f.fy = camera.fy;
  f.cx = camera.cx;
  f.cy = camera.cy;
  f.u_limit = static_cast<float>(width) - 0.5f;
  f.v_limit = static_cast<float>(height) - 0.5f;
  f.u_inner = static_cast<float>(width - 1);
  f.v_inner = static_cast<float>(height - 1);
  f.min_depth_m = min_depth_m;
  f.max_depth_m = max_depth_m;
  f.truncation_m = truncation_m;
  f.half_truncation_m = 0.5f * truncation_m;
  f.band = noise_band;
  f.edge_slope_per_m = 4.0f / std::min(camera.fx, camera.fy);  // depth steps, UpdateRowScalar
  f.max_weight = max_weight;
  f.inv_count = impl.inv_count.data();
  f.max_colour_weight = static_cast<int>(std::min(options_.max_weight, 255.0));
  if (colour != nullptr && !colour->rgb.empty()) {
    const core::Rigid3d colour_from_camera = colour->world_from_camera.Inverse() * world_from_camera;
    const Eigen::Matrix3f r = colour_from_camera.rotation.toRotationMatrix().cast<float>();
    for (int i = 0; i < 9; ++i) f.colour_rotation[i] = r(i / 3, i % 3);
    for (int i = 0; i < 3; ++i) f.colour_translation[i] = static_cast<float>(colour_from_camera.translation[i]);
    f.colour_rgb = colour->rgb.ptr<std::uint8_t>(0);
    f.colour_step = colour->rgb.step1();
    f.colour_width = colour->camera.width;
    f.colour_height = colour->camera.height;
    f.colour_fx = colour->camera.fx;
    f.colour_fy = colour->camera.fy;
    f.colour_cx = colour->camera.cx;
    f.colour_cy = colour->camera.cy;
    f.colour_u_limit = static_cast<float>(colour->camera.width) - 0.5f;
    f.colour_v_limit = static_cast<float>(colour->camera.height) - 0.5f;
    const std::vector<core::Rigid3d>& bands = colour->world_from_camera_bands;
    assert(bands.empty() || (bands.size() >= 2 && bands.size() <= static_cast<size_t>(kMaxColourBands)));
    f.colour_bands = static_cast<int>(bands.size());
    f.colour_band_scale = static_cast<float>(bands.size()) / static_cast<float>(colour->camera.height);
    for (size_t k = 0; k < bands.size(); ++k) {
      const core::Rigid3d band_from_camera = bands[k].Inverse() * world_from_camera;
      const Eigen::Matrix3f br = band_from_camera.rotation.toRotationMatrix().cast<float>();
      for (int i = 0; i < 9; ++i) f.band_rotation[i][k] = br(i / 3, i % 3);
      for (int i = 0; i < 3; ++i) f.band_translation[i][k] = static_cast<float>(band_from_camera.translation[i]);
    }
  }
  // Voxel steps along the world axes, in the camera frame.
  for (int i = 0; i < 3; ++i) {
    f.step_x[i] = cw_rotation(i, 0) * voxel_m;
    f.step_y[i] = cw_rotation(i, 1) * voxel_m;
    f.step_z[i] = cw_rotation(i, 2) * voxel_m;
  }
  int (*update_block)(const FrameParams&, const Eigen::Vector3f&, Voxel*, bool) = UpdateBlockScalar;
#ifdef HW_TSDF_AVX2
  if (internal::UseAvx2Kernels()) update_block = UpdateBlockAvx2;
#endif

  // Blocks whose centre lies beyond this depth, never seen nearer, are updated coarsely.
  const float coarse_beyond_m = static_cast<float>(options_.CoarseBeyondM(std::min(camera.fx, camera.fy)));
  const Eigen::Vector3f centre_offset = cw_rotation * Eigen::Vector3f::Constant(0.5f * (block_m - voxel_m));
  // The block's voxel centres lie within this of its centre (half the diagonal of the
  // centres' cube), so its nearest is at least z_centre − this deep.
  const float near_offset_m = 0.5f * (block_m - voxel_m) * std::sqrt(3.0f);
  std::vector<int64_t> updated(num_threads, 0);
  std::vector<int> coarse_blocks(num_threads, 0);
  std::atomic<size_t> next_block{0};
  constexpr size_t kChunkBlocks = 32;
  internal::RunChunks(num_threads, [&](int chunk) {
    int64_t count = 0;
    int coarse_count = 0;
    for (;;) {
      const size_t begin = next_block.fetch_add(kChunkBlocks, std::memory_order_relaxed);
      if (begin >= visible.size()) break;
      const size_t end = std::min(begin + kChunkBlocks, visible.size());
      for (size_t b = begin; b < end; ++b) {
        static_assert(kBlockSide * sizeof(Voxel) == 64);
        // The next block's voxels, one cache line per row, fetched while this one is
        // updated: a coarse update reads every other row and slab, which the hardware's
        // prefetcher does not follow (measured on the 10 s `building` sweep: −10-15 % of the
        // integration; −7 % for blocks updated whole).
        if (b + 1 < end && fresh[b + 1] == ~uint64_t{0}) {
          const char* next = reinterpret_cast<const char*>(visible[b + 1]->voxels.data());
          for (int row = 0; row < kBlockVoxels / kBlockSide; ++row) __builtin_prefetch(next + 64 * row, 1, 3);
        }
        if (fresh[b] != ~uint64_t{0}) BlockArena::Construct(visible[b], Unpack(fresh[b]));
        VoxelBlock& block = *visible[b];
        const Eigen::Vector3f corner_in_world = block.key.cast<float>() * block_m;
        const Eigen::Vector3f corner_in_camera = cw_rotation * corner_in_world + cw_translation;
        const float centre_z = (corner_in_camera + centre_offset).z();
        if (centre_z <= coarse_beyond_m) block.seen_near = true;
        // A reading updates a voxel at depth z only from d >= z − band(d) >= z − band(z)
        // (hidden beyond its band), its band taken at the nearest pixel's depth, which the
        // bilinear d may exceed by the spread it accepts (UpdateRowScalar): the band is at
        // least band(max(z_near − band(z_near) − that spread, the noise model's minimum)),
        // z_near the block's nearest voxel centre.
        const float z_near = std::max(centre_z - near_offset_m, 0.0f);
        const float spread_m = f.half_truncation_m + z_near * f.edge_slope_per_m;
        block.LowerBand(noise_band.At(std::max(z_near - noise_band.At(z_near) - spread_m, noise_band.reference_m)));
        coarse_count += !block.seen_near;
        count += update_block(f, corner_in_camera, block.voxels.data(), !block.seen_near);
      }
    }
    updated[chunk] = count;
    coarse_blocks[chunk] = coarse_count;
  });
  for (const int64_t n : updated) stats.voxels_updated += n;
  for (const int n : coarse_blocks) stats.blocks_coarse += n;
  return stats;
}

}  // namespace hw::reconstruct
