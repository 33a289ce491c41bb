#include "reconstruct/rotation_prealign.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numbers>
#include <vector>

#include <Eigen/Cholesky>
#include <opencv2/imgproc.hpp>

#include "core/option_check.h"
#include "reconstruct/row_bands.h"

namespace hw::reconstruct {

namespace {

constexpr double kRadToDeg = 180.0 / std::numbers::pi;
constexpr double kMaxBlurFraction = 0.04;
// A scale's iteration stops after a step turning less than this, rad (0.006°: a 70th of a
// pixel of a 160 px level; ICP refines from there). 1e-5 took 9.5 iterations per frame over
// the three scales of the full-size `equipment` sweep, this 7.3, with the same trajectory.
constexpr double kConvergedRad = 1e-4;

// Grey image blurred over the pixels with depth only (normalised convolution: holes neither
// darken nor brighten their surroundings), and the blurred coverage (1 inside the valid
// region, falling to 0 outside it).
void BlurValid(const PrealignImage& image, double sigma_px, cv::Mat& grey, cv::Mat& coverage) {
  const cv::Mat valid = image.depth_m > 0;
  cv::Mat mask;
  valid.convertTo(mask, CV_32FC1, 1.0 / 255);
  cv::Mat weighted = image.grey.mul(mask);
  if (sigma_px > 0) {
    cv::GaussianBlur(weighted, weighted, cv::Size(), sigma_px, sigma_px, cv::BORDER_REPLICATE);
    cv::GaussianBlur(mask, coverage, cv::Size(), sigma_px, sigma_px, cv::BORDER_REPLICATE);
  } else {
    coverage = mask;
  }
  grey.create(image.grey.size(), CV_32FC1);
  for (int y = 0; y < grey.rows; ++y) {
    const float* w = weighted.ptr<float>(y);
    const float* c = coverage.ptr<float>(y);
    float* g = grey.ptr<float>(y);
    for (int x = 0; x < grey.cols; ++x) g[x] = c[x] > 1e-3f ? w[x] / c[x] : 0.0f;
  }
}


// A pose in float: rotation row-major, translation.
struct PoseF {
  float r[9];
  float t[3];
};

PoseF ToFloat(const Eigen::Matrix3d& rotation, const Eigen::Vector3d& t) {
  PoseF pose;
  for (int i = 0; i < 9; ++i) pose.r[i] = static_cast<float>(rotation(i / 3, i % 3));
  for (int i = 0; i < 3; ++i) pose.t[i] = static_cast<float>(t[i]);
  return pose;
}

// One current point's residual and Jacobian, as internal::PrealignResidual says, in float on
// the packed image (the one implementation: AccumulatePrealign sums it, the tests check it).
[[gnu::always_inline]] inline bool PointTerm(const internal::PrealignImages& previous, const PoseF& pose, float X, float Y, float Z,
                      float grey, float offset, float& residual, float (&jacobian)[4]) {
  const PinholeCamera& pc = previous.camera;
  const float* r = pose.r;
  const float zx = r[0] * X + r[1] * Y + r[2] * Z;
  const float zy = r[3] * X + r[4] * Y + r[5] * Z;
  const float zz = r[6] * X + r[7] * Y + r[8] * Z;
  const float px = zx + pose.t[0], py = zy + pose.t[1], pz = zz + pose.t[2];
  if (!(pz > 1e-3f)) return false;
  const float inv_z = 1.0f / pz;
  const float u = pc.fx * px * inv_z + pc.cx, v = pc.fy * py * inv_z + pc.cy;
  if (!(u >= 1 && v >= 1 && u < static_cast<float>(previous.packed.cols - 2) &&
        v < static_cast<float>(previous.packed.rows - 2))) {
    return false;
  }
  const int x0 = static_cast<int>(u), y0 = static_cast<int>(v);
  const float a = u - static_cast<float>(x0), b = v - static_cast<float>(y0);
  const float* top = previous.packed.ptr<float>(y0) + 4 * x0;
  const float* bottom = previous.packed.ptr<float>(y0 + 1) + 4 * x0;
  float value[4];  // grey, coverage, grad_x, grad_y, bilinear
  for (int k = 0; k < 4; ++k) {
    const float upper = top[k] + a * (top[4 + k] - top[k]);
    const float lower = bottom[k] + a * (bottom[4 + k] - bottom[k]);
    value[k] = upper + b * (lower - upper);
  }
  if (value[1] < 0.5f) return false;  // beside a hole or edge
  residual = value[0] - grey - offset;
  // dr/dp = g_x · d(u)/dp + g_y · d(v)/dp; for p = Exp(ω)·R·X + t, dp/dω = −[R X]×, so
  // dr/dω = (R X) × dr/dp.
  const float gx = value[2] * pc.fx * inv_z, gy = value[3] * pc.fy * inv_z;
  const float gz = -(gx * px + gy * py) * inv_z;
  jacobian[0] = zy * gz - zz * gy;
  jacobian[1] = zz * gx - zx * gz;
  jacobian[2] = zx * gy - zy * gx;
  jacobian[3] = -1.0f;
  return true;
}

}  // namespace

namespace internal {

PrealignImages PreparePrevious(const PrealignImage& previous, double blur_sigma_px) {
  PrealignImages out;
  out.camera = previous.camera;
  cv::Mat grey, coverage;
  const auto cached = std::find_if(previous.blurs.begin(), previous.blurs.end(),
                                   [&](const PrealignBlur& b) { return b.sigma_px == blur_sigma_px; });
  if (cached != previous.blurs.end()) {
    assert(cached->grey.size() == previous.grey.size() && cached->coverage.size() == previous.grey.size());
    grey = cached->grey;
    coverage = cached->coverage;
  } else {
    BlurValid(previous, blur_sigma_px, grey, coverage);
  }
  const int width = grey.cols, height = grey.rows;
  cv::Mat grad_x(height, width, CV_32FC1, cv::Scalar(0)), grad_y(height, width, CV_32FC1, cv::Scalar(0));
  for (int y = 1; y + 1 < height; ++y) {
    const float* row = grey.ptr<float>(y);
    const float* up = grey.ptr<float>(y - 1);
    const float* down = grey.ptr<float>(y + 1);
    float* gx = grad_x.ptr<float>(y);
    float* gy = grad_y.ptr<float>(y);
    for (int x = 1; x + 1 < width; ++x) {
      gx[x] = 0.5f * (row[x + 1] - row[x - 1]);
      gy[x] = 0.5f * (down[x] - up[x]);
    }
  }
  const cv::Mat channels[4] = {grey, coverage, grad_x, grad_y};
  cv::merge(channels, 4, out.packed);
  return out;
}

bool PrealignResidual(const PrealignImages& previous, const Eigen::Matrix3d& rotation, const Eigen::Vector3d& t,
                      const Eigen::Vector3d& point, float grey, double offset, double& residual,
                      Eigen::Vector4d& jacobian) {
  float r = 0, j[4];
  if (!PointTerm(previous, ToFloat(rotation, t), static_cast<float>(point.x()), static_cast<float>(point.y()),
                 static_cast<float>(point.z()), grey, static_cast<float>(offset), r, j)) {
    return false;
  }
  residual = r;
  for (int k = 0; k < 4; ++k) jacobian[k] = j[k];
  return true;
}

PrealignSums AccumulatePrealign(const PrealignImages& previous, const Eigen::Matrix3d& rotation,
                                const Eigen::Vector3d& t, const PrealignPoints& points, double offset,
                                double huber, int num_threads) {
  assert(previous.packed.type() == CV_32FC4);
  assert(points.y.size() == points.size() && points.z.size() == points.size() &&
         points.grey.size() == points.size());
  const PoseF pose = ToFloat(rotation, t);
  const float off = static_cast<float>(offset), hub = static_cast<float>(huber);

  // Float partial sums per chunk (short enough that float keeps ~6 digits of each).
  constexpr int kChunk = 256;
  struct Partial {
    float normal[10] = {}, rhs[4] = {}, sum_wr2 = 0, sum_w = 0;
    int used = 0;
  };
  const int n = static_cast<int>(points.size());
  const int chunks = (n + kChunk - 1) / kChunk;
  std::vector<Partial> partial(chunks);
  ForEachBand(chunks, num_threads, [&](int c0, int c1) {
    for (int c = c0; c < c1; ++c) {
      Partial& s = partial[c];
      const int end = std::min(n, (c + 1) * kChunk);
      for (int i = c * kChunk; i < end; ++i) {
        float res = 0, j[4];
        if (!PointTerm(previous, pose, points.x[i], points.y[i], points.z[i], points.grey[i], off, res, j)) continue;
        const float abs_r = std::abs(res);
        const float w = abs_r <= hub ? 1.0f : hub / abs_r;
        int k = 0;  // unrolled: -O2 keeps these loops otherwise
#pragma GCC unroll 4
        for (int p = 0; p < 4; ++p) {
          const float wj = w * j[p];
#pragma GCC unroll 4
          for (int q = p; q < 4; ++q) s.normal[k++] += wj * j[q];
          s.rhs[p] -= wj * res;
        }
        s.sum_wr2 += w * res * res;
        s.sum_w += w;
        ++s.used;
      }
    }
  });
  PrealignSums total;
  for (const Partial& s : partial) {
    int k = 0;
    for (int p = 0; p < 4; ++p) {
      for (int q = p; q < 4; ++q) total.normal(p, q) += double{s.normal[k++]};
      total.rhs[p] += double{s.rhs[p]};
    }
    total.sum_wr2 += double{s.sum_wr2};
    total.sum_w += double{s.sum_w};
    total.used += s.used;
  }
  total.normal.triangularView<Eigen::StrictlyLower>() = total.normal.transpose();
  return total;
}

double DepthMisfit(const PrealignImage& previous, const PrealignImage& current, const Eigen::Matrix3d& rotation,
                   const Eigen::Vector3d& t, int step) {
  const PinholeCamera& cc = current.camera;
  const PinholeCamera& pc = previous.camera;
  const int width = current.depth_m.cols, height = current.depth_m.rows;
  double sum = 0;
  int n = 0;
  for (int y = 1; y + 1 < height; y += step) {
    const float* depth = current.depth_m.ptr<float>(y);
    for (int x = 1; x + 1 < width; x += step) {
      const float d = depth[x];
      if (!(d > 0) || !std::isfinite(d)) continue;
      const Eigen::Vector3d point(double{d} * (x - double{cc.cx}) / double{cc.fx},
                                  double{d} * (y - double{cc.cy}) / double{cc.fy}, double{d});
      const Eigen::Vector3d p = rotation * point + t;
      if (!(p.z() > 1e-3)) continue;
      const double u = double{pc.fx} * p.x() / p.z() + double{pc.cx}, v = double{pc.fy} * p.y() / p.z() + double{pc.cy};
      if (!(u > -0.5 && v > -0.5 && u < previous.depth_m.cols - 0.5 && v < previous.depth_m.rows - 0.5)) continue;
      const float z_previous =
          previous.depth_m.at<float>(static_cast<int>(std::lround(v)), static_cast<int>(std::lround(u)));
      if (!(z_previous > 0) || !std::isfinite(z_previous)) continue;
      sum += std::min(std::abs(double{z_previous} - p.z()), kDepthMisfitCapM);
      ++n;
    }
  }
  return n > 0 ? sum / n : 0.0;
}

}  // namespace internal

std::string RotationPrealignOptions::Check() const {
  using core::InRange;
  using core::OptionFail;
  if (iterations < 0 || iterations > 50) return OptionFail("iterations", iterations, "in [0, 50]");
  if (!InRange(blur_sigma_px, 0, 5)) return OptionFail("blur_sigma_px", blur_sigma_px, "in [0, 5] px");
  if (!(max_rotation_deg > 0 && max_rotation_deg <= 90)) {
    return OptionFail("max_rotation_deg", max_rotation_deg, "in (0, 90] degrees");
  }
  if (!(min_correction_deg >= 0 && min_correction_deg < max_rotation_deg)) {
    return OptionFail("min_correction_deg", min_correction_deg, "in [0, max_rotation_deg) degrees");
  }
  if (!(huber > 0 && huber <= 1)) return OptionFail("huber", huber, "in (0, 1] grey levels");
  if (min_pixels < 10) return OptionFail("min_pixels", min_pixels, ">= 10");
  if (scales < 1 || scales > 4) return OptionFail("scales", scales, "in [1, 4]");
  if (!(max_depth_misfit_ratio == 0 || (max_depth_misfit_ratio >= 1 && std::isfinite(max_depth_misfit_ratio)))) {
    return OptionFail("max_depth_misfit_ratio", max_depth_misfit_ratio, "0 (off) or finite and >= 1");
  }
  if (num_threads < 0) return OptionFail("num_threads", num_threads, ">= 0 (0: all cores)");
  return "";
}

RotationPrealignResult PrealignRotation(const PrealignImage& previous, const PrealignImage& current,
                                        const Eigen::Quaterniond& guess_rotation,
                                        const Eigen::Vector3d& guess_translation_m,
                                        const RotationPrealignOptions& options,
                                        std::vector<PrealignBlur>* current_blurs) {
  assert(previous.grey.type() == CV_32FC1 && current.grey.type() == CV_32FC1);
  assert(previous.grey.size() == current.grey.size() && previous.depth_m.size() == previous.grey.size() &&
         current.depth_m.size() == current.grey.size());
  RotationPrealignResult result;
  result.previous_from_current = guess_rotation.normalized();
  if (current_blurs != nullptr) current_blurs->clear();
  if (!options.enabled()) return result;
  const int width = previous.grey.cols, height = previous.grey.rows;
  if (width < 4 || height < 4) return result;

  // Coarse to fine in scale space: each scale doubles the blur of the next finer one. A
  // brick wall's courses repeat every few pixels at this level, so a turn of several degrees
  // beyond the prediction (a swing across a dropped frame: 4° measured) aligns the finest
  // scale's images one course off; at the coarsest scale only the larger structures remain.
  const PinholeCamera& cam = current.camera;
  const int base_step = width >= 120 ? 2 : 1;
  Eigen::Matrix3d rotation = result.previous_from_current.toRotationMatrix();
  const Eigen::Vector3d& t = guess_translation_m;
  double offset = 0;  // brightness: I_prev − I_cur
  const double huber = options.huber;
  // The coarsest blur kept within kMaxBlurFraction of the image width: beyond that too few
  // structures are left to align (an 80 px level gets two scales, a 160 px one three).
  int scales = options.scales;
  while (scales > 1 && options.blur_sigma_px * std::ldexp(1.0, scales - 1) > kMaxBlurFraction * width) --scales;
  for (int scale = scales - 1; scale >= 0; --scale) {
    const double sigma_px = options.blur_sigma_px * std::ldexp(1.0, scale);
    const internal::PrealignImages images = internal::PreparePrevious(previous, sigma_px);
    cv::Mat cur_grey, cur_coverage;
    BlurValid(current, sigma_px, cur_grey, cur_coverage);
    if (current_blurs != nullptr) current_blurs->push_back({sigma_px, cur_grey, cur_coverage});

    // The current frame's samples: camera-frame points and their grey levels. Every second
    // pixel (the blur has removed what lies between) where the image is large enough, every
    // fourth at a blur of 4× the finest.
    const int step = base_step << std::max(0, scale - 1);
    internal::PrealignPoints points;
    for (int y = 1; y + 1 < height; y += step) {
      const float* depth = current.depth_m.ptr<float>(y);
      const float* g = cur_grey.ptr<float>(y);
      for (int x = 1; x + 1 < width; x += step) {
        const float d = depth[x];
        if (!(d > 0) || !std::isfinite(d)) continue;
        points.x.push_back(d * (static_cast<float>(x) - cam.cx) / cam.fx);
        points.y.push_back(d * (static_cast<float>(y) - cam.cy) / cam.fy);
        points.z.push_back(d);
        points.grey.push_back(g[x]);
      }
    }
    // A coarser scale is only a start: one with too few samples (every fourth pixel of a
    // frame with holes) or that fails is skipped, the finest decides.
    if (static_cast<int>(points.size()) < options.min_pixels) {
      if (scale > 0) continue;
      return result;
    }

    // The robust RMS and normal equations at a rotation and offset; false with too few pairs.
    Eigen::Matrix4d normal;
    Eigen::Vector4d rhs;
    double rms = 0;
    const auto evaluate = [&](const Eigen::Matrix3d& r_eval, double offset_eval) {
      const internal::PrealignSums sums =
          internal::AccumulatePrealign(images, r_eval, t, points, offset_eval, huber, options.num_threads);
      normal = sums.normal;
      rhs = sums.rhs;
      result.pixels = sums.used;
      rms = sums.used > 0 ? std::sqrt(sums.sum_wr2 / sums.sum_w) : 0.0;
      return sums.used >= options.min_pixels;
    };
    // Accepted or not by the finest scale's residual at the guess (no offset) and at the end.
    if (scale == 0) {
      if (!evaluate(result.previous_from_current.toRotationMatrix(), 0.0)) return result;
      result.rms_before = rms;
    }
    const Eigen::Matrix3d start_rotation = rotation;
    const double start_offset = offset;
    bool converged = false;
    bool failed = false;
    for (int iteration = 0;; ++iteration) {
      if (!evaluate(rotation, offset)) {
        failed = true;
        break;
      }
      result.rms_after = rms;  // at the rotation reached so far
      if (converged || iteration == options.iterations) break;
      const Eigen::Vector4d delta = normal.ldlt().solve(rhs);
      if (!delta.allFinite()) {
        failed = true;
        break;
      }
      const Eigen::Vector3d omega = delta.head<3>();
      if (omega.norm() > 0) rotation = Eigen::AngleAxisd(omega.norm(), omega.normalized()).toRotationMatrix() * rotation;
      offset += delta[3];
      ++result.iterations;
      converged = omega.norm() < kConvergedRad;  // one more pass evaluates the residual there
    }
    if (failed) {
      if (scale == 0) return result;
      // Back to where this scale started: its run led somewhere the samples do not cover.
      rotation = start_rotation;
      offset = start_offset;
    }
  }
  const Eigen::Quaterniond estimate(rotation);
  result.correction_deg = estimate.angularDistance(result.previous_from_current) * kRadToDeg;
  result.ok = result.rms_after < result.rms_before && result.correction_deg >= options.min_correction_deg &&
              result.correction_deg <= options.max_rotation_deg;
  // The depth's say (max_depth_misfit_ratio): the same points, at the guess and at the end.
  if (result.ok && options.max_depth_misfit_ratio > 0) {
    result.depth_misfit_before_m =
        internal::DepthMisfit(previous, current, result.previous_from_current.toRotationMatrix(), t, base_step);
    result.depth_misfit_after_m = internal::DepthMisfit(previous, current, rotation, t, base_step);
    if (!(result.depth_misfit_after_m <= options.max_depth_misfit_ratio * result.depth_misfit_before_m)) {
      result.ok = false;
      result.rejected_by_depth = true;
    }
  }
  if (result.ok) result.previous_from_current = estimate.normalized();
  return result;
}

}  // namespace hw::reconstruct
