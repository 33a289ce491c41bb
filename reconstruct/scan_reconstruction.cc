#include "reconstruct/reconstruction.h"

// Running a Reconstruction over a scan folder: frames loaded in order with their colour,
// thermal frames fed to a ThermalFusion as the trajectory reaches them.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <future>
#include <optional>
#include <stdexcept>

#include "core/error.h"
#include "core/strings.h"
#include "reconstruct/elapsed.h"
#include "reconstruct/row_bands.h"

namespace hw::reconstruct {

namespace {

// Largest time between a depth frame and the colour frame used with it, s: three frames at
// 30 Hz (a dropped frame or two), short enough for the predicted motion to bridge.
constexpr double kMaxColourGapS = 0.1;

}  // namespace

FrameInput LoadScanFrame(const core::Scan& scan, int depth_index, bool with_rgb) {
  using core::Stream;
  FrameInput frame;
  frame.timestamp_s = scan.Timestamp(Stream::kDepth, depth_index);
  frame.depth_m = scan.LoadDepth(depth_index);
  if (with_rgb && scan.rig().rgb) {
    // The nearest colour frame within kMaxColourGapS, not only an associated one (within half a
    // frame): a dropped colour frame must not leave the depth frame without its photometric
    // term — on a wall, geometry alone lets ICP slide (measured: 80 mm in one frame). The
    // motion between the two exposures is compensated (registration and integration use the
    // pose at the colour frame's own time).
    const std::optional<int> j =
        scan.NearestFrame(Stream::kRgb, scan.DepthClockTime(Stream::kDepth, depth_index), kMaxColourGapS);
    if (j && scan.FrameExists(Stream::kRgb, *j)) {
      frame.rgb = scan.LoadRgb(*j);
      frame.rgb_timestamp_s = scan.DepthClockTime(Stream::kRgb, *j);
    }
  }
  return frame;
}

namespace {

// Feeds a scan's thermal frames to a ThermalFusion in time order, each once the fused depth
// poses reach it.
class ThermalFeeder {
 public:
  ThermalFeeder(const core::Scan& scan, ThermalFusion* fusion, ScanReconstruction& out)
      : scan_(scan), fusion_(fusion), out_(out),
        n_(fusion ? scan.NumFrames(core::Stream::kThermal) : 0) {
    const double period_s = scan.MedianPeriod(core::Stream::kDepth);
    max_live_dt_s_ = std::isfinite(period_s) ? 1.5 * period_s : 0.05;
  }

  // A fused depth frame (as recorded, distorted) and its pose: the thermal frames fed next
  // test occlusion against the last two (ThermalFusionOptions).
  void AddDepth(double timestamp_s, const cv::Mat& depth_m, const core::Rigid3d& world_from_depth) {
    if (!fusion_) return;
    if (live_.size() == 2) live_.erase(live_.begin());
    live_.push_back({timestamp_s, LiveDepth{depth_m, world_from_depth}});
  }

  // Fuses the frames the trajectory now reaches; with `flush`, all remaining ones (those past
  // the trajectory's end are only counted).
  void Feed(const Reconstruction& reconstruction, bool flush) {
    using core::Stream;
    while (next_ < n_) {
      const double t = scan_.Timestamp(Stream::kThermal, next_);
      if (!flush && !fusion_->PoseAvailable(t, reconstruction.trajectory())) return;
      const int i = next_++;
      if (flush && !fusion_->PoseAvailable(t, reconstruction.trajectory())) {
        ++out_.thermal_after_end;
        continue;
      }
      if (!scan_.FrameExists(Stream::kThermal, i)) {
        ++out_.thermal_missing_frames;
        out_.warnings.push_back(core::StringPrintf("thermal frame %d at %.6f s: %s is missing, skipped", i, t,
                                                   scan_.FramePath(Stream::kThermal, i).c_str()));
        continue;
      }
      auto start = std::chrono::steady_clock::now();
      ThermalFrameInput frame;
      frame.index = i;
      frame.timestamp_s = t;
      frame.apparent_c = scan_.LoadThermal(i);
      out_.thermal_load_seconds += internal::MsSince(start) / 1000;
      start = std::chrono::steady_clock::now();
      // The fused depth frames around it: within a depth period and a half of its time.
      std::vector<LiveDepth> live;
      const double t_depth = fusion_->DepthClockTime(t);
      for (const auto& [t_live, depth] : live_) {
        if (std::abs(t_live - t_depth) <= max_live_dt_s_) live.push_back(depth);
      }
      fusion_->AddFrame(reconstruction.volume(), frame, reconstruction.trajectory(), live);
      out_.thermal_seconds += internal::MsSince(start) / 1000;
      ++out_.thermal_frames;
    }
  }

 private:
  const core::Scan& scan_;
  ThermalFusion* fusion_;
  ScanReconstruction& out_;
  int n_ = 0, next_ = 0;
  std::vector<std::pair<double, LiveDepth>> live_;  // the last two fused depth frames, oldest first
  double max_live_dt_s_ = 0.05;
};

}  // namespace

double PoseGapLimitS(const core::Scan& scan) {
  const double period_s = scan.MedianPeriod(core::Stream::kDepth);
  return std::isfinite(period_s) ? std::max(0.1, 3 * period_s) : 0.1;
}

ScanReconstruction ReconstructScan(const core::Scan& scan, Reconstruction& reconstruction,
                                   const ScanReconstructionOptions& options,
                                   const std::function<void(int, int)>& frame_done, ThermalFusion* thermal) {
  assert(options.Check().empty());
  using core::Stream;
  ScanReconstruction out;
  const int n = scan.NumFrames(Stream::kDepth);
  const int first = std::min(options.first_frame, n);
  const int last = options.max_frames > 0 ? std::min(n, first + options.max_frames) : n;
  const bool use_rgb = reconstruction.options().integrate_colour && scan.rig().rgb &&
                       scan.NumFrames(Stream::kRgb) > 0;
  ThermalFeeder feeder(scan, thermal, out);
  const double pose_gap_s = PoseGapLimitS(scan);
  // A frame loaded and being prepared (on its own thread with prepare_ahead) while the one
  // before it is processed.
  struct Pending {
    int index = 0;
    FrameInput frame;
    std::future<PreparedFrame> prepared;
  };
  std::optional<Pending> pending;
  // One thread asked for: one thread used.
  const bool prepare_ahead = options.prepare_ahead && ResolveThreads(reconstruction.options().num_threads) > 1;
  const auto process = [&](Pending& p) {
    const int i = p.index;
    const double t = p.frame.timestamp_s;
    if (options.start_at_groundtruth && reconstruction.trajectory().empty()) {
      const std::optional<core::Rigid3d> gt =
          scan.groundtruth() ? scan.groundtruth()->At(t) : std::nullopt;
      if (!gt) {
        throw std::invalid_argument(core::StringPrintf(
            "start at groundtruth: %s has no pose at %.6f s (depth frame %d)",
            scan.groundtruth() ? "groundtruth.txt" : "the scan has no groundtruth.txt, so it", t, i));
      }
      reconstruction.SetInitialPose(*gt);
    }
    const auto process_start = std::chrono::steady_clock::now();
    const FrameRecord* record_ptr = nullptr;
    if (p.prepared.valid()) {
      const auto wait_start = std::chrono::steady_clock::now();
      PreparedFrame prepared = p.prepared.get();  // rethrows Prepare's invalid_argument
      prepared.wait_ms = internal::MsSince(wait_start);
      prepared.ahead = true;
      record_ptr = &reconstruction.AddFrame(p.frame, std::move(prepared));
    } else {
      record_ptr = &reconstruction.AddFrame(p.frame);
    }
    const FrameRecord& record = *record_ptr;
    out.process_seconds += internal::MsSince(process_start) / 1000;
    out.depth_frame_index.push_back(i);
    if (record.status == FrameStatus::kLost) {
      out.warnings.push_back(core::StringPrintf("depth frame %d at %.6f s: tracking lost (%s), not fused",
                                                i, t, IcpStatusName(record.icp_status).c_str()));
    } else if (record.status == FrameStatus::kUnconstrained) {
      out.warnings.push_back(core::StringPrintf(
          "depth frame %d at %.6f s: unconstrained (the depth leaves a direction free), tracked but not fused", i, t));
    } else if (record.status == FrameStatus::kRecovered) {
      out.warnings.push_back(core::StringPrintf("depth frame %d at %.6f s: tracking recovered", i, t));
    } else if (record.status == FrameStatus::kNoDepth) {
      out.warnings.push_back(core::StringPrintf(
          "depth frame %d at %.6f s: only %.1f %% of pixels have depth, skipped", i, t,
          100 * record.valid_depth_fraction));
    }
    if (thermal && record.fused) {
      feeder.AddDepth(t, p.frame.depth_m, reconstruction.trajectory().poses().back().world_from_sensor);
      feeder.Feed(reconstruction, false);
    }
    if (frame_done) frame_done(i - first + 1, last - first);
  };
  // Processes the pending frame, if any. On the way out of an exception, the frame being
  // prepared is waited for (its thread reads the reconstruction) by the future's destructor.
  const auto flush = [&] {
    if (!pending) return;
    Pending p = std::move(*pending);
    pending.reset();
    process(p);
  };
  for (int i = first; i < last; ++i) {
    const double t = scan.Timestamp(Stream::kDepth, i);
    if (!scan.FrameExists(Stream::kDepth, i)) {
      flush();
      ++out.missing_frames;
      out.warnings.push_back(core::StringPrintf("depth frame %d at %.6f s: %s is missing, skipped",
                                                i, t, scan.FramePath(Stream::kDepth, i).c_str()));
      if (frame_done) frame_done(i - first + 1, last - first);
      continue;
    }
    std::optional<core::Rigid3d> given_pose;
    if (options.poses) {
      given_pose = options.poses->At(t, pose_gap_s);
      if (!given_pose) {
        flush();
        ++out.unposed_frames;
        out.warnings.push_back(core::StringPrintf("depth frame %d at %.6f s: no given pose, skipped", i, t));
        if (frame_done) frame_done(i - first + 1, last - first);
        continue;
      }
    }
    auto load_start = std::chrono::steady_clock::now();
    Pending next;
    next.index = i;
    next.frame = LoadScanFrame(scan, i, use_rgb);
    next.frame.world_from_depth = given_pose;
    out.load_seconds += internal::MsSince(load_start) / 1000;
    if (prepare_ahead) {
      // The frame's own data only (cv::Mat shares the pixels; nothing writes them while the
      // preparation runs), on the calling thread of the preparation alone (Prepare).
      next.prepared = std::async(std::launch::async, [&reconstruction, frame = next.frame] {
        return reconstruction.Prepare(frame, 1);
      });
    }
    flush();
    pending = std::move(next);
  }
  flush();
  if (thermal) {
    feeder.Feed(reconstruction, true);
    const auto flush_start = std::chrono::steady_clock::now();
    thermal->Flush(reconstruction.volume());  // the last window's frame
    out.thermal_seconds += internal::MsSince(flush_start) / 1000;
    const auto finish_start = std::chrono::steady_clock::now();
    thermal->Finish();
    out.thermal_finish_seconds = internal::MsSince(finish_start) / 1000;
  }
  // Depth alone does not fix the pose in front of a plain wall (or a wall and a floor), and
  // nothing in ICP's residual or conditioning shows the slide (README, Tracking without
  // colour): say so when most of the tracking had nothing else — first, as it concerns the
  // whole trajectory (a summary lists the first few warnings).
  int tracked = 0, depth_alone = 0;
  for (const FrameRecord& f : reconstruction.frames()) {
    if (f.status != FrameStatus::kTracked && f.status != FrameStatus::kRecovered) continue;
    ++tracked;
    depth_alone += f.depth_alone;
  }
  if (depth_alone > 0 && 2 * depth_alone >= tracked) {
    out.warnings.insert(out.warnings.begin(), core::StringPrintf(
        "%d of %d tracked frames aligned on depth alone (no colour frame, --no-colour or --photometric-weight 0): "
        "in front of a plain wall, or a wall and a floor, ICP can slide along it with nothing in its residual to "
        "show it (README, Tracking without colour); track with colour, or check the trajectory",
        depth_alone, tracked));
  }
  if (reconstruction.trajectory().empty() && options.poses && out.unposed_frames > 0 &&
      out.unposed_frames + out.missing_frames == last - first) {
    throw core::InputError(scan.IndexPath(Stream::kDepth),
                           core::StringPrintf("none of the %d depth frames used lies within the given poses "
                                              "(%.6f to %.6f s)",
                                              last - first, options.poses->StartTime(), options.poses->EndTime()));
  }
  if (reconstruction.trajectory().empty()) {
    throw core::InputError(scan.IndexPath(Stream::kDepth),
                           core::StringPrintf("no usable depth: none of the %d depth frames used has "
                                              "valid depth on %.0f %% of its pixels",
                                              last - first,
                                              100 * reconstruction.options().min_valid_depth_fraction));
  }
  return out;
}

}  // namespace hw::reconstruct
