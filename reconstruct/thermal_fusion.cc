#include "reconstruct/thermal_fusion.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstring>
#include <future>
#include <limits>
#include <memory>
#include <stdexcept>

#include <Eigen/Geometry>

#include "core/option_check.h"
#include "core/strings.h"
#include "reconstruct/elapsed.h"
#include "reconstruct/thermal_fusion_impl.h"
#include "reconstruct/tsdf_volume_impl.h"

namespace hw::reconstruct {

std::string ThermalFusionOptions::Check() const {
  using core::OptionFail;
  using core::InRange;
  if (std::string e = confidence.Check(); !e.empty()) return "confidence." + e;
  if (std::string e = offline.Check(); !e.empty()) return "offline." + e;
  if (std::string e = scene_correction.Check(); !e.empty()) return "scene_correction." + e;
  if (std::string e = reflections.Check(); !e.empty()) return "reflections." + e;
  if (!InRange(recency_bias, 0, 1)) return OptionFail("recency_bias", recency_bias, "in [0, 1]");
  if (!(capped_mean_max_weight >= 1) || !std::isfinite(capped_mean_max_weight)) {
    return OptionFail("capped_mean_max_weight", capped_mean_max_weight, "finite and >= 1");
  }
  if (!(min_ray_confidence >= 0 && min_ray_confidence < 1)) {
    return OptionFail("min_ray_confidence", min_ray_confidence, "in [0, 1)");
  }
  if (!(max_pose_gap_s > 0) || !std::isfinite(max_pose_gap_s)) {
    return OptionFail("max_pose_gap_s", max_pose_gap_s, "finite and > 0 s");
  }
  if (!(min_depth_m >= 0) || !std::isfinite(min_depth_m)) return OptionFail("min_depth_m", min_depth_m, ">= 0 m");
  if (!(max_depth_m > min_depth_m) || !std::isfinite(max_depth_m)) {
    return OptionFail("max_depth_m", max_depth_m, "finite and > min_depth_m");
  }
  if (!(vignetting >= 0 && vignetting < 1)) return OptionFail("vignetting", vignetting, "in [0, 1)");
  if (!(edge_radius_px >= 0 && edge_radius_px <= 10)) return OptionFail("edge_radius_px", edge_radius_px, "in [0, 10]");
  if (!(occlusion_margin_m >= 0) || !std::isfinite(occlusion_margin_m)) {
    return OptionFail("occlusion_margin_m", occlusion_margin_m, ">= 0 m");
  }
  if (!(occlusion_margin_fraction >= 0 && occlusion_margin_fraction < 1)) {
    return OptionFail("occlusion_margin_fraction", occlusion_margin_fraction, "in [0, 1)");
  }
  if (max_views_per_region < 0) return OptionFail("max_views_per_region", max_views_per_region, ">= 0");
  if (!InRange(frame_interval_s, 0, 1)) return OptionFail("frame_interval_s", frame_interval_s, "in [0, 1] s");
  if (num_threads < 0) return OptionFail("num_threads", num_threads, ">= 0");
  return "";
}

std::string ThermalFrameStatusName(ThermalFrameStatus status) {
  switch (status) {
    case ThermalFrameStatus::kFused: return "fused";
    case ThermalFrameStatus::kNoPose: return "no-pose";
    case ThermalFrameStatus::kFrozen: return "frozen";
    case ThermalFrameStatus::kNoSurface: return "no-surface";
    case ThermalFrameStatus::kSkipped: return "skipped";
    case ThermalFrameStatus::kHeld: return "held";
  }
  return "?";
}


void ThermalFusion::Impl::WarpLiveDepth(const core::Rigid3d& world_from_thermal, std::span<const LiveDepth> live) {
  live_range.clear();
  // Without the occlusion test nothing reads it (the raycast's hints take their window from
  // the test's margin).
  if (live.empty() || (options.occlusion_margin_m <= 0 && options.occlusion_margin_fraction <= 0)) return;
  const int width = rays.width(), height = rays.height();
  const int num_threads = std::min(ResolveThreads(options.num_threads), height);
  // Every depth pixel's point, through the thermal lens model, the nearest range per thermal
  // pixel — so that what stood on the thermal camera's own line of sight is found (the depth
  // camera, 5 cm away, sees past an occluder's side that the thermal camera's ray meets).
  if (depth_rays.empty()) {  // each depth pixel's ray (z = 1), NaN where the lens model has none
    const core::CameraModel& d = rig.depth;
    depth_rays.resize(size_t(d.width) * d.height);
    for (int y = 0; y < d.height; ++y) {
      for (int x = 0; x < d.width; ++x) {
        const std::optional<Eigen::Vector3d> ray = d.Unproject(Eigen::Vector2d(x, y));
        depth_rays[size_t(y) * d.width + x] = ray ? Eigen::Vector3f(ray->cast<float>()) : Eigen::Vector3f::Constant(kNaN);
      }
    }
  }
  const core::Rigid3d thermal_from_world_pose = world_from_thermal.Inverse();
  std::vector<std::vector<float>>& buffers = live_range_scratch;
  buffers.resize(num_threads);
  for (auto& b : buffers) b.assign(size_t(width) * height, std::numeric_limits<float>::infinity());
  const core::CameraModel& thermal_camera = *rig.thermal;
  // Every step-th depth pixel along both axes: about one per thermal pixel (a 640×480
  // depth image over a 320×240 thermal one: every second), a quarter of the work (the
  // warp of every pixel took 16–18 ms of a thermal frame's 80); a thermal pixel no depth
  // point lands on is covered by the occlusion test's dilation (ShadeRays), and its ray is
  // cast without a hint.
  const int step = std::max(1, rig.depth.width / std::max(1, width));
  for (const LiveDepth& d : live) {
    const core::Rigid3d thermal_from_depth = thermal_from_world_pose * d.world_from_depth;
    const Eigen::Matrix3f rotation = thermal_from_depth.rotation.toRotationMatrix().cast<float>();
    const Eigen::Vector3f translation = thermal_from_depth.translation.cast<float>();
    const int rows = d.depth_m.rows, cols = d.depth_m.cols;
    internal::RunChunks(num_threads, [&](int chunk) {
      std::vector<float>& buffer = buffers[chunk];
      const int band_rows = (rows + step - 1) / step;
      for (int yb = chunk * band_rows / num_threads; yb < (chunk + 1) * band_rows / num_threads; ++yb) {
        const int y = yb * step;
        const float* row = d.depth_m.ptr<float>(y);
        for (int x = 0; x < cols; x += step) {
          const float z = row[x];
          if (!(z > 0)) continue;
          const Eigen::Vector3f& ray = depth_rays[size_t(y) * cols + x];
          if (!IsValid(ray)) continue;
          const Eigen::Vector3f p = rotation * (z * ray) + translation;
          if (p.z() <= 1e-3f) continue;
          const Eigen::Vector2d uv = thermal_camera.Project(p.cast<double>());
          const int u = static_cast<int>(std::lround(uv.x())), v = static_cast<int>(std::lround(uv.y()));
          if (u < 0 || v < 0 || u >= width || v >= height) continue;
          float& nearest = buffer[size_t(v) * width + u];
          nearest = std::min(nearest, p.norm());
        }
      }
    });
  }
  live_range.assign(buffers[0].begin(), buffers[0].end());
  for (size_t b = 1; b < buffers.size(); ++b) {
    for (size_t i = 0; i < live_range.size(); ++i) live_range[i] = std::min(live_range[i], buffers[b][i]);
  }
}

std::vector<Ray>& ThermalFusion::Impl::ShadeRays(const PointMap& map, const std::vector<PixelReflection>& reflections,
                                                       const cv::Mat& apparent_c,
                                                       const core::Rigid3d& world_from_thermal,
                                                       const Eigen::Vector3d& linear_velocity_mps,
                                                       const Eigen::Vector3d& angular_velocity_radps, double operating,
                                                       ThermalFrameRecord& record) {
  const int width = map.width, height = map.height;
  const int num_threads = std::min(ResolveThreads(options.num_threads), height);
  std::vector<ShadePart>& parts = shade_scratch;
  parts.resize(num_threads);
  for (ShadePart& part : parts) part.Clear();
  const Eigen::Matrix3d thermal_from_world = world_from_thermal.rotation.conjugate().toRotationMatrix();
  const Eigen::Vector3d origin = world_from_thermal.translation;
  const double fx = rig.thermal->fx, fy = rig.thermal->fy;
  const ThermalConfidenceOptions& co = options.confidence;
  // Each pixel's range to its hit (NaN: none, or no ray through the lens), for the depth-edge
  // test, which reads the neighbouring rows too: a pass of its own.
  std::vector<float>& range = range_scratch;
  range.resize(size_t(width) * height);
  internal::RunChunks(num_threads, [&](int chunk) {
    for (int y = chunk * height / num_threads; y < (chunk + 1) * height / num_threads; ++y) {
      for (int x = 0; x < width; ++x) {
        const size_t i = map.Index(x, y);
        range[i] = IsValid(map.points[i]) ? (map.points[i] - origin.cast<float>()).norm() : kNaN;
      }
    }
  });
  const int edge_radius = options.edge_radius_px;
  const float tan_max_angle = static_cast<float>(std::tan(options.confidence.max_angle_deg * M_PI / 180));
  // True when a pixel within edge_radius of (x, y) that has a ray through the lens met the
  // model farther from range r than a surface at the largest angle fused could (r·α·tan θ,
  // α the rays' angle: the pixel's angular size times their distance in pixels), or not at
  // all. Pixels beyond the image or without a ray are no edge: the border is no silhouette.
  // The neighbours' distances in pixels, once per frame rather than per pixel and neighbour.
  const int window = 2 * edge_radius + 1;
  std::vector<float> offset_px(size_t(window) * window);
  for (int dv = -edge_radius; dv <= edge_radius; ++dv) {
    for (int du = -edge_radius; du <= edge_radius; ++du) {
      offset_px[size_t(dv + edge_radius) * window + (du + edge_radius)] =
          std::hypot(static_cast<float>(du), static_cast<float>(dv));
    }
  }
  auto near_depth_edge = [&](int x, int y, float r) {
    const float per_px = r * pixel_angle_rad[map.Index(x, y)] * tan_max_angle;
    for (int v = std::max(0, y - edge_radius); v <= std::min(height - 1, y + edge_radius); ++v) {
      const float* offsets = &offset_px[size_t(v - y + edge_radius) * window];
      for (int u = std::max(0, x - edge_radius); u <= std::min(width - 1, x + edge_radius); ++u) {
        if (!rays.valid(u, v)) continue;
        const float other = range[map.Index(u, v)];
        if (!(std::abs(other - r) <= per_px * offsets[u - x + edge_radius])) return true;  // NaN: no hit
      }
    }
    return false;
  };
  // The occlusion test (WarpLiveDepth has the live depth frames, the fused depth frames
  // around the thermal frame's time, warped into this view): a hit whose model range lies
  // behind the live range by more than max(margin, fraction · live range) was occluded; a
  // ray is then rejected when a pixel within max(edge_radius_px, 1) of it is occluded: the
  // occluder's edge moves between the depth and thermal exposures (a walker 2 cm in 17 ms)
  // and the optics and lag spread it by a pixel (the silhouette rule's reasons).
  const bool occlusion_test = !live_range.empty();  // WarpLiveDepth fills it only for the test
  std::vector<uint8_t>& occluded_flag = occluded_scratch;
  if (occlusion_test) {
    const float margin_m = static_cast<float>(options.occlusion_margin_m);
    const float fraction = static_cast<float>(options.occlusion_margin_fraction);
    occluded_flag.assign(size_t(width) * height, 0);
    for (size_t i = 0; i < occluded_flag.size(); ++i) {
      const float r = range[i], live = live_range[i];
      occluded_flag[i] = std::isfinite(r) && std::isfinite(live) && live < r - std::max(margin_m, fraction * live);
    }
  }
  const int occlusion_radius = std::max(edge_radius, 1);
  auto near_occluded = [&](int x, int y) {
    for (int v = std::max(0, y - occlusion_radius); v <= std::min(height - 1, y + occlusion_radius); ++v) {
      for (int u = std::max(0, x - occlusion_radius); u <= std::min(width - 1, x + occlusion_radius); ++u) {
        if (occluded_flag[map.Index(u, v)]) return true;
      }
    }
    return false;
  };
  internal::RunChunks(num_threads, [&](int chunk) {
    ShadePart& part = parts[chunk];
    for (int y = chunk * height / num_threads; y < (chunk + 1) * height / num_threads; ++y) {
      const float* row = apparent_c.ptr<float>(y);
      for (int x = 0; x < width; ++x) {
        const size_t i = map.Index(x, y);
        if (!IsValid(map.points[i])) continue;
        ++part.hits;
        if (!IsValid(map.normals[i])) {
          ++part.no_normal;
          continue;
        }
        if (edge_radius > 0 && near_depth_edge(x, y, range[i])) {
          ++part.depth_edge;
          continue;
        }
        if (occlusion_test && near_occluded(x, y)) {
          ++part.occluded;
          continue;
        }
        const Eigen::Vector3d point = map.points[i].cast<double>();
        const Eigen::Vector3d ray = point - origin;
        const double distance_m = ray.norm();
        const double cos_angle = -ray.dot(map.normals[i].cast<double>()) / distance_m;
        ConfidenceTerms terms;
        const Eigen::Vector3d point_in_camera = thermal_from_world * ray;
        terms.motion = MotionConfidence(
            ImageSpeedPxPerS(point_in_camera, linear_velocity_mps, angular_velocity_radps, fx, fy) *
                co.integration_time_s,
            co);
        terms.distortion = distortion_confidence[i];
        terms.angle = AngleConfidence(cos_angle, co);
        terms.distance = DistanceConfidence(distance_m, co);
        terms.operating = operating;
        const double confidence = RayConfidence(terms, co);
        if (!(confidence >= options.min_ray_confidence) || confidence <= 0) {
          ++part.low_confidence;
          continue;
        }
        // The emissivity at the hit: ReflectPixels' when it traced the frame's mirror rays.
        PixelReflection reflection;
        if (!reflections.empty()) {
          reflection = reflections[i];
        } else {
          reflection.surface = emissivity.At(map.points[i]);
          reflection.emissivity_at_angle = static_cast<float>(core::DirectionalEmissivity(
              reflection.surface.law, reflection.surface.emissivity, std::clamp(cos_angle, 0.0, 1.0)));
        }
        const double emissivity_at_angle = reflection.emissivity_at_angle;
        double apparent = row[x];
        if (!vignetting_gain.empty()) {
          // Undo the radiance the optics lost at this pixel.
          apparent = core::KelvinToCelsius(
              band.Temperature(band.Radiance(core::CelsiusToKelvin(apparent)) / static_cast<double>(vignetting_gain[i])));
        }
        double reflected_c = reflection.surface.reflected_c;
        MirrorSource source = MirrorSource::kRoom;
        if (!std::isnan(reflection.mirror_m)) {
          reflected_c = ReflectedC(map, apparent_c, world_from_thermal, i, reflection, &source);
        }
        const double surface = emissivity_at_angle > 0
                                   ? core::SurfaceFromApparent(band, apparent, emissivity_at_angle, reflected_c)
                                   : std::numeric_limits<double>::quiet_NaN();
        if (!std::isfinite(surface)) {
          ++part.no_surface;
          continue;
        }
        // The footprint: one pixel (1/f rad) across, stretched by 1/cos θ along the slope
        // (cos θ floored at the largest angle fused, so the axis stays finite).
        const Eigen::Vector3d normal = map.normals[i].cast<double>();
        const double across_m = distance_m / fx;
        Eigen::Vector3d along = ray - ray.dot(normal) * normal;
        if (along.norm() < 1e-9 * distance_m) along = normal.unitOrthogonal();
        along.normalize();
        const Eigen::Vector3d side = normal.cross(along);
        const double along_m = across_m / std::max(cos_angle, 0.1);
        part.rays.push_back(Ray{map.points[i], (along * along_m).cast<float>(), (side * across_m).cast<float>(),
                                static_cast<float>(std::sqrt(across_m * along_m)), static_cast<float>(confidence), static_cast<float>(surface),
                                static_cast<float>(apparent), static_cast<float>(emissivity_at_angle),
                                static_cast<int32_t>(i)});
        part.confidence_sum += confidence;
        part.mirror_operator += source == MirrorSource::kOperator;
        part.mirror_surface += source == MirrorSource::kSurface;
      }
    }
  });
  std::vector<Ray>& fused = fused_scratch;
  fused.clear();
  double confidence_sum = 0;
  for (ShadePart& part : parts) {
    record.hits += part.hits;
    record.low_confidence += part.low_confidence;
    record.no_normal += part.no_normal;
    record.depth_edge += part.depth_edge;
    record.occluded += part.occluded;
    record.no_surface_temperature += part.no_surface;
    record.mirror_operator += part.mirror_operator;
    record.mirror_surface += part.mirror_surface;
    confidence_sum += part.confidence_sum;
    fused.insert(fused.end(), part.rays.begin(), part.rays.end());
  }
  record.fused = static_cast<int>(fused.size());
  record.mean_confidence = fused.empty() ? 0 : confidence_sum / fused.size();
  return fused;
}

namespace {

// 1 − v·r² per pixel (ThermalFusionOptions::vignetting).
std::vector<float> VignettingGain(const core::CameraModel& camera, double vignetting) {
  std::vector<float> gain;
  if (vignetting == 0) return gain;
  double r_max2 = 0;
  for (double x : {-0.5, camera.width - 0.5}) {
    for (double y : {-0.5, camera.height - 0.5}) {
      r_max2 = std::max(r_max2, (x - camera.cx) * (x - camera.cx) + (y - camera.cy) * (y - camera.cy));
    }
  }
  gain.resize(size_t(camera.width) * camera.height);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const double r2 = ((x - camera.cx) * (x - camera.cx) + (y - camera.cy) * (y - camera.cy)) / r_max2;
      gain[size_t(y) * camera.width + x] = static_cast<float>(1 - vignetting * r2);
    }
  }
  return gain;
}

}  // namespace

ThermalFusion::ThermalFusion(const core::Rig& rig, const ThermalFusionOptions& options, EmissivityMap emissivity,
                             std::vector<double> ffc_timestamps_s) {
  assert(options.Check().empty());
  assert(rig.thermal && rig.thermal_settings);
  impl_ = std::make_unique<Impl>(rig, options, std::move(emissivity), std::move(ffc_timestamps_s));
  Impl& m = *impl_;
  m.voxel_m = 0;  // set from the volume on the first frame
  m.vignetting_gain = VignettingGain(*rig.thermal, options.vignetting);
  const int width = m.rays.width(), height = m.rays.height();
  m.distortion_confidence.resize(size_t(width) * height);
  // Each pixel's angular size: the larger angle to its right and lower neighbours' rays (the
  // left and upper ones on the last column and row).
  m.pixel_angle_rad.assign(size_t(width) * height, 0.0f);
  auto ray_at = [&](int x, int y) {
    const Eigen::Vector2f xy = m.rays.xy(x, y);
    return Eigen::Vector3f(xy.x(), xy.y(), 1.0f).normalized();
  };
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      if (!m.rays.valid(x, y)) continue;
      float angle = 0;
      const int nx = x + 1 < width ? x + 1 : x - 1, ny = y + 1 < height ? y + 1 : y - 1;
      for (const auto& [u, v] : {std::pair{nx, y}, std::pair{x, ny}}) {
        if (u < 0 || v < 0 || !m.rays.valid(u, v)) continue;
        angle = std::max(angle, std::acos(std::clamp(ray_at(x, y).dot(ray_at(u, v)), -1.0f, 1.0f)));
      }
      m.pixel_angle_rad[size_t(y) * width + x] = angle;
    }
  }
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      m.num_rays += m.rays.valid(x, y);
      m.distortion_confidence[size_t(y) * width + x] =
          m.rays.valid(x, y) ? static_cast<float>(DistortionConfidence(m.rays.distortion_px(x, y), options.confidence))
                             : 0.0f;
    }
  }
}

ThermalFusion::~ThermalFusion() = default;

ThermalFusion::ThermalFusion(ThermalFusion&&) noexcept = default;
ThermalFusion& ThermalFusion::operator=(ThermalFusion&&) noexcept = default;

double ThermalFusion::DepthClockTime(double thermal_timestamp_s) const {
  return thermal_timestamp_s + impl_->rig.thermal_time_offset_s;
}

bool ThermalFusion::PoseAvailable(double thermal_timestamp_s, const core::Trajectory& world_from_depth) const {
  return !world_from_depth.empty() && world_from_depth.EndTime() >= DepthClockTime(thermal_timestamp_s);
}

const ThermalFrameRecord& ThermalFusion::AddFrame(const TsdfVolume& volume, const ThermalFrameInput& frame,
                                                  const core::Trajectory& world_from_depth,
                                                  std::span<const LiveDepth> live) {
  for (const LiveDepth& d : live) {
    assert(d.depth_m.type() == CV_32FC1 && d.depth_m.cols == impl_->rig.depth.width &&
           d.depth_m.rows == impl_->rig.depth.height);
    (void)d;
  }
  Impl& m = *impl_;
  const core::CameraModel& camera = *m.rig.thermal;
  if (frame.apparent_c.type() != CV_32FC1 || frame.apparent_c.cols != camera.width ||
      frame.apparent_c.rows != camera.height) {
    throw std::invalid_argument(core::StringPrintf(
        "thermal frame %d: expected a %dx%d CV_32FC1 image of apparent temperature, got %dx%d type %d",
        frame.index, camera.width, camera.height, frame.apparent_c.cols, frame.apparent_c.rows,
        frame.apparent_c.type()));
  }
  if (m.voxel_m == 0) m.voxel_m = volume.voxel_size_m();
  assert(m.voxel_m == volume.voxel_size_m());
  m.finished = false;
  ThermalFrameRecord& record = m.frames.emplace_back();
  record.index = frame.index;
  record.timestamp_s = frame.timestamp_s;
  record.depth_clock_s = DepthClockTime(frame.timestamp_s);
  record.time_since_ffc_s = m.TimeSinceFfc(frame.timestamp_s);

  // A repeated image: the camera froze it during a shutter closure, and its pose now is
  // not the pose it was taken at.
  const cv::Mat image = frame.apparent_c.isContinuous() ? frame.apparent_c : frame.apparent_c.clone();
  const bool frozen = !m.previous_image.empty() &&
                      std::memcmp(image.data, m.previous_image.data, image.total() * sizeof(float)) == 0;
  m.previous_image = image.clone();
  if (frozen) {
    record.status = ThermalFrameStatus::kFrozen;
    m.last_frozen_s = frame.timestamp_s;  // a shutter event, listed in ffc.txt or not
    return record;
  }

  // The two fused depth poses around the frame's time, within max_pose_gap_s.
  const auto& poses = world_from_depth.poses();
  const double t = record.depth_clock_s;
  auto after = std::lower_bound(poses.begin(), poses.end(), t,
                                [](const core::TimedPose& p, double time) { return p.timestamp_s < time; });
  if (after == poses.end() || poses.size() < 2) {
    record.status = ThermalFrameStatus::kNoPose;
    return record;
  }
  if (after == poses.begin()) {
    if (after->timestamp_s > t) {
      record.status = ThermalFrameStatus::kNoPose;
      return record;
    }
    ++after;  // t is exactly the first pose's time
  }
  const core::TimedPose& p0 = *(after - 1);
  const core::TimedPose& p1 = *after;
  const double dt = p1.timestamp_s - p0.timestamp_s;
  if (!(dt > 0) || dt > m.options.max_pose_gap_s) {
    record.status = ThermalFrameStatus::kNoPose;
    return record;
  }
  const std::optional<core::Rigid3d> world_from_depth_at_t = world_from_depth.At(t, m.options.max_pose_gap_s);
  if (!world_from_depth_at_t) {
    record.status = ThermalFrameStatus::kNoPose;
    return record;
  }
  const core::Rigid3d world_from_thermal = *world_from_depth_at_t * m.rig.depth_from_thermal;
  const core::Rigid3d world_from_thermal0 = p0.world_from_sensor * m.rig.depth_from_thermal;
  const core::Rigid3d world_from_thermal1 = p1.world_from_sensor * m.rig.depth_from_thermal;
  // Velocity of the thermal camera in its own frame: the body-frame twist between the two poses.
  const Eigen::Quaterniond thermal_from_world = world_from_thermal.rotation.conjugate();
  const Eigen::Vector3d linear_velocity_mps =
      thermal_from_world * (world_from_thermal1.translation - world_from_thermal0.translation) / dt;
  const Eigen::AngleAxisd rotation(world_from_thermal0.rotation.conjugate() * world_from_thermal1.rotation);
  const Eigen::Vector3d angular_velocity_radps = rotation.axis() * rotation.angle() / dt;
  record.linear_speed_mps = linear_velocity_mps.norm();
  record.angular_speed_dps = angular_velocity_radps.norm() * 180 / M_PI;

  // A frame past the current window closes it (first, so that this frame's confidence
  // reads the range of the frame fused now).
  const double interval_s = m.options.frame_interval_s;
  if (m.held && !(frame.timestamp_s < m.window_start_s + interval_s)) m.CloseWindow(volume);
  const double operating = OperatingConfidence(record.time_since_ffc_s, false, m.options.confidence);
  record.frame_confidence = m.FrameConfidence(linear_velocity_mps, angular_velocity_radps, operating);
  Impl::HeldFrame candidate{m.frames.size() - 1, m.previous_image, world_from_thermal, linear_velocity_mps,
                            angular_velocity_radps, operating, std::vector<LiveDepth>(live.begin(), live.end())};
  if (interval_s == 0) {
    m.Fuse(volume, candidate);
  } else if (!m.held) {  // it opens a window
    m.window_start_s = frame.timestamp_s;
    record.status = ThermalFrameStatus::kHeld;
    m.held = std::move(candidate);
  } else if (record.frame_confidence > m.frames[m.held->record].frame_confidence) {  // ties: the earlier
    m.frames[m.held->record].status = ThermalFrameStatus::kSkipped;
    record.status = ThermalFrameStatus::kHeld;
    m.held = std::move(candidate);
  } else {
    record.status = ThermalFrameStatus::kSkipped;
  }
  return m.frames.back();
}

double ThermalFusion::Impl::FrameConfidence(const Eigen::Vector3d& linear_velocity_mps,
                                            const Eigen::Vector3d& angular_velocity_radps,
                                            double operating) const {
  const core::CameraModel& camera = *rig.thermal;
  const ThermalConfidenceOptions& co = options.confidence;
  double sum = 0;
  int n = 0;
  for (int j = 1; j <= 3; ++j) {
    for (int i = 1; i <= 3; ++i) {
      const int x = camera.width * i / 4, y = camera.height * j / 4;
      if (!rays.valid(x, y)) continue;
      const Eigen::Vector2f xy = rays.xy(x, y);
      const Eigen::Vector3d ray(xy.x(), xy.y(), 1.0);
      const Eigen::Vector3d point_in_camera = ray * (reference_range_m / ray.norm());
      ConfidenceTerms terms;
      terms.motion = MotionConfidence(ImageSpeedPxPerS(point_in_camera, linear_velocity_mps, angular_velocity_radps,
                                                       camera.fx, camera.fy) *
                                          co.integration_time_s,
                                      co);
      terms.operating = operating;
      sum += RayConfidence(terms, co);
      ++n;
    }
  }
  return n > 0 ? sum / n : 0;
}

void ThermalFusion::Impl::Fuse(const TsdfVolume& volume, const HeldFrame& frame) {
  Wait();  // the previous frame's regions are this one's to update
  ThermalFrameRecord& record = frames[frame.record];
  const auto start = std::chrono::steady_clock::now();
  RaycastOptions raycast;
  raycast.min_depth_m = options.min_depth_m;
  raycast.max_depth_m = options.max_depth_m;
  raycast.num_threads = options.num_threads;
  WarpLiveDepth(frame.world_from_thermal, frame.live);
  // The live depth says where each ray's surface is: the ray searches there first, to the
  // occlusion test's margin behind it (a hit farther behind would be rejected as occluded).
  RayHints hints;
  hints.range_m = live_range;
  hints.behind_m = static_cast<float>(options.occlusion_margin_m);
  hints.behind_fraction = static_cast<float>(options.occlusion_margin_fraction);
  PointMap map = live_range.empty() ? Raycast(volume, rays, frame.world_from_thermal, raycast)
                                    : Raycast(volume, rays, frame.world_from_thermal, raycast, hints);
  record.raycast_ms = internal::MsSince(start);
  record.rays = num_rays;
  record.live_depth = !frame.live.empty();
  // The median range of the hits (every 7th pixel: ~11 k of a 320×240 frame), for the next
  // frames' confidence (here, so that it does not wait for the background stage).
  const Eigen::Vector3f origin = frame.world_from_thermal.translation.cast<float>();
  std::vector<float> ranges;
  for (size_t i = 0; i < map.points.size(); i += 7) {
    if (IsValid(map.points[i])) ranges.push_back((map.points[i] - origin).norm());
  }
  if (!ranges.empty()) {
    std::nth_element(ranges.begin(), ranges.begin() + ranges.size() / 2, ranges.end());
    reference_range_m = ranges[ranges.size() / 2];
  }
  // Each hit's emissivity and its mirror ray, marched here while the volume may be read.
  const auto reflect_start = std::chrono::steady_clock::now();
  std::vector<PixelReflection> reflections;
  if (options.reflections.trace) {
    const float min_cos = static_cast<float>(std::cos(options.confidence.max_angle_deg * M_PI / 180));
    reflections = ReflectPixels(volume, map, origin, emissivity, options.reflections, min_cos, options.num_threads,
                                &record.mirror_traced);
  }
  record.reflect_ms = internal::MsSince(reflect_start);
  // The rest touches only this object's regions, not the volume: it may run while the
  // caller integrates the next depth frames (ThermalFusionOptions::background).
  auto stage = [this, map = std::move(map), reflections = std::move(reflections), image = frame.image,
                world_from_thermal = frame.world_from_thermal,
                linear = frame.linear_velocity_mps, angular = frame.angular_velocity_radps,
                operating = frame.operating, frozen_s = last_frozen_s](ThermalFrameRecord& out) {
    const auto stage_start = std::chrono::steady_clock::now();
    const cv::Mat corrected = scene_correction.CorrectPixels(image);
    std::vector<Ray>& fused = ShadeRays(map, reflections, corrected, world_from_thermal, linear, angular, operating, out);
    if (scene_correction.enabled()) CorrectFrame(fused, frozen_s, out);
    camera_in_world = world_from_thermal.translation.cast<float>();
    Splat(fused, out);
    out.fuse_ms = internal::MsSince(stage_start);
    out.status = out.hits == 0 ? ThermalFrameStatus::kNoSurface : ThermalFrameStatus::kFused;
  };
  if (!options.background || options.frame_interval_s == 0) {
    stage(record);
    return;
  }
  background_index = frame.record;
  background_record = record;
  background = std::async(std::launch::async, [this, stage = std::move(stage)]() { stage(background_record); });
}

void ThermalFusion::Impl::Wait() {
  if (!background.valid()) return;
  background.get();  // rethrows what the stage threw
  frames[background_index] = background_record;
}

void ThermalFusion::Impl::CloseWindow(const TsdfVolume& volume) {
  if (held) Fuse(volume, *held);
  held.reset();
}

void ThermalFusion::Flush(const TsdfVolume& volume) {
  impl_->CloseWindow(volume);
  impl_->Wait();
}

void ThermalFusion::Finish() {
  assert(!impl_->held && "ThermalFusion::Flush before Finish");
  Impl& m = *impl_;
  m.Wait();
  m.finished = true;
  m.offline_rejected = 0;
  if (!m.options.keep_observations || m.num_records == 0) return;
  // Group the observations by region (and cap their views), then estimate each region alone.
  std::vector<uint32_t> begin;
  m.Compact(&begin);
  const size_t n_regions = m.regions.size();
  assert(m.records.size() == 1);  // Compact leaves one chunk, grouped by region
  const RecordChunk& grouped = m.records.front();
  const int num_threads = ResolveThreads(m.options.num_threads);
  std::vector<int64_t> rejected(num_threads, 0);
  internal::RunChunks(num_threads, [&](int chunk) {
    // A region's views are copied into this thread's buffers (RobustEstimate sorts them):
    // two arrays of every observation took a third of the offline estimate's time on a 4 s
    // full-size scan, most of it faulting their pages in on one thread.
    std::vector<Observation> surface, apparent;
    for (size_t i = chunk; i < n_regions; i += num_threads) {
      Region& region = m.regions[i];
      const size_t b = begin[i], e = begin[i + 1];
      if (b == e) continue;
      surface.resize(e - b);
      apparent.resize(e - b);
      for (size_t k = b; k < e; ++k) {
        surface[k - b] = Observation{grouped[k].surface_c, grouped[k].confidence};
        apparent[k - b] = Observation{grouped[k].apparent_c, grouped[k].confidence};
      }
      const OfflineEstimate s = RobustEstimate(surface, m.options.offline);
      const OfflineEstimate a = RobustEstimate(apparent, m.options.offline);
      region.offline_views = static_cast<uint16_t>(std::min<int>(s.views, std::numeric_limits<uint16_t>::max()));
      region.offline_surface_c = static_cast<float>(s.value_c);
      region.offline_apparent_c = static_cast<float>(a.value_c);
      region.offline_confidence = static_cast<float>(s.confidence);
      region.offline_std_c = static_cast<float>(s.std_c);
      rejected[chunk] += s.rejected;
    }
  });
  for (int64_t r : rejected) m.offline_rejected += r;
}

PointTemperatures ThermalFusion::Sample(const std::vector<Eigen::Vector3f>& points_in_world,
                                        ThermalMethod method) const {
  impl_->Wait();
  const Impl& m = *impl_;
  PointTemperatures out;
  const size_t n = points_in_world.size();
  out.surface_c.assign(n, kNaN);
  out.apparent_c.assign(n, kNaN);
  out.confidence.assign(n, 0.0f);
  out.std_c.assign(n, kNaN);
  out.footprint_m.assign(n, kNaN);
  out.view_m.assign(n, Eigen::Vector3f::Constant(kNaN));
  out.views.assign(n, 0);
  if (m.regions.empty() || m.voxel_m == 0) return out;
  const int num_threads = std::max(1, std::min<int>(ResolveThreads(m.options.num_threads),
                                                    static_cast<int>(n / 4096) + 1));
  internal::RunChunks(num_threads, [&](int chunk) {
    uint64_t cached_key = ~uint64_t{0};
    int32_t cached_block = -1;
    std::array<Eigen::Vector3i, 8> voxel;
    std::array<float, 8> weight;
    for (size_t i = chunk * n / num_threads; i < (chunk + 1) * n / num_threads; ++i) {
      m.Corners(points_in_world[i], voxel, weight);
      double w_sum = 0, surface = 0, apparent = 0, confidence = 0, spread = 0, views = 0, w_spread = 0, footprint = 0;
      Eigen::Vector3d view = Eigen::Vector3d::Zero();
      for (int c = 0; c < 8; ++c) {
        if (weight[c] <= 0) continue;
        const int32_t r = m.FindRegion(voxel[c].x(), voxel[c].y(), voxel[c].z(), cached_key, cached_block);
        if (r < 0) continue;
        const Region& g = m.regions[r];
        float s = kNaN, a = kNaN, conf = 0, sd = kNaN, v = 0;
        switch (method) {
          case ThermalMethod::kLatest:
            s = g.latest_surface_c, a = g.latest_apparent_c, conf = g.latest_confidence;
            break;
          case ThermalMethod::kMean:
            if (g.views > 0) s = g.mean_surface_c, a = g.mean_apparent_c, conf = g.mean_confidence;
            break;
          case ThermalMethod::kCappedMean:
            if (g.views > 0) s = g.capped_surface_c, a = g.capped_apparent_c, conf = g.mean_confidence;
            break;
          case ThermalMethod::kOnline:
            if (g.online_confidence >= 0) s = g.online_surface_c, a = g.online_apparent_c, conf = g.online_confidence;
            break;
          case ThermalMethod::kOffline:
            if (g.offline_views > 0) {
              s = g.offline_surface_c, a = g.offline_apparent_c, conf = g.offline_confidence, sd = g.offline_std_c;
              v = g.offline_views;
            }
            break;
        }
        if (!std::isfinite(s) || !std::isfinite(a)) continue;
        if (method != ThermalMethod::kOffline) {
          v = g.views;
          sd = g.views > 1 ? std::sqrt(g.m2_surface / (g.views - 1)) : 0.0f;
        }
        const double w = weight[c];
        w_sum += w;
        surface += w * static_cast<double>(s);
        apparent += w * static_cast<double>(a);
        confidence += w * static_cast<double>(conf);
        views += w * static_cast<double>(v);
        footprint += w * static_cast<double>(g.footprint_m);
        view += w * Eigen::Vector3d(g.view_x, g.view_y, g.view_z);
        if (std::isfinite(sd)) {
          spread += w * static_cast<double>(sd);
          w_spread += w;
        }
      }
      if (w_sum <= 0) continue;
      out.surface_c[i] = static_cast<float>(surface / w_sum);
      out.apparent_c[i] = static_cast<float>(apparent / w_sum);
      out.confidence[i] = static_cast<float>(confidence / w_sum);
      out.views[i] = static_cast<uint16_t>(std::max(1.0, std::round(views / w_sum)));
      out.footprint_m[i] = static_cast<float>(footprint / w_sum);
      out.view_m[i] = (view / w_sum).cast<float>();
      if (w_spread > 0) out.std_c[i] = static_cast<float>(spread / w_spread);
    }
  });
  return out;
}

const std::vector<ThermalFrameRecord>& ThermalFusion::frames() const {
  impl_->Wait();
  return impl_->frames;
}
const ThermalFusionOptions& ThermalFusion::options() const { return impl_->options; }
const EmissivityMap& ThermalFusion::emissivity() const { return impl_->emissivity; }
size_t ThermalFusion::NumRegions() const {
  impl_->Wait();
  return impl_->regions.size();
}
size_t ThermalFusion::NumObservations() const {
  impl_->Wait();
  return impl_->num_records;
}
size_t ThermalFusion::NumObservationsDropped() const {
  impl_->Wait();
  return impl_->records_dropped;
}
int64_t ThermalFusion::OfflineRejected() const {
  impl_->Wait();
  return impl_->offline_rejected;
}

size_t ThermalFusion::MemoryBytes() const {
  impl_->Wait();
  const Impl& m = *impl_;
  return m.regions.CapacityBytes() + m.frame_sums.CapacityBytes() + m.blocks.CapacityBytes() +
         m.block_index.size() * 32 +
         m.num_records * sizeof(Record);
}

}  // namespace hw::reconstruct
