#include "reconstruct/keyframes.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <numeric>
#include <numbers>

#include <opencv2/imgproc.hpp>

#include "reconstruct/option_check.h"

namespace hw::reconstruct {

using internal::Fail;
using internal::InRange;

namespace {

// Below this fraction of a descriptor pixel's (kernel-weighted) neighbourhood with depth,
// the pixel has none: an eighth keeps the rims of surfaces and the image border (where up to
// half the kernel lies outside), not specks of a few source pixels.
constexpr float kMinValidWeight = 0.125f;
// Scales of the two terms: 0.1 m of depth (a few centimetres of viewpoint change at 1–2 m
// moves a blurred pixel's depth by less), 1 deviation of grey.
constexpr float kDepthScaleM = 0.1f, kGreyScale = 1.0f;

}  // namespace

std::string KeyframeOptions::Check() const {
  if (candidates < 0 || candidates > 10) return Fail("candidates", candidates, "in [0, 10]");
  if (!(min_distance_m > 0) || !std::isfinite(min_distance_m)) {
    return Fail("min_distance_m", min_distance_m, "> 0 m and finite");
  }
  if (!(min_angle_deg > 0) || !std::isfinite(min_angle_deg)) {
    return Fail("min_angle_deg", min_angle_deg, "> 0 degrees and finite");
  }
  if (descriptor_width < 8 || descriptor_width > 160) {
    return Fail("descriptor_width", descriptor_width, "in [8, 160] px");
  }
  if (!(max_distance > 0 && max_distance <= 1)) return Fail("max_distance", max_distance, "in (0, 1]");
  return "";
}

KeyframeDescriptor DescribeFrame(const cv::Mat& depth_m, const cv::Mat& grey, int width) {
  assert(depth_m.type() == CV_32FC1 && width > 0);
  assert(grey.empty() || (grey.type() == CV_32FC1 && grey.size() == depth_m.size()));
  const int out_w = std::min(width, depth_m.cols);
  const int out_h = std::max(1, static_cast<int>(std::lround(static_cast<double>(depth_m.rows) * out_w / depth_m.cols)));
  // Block sums over valid pixels: depth, grey, and the fraction of the block with depth.
  cv::Mat depth_sum(out_h, out_w, CV_32FC1, cv::Scalar(0)), grey_sum(out_h, out_w, CV_32FC1, cv::Scalar(0)),
      weight(out_h, out_w, CV_32FC1, cv::Scalar(0));
  for (int y = 0; y < out_h; ++y) {
    const int y0 = y * depth_m.rows / out_h, y1 = (y + 1) * depth_m.rows / out_h;
    for (int x = 0; x < out_w; ++x) {
      const int x0 = x * depth_m.cols / out_w, x1 = (x + 1) * depth_m.cols / out_w;
      float d = 0, g = 0;
      int n = 0;
      for (int v = y0; v < y1; ++v) {
        const float* row = depth_m.ptr<float>(v);
        const float* grey_row = grey.empty() ? nullptr : grey.ptr<float>(v);
        for (int u = x0; u < x1; ++u) {
          if (!(row[u] > 0) || !std::isfinite(row[u])) continue;
          d += row[u];
          if (grey_row) g += grey_row[u];
          ++n;
        }
      }
      if (n == 0) continue;
      const float area = static_cast<float>((y1 - y0) * (x1 - x0));
      weight.at<float>(y, x) = n / area;
      depth_sum.at<float>(y, x) = d / area;  // = mean depth × weight
      grey_sum.at<float>(y, x) = g / area;
    }
  }
  // The blur, normalised by the weight around: a hole's rim keeps its depth.
  const auto blur = [](const cv::Mat& in) {
    cv::Mat out;
    cv::GaussianBlur(in, out, cv::Size(5, 5), 1.0, 1.0, cv::BORDER_CONSTANT);
    return out;
  };
  const cv::Mat w = blur(weight), d = blur(depth_sum), g = blur(grey_sum);
  KeyframeDescriptor out;
  out.width = out_w;
  out.height = out_h;
  out.depth_m.assign(static_cast<size_t>(out_w) * out_h, 0.0f);
  if (!grey.empty()) out.grey.assign(out.depth_m.size(), 0.0f);
  double grey_mean = 0, grey_square = 0;
  int valid = 0;
  for (int y = 0; y < out_h; ++y) {
    for (int x = 0; x < out_w; ++x) {
      const float wi = w.at<float>(y, x);
      if (wi < kMinValidWeight) continue;
      const size_t i = static_cast<size_t>(y) * out_w + x;
      out.depth_m[i] = d.at<float>(y, x) / wi;
      if (!out.grey.empty()) {
        out.grey[i] = g.at<float>(y, x) / wi;
        const double grey_i = out.grey[i];
        grey_mean += grey_i;
        grey_square += grey_i * grey_i;
      }
      ++valid;
    }
  }
  if (!out.grey.empty()) {
    if (valid == 0) {
      out.grey.clear();
    } else {
      grey_mean /= valid;
      const double deviation = std::sqrt(std::max(0.0, grey_square / valid - grey_mean * grey_mean));
      // A uniform image has no texture to compare: its grey says nothing.
      if (deviation < 1e-3) {
        out.grey.clear();
      } else {
        for (size_t i = 0; i < out.grey.size(); ++i) {
          out.grey[i] = out.depth_m[i] > 0 ? static_cast<float>((static_cast<double>(out.grey[i]) - grey_mean) / deviation) : 0.0f;
        }
      }
    }
  }
  return out;
}

double KeyframeDistance(const KeyframeDescriptor& a, const KeyframeDescriptor& b) {
  assert(a.width == b.width && a.height == b.height);
  const bool with_grey = !a.grey.empty() && !b.grey.empty();
  double sum = 0;
  int both = 0, one = 0;
  for (size_t i = 0; i < a.depth_m.size(); ++i) {
    const bool in_a = a.depth_m[i] > 0, in_b = b.depth_m[i] > 0;
    if (in_a != in_b) ++one;
    if (!in_a || !in_b) continue;
    ++both;
    const float ed = std::min(std::abs(a.depth_m[i] - b.depth_m[i]) / kDepthScaleM, 1.0f);
    float e = ed * ed;
    if (with_grey) {
      const float eg = std::min(std::abs(a.grey[i] - b.grey[i]) / kGreyScale, 1.0f);
      e = 0.5f * (e + eg * eg);
    }
    sum += static_cast<double>(e);
  }
  if (both < static_cast<int>(a.depth_m.size()) / 4) return 1.0;
  return (sum + 0.5 * 0.5 * one) / (both + 0.5 * one);
}

bool KeyframeDatabase::SamePlace(const core::Rigid3d& a, const core::Rigid3d& b) const {
  const core::PoseError e = core::ComparePoses(a, b);
  return e.translation_m <= options_.min_distance_m && e.rotation_rad <= options_.min_angle_deg * std::numbers::pi / 180;
}

bool KeyframeDatabase::IsNewPlace(const core::Rigid3d& world_from_depth) const {
  return std::none_of(poses_.begin(), poses_.end(),
                      [&](const core::Rigid3d& pose) { return SamePlace(pose, world_from_depth); });
}

void KeyframeDatabase::Add(const core::Rigid3d& world_from_depth, KeyframeDescriptor descriptor) {
  assert(descriptors_.empty() || (descriptor.width == descriptors_.front().width &&
                                  descriptor.height == descriptors_.front().height));
  poses_.push_back(world_from_depth);
  descriptors_.push_back(std::move(descriptor));
}

std::vector<int> KeyframeDatabase::MostAlike(const KeyframeDescriptor& query, int count) const {
  std::vector<std::pair<double, int>> scored;
  for (int i = 0; i < size(); ++i) {
    const double d = KeyframeDistance(query, descriptors_[i]);
    if (d <= options_.max_distance) scored.emplace_back(d, i);
  }
  std::sort(scored.begin(), scored.end());
  std::vector<int> out;
  for (int i = 0; i < std::min<int>(count, scored.size()); ++i) out.push_back(scored[i].second);
  return out;
}

}  // namespace hw::reconstruct
