#include "reconstruct/dynamic_mask.h"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cmath>
#include <limits>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "reconstruct/option_check.h"
#include "reconstruct/row_bands.h"

namespace hw::reconstruct {
std::string DynamicMaskOptions::Check() const {
  if (!(margin_m >= 0) || !std::isfinite(margin_m)) return internal::Fail("margin_m", margin_m, ">= 0 m");
  if (!(margin_fraction >= 0 && margin_fraction < 1)) {
    return internal::Fail("margin_fraction", margin_fraction, "in [0, 1)");
  }
  return "";
}

int MaskInFrontOfModel(cv::Mat& depth_m, const PinholeCamera& camera, const core::Rigid3d& world_from_depth,
                       const PointMap& model, const PinholeCamera& model_camera,
                       const core::Rigid3d& world_from_model, const DynamicMaskOptions& options,
                       int num_threads) {
  assert(options.Check().empty());
  assert(depth_m.type() == CV_32FC1 && depth_m.cols == camera.width && depth_m.rows == camera.height);
  assert(model.width == model_camera.width && model.height == model_camera.height);
  if (!options.enabled() || model.points.empty()) return 0;
  // Depth camera → model camera, and world → model camera for the model's points.
  const core::Rigid3d model_from_world = world_from_model.Inverse();
  const core::Rigid3d model_from_depth = model_from_world * world_from_depth;
  const Eigen::Matrix3f rotation = model_from_depth.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f translation = model_from_depth.translation.cast<float>();
  const Eigen::Matrix3f model_rotation = model_from_world.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f model_translation = model_from_world.translation.cast<float>();
  const float margin_m = static_cast<float>(options.margin_m);
  const float margin_fraction = static_cast<float>(options.margin_fraction);
  // The model's depth along its own camera axis per pixel, NaN without a surface.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<float> model_z(model.points.size());
  ForEachBand(model.height, num_threads, [&](int begin, int end) {
    for (size_t i = model.Index(0, begin); i < model.Index(0, end); ++i) {
      model_z[i] = IsValid(model.points[i]) ? (model_rotation * model.points[i] + model_translation).z() : nan;
    }
  });
  // The nearest model surface over the 3×3 model pixels around each: a point on an object's
  // rim that projects a pixel off onto the background behind it is not in front of the
  // object, and masking rims would erode every silhouette a little more each frame (the rim
  // never integrated, the model's silhouette shrinking). A neighbour without a surface
  // (unseen, or the image border) keeps the point: nothing says it moved in (NaN). Once per
  // model pixel, not per depth pixel (four of them per model pixel at the default level).
  std::vector<float> nearest(model.points.size(), nan);
  ForEachBand(model.height, num_threads, [&](int begin, int end) {
    for (int v = std::max(begin, 1); v < std::min(end, model.height - 1); ++v) {
      for (int u = 1; u + 1 < model.width; ++u) {
        float nearest_z = std::numeric_limits<float>::infinity();
        bool all_seen = true;
        for (int dv = -1; dv <= 1 && all_seen; ++dv) {
          for (int du = -1; du <= 1; ++du) {
            const float mz = model_z[model.Index(u + du, v + dv)];
            if (!(mz > 0)) {
              all_seen = false;
              break;
            }
            nearest_z = std::min(nearest_z, mz);
          }
        }
        if (all_seen) nearest[model.Index(u, v)] = nearest_z;
      }
    }
  });
  std::atomic<int> masked{0};
  ForEachBand(depth_m.rows, num_threads, [&](int begin, int end) {
    int count = 0;
    for (int y = begin; y < end; ++y) {
      float* row = depth_m.ptr<float>(y);
      for (int x = 0; x < depth_m.cols; ++x) {
        const float z = row[x];
        if (!(z > 0)) continue;
        const Eigen::Vector3f p = rotation * camera.Unproject(static_cast<float>(x), static_cast<float>(y), z) + translation;
        if (p.z() <= 1e-3f) continue;
        const Eigen::Vector2f uv = model_camera.Project(p);
        int u, v;
        if (!internal::RoundedIndex(uv.x(), 0, model.width, u) || !internal::RoundedIndex(uv.y(), 0, model.height, v)) {
          continue;
        }
        const float nearest_z = nearest[model.Index(u, v)];  // NaN fails the test below
        // Both along the model camera's axis: the point lies on (nearly) the ray of (u, v).
        if (p.z() < nearest_z - std::max(margin_m, margin_fraction * z)) {
          row[x] = 0;
          ++count;
        }
      }
    }
    masked += count;
  });
  return masked.load();
}

std::vector<Eigen::Vector3f> ModelSeenThrough(const cv::Mat& depth_m, const PinholeCamera& camera,
                                              const core::Rigid3d& world_from_depth, const PointMap& model,
                                              const DynamicMaskOptions& options, int num_threads) {
  assert(options.Check().empty());
  assert(depth_m.type() == CV_32FC1 && depth_m.cols == camera.width && depth_m.rows == camera.height);
  std::vector<Eigen::Vector3f> seen_through;
  if (!options.enabled() || model.points.empty()) return seen_through;
  const core::Rigid3d depth_from_world = world_from_depth.Inverse();
  const Eigen::Matrix3f rotation = depth_from_world.rotation.toRotationMatrix().cast<float>();
  const Eigen::Vector3f translation = depth_from_world.translation.cast<float>();
  const float margin_m = static_cast<float>(options.margin_m);
  const float margin_fraction = static_cast<float>(options.margin_fraction);
  std::vector<std::vector<Eigen::Vector3f>> parts(model.height);  // per model row: in row order
  ForEachBand(model.height, num_threads, [&](int begin, int end) {
    for (int v = begin; v < end; ++v) {
      std::vector<Eigen::Vector3f>& part = parts[v];
      for (int u = 0; u < model.width; ++u) {
        const Eigen::Vector3f& point = model.points[model.Index(u, v)];
        if (!IsValid(point)) continue;
        const Eigen::Vector3f p = rotation * point + translation;
        if (p.z() <= 1e-3f) continue;
        const Eigen::Vector2f xy = camera.Project(p);
        int x, y;
        if (!internal::RoundedIndex(xy.x(), 1, camera.width - 1, x) || !internal::RoundedIndex(xy.y(), 1, camera.height - 1, y)) {
          continue;
        }
        bool through = true;
        for (int dy = -1; dy <= 1 && through; ++dy) {
          const float* row = depth_m.ptr<float>(y + dy);
          for (int dx = -1; dx <= 1; ++dx) {
            const float z = row[x + dx];
            if (!(z > 0) || !(z > p.z() + std::max(margin_m, margin_fraction * z))) {
              through = false;
              break;
            }
          }
        }
        if (through) part.push_back(point);
      }
    }
  });
  for (const auto& part : parts) seen_through.insert(seen_through.end(), part.begin(), part.end());
  return seen_through;
}

double ModelConflict::Fraction() const {
  return (depth_pixels > 0 ? static_cast<double>(in_front) / depth_pixels : 0.0) +
         (model_points > 0 ? static_cast<double>(seen_through) / model_points : 0.0);
}

ModelConflict MeasureModelConflict(const cv::Mat& depth_m, const PinholeCamera& camera,
                                   const core::Rigid3d& world_from_depth, const PointMap& model,
                                   const PinholeCamera& model_camera, const core::Rigid3d& world_from_model,
                                   const DynamicMaskOptions& options, int num_threads) {
  ModelConflict c;
  c.depth_pixels = cv::countNonZero(depth_m > 0);
  c.model_points = model.NumValid();
  if (!options.enabled()) return c;
  cv::Mat masked = depth_m.clone();
  c.in_front = MaskInFrontOfModel(masked, camera, world_from_depth, model, model_camera, world_from_model, options,
                                  num_threads);
  c.seen_through =
      static_cast<int>(ModelSeenThrough(depth_m, camera, world_from_depth, model, options, num_threads).size());
  return c;
}

}  // namespace hw::reconstruct
