#include "calibrate/extrinsics_targetless.h"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cmath>
#include <mutex>
#include <thread>

#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/option_check.h"

namespace hw::calibrate {
namespace {

struct PlannedFrame {
  int thermal_index = 0;
  int depth_index = 0;
  double dt_s = 0;
  core::Rigid3d thermal_time_from_depth_time;  // depth(t_thermal)_from_depth(t_depth)
};

std::vector<PlannedFrame> PlanFrames(const core::Scan& scan, const std::optional<core::Trajectory>& trajectory,
                                     const TargetlessOptions& options) {
  std::vector<int> candidates;
  for (int i = 0; i < scan.NumFrames(core::Stream::kThermal); i += options.frame_step) {
    if (scan.FrameExists(core::Stream::kThermal, i)) candidates.push_back(i);
  }
  std::vector<PlannedFrame> planned;
  const double max_dt = trajectory ? std::max(scan.MedianPeriod(core::Stream::kDepth), 1e-3) : options.max_pair_dt_s;
  for (const int i : candidates) {
    const double t = scan.DepthClockTime(core::Stream::kThermal, i);
    const auto j = scan.NearestFrame(core::Stream::kDepth, t, max_dt);
    if (!j || !scan.FrameExists(core::Stream::kDepth, *j)) continue;
    PlannedFrame p;
    p.thermal_index = i;
    p.depth_index = *j;
    p.dt_s = scan.DepthClockTime(core::Stream::kDepth, *j) - t;
    if (trajectory) {
      const auto at_thermal = trajectory->At(t, options.max_trajectory_gap_s);
      const auto at_depth = trajectory->At(scan.DepthClockTime(core::Stream::kDepth, *j), options.max_trajectory_gap_s);
      if (!at_thermal || !at_depth) continue;
      p.thermal_time_from_depth_time = at_thermal->Inverse() * *at_depth;
    }
    planned.push_back(p);
  }
  if (static_cast<int>(planned.size()) > options.max_frames) {
    std::vector<PlannedFrame> spread;
    for (int k = 0; k < options.max_frames; ++k) {
      spread.push_back(planned[static_cast<size_t>(k) * planned.size() / options.max_frames]);
    }
    planned = std::move(spread);
  }
  return planned;
}

}  // namespace

std::string TargetlessOptions::Check() const {
  using core::OptionFail;
  if (std::string e = depth_lines.Check(); !e.empty()) return "depth_lines." + e;
  if (std::string e = image_lines.Check(); !e.empty()) return "image_lines." + e;
  if (std::string e = alignment.Check(); !e.empty()) return "alignment." + e;
  if (frame_step < 1) return OptionFail("frame_step", frame_step, ">= 1");
  if (max_frames < 1) return OptionFail("max_frames", max_frames, ">= 1");
  if (!(max_pair_dt_s > 0)) return OptionFail("max_pair_dt_s", max_pair_dt_s, "> 0 s");
  if (!(max_trajectory_gap_s > 0)) return OptionFail("max_trajectory_gap_s", max_trajectory_gap_s, "> 0 s");
  if (num_threads < 0) return OptionFail("num_threads", num_threads, ">= 0");
  return "";
}

TargetlessResult EstimateTargetlessExtrinsics(const core::Scan& scan,
                                              const std::optional<core::Trajectory>& world_from_depth,
                                              const TargetlessOptions& options, const TargetlessProgressFn& progress) {
  assert(options.Check().empty());
  const core::Rig& rig = scan.rig();
  if (!rig.thermal) throw core::InputError(scan.folder(), "targetless extrinsics: the rig has no thermal camera");
  if (scan.NumFrames(core::Stream::kThermal) == 0) {
    throw core::InputError(scan.folder(), "targetless extrinsics: the scan has no thermal frames");
  }
  const std::vector<PlannedFrame> planned = PlanFrames(scan, world_from_depth, options);
  if (planned.empty()) {
    throw core::InputError(scan.folder(),
                           world_from_depth
                               ? "targetless extrinsics: no thermal frame has a depth frame within one depth period on the trajectory"
                               : "targetless extrinsics: no thermal frame is within max_pair_dt_s of a depth frame (give a trajectory)");
  }
  TargetlessResult result;
  result.used_trajectory = world_from_depth.has_value();
  result.initial_depth_from_thermal = rig.depth_from_thermal;
  const Rectifier rectifier(*rig.thermal);
  result.rectified_thermal = rectifier.pinhole();
  const cv::Mat rays = DepthRays(rig.depth);
  const cv::Mat depth_offsets =
      rig.depth_correction ? core::DepthOffsetMap(*rig.depth_correction, rig.depth) : cv::Mat();
  const double depth_focal_px = 0.5 * (rig.depth.fx + rig.depth.fy);

  // Lines of every planned frame, in parallel.
  result.line_frames.resize(planned.size());
  result.frames.resize(planned.size());
  std::atomic<size_t> next{0};
  std::atomic<int> done{0};
  std::mutex mutex;
  std::exception_ptr error;
  auto work = [&] {
    for (size_t k = next++; k < planned.size(); k = next++) {
      try {
        const PlannedFrame& p = planned[k];
        cv::Mat depth = scan.LoadDepth(p.depth_index);
        // The rig's depth calibration, when it has one: straighter planes, truer lines.
        if (!depth_offsets.empty()) core::CorrectDepth(depth_offsets, &depth);
        LineFrame& lf = result.line_frames[k];
        lf.thermal_index = p.thermal_index;
        lf.lines_3d = ExtractDepthLines(depth, rays, depth_focal_px, options.depth_lines);
        std::erase_if(lf.lines_3d, [&](const Segment3d& s) {
          return s.kind == LineKind::kFold ? !options.use_fold_lines : !options.use_occlusion_lines;
        });
        if (world_from_depth) {
          for (Segment3d& s : lf.lines_3d) {
            s.a = p.thermal_time_from_depth_time * s.a;
            s.b = p.thermal_time_from_depth_time * s.b;
            s.edge_shift_per_px = p.thermal_time_from_depth_time.rotation * s.edge_shift_per_px;
          }
        }
        const cv::Mat thermal = rectifier.Apply(scan.LoadThermal(p.thermal_index));
        lf.lines_2d = DetectImageLines(StretchThermal(thermal, rectifier.valid(), options.image_lines),
                                       rectifier.valid(), options.image_lines);
        TargetlessFrameStats& st = result.frames[k];
        st.thermal_index = p.thermal_index;
        st.depth_index = p.depth_index;
        st.dt_s = p.dt_s;
        st.lines_3d = static_cast<int>(lf.lines_3d.size());
        st.lines_2d = static_cast<int>(lf.lines_2d.size());
      } catch (...) {
        std::lock_guard<std::mutex> lock(mutex);
        if (!error) error = std::current_exception();
        next = planned.size();
      }
      const int d = ++done;
      if (progress) {
        std::lock_guard<std::mutex> lock(mutex);
        progress(d, static_cast<int>(planned.size()));
      }
    }
  };
  const int threads = std::max(1, std::min<int>(options.num_threads > 0 ? options.num_threads
                                                                         : static_cast<int>(std::thread::hardware_concurrency()),
                                                static_cast<int>(planned.size())));
  std::vector<std::thread> pool;
  for (int i = 1; i < threads; ++i) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);

  const LineAlignmentResult aligned =
      AlignLines(result.line_frames, result.rectified_thermal, rig.depth_from_thermal, options.alignment);
  result.estimate = aligned.estimate;
  result.matches = static_cast<int>(aligned.matches.size());
  result.inlier_fraction = aligned.inlier_fraction;
  result.robust_sigma_px = aligned.robust_sigma_px;
  result.edge_offset_px = aligned.edge_offset_px;
  result.edge_offset_sigma_px = aligned.edge_offset_sigma_px;
  result.cost_per_iteration = aligned.cost_per_iteration;
  result.matches_per_iteration = aligned.matches_per_iteration;
  for (const LineMatch& m : aligned.matches) ++result.frames[m.frame].matches;
  if (!aligned.failure.empty()) {
    throw core::InputError(scan.folder(), "targetless extrinsics: " + aligned.failure + " (" +
                                              std::to_string(planned.size()) + " frames used)");
  }
  return result;
}

cv::Mat DrawTargetlessDiagnostic(const core::Scan& scan, const TargetlessResult& result, int frame,
                                 const TargetlessOptions& options, int zoom) {
  assert(frame >= 0 && frame < static_cast<int>(result.line_frames.size()) && zoom >= 1);
  const LineFrame& lf = result.line_frames[frame];
  const Rectifier rectifier(*scan.rig().thermal);
  const cv::Mat grey = StretchThermal(rectifier.Apply(scan.LoadThermal(lf.thermal_index)), rectifier.valid(),
                                      options.image_lines);
  cv::Mat big, image;
  cv::resize(grey, big, cv::Size(), zoom, zoom, cv::INTER_NEAREST);
  cv::cvtColor(big, image, cv::COLOR_GRAY2BGR);
  auto pt = [&](const Eigen::Vector2d& p) { return cv::Point2d((p.x() + 0.5) * zoom - 0.5, (p.y() + 0.5) * zoom - 0.5); };
  for (const Segment2d& s : lf.lines_2d) cv::line(image, pt(s.a), pt(s.b), cv::Scalar(0, 255, 255), 1, cv::LINE_AA);
  const core::CameraModel& k = result.rectified_thermal;
  for (const Segment3d& s : lf.lines_3d) {
    Eigen::Vector2d a, b;
    if (ProjectSegment(s, result.initial_depth_from_thermal, k, &a, &b)) {
      cv::line(image, pt(a), pt(b), cv::Scalar(0, 0, 255), 1, cv::LINE_AA);
    }
    if (ProjectSegment(s, result.estimate.depth_from_camera, k, &a, &b)) {
      cv::line(image, pt(a), pt(b), cv::Scalar(0, 255, 0), 1, cv::LINE_AA);
    }
  }
  return image;
}

}  // namespace hw::calibrate
