#include "reconstruct/icp.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>

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

  void Add(const Sums& o) {
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
  // Photometric term, when both are set: the live grey levels (row-major like the live map)
  // and the model's (NaN where unknown), and the term's weight (m per grey level).
  float model_from_live_r[9] = {};  // rotation of model_from_world · world_from_live
  const float* live_intensity = nullptr;
  const float* model_intensity = nullptr;
  float photometric_weight = 0;
};

// The terms of one image row's normal equations, as a structure of arrays (one column per
// Jacobian entry, then the residual and the Huber weight): association fills it point by
// point, SumTerms then adds w x xᵀ over all of them eight at a time.
struct TermRows {
  static constexpr int kColumns = 8;  // J (6), r, w
  std::vector<float> columns[kColumns];
  int size = 0;

  explicit TermRows(int capacity) {
    // Rounded up to whole groups of eight, which SumTerms reads.
    for (auto& c : columns) c.resize(size_t(capacity + 8));
  }
};

using Float8 = float __attribute__((vector_size(32)));

// Adds Σ w x xᵀ (x = [J; r]) of the first `rows.size` terms to the upper triangle `ata`
// (row-major, 21) and to `atb` (6): eight terms at a time in float lanes (each lane sums a
// few hundred terms at most), the lanes added in double. Pads rows to a multiple of eight
// with zero weights. Cloned for AVX-512 and AVX2 (more and wider registers: the 27 sums stay
// in registers); every clone adds in the same order, so the results are the same.
__attribute__((target_clones("arch=x86-64-v4", "avx2", "default"))) void SumTerms(
    TermRows& rows, double* ata, double* atb) {
  const int n = rows.size;
  const int padded = (n + 7) / 8 * 8;
  for (auto& c : rows.columns) std::fill(c.begin() + n, c.begin() + padded, 0.0f);
  Float8 sums[27] = {};
  const float* col[TermRows::kColumns];
  for (int c = 0; c < TermRows::kColumns; ++c) col[c] = rows.columns[c].data();
  for (int i = 0; i < padded; i += 8) {
    Float8 x[7];
    for (int c = 0; c < 7; ++c) std::memcpy(&x[c], col[c] + i, sizeof(Float8));
    Float8 w;
    std::memcpy(&w, col[7] + i, sizeof(Float8));
    int k = 0;
    for (int a = 0; a < 6; ++a) {
      const Float8 w_xa = w * x[a];
      for (int b = a; b < 7; ++b) sums[k++] += w_xa * x[b];
    }
  }
  // sums: for each a, columns b = a..5 of the triangle, then b = 6 (the right-hand side).
  int k = 0, t = 0;
  for (int a = 0; a < 6; ++a) {
    for (int b = a; b < 7; ++b) {
      double s = 0;
      for (int lane = 0; lane < 8; ++lane) s += double(sums[k][lane]);
      if (b < 6) {
        ata[t++] += s;
      } else {
        atb[a] += s;
      }
      ++k;
    }
  }
}

inline float HuberWeight(float r, float k) {
  const float abs_r = std::abs(r);
  return abs_r <= k ? 1.0f : k / abs_r;
}

// The hot loop reads point maps as packed float triples.
static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float));

// Associates and accumulates rows [y0, y1) of the live map.
Sums AccumulateRows(const Pass& pass, int y0, int y1, TermRows& terms) {
  const PointMap& live = *pass.live;
  const PointMap& model = *pass.model;
  // Local copies of everything the loop reads in float: the terms it stores are floats too,
  // and the compiler would otherwise reload every value the stores might have changed.
  const PinholeCamera cam = pass.model_camera;
  float R[9], T[3], M[9], Mt[3], MR[9];
  std::copy_n(pass.world_from_live.r, 9, R);
  std::copy_n(pass.world_from_live.t, 3, T);
  std::copy_n(pass.model_from_world.r, 9, M);
  std::copy_n(pass.model_from_world.t, 3, Mt);
  std::copy_n(pass.model_from_live_r, 9, MR);
  const float max_distance_sq = pass.max_distance_sq, min_normal_cos = pass.min_normal_cos;
  const float huber = pass.huber, lambda = pass.photometric_weight;
  const float* live_intensity = pass.live_intensity;
  const float* model_intensity = pass.model_intensity;
  const float u_max = cam.width - 0.5f, v_max = cam.height - 0.5f;
  const float* model_points = model.points.data()->data();
  const float* model_normals = model.normals.data()->data();
  float* columns[TermRows::kColumns];
  for (int c = 0; c < TermRows::kColumns; ++c) columns[c] = terms.columns[c].data();
  int n_terms = 0;
  // Stores a term at the end of the row's terms; the caller counts it in when it is one.
  auto store = [&](float j0, float j1, float j2, float j3, float j4, float j5, float r, float w) {
    columns[0][n_terms] = j0;
    columns[1][n_terms] = j1;
    columns[2][n_terms] = j2;
    columns[3][n_terms] = j3;
    columns[4][n_terms] = j4;
    columns[5][n_terms] = j5;
    columns[6][n_terms] = r;
    columns[7][n_terms] = w;
  };
  Sums sums;
  for (int y = y0; y < y1; ++y) {
    // The row's terms are collected, then summed in float lanes and added in double per row.
    n_terms = 0;
    float sum_r_sq = 0;
    int inliers = 0, valid = 0;
    const size_t row = live.Index(0, y);
    const float* points = live.points[row].data();
    const float* normals = live.normals[row].data();
    for (int x = 0; x < live.width; ++x) {
      const float* n = normals + 3 * x;
      if (std::isnan(n[0])) continue;  // no normal (or no point)
      ++valid;
      const float* p = points + 3 * x;
      // The live point in the world, then in the model camera.
      const float wx = R[0] * p[0] + R[1] * p[1] + R[2] * p[2] + T[0];
      const float wy = R[3] * p[0] + R[4] * p[1] + R[5] * p[2] + T[1];
      const float wz = R[6] * p[0] + R[7] * p[1] + R[8] * p[2] + T[2];
      const float mx = M[0] * wx + M[1] * wy + M[2] * wz + Mt[0];
      const float my = M[3] * wx + M[4] * wy + M[5] * wz + Mt[1];
      const float mz = M[6] * wx + M[7] * wy + M[8] * wz + Mt[2];
      // Branch-free from here: whether a point pairs up is data (edges, holes, the gates), so
      // a branch per gate mispredicts often. Every candidate's term is computed and stored;
      // only the inliers advance the count, the others are overwritten by the next.
      const float inv_z = 1.0f / mz;
      const float u = cam.fx * mx * inv_z + cam.cx;
      const float v = cam.fy * my * inv_z + cam.cy;
      // Rounding to the nearest pixel; the range test also rejects NaN and huge values.
      const bool in_image = (mz > 0) & (u > -0.5f) & (v > -0.5f) & (u < u_max) & (v < v_max);
      // Outside the image pixel (0, 0) stands in (a valid address); its term is dropped.
      const float us = in_image ? u : 0.0f, vs = in_image ? v : 0.0f;
      const size_t j = model.Index(static_cast<int>(us + 0.5f), static_cast<int>(vs + 0.5f));
      const float* nm = model_normals + 3 * j;
      const float* q = model_points + 3 * j;
      const float dx = wx - q[0], dy = wy - q[1], dz = wz - q[2];
      // The model normal in the live camera frame, n_c = Rᵀ n_model: the angle gate compares
      // it with the live normal there, and it is the Jacobian's translation part.
      const float ncx = R[0] * nm[0] + R[3] * nm[1] + R[6] * nm[2];
      const float ncy = R[1] * nm[0] + R[4] * nm[1] + R[7] * nm[2];
      const float ncz = R[2] * nm[0] + R[5] * nm[1] + R[8] * nm[2];
      // A model pixel without a normal (NaN) fails both gates.
      const bool inlier = in_image & (dx * dx + dy * dy + dz * dz <= max_distance_sq) &
                          (ncx * n[0] + ncy * n[1] + ncz * n[2] >= min_normal_cos);
      const float r = nm[0] * dx + nm[1] * dy + nm[2] * dz;
      // r(ξ) for world_from_live · Exp(ξ), ξ = [ω; v] in the live camera frame:
      // dr/dω = p × n_c, dr/dv = n_c.
      store(p[1] * ncz - p[2] * ncy, p[2] * ncx - p[0] * ncz, p[0] * ncy - p[1] * ncx, ncx, ncy,
           ncz, r, HuberWeight(r, huber));
      n_terms += inlier;
      sum_r_sq += inlier ? r * r : 0.0f;
      inliers += inlier;
      if (live_intensity != nullptr) {
        // Photometric residual of this pair: the model's grey level, bilinear at the
        // projected pixel, minus the live one; weighted into metres by photometric_weight.
        const int u0 = static_cast<int>(std::floor(us)), v0 = static_cast<int>(std::floor(vs));
        const bool in_patch =
            inlier & (u0 >= 0) & (v0 >= 0) & (u0 + 1 < cam.width) & (v0 + 1 < cam.height);
        const float* g0 = model_intensity + (in_patch ? size_t(v0) * cam.width + u0 : 0);
        const float* g1 = g0 + cam.width;
        const float i00 = g0[0], i10 = g0[1], i01 = g1[0], i11 = g1[1];
        const float live_i = live_intensity[row + x];
        const bool photometric = in_patch & !std::isnan(i00 + i10 + i01 + i11 + live_i);
        const float fu = us - u0, fv = vs - v0;
        const float model_i =
            (1 - fv) * ((1 - fu) * i00 + fu * i10) + fv * ((1 - fu) * i01 + fu * i11);
        // Gradient of the bilinear patch (per pixel), then d(grey)/d(p_model) through the
        // projection, then into the live camera frame (g_c = (M R)ᵀ g_m): the Jacobian has
        // the geometric one's form with g_c in place of n_c.
        const float gu = (1 - fv) * (i10 - i00) + fv * (i11 - i01);
        const float gv = (1 - fu) * (i01 - i00) + fu * (i11 - i10);
        const float gmx = lambda * gu * cam.fx * inv_z, gmy = lambda * gv * cam.fy * inv_z;
        const float gmz = -(gmx * mx + gmy * my) * inv_z;
        const float gcx = MR[0] * gmx + MR[3] * gmy + MR[6] * gmz;
        const float gcy = MR[1] * gmx + MR[4] * gmy + MR[7] * gmz;
        const float gcz = MR[2] * gmx + MR[5] * gmy + MR[8] * gmz;
        const float ri = lambda * (model_i - live_i);
        store(p[1] * gcz - p[2] * gcy, p[2] * gcx - p[0] * gcz, p[0] * gcy - p[1] * gcx, gcx, gcy,
             gcz, ri, HuberWeight(ri, huber));
        n_terms += photometric;
      }
    }
    terms.size = n_terms;
    SumTerms(terms, sums.ata.data(), sums.atb.data());
    sums.sum_r_sq += double(sum_r_sq);
    sums.inliers += inliers;
    sums.valid += valid;
  }
  return sums;
}

// One association pass over the whole live map, chunks summed in row order.
Sums Accumulate(const Pass& pass, int num_threads) {
  const int chunks = (pass.live->height + kChunkRows - 1) / kChunkRows;
  std::vector<Sums> partial(chunks);
  ForEachBand(chunks, num_threads, [&](int c0, int c1) {
    TermRows terms(2 * pass.live->width);  // a geometric and a photometric term per pixel
    for (int c = c0; c < c1; ++c) {
      partial[c] = AccumulateRows(pass, c * kChunkRows,
                                  std::min(pass.live->height, (c + 1) * kChunkRows), terms);
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

// The Gauss-Newton step -A⁻¹ b restricted to the directions the data constrain: in the
// eigenbasis of A (rotation scaled by the lever), directions whose eigenvalue is below
// largest / max_condition get no update. A flat wall leaves its in-plane motion free; a
// plain solve would slide the estimate along it by whatever the noise says, this keeps the
// prediction there (and the condition check reports the frame).
Vector6d Step(const Matrix6d& A, const Vector6d& b, double max_condition) {
  Vector6d scale;
  scale << Eigen::Vector3d::Constant(1.0 / kConditionLeverM), Eigen::Vector3d::Ones();
  const Matrix6d scaled = scale.asDiagonal() * A * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix6d> solver(scaled);
  const Vector6d& eig = solver.eigenvalues();  // ascending
  if (!(eig(5) > 0)) return Vector6d::Constant(std::numeric_limits<double>::quiet_NaN());
  const Vector6d rhs = solver.eigenvectors().transpose() * (scale.asDiagonal() * -b);
  Vector6d in_eigenbasis = Vector6d::Zero();
  for (int k = 0; k < 6; ++k) {
    if (eig(k) * max_condition >= eig(5)) in_eigenbasis(k) = rhs(k) / eig(k);
  }
  return scale.asDiagonal() * (solver.eigenvectors() * in_eigenbasis);
}

double Condition(const Matrix6d& A) {
  Vector6d scale;
  scale << Eigen::Vector3d::Constant(1.0 / kConditionLeverM), Eigen::Vector3d::Ones();
  const Matrix6d scaled = scale.asDiagonal() * A * scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Matrix6d> solver(scaled, Eigen::EigenvaluesOnly);
  const Vector6d& eig = solver.eigenvalues();  // ascending
  if (!(eig(0) > 0)) return std::numeric_limits<double>::infinity();
  return eig(5) / eig(0);
}

}  // namespace

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
  if (!(max_residual_m > 0)) return Fail("max_residual_m", max_residual_m, "> 0 m");
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
    // Photometric term: needs grey levels on both sides.
    std::vector<float> model_intensity;
    const cv::Mat& live_intensity = live.levels[l].intensity;
    if (options.photometric_weight > 0 && !live_intensity.empty() && !model_map.colours.empty()) {
      assert(live_intensity.isContinuous() && live_intensity.cols == live_map.width);
      model_intensity = GreyOf(model_map);
      pass.live_intensity = live_intensity.ptr<float>();
      pass.model_intensity = model_intensity.data();
      pass.photometric_weight = static_cast<float>(options.photometric_weight);
    }
    for (int it = 0; it < options.iterations[l]; ++it) {
      pass.world_from_live = Affine::Of(estimate);
      const Affine model_from_live = Affine::Of(model_from_world * estimate);
      std::copy(model_from_live.r, model_from_live.r + 9, pass.model_from_live_r);
      last = Accumulate(pass, options.num_threads);
      last_A = NormalMatrix(last);
      ++result.iterations;
      if (last.inliers < 6) break;  // fewer equations than unknowns
      const Vector6d xi =
          Step(last_A, Eigen::Map<const Vector6d>(last.atb.data()), options.max_condition);
      if (!xi.allFinite()) break;
      estimate = estimate * core::Rigid3d::Exp(xi);
      if (xi.head<3>().norm() < options.min_update_rad &&
          xi.tail<3>().norm() < options.min_update_m) {
        break;
      }
    }
  }

  result.world_from_camera = estimate;
  result.inliers = last.inliers;
  result.valid_points = last.valid;
  result.residual_rms_m = last.inliers > 0 ? std::sqrt(last.sum_r_sq / last.inliers) : 0.0;
  result.information = last_A;
  result.condition = last.inliers > 0 ? Condition(last_A) : std::numeric_limits<double>::infinity();
  const core::PoseError jump = core::ComparePoses(initial_world_from_camera, estimate);
  if (last.inliers < options.min_inliers ||
      last.inliers < options.min_inlier_fraction * last.valid) {
    result.status = IcpStatus::kTooFewInliers;
  } else if (!(result.condition <= options.max_condition)) {
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
