#include "reconstruct/icp.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

#include "reconstruct/float8.h"
#include "reconstruct/row_bands.h"

namespace hw::reconstruct {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

std::string Fail(const char* field, double value, const char* constraint) {
  std::ostringstream s;
  s << field << ": must be " << constraint << ", got " << value;
  return s.str();
}

// Rows per unit of work whose partial sums are kept apart: the reduction adds them in row
// order, so the result does not depend on the number of threads.
constexpr int kChunkRows = 8;
// The lever that makes a rotation (rad) comparable with a translation (m) in the condition
// number: a rotation of 1 rad moves a point 1 m away by 1 m. Points seen by a hand-held
// depth camera are 0.3–4 m away.
constexpr double kConditionLeverM = 1.0;

// Sums of one association pass: the upper triangle of Σ w J Jᵀ (row-major), Σ w J r, and
// figures of the inliers.
struct Sums {
  std::array<double, 21> ata{};
  std::array<double, 6> atb{};
  double sum_r_sq = 0;  // unweighted, of inliers
  int inliers = 0;
  int valid = 0;  // live points with a normal
  // Photometric pairs: Σ w (model − live grey level) before the offset, Σ w (Huber weights).
  double photo_r = 0, photo_w = 0;

  void Add(const Sums& o) {
    photo_r += o.photo_r;
    photo_w += o.photo_w;
    for (int k = 0; k < 21; ++k) ata[k] += o.ata[k];
    for (int k = 0; k < 6; ++k) atb[k] += o.atb[k];
    sum_r_sq += o.sum_r_sq;
    inliers += o.inliers;
    valid += o.valid;
  }
};

// A rigid transform as 12 floats, applied without Eigen's expression machinery (which the
// compiler does not always inline in the hot loop).
struct Affine {
  float r[9];  // row-major
  float t[3];
  static Affine Of(const core::Rigid3d& transform) {
    Affine a;
    const Eigen::Matrix3d R = transform.rotation.toRotationMatrix();
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) a.r[3 * i + j] = static_cast<float>(R(i, j));
      a.t[i] = static_cast<float>(transform.translation(i));
    }
    return a;
  }
};

// Everything one pass needs, in float: the hot loop runs on it.
struct Pass {
  const PointMap* live = nullptr;   // camera frame
  const PointMap* model = nullptr;  // world frame
  PinholeCamera model_camera;
  Affine world_from_live;
  Affine model_from_world;
  float max_distance_sq = 0;
  float min_normal_cos = 0;
  float huber = 0;
  float noise_reference_depth = 0;  // m; 0: no depth-dependent weighting
  // Depth-noise gate (IcpOptions::noise_gate_sigmas; 0: off) and σ_z(z)'s coefficients.
  float noise_gate_sigmas = 0, noise_base = 0, noise_quadratic = 0, noise_reference = 0;
  // Photometric term, when both are set: the live grey levels (row-major like the live map)
  // and the model's (NaN where unknown), and the term's weight (m per grey level).
  float model_from_live_r[9] = {};  // rotation of model_from_world · world_from_live
  const float* live_intensity = nullptr;
  const float* model_intensity = nullptr;
  float photometric_weight = 0;
  float photometric_offset = 0;  // grey levels subtracted from model − live
};

// Eight pixels at a time (reconstruct/float8.h; AccumulateRows is cloned for AVX2 and
// AVX-512).
using internal::Abs8;
using internal::Float8;
using internal::Floor8;
using internal::Gather8;
using internal::Int8;
using internal::LoadTriples8;
using internal::Masked8;
using internal::Max8;
using internal::Select8;
using internal::Splat8;

inline Float8 HuberWeight8(Float8 r, Float8 k) {
  const Float8 abs_r = Abs8(r);
  return Select8(abs_r <= k, Splat8(1.0f), k / abs_r);
}
// The 6×6 system's sums for one row, eight lanes each: Σ w J_a J_b (upper triangle, a ≤ b,
// row-major, 21) then Σ w J_a r (6).
struct RowSums8 {
  Float8 s[27] = {};
  // Adds the terms (J, r) with weights w (0 in lanes that are not terms; J and r finite there).
  void Add(const Float8 (&j)[6], Float8 r, Float8 w) {
    // Unrolled (-O2 keeps the loops otherwise: an address computation per term).
    int k = 0;
#pragma GCC unroll 6
    for (int a = 0; a < 6; ++a) {
      const Float8 w_ja = w * j[a];
#pragma GCC unroll 6
      for (int b = a; b < 6; ++b) s[k++] += w_ja * j[b];
    }
#pragma GCC unroll 6
    for (int a = 0; a < 6; ++a) s[21 + a] += w * j[a] * r;
  }
};

inline double LaneSum(Float8 v) {
  double s = 0;
  for (int lane = 0; lane < 8; ++lane) s += double(v[lane]);
  return s;
}

// The hot loop reads point maps as packed float triples.
static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float));

// Associates and accumulates rows [y0, y1) of the live map, eight pixels at a time: each
// lane goes through the whole computation, and the association's gates (data: edges, holes,
// outliers, which a branch per gate would mispredict) become masks that zero a lane's terms.
// The gathers from the model (its pixel depends on the lane's point) are scalar loads. Sums
// are in float lanes over a row (a few hundred terms per lane), added in double per row.
// Cloned for AVX-512 and AVX2; every clone computes the same operations in the same order
// (no contraction into FMA in ISO C++ mode), so the sums do not depend on the clone.
__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) Sums AccumulateRows(
    const Pass& pass, int y0, int y1) {
  const PointMap& live = *pass.live;
  const PointMap& model = *pass.model;
  const PinholeCamera cam = pass.model_camera;
  float R[9], T[3], M[9], Mt[3], MR[9];
  std::copy_n(pass.world_from_live.r, 9, R);
  std::copy_n(pass.world_from_live.t, 3, T);
  std::copy_n(pass.model_from_world.r, 9, M);
  std::copy_n(pass.model_from_world.t, 3, Mt);
  std::copy_n(pass.model_from_live_r, 9, MR);
  const float max_distance_sq = pass.max_distance_sq, min_normal_cos = pass.min_normal_cos;
  const float huber = pass.huber, lambda = pass.photometric_weight;
  const float noise_ref = pass.noise_reference_depth;
  const float gate_sigmas = pass.noise_gate_sigmas, noise_base = pass.noise_base,
              noise_quadratic = pass.noise_quadratic, noise_reference = pass.noise_reference;
  const float* live_intensity = pass.live_intensity;
  const float* model_intensity = pass.model_intensity;
  const float u_max = cam.width - 0.5f, v_max = cam.height - 0.5f;
  const float* model_points = model.points.data()->data();
  const float* model_normals = model.normals.data()->data();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Sums sums;
  for (int y = y0; y < y1; ++y) {
    RowSums8 acc;
    Float8 sum_r_sq = {}, photo_r = {}, photo_w = {};
    Int8 inliers = {}, valid = {};
    const size_t row = live.Index(0, y);
    const float* points = live.points[row].data();
    const float* normals = live.normals[row].data();
    for (int x0 = 0; x0 < live.width; x0 += 8) {
      // The lanes' live points and normals (pixels past the row's end: no normal).
      Float8 p[3], n[3];
      const bool whole = x0 + 8 <= live.width;
      if (whole) {
        LoadTriples8(points + 3 * x0, p);
        LoadTriples8(normals + 3 * x0, n);
      } else {
        for (int k = 0; k < 8; ++k) {
          const bool inside = x0 + k < live.width;
          for (int c = 0; c < 3; ++c) {
            p[c][k] = inside ? points[3 * (x0 + k) + c] : 0.0f;
            n[c][k] = inside ? normals[3 * (x0 + k) + c] : nan;
          }
        }
      }
      const Int8 has_normal = n[0] == n[0];  // not NaN
      valid -= has_normal;
      if (!(has_normal[0] | has_normal[1] | has_normal[2] | has_normal[3] | has_normal[4] |
            has_normal[5] | has_normal[6] | has_normal[7])) {
        continue;  // a hole: nothing to pair
      }
      // Lanes without a point compute on zeros and are masked out.
      for (int c = 0; c < 3; ++c) p[c] = Masked8(p[c], has_normal);
      // The live point in the world, then in the model camera.
      const Float8 wx = R[0] * p[0] + R[1] * p[1] + R[2] * p[2] + T[0];
      const Float8 wy = R[3] * p[0] + R[4] * p[1] + R[5] * p[2] + T[1];
      const Float8 wz = R[6] * p[0] + R[7] * p[1] + R[8] * p[2] + T[2];
      const Float8 mx = M[0] * wx + M[1] * wy + M[2] * wz + Mt[0];
      const Float8 my = M[3] * wx + M[4] * wy + M[5] * wz + Mt[1];
      const Float8 mz = M[6] * wx + M[7] * wy + M[8] * wz + Mt[2];
      const Float8 inv_z = 1.0f / mz;
      const Float8 u = cam.fx * mx * inv_z + cam.cx;
      const Float8 v = cam.fy * my * inv_z + cam.cy;
      // Rounding to the nearest pixel; the range test also rejects NaN and huge values.
      const Int8 in_image =
          has_normal & (mz > 0) & (u > -0.5f) & (v > -0.5f) & (u < u_max) & (v < v_max);
      // Outside the image pixel (0, 0) stands in (a valid address); its lane is masked out.
      const Float8 us = Masked8(u, in_image), vs = Masked8(v, in_image);
      Int8 ui = __builtin_convertvector(us + 0.5f, Int8);
      Int8 vi = __builtin_convertvector(vs + 0.5f, Int8);
      // u + 0.5 can round up to the width itself just below the limit.
      ui = ui < cam.width - 1 ? ui : cam.width - 1;
      vi = vi < cam.height - 1 ? vi : cam.height - 1;
      const Int8 j = vi * cam.width + ui;
      Float8 q[3], nm[3];
      for (int c = 0; c < 3; ++c) {
        q[c] = Gather8(model_points + c, 3 * j);
        nm[c] = Gather8(model_normals + c, 3 * j);
      }
      const Float8 dx = wx - q[0], dy = wy - q[1], dz = wz - q[2];
      // The model normal in the live camera frame, n_c = Rᵀ n_model: the angle gate compares
      // it with the live normal there, and it is the Jacobian's translation part.
      const Float8 ncx = R[0] * nm[0] + R[3] * nm[1] + R[6] * nm[2];
      const Float8 ncy = R[1] * nm[0] + R[4] * nm[1] + R[7] * nm[2];
      const Float8 ncz = R[2] * nm[0] + R[5] * nm[1] + R[8] * nm[2];
      // A model pixel without a normal (NaN) fails both gates.
      // The lane's noise allowance k·σ_z(z) (0 with the gate off): gate and Huber threshold
      // are the larger of theirs and it.
      const Float8 zr = p[2] - noise_reference;
      const Float8 allowance = gate_sigmas * (noise_base + noise_quadratic * (zr * zr));
      const Float8 gate_sq = Max8(Splat8(max_distance_sq), allowance * allowance);
      const Float8 huber_lane = Max8(Splat8(huber), allowance);
      const Int8 inlier = in_image & (dx * dx + dy * dy + dz * dz <= gate_sq) &
                          (ncx * n[0] + ncy * n[1] + ncz * n[2] >= min_normal_cos);
      inliers -= inlier;
      // r(ξ) for world_from_live · Exp(ξ), ξ = [ω; v] in the live camera frame:
      // dr/dω = p × n_c, dr/dv = n_c. Masked: NaN in rejected lanes becomes 0.
      const Float8 r = Masked8(nm[0] * dx + nm[1] * dy + nm[2] * dz, inlier);
      {
        // Rows scaled by z_ref / z when the noise grows with depth (1 otherwise; 0 in
        // rejected lanes, whose z may be 0).
        const Float8 s = noise_ref > 0 ? Masked8(noise_ref / p[2], inlier) : Masked8(Splat8(1.0f), inlier);
        const Float8 cx = Masked8(ncx * s, inlier), cy = Masked8(ncy * s, inlier),
                     cz = Masked8(ncz * s, inlier);
        const Float8 jac[6] = {p[1] * cz - p[2] * cy, p[2] * cx - p[0] * cz,
                               p[0] * cy - p[1] * cx, cx, cy, cz};
        const Float8 rs = r * s;
        acc.Add(jac, rs, Masked8(HuberWeight8(rs, huber_lane), inlier));
        // In near-range metres (huber / huber_lane: exactly 1 with the gate off).
        const Float8 r_near = r * (huber / huber_lane);
        sum_r_sq += r_near * r_near;
      }
      if (live_intensity == nullptr) continue;
      // Photometric residual of each pair: the model's grey level, bilinear at the projected
      // pixel, minus the live one; weighted into metres by photometric_weight.
      const Int8 u0 = Floor8(us), v0 = Floor8(vs);
      Int8 in_patch = inlier & (u0 >= 0) & (v0 >= 0) & (u0 + 1 < cam.width) &
                      (v0 + 1 < cam.height);
      const Int8 g = (v0 & in_patch) * cam.width + (u0 & in_patch);
      const Float8 i00 = Gather8(model_intensity, g), i10 = Gather8(model_intensity + 1, g);
      const Float8 i01 = Gather8(model_intensity + cam.width, g);
      const Float8 i11 = Gather8(model_intensity + cam.width + 1, g);
      Float8 live_i;
      if (whole) {
        std::memcpy(&live_i, live_intensity + row + x0, sizeof(Float8));
      } else {
        for (int k = 0; k < 8; ++k) live_i[k] = x0 + k < live.width ? live_intensity[row + x0 + k] : nan;
      }
      const Float8 sum_i = i00 + i10 + i01 + i11 + live_i;
      in_patch &= sum_i == sum_i;  // none NaN
      const Float8 fu = us - __builtin_convertvector(u0, Float8);
      const Float8 fv = vs - __builtin_convertvector(v0, Float8);
      const Float8 model_i =
          (1 - fv) * ((1 - fu) * i00 + fu * i10) + fv * ((1 - fu) * i01 + fu * i11);
      // Gradient of the bilinear patch (per pixel), then d(grey)/d(p_model) through the
      // projection, then into the live camera frame (g_c = (M R)ᵀ g_m): the Jacobian has the
      // geometric one's form with g_c in place of n_c.
      const Float8 gu = (1 - fv) * (i10 - i00) + fv * (i11 - i01);
      const Float8 gv = (1 - fu) * (i01 - i00) + fu * (i11 - i10);
      const Float8 gmx = lambda * gu * cam.fx * inv_z, gmy = lambda * gv * cam.fy * inv_z;
      const Float8 gmz = -(gmx * mx + gmy * my) * inv_z;
      const Float8 gcx = Masked8(MR[0] * gmx + MR[3] * gmy + MR[6] * gmz, in_patch);
      const Float8 gcy = Masked8(MR[1] * gmx + MR[4] * gmy + MR[7] * gmz, in_patch);
      const Float8 gcz = Masked8(MR[2] * gmx + MR[5] * gmy + MR[8] * gmz, in_patch);
      const Float8 ri = Masked8(lambda * (model_i - live_i - pass.photometric_offset), in_patch);
      const Float8 wi = Masked8(HuberWeight8(ri, Splat8(huber)), in_patch);
      // For the next pass's offset: the pairs' weighted differences without this one.
      photo_r += wi * Masked8(model_i - live_i, in_patch);
      photo_w += wi;
      const Float8 jac[6] = {p[1] * gcz - p[2] * gcy, p[2] * gcx - p[0] * gcz,
                             p[0] * gcy - p[1] * gcx, gcx, gcy, gcz};
      acc.Add(jac, ri, wi);
    }
    int k = 0;
    for (int a = 0; a < 6; ++a) {
      for (int b = a; b < 6; ++b, ++k) sums.ata[k] += LaneSum(acc.s[k]);
      sums.atb[a] += LaneSum(acc.s[21 + a]);
    }
    sums.sum_r_sq += LaneSum(sum_r_sq);
    sums.photo_r += LaneSum(photo_r);
    sums.photo_w += LaneSum(photo_w);
    for (int lane = 0; lane < 8; ++lane) {
      sums.inliers += inliers[lane];
      sums.valid += valid[lane];
    }
  }
  return sums;
}

// One association pass over the whole live map, chunks summed in row order.
Sums Accumulate(const Pass& pass, int num_threads) {
  const int chunks = (pass.live->height + kChunkRows - 1) / kChunkRows;
  std::vector<Sums> partial(chunks);
  ForEachBand(chunks, num_threads, [&](int c0, int c1) {
    for (int c = c0; c < c1; ++c) {
      partial[c] = AccumulateRows(pass, c * kChunkRows,
                                  std::min(pass.live->height, (c + 1) * kChunkRows));
    }
  });
  Sums total;
  for (const Sums& s : partial) total.Add(s);
  return total;
}

// Rec. 601 luma (as BuildDepthPyramid's intensity) of a map's colours, in [0, 1]; NaN where
// the map has no point.
std::vector<float> GreyOf(const PointMap& map) {
  std::vector<float> grey(map.points.size(), std::numeric_limits<float>::quiet_NaN());
  for (size_t i = 0; i < grey.size(); ++i) {
    if (!IsValid(map.points[i])) continue;
    const Rgb8& c = map.colours[i];
    grey[i] = (0.299f * c[0] + 0.587f * c[1] + 0.114f * c[2]) * (1.0f / 255.0f);
  }
  return grey;
}

Matrix6d NormalMatrix(const Sums& sums) {
  Matrix6d A;
  int k = 0;
  for (int a = 0; a < 6; ++a) {
    for (int b = a; b < 6; ++b) {
      A(a, b) = sums.ata[k];
      A(b, a) = sums.ata[k];
      ++k;
    }
  }
  return A;
}

// Rotation rows/columns of A scaled by the lever (rotation in metres at kConditionLeverM):
// the frame in which eigenvalues of rotation and translation compare.
Vector6d LeverScale() {
  Vector6d scale;
  scale << Eigen::Vector3d::Constant(1.0 / kConditionLeverM), Eigen::Vector3d::Ones();
  return scale;
}

// A direction whose eigenvalue is below largest / max_condition is weak (unconstrained).
bool IsWeak(double eigenvalue, double largest, double max_condition) {
  return !(eigenvalue * max_condition >= largest);
}

// The Gauss-Newton step -A⁻¹ b restricted to the directions the data constrain: in the
// eigenbasis of A (rotation scaled by the lever), weak directions (IsWeak) get no update. A
// flat wall leaves its in-plane motion free; a plain solve would slide the estimate along it
// by whatever the noise says, this keeps the prediction there (and the condition check
// reports the frame).
Vector6d Step(const Matrix6d& A, const Vector6d& b, double max_condition) {
  const Vector6d scale = LeverScale();
  const Matrix6d scaled = scale.asDiagonal() * A * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix6d> solver(scaled);
  const Vector6d& eig = solver.eigenvalues();  // ascending
  if (!(eig(5) > 0)) return Vector6d::Constant(std::numeric_limits<double>::quiet_NaN());
  const Vector6d rhs = solver.eigenvectors().transpose() * (scale.asDiagonal() * -b);
  Vector6d in_eigenbasis = Vector6d::Zero();
  for (int k = 0; k < 6; ++k) {
    if (!IsWeak(eig(k), eig(5), max_condition)) in_eigenbasis(k) = rhs(k) / eig(k);
  }
  return scale.asDiagonal() * (solver.eigenvectors() * in_eigenbasis);
}

// The condition of A (largest / smallest eigenvalue with rotation scaled by the lever;
// infinity when singular) and the number of weak directions, the ones Step leaves at the
// initial pose (6 when A is zero).
struct Conditioning {
  double condition = std::numeric_limits<double>::infinity();
  int weak_directions = 6;
};
Conditioning ConditioningOf(const Matrix6d& A, double max_condition) {
  const Vector6d scale = LeverScale();
  const Matrix6d scaled = scale.asDiagonal() * A * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix6d> solver(scaled, Eigen::EigenvaluesOnly);
  const Vector6d& eig = solver.eigenvalues();  // ascending
  Conditioning c;
  if (eig(0) > 0) c.condition = eig(5) / eig(0);
  if (!(eig(5) > 0)) return c;
  c.weak_directions = 0;
  for (int k = 0; k < 6; ++k) c.weak_directions += IsWeak(eig(k), eig(5), max_condition);
  return c;
}

}  // namespace

Vector6d WeakestDirection(const Matrix6d& information) {
  const Vector6d scale = LeverScale();
  const Matrix6d scaled = scale.asDiagonal() * information * scale.asDiagonal();
  if (!(scaled.diagonal().maxCoeff() > 0)) return Vector6d::Zero();
  const Eigen::SelfAdjointEigenSolver<Matrix6d> solver(scaled);
  // The eigenvector is a unit vector of the scaled problem; back in (rad, m) its rotation
  // is divided by the lever (1 m: the same numbers).
  return scale.asDiagonal() * solver.eigenvectors().col(0);  // eigenvalues ascending
}

double IcpBasinM(const DepthPyramid& live, const ModelPyramid& model, const IcpResult& aligned, double step_m,
                 const IcpOptions& options) {
  assert(step_m > 0);
  const core::Rigid3d moved = aligned.world_from_camera * core::Rigid3d::Exp(step_m * WeakestDirection(aligned.information));
  const IcpResult probe = AlignToModel(live, model, moved, options);
  const core::PoseError apart = core::ComparePoses(aligned.world_from_camera, probe.world_from_camera);
  return std::hypot(apart.translation_m, apart.rotation_rad * kConditionLeverM);
}

std::string IcpOptions::Check() const {
  bool any = false;
  for (size_t l = 0; l < iterations.size(); ++l) {
    if (iterations[l] < 0 || iterations[l] > 100) {
      return Fail(("iterations[" + std::to_string(l) + "]").c_str(), iterations[l], "in [0, 100]");
    }
    any = any || iterations[l] > 0;
  }
  if (!any) return "iterations: must have a level with > 0, got all 0";
  if (!(max_distance_m > 0) || !std::isfinite(max_distance_m)) {
    return Fail("max_distance_m", max_distance_m, "> 0 m and finite");
  }
  if (!(min_distance_m > 0 && min_distance_m <= max_distance_m)) {
    return Fail("min_distance_m", min_distance_m, "in (0, max_distance_m] m");
  }
  if (!(max_normal_angle_deg > 0 && max_normal_angle_deg <= 90)) {
    return Fail("max_normal_angle_deg", max_normal_angle_deg, "in (0, 90] degrees");
  }
  if (!(huber_m > 0) || !std::isfinite(huber_m))
    return Fail("huber_m", huber_m, "> 0 m and finite");
  if (!(noise_reference_depth_m == 0 || (noise_reference_depth_m >= 0.1 && noise_reference_depth_m <= 10)))
    return Fail("noise_reference_depth_m", noise_reference_depth_m, "0 (off) or in [0.1, 10] m");
  if (!(min_update_rad >= 0) || !std::isfinite(min_update_rad)) {
    return Fail("min_update_rad", min_update_rad, ">= 0 rad and finite");
  }
  if (!(min_update_m >= 0) || !std::isfinite(min_update_m)) {
    return Fail("min_update_m", min_update_m, ">= 0 m and finite");
  }
  if (!(min_inlier_fraction >= 0 && min_inlier_fraction <= 1)) {
    return Fail("min_inlier_fraction", min_inlier_fraction, "in [0, 1]");
  }
  if (min_inliers < 6) return Fail("min_inliers", min_inliers, ">= 6");
  if (!(max_condition > 1)) return Fail("max_condition", max_condition, "> 1");
  if (max_held_directions < 0 || max_held_directions > 5) {
    return Fail("max_held_directions", max_held_directions, "in [0, 5]");
  }
  if (!(max_residual_m > 0)) return Fail("max_residual_m", max_residual_m, "> 0 m");
  if (!(noise_gate_sigmas >= 0 && noise_gate_sigmas <= 10)) {
    return Fail("noise_gate_sigmas", noise_gate_sigmas, "in [0, 10]");
  }
  if (std::string m = depth_noise.Check(); !m.empty()) return "depth_noise." + m;
  if (!(max_jump_m > 0)) return Fail("max_jump_m", max_jump_m, "> 0 m");
  if (!(max_jump_deg > 0)) return Fail("max_jump_deg", max_jump_deg, "> 0 degrees");
  if (!(photometric_weight >= 0 && photometric_weight <= 1)) {
    return Fail("photometric_weight", photometric_weight, "in [0, 1] m per grey level");
  }
  if (num_threads < 0) return Fail("num_threads", num_threads, ">= 0 (0: hardware concurrency)");
  return "";
}

std::string IcpStatusName(IcpStatus status) {
  switch (status) {
    case IcpStatus::kOk:
      return "ok";
    case IcpStatus::kTooFewInliers:
      return "too_few_inliers";
    case IcpStatus::kIllConditioned:
      return "ill_conditioned";
    case IcpStatus::kLargeResidual:
      return "large_residual";
    case IcpStatus::kImplausibleJump:
      return "implausible_jump";
    case IcpStatus::kModelConflict:
      return "model_conflict";
    case IcpStatus::kUnconstrained:
      return "unconstrained";
  }
  assert(false && "unknown IcpStatus");
  return "unknown";
}

ModelPyramid BuildModelPyramid(PointMap level0, const PinholeCamera& camera,
                               const core::Rigid3d& world_from_camera, int num_levels,
                               int num_threads) {
  assert(num_levels >= 1);
  assert(level0.width == camera.width && level0.height == camera.height);
  ModelPyramid pyramid;
  pyramid.world_from_camera = world_from_camera;
  pyramid.cameras.push_back(camera);
  pyramid.maps.push_back(std::move(level0));
  // Depth along the raycast camera's axis of a world point: z = r3 · (p − t), r3 the third
  // column of the world-from-camera rotation.
  const Eigen::Vector3f axis = world_from_camera.rotation.toRotationMatrix().col(2).cast<float>();
  const Eigen::Vector3f origin = world_from_camera.translation.cast<float>();
  for (int l = 1; l < num_levels; ++l) {
    const PointMap& above = pyramid.maps.back();
    if (above.width < 2 || above.height < 2) break;
    const PinholeCamera half = pyramid.cameras.back().Half();
    PointMap map(half.width, half.height);
    const bool colours = !above.colours.empty();
    if (colours) map.colours.assign(size_t(half.width) * half.height, Rgb8::Zero());
    ForEachBand(half.height, num_threads, [&](int y0, int y1) {
      for (int y = y0; y < y1; ++y) {
        for (int x = 0; x < half.width; ++x) {
          const size_t block[4] = {above.Index(2 * x, 2 * y), above.Index(2 * x + 1, 2 * y),
                                   above.Index(2 * x, 2 * y + 1),
                                   above.Index(2 * x + 1, 2 * y + 1)};
          float depth[4];
          float sum = 0;
          int n = 0;
          for (int k = 0; k < 4; ++k) {
            const Eigen::Vector3f& p = above.points[block[k]];
            depth[k] = IsValid(p) ? axis.dot(p - origin) : -1.0f;
            if (depth[k] >= 0) {
              sum += depth[k];
              ++n;
            }
          }
          if (n == 0) continue;
          const float mean = sum / static_cast<float>(n);
          int best = -1;
          for (int k = 0; k < 4; ++k) {
            if (depth[k] >= 0 &&
                (best < 0 || std::abs(depth[k] - mean) < std::abs(depth[best] - mean))) {
              best = k;
            }
          }
          const size_t i = map.Index(x, y);
          map.points[i] = above.points[block[best]];
          map.normals[i] = above.normals[block[best]];
          if (colours) map.colours[i] = above.colours[block[best]];
        }
      }
    });
    pyramid.cameras.push_back(half);
    pyramid.maps.push_back(std::move(map));
  }
  return pyramid;
}

IcpResult AlignToModel(const DepthPyramid& live, const ModelPyramid& model,
                       const core::Rigid3d& initial_world_from_camera, const IcpOptions& options) {
  assert(options.Check().empty());
  assert(model.cameras.size() == model.maps.size());
  IcpResult result;
  result.world_from_camera = initial_world_from_camera;
  result.status = IcpStatus::kTooFewInliers;
  const int num_levels = static_cast<int>(
      std::min({live.levels.size(), model.maps.size(), options.iterations.size()}));
  int coarsest = -1;
  for (int l = num_levels - 1; l >= 0; --l) {
    if (options.iterations[l] > 0) {
      coarsest = l;
      break;
    }
  }
  if (coarsest < 0) return result;  // no level to work on: nothing is aligned

  const core::Rigid3d model_from_world = model.world_from_camera.Inverse();
  const float min_normal_cos =
      static_cast<float>(std::cos(options.max_normal_angle_deg * std::numbers::pi / 180.0));
  core::Rigid3d estimate = initial_world_from_camera;
  Sums last;
  Matrix6d last_A = Matrix6d::Zero();
  float photometric_offset = 0;  // carried from level to level
  for (int l = coarsest; l >= 0; --l) {
    if (options.iterations[l] == 0) continue;
    const PointMap& live_map = live.levels[l].map;
    const PointMap& model_map = model.maps[l];
    assert(live_map.width == model_map.width && live_map.height == model_map.height);
    assert(model.cameras[l].width == model_map.width &&
           model.cameras[l].height == model_map.height);
    const double gate =
        std::max(options.min_distance_m, options.max_distance_m / double(1 << (coarsest - l)));
    Pass pass;
    pass.live = &live_map;
    pass.model = &model_map;
    pass.model_camera = model.cameras[l];
    pass.model_from_world = Affine::Of(model_from_world);
    pass.max_distance_sq = static_cast<float>(gate * gate);
    pass.min_normal_cos = min_normal_cos;
    pass.huber = static_cast<float>(options.huber_m);
    pass.noise_reference_depth = static_cast<float>(options.noise_reference_depth_m);
    pass.noise_gate_sigmas = static_cast<float>(options.noise_gate_sigmas);
    pass.noise_base = static_cast<float>(options.depth_noise.base_m);
    pass.noise_quadratic = static_cast<float>(options.depth_noise.quadratic_per_m);
    pass.noise_reference = static_cast<float>(options.depth_noise.reference_m);
    // Photometric term: needs grey levels on both sides.
    std::vector<float> model_intensity;
    const cv::Mat& live_intensity = live.levels[l].intensity;
    if (options.photometric_weight > 0 && !live_intensity.empty() && !model_map.colours.empty()) {
      assert(live_intensity.isContinuous() && live_intensity.cols == live_map.width);
      model_intensity = GreyOf(model_map);
      pass.live_intensity = live_intensity.ptr<float>();
      pass.model_intensity = model_intensity.data();
      pass.photometric_weight = static_cast<float>(options.photometric_weight);
      pass.photometric_offset = photometric_offset;
    }
    for (int it = 0; it < options.iterations[l]; ++it) {
      pass.world_from_live = Affine::Of(estimate);
      const Affine model_from_live = Affine::Of(model_from_world * estimate);
      std::copy(model_from_live.r, model_from_live.r + 9, pass.model_from_live_r);
      last = Accumulate(pass, options.num_threads);
      // The offset for the next pass: the weighted mean of this pass's differences.
      if (options.photometric_offset && last.photo_w > 0) {
        photometric_offset = std::clamp(static_cast<float>(last.photo_r / last.photo_w), -1.0f, 1.0f);
        pass.photometric_offset = photometric_offset;
      }
      last_A = NormalMatrix(last);
      ++result.iterations;
      if (last.inliers < 6) break;  // fewer equations than unknowns
      const Vector6d xi =
          Step(last_A, Eigen::Map<const Vector6d>(last.atb.data()), options.max_condition);
      if (!xi.allFinite()) break;
      estimate = estimate * core::Rigid3d::Exp(xi);
      const double level_scale = static_cast<double>(1 << l);
      if (xi.head<3>().norm() < options.min_update_rad * level_scale &&
          xi.tail<3>().norm() < options.min_update_m * level_scale) {
        break;
      }
    }
  }

  result.world_from_camera = estimate;
  result.inliers = last.inliers;
  result.valid_points = last.valid;
  result.photometric_offset = photometric_offset;
  result.residual_rms_m = last.inliers > 0 ? std::sqrt(last.sum_r_sq / last.inliers) : 0.0;
  result.information = last_A;
  if (last.inliers > 0) {
    const Conditioning c = ConditioningOf(last_A, options.max_condition);
    result.condition = c.condition;
    result.held_directions = c.weak_directions;
  } else {
    result.condition = std::numeric_limits<double>::infinity();
    result.held_directions = 6;
  }
  const core::PoseError jump = core::ComparePoses(initial_world_from_camera, estimate);
  if (last.inliers < options.min_inliers ||
      last.inliers < options.min_inlier_fraction * last.valid) {
    result.status = IcpStatus::kTooFewInliers;
  } else if (result.held_directions > options.max_held_directions) {
    result.status = IcpStatus::kIllConditioned;
  } else if (result.residual_rms_m > options.max_residual_m) {
    result.status = IcpStatus::kLargeResidual;
  } else if (jump.translation_m > options.max_jump_m ||
             jump.rotation_rad > options.max_jump_deg * std::numbers::pi / 180.0) {
    result.status = IcpStatus::kImplausibleJump;
  } else {
    result.status = IcpStatus::kOk;
  }
  return result;
}

}  // namespace hw::reconstruct
