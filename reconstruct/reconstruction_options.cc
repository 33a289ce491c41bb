#include "reconstruct/reconstruction.h"

// The pipeline's options: their validation and the stage options they imply, and the frame
// status names.

#include <cmath>
#include <string>
#include <utility>

#include "reconstruct/option_check.h"

namespace hw::reconstruct {

using internal::Fail;
using internal::InRange;

namespace internal {

ReconstructionOptions EffectiveOptions(ReconstructionOptions o) {
  o.tsdf.min_depth_m = o.depth.min_depth_m = o.raycast.min_depth_m = o.min_depth_m;
  o.tsdf.max_depth_m = o.depth.max_depth_m = o.raycast.max_depth_m = o.max_depth_m;
  o.tsdf.num_threads = o.depth.num_threads = o.icp.num_threads = o.raycast.num_threads =
      o.mesh.num_threads = o.prealign.num_threads = o.num_threads;
  if (o.raycast_level >= 0 && o.raycast_level < static_cast<int>(o.icp.iterations.size())) {
    for (int l = 0; l < o.raycast_level; ++l) o.icp.iterations[l] = 0;
    if (o.raycast_level < o.depth.num_levels) o.depth.first_map_level = o.raycast_level;
  }
  return o;
}

}  // namespace internal

std::string FrameStatusName(FrameStatus status) {
  switch (status) {
    case FrameStatus::kInitialised: return "initialised";
    case FrameStatus::kTracked: return "tracked";
    case FrameStatus::kRecovered: return "recovered";
    case FrameStatus::kLost: return "lost";
    case FrameStatus::kUnconstrained: return "unconstrained";
    case FrameStatus::kNoDepth: return "no_depth";
    case FrameStatus::kPosed: return "posed";
  }
  return "?";
}

std::string ReconstructionOptions::Check() const {
  if (!(min_depth_m >= 0) || !std::isfinite(min_depth_m)) return Fail("min_depth_m", min_depth_m, ">= 0 m");
  if (!(max_depth_m > min_depth_m) || !std::isfinite(max_depth_m)) {
    return Fail("max_depth_m", max_depth_m, "finite and > min_depth_m");
  }
  if (!InRange(min_valid_depth_fraction, 0, 1)) {
    return Fail("min_valid_depth_fraction", min_valid_depth_fraction, "in [0, 1]");
  }
  if (!(relocalisation_max_conflict >= 0 && relocalisation_max_conflict <= 1)) {
    return Fail("relocalisation_max_conflict", relocalisation_max_conflict, "in [0, 1]");
  }
  if (!(relocalisation_widening >= 1) || !std::isfinite(relocalisation_widening)) {
    return Fail("relocalisation_widening", relocalisation_widening, ">= 1");
  }
  if (!(basin_check_m >= 0 && basin_check_m <= 0.1)) return Fail("basin_check_m", basin_check_m, "in [0, 0.1] (0: off)");
  if (!(max_condition_ratio > 1) || !std::isfinite(max_condition_ratio)) {
    return Fail("max_condition_ratio", max_condition_ratio, "> 1 and finite");
  }
  if (!(max_residual_ratio > 1) || !std::isfinite(max_residual_ratio)) {
    return Fail("max_residual_ratio", max_residual_ratio, "> 1 and finite");
  }
  if (num_threads < 0) return Fail("num_threads", num_threads, ">= 0");
  if (raycast_level < 0 || raycast_level > 2 || raycast_level >= depth.num_levels) {
    return Fail("raycast_level", raycast_level, "in [0, 2] and < depth.num_levels");
  }
  if (icp.iterations[raycast_level] == 0 &&
      (raycast_level + 1 >= 3 || icp.iterations[raycast_level + 1] == 0) &&
      (raycast_level + 2 >= 3 || icp.iterations[raycast_level + 2] == 0)) {
    return Fail("icp.iterations", 0, "> 0 at raycast_level or a coarser level");
  }
  if (raycast_interval < 1 || raycast_interval > 8) return Fail("raycast_interval", raycast_interval, "in [1, 8]");
  // The reuse and integration limits: each > 0 and finite.
  for (const auto& [name, value] : {std::pair<const char*, double>{"reuse_max_correction_m", reuse_max_correction_m},
                                    {"reuse_max_correction_deg", reuse_max_correction_deg},
                                    {"reuse_max_motion_m", reuse_max_motion_m},
                                    {"reuse_max_motion_deg", reuse_max_motion_deg},
                                    {"integrate_max_motion_m", integrate_max_motion_m},
                                    {"integrate_max_motion_deg", integrate_max_motion_deg}}) {
    if (!(value > 0) || !std::isfinite(value)) return Fail(name, value, "> 0 and finite");
  }
  if (!(reuse_lead >= 0 && reuse_lead <= 1)) return Fail("reuse_lead", reuse_lead, "in [0, 1]");
  const ReconstructionOptions e = internal::EffectiveOptions(*this);
  if (std::string m = e.tsdf.Check(); !m.empty()) return "tsdf." + m;
  if (std::string m = e.depth.Check(); !m.empty()) return "depth." + m;
  if (std::string m = e.icp.Check(); !m.empty()) return "icp." + m;
  if (std::string m = e.raycast.Check(); !m.empty()) return "raycast." + m;
  if (std::string m = e.mesh.Check(); !m.empty()) return "mesh." + m;
  if (std::string m = e.dynamic.Check(); !m.empty()) return "dynamic." + m;
  if (std::string m = keyframes.Check(); !m.empty()) return "keyframes." + m;
  if (std::string m = prealign.Check(); !m.empty()) return "prealign." + m;
  return "";
}

std::string ScanReconstructionOptions::Check() const {
  if (first_frame < 0) return Fail("first_frame", first_frame, ">= 0");
  if (max_frames < 0) return Fail("max_frames", max_frames, ">= 0 (0: all)");
  return "";
}

}  // namespace hw::reconstruct
