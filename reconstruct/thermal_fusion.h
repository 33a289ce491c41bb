#pragma once

// Temperature on the model (HeatWave, Moghadam & Vidas, CSIRO, §2.2): every thermal pixel's
// ray is cast through the thermal lens model into the fused TSDF; the surface it meets gets
// an observation — apparent temperature and, corrected for emissivity (at the viewing angle)
// and reflected temperature (its mirror part traced on the model: thermal_reflections.h),
// surface temperature — with the ray's confidence
// C_R = Π c_i^p_i (thermal_confidence.h). Each observation goes to the voxel nearest the hit
// (a "region" is a voxel: 5 mm at the default voxel size) — or, when the pixel's footprint on
// the surface is wider than a voxel (far or grazing views), to the voxels nearest a grid of
// points covering the footprint, so that no voxel between rays goes unobserved — and the
// rays of one frame are merged per region (one view, one observation); each voxel then keeps, side by side, the estimates of every update
// rule (thermal_update.h) so that they can be compared on one run: the latest observation,
// the plain mean, voxblox's capped running mean, the paper's online rule, and (after the
// scan, from every observation kept) the robust offline mean with the spread across views.
// A mesh vertex reads the voxels of its cell, trilinearly weighted, observed ones only.

#include <array>
#include <cstdint>
#include <string>
#include <span>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core/mat.hpp>

#include "core/radiometry.h"
#include "core/rig.h"
#include "core/trajectory.h"
#include "reconstruct/camera_rays.h"
#include "reconstruct/emissivity_map.h"
#include "reconstruct/raycast.h"
#include "reconstruct/thermal_confidence.h"
#include "reconstruct/thermal_reflections.h"
#include "reconstruct/thermal_scene_correction.h"
#include "reconstruct/thermal_update.h"
#include "reconstruct/tsdf_volume.h"

namespace hw::reconstruct {

struct ThermalFusionOptions {
  ThermalConfidenceOptions confidence;
  // b of the online rule: 0 keeps the most confident view, 1 always takes the newest one.
  // 0.1: a view 0.1 less confident than the region's best still moves it a little, so a
  // surface that changes temperature during the scan is followed (the paper leaves b to
  // the user). [0, 1].
  double recency_bias = 0.1;
  // Weight cap of the capped running mean (voxblox's intensity integrator default is 100
  // observations; thermal regions see tens of frames, so the cap rarely bites). >= 1.
  double capped_mean_max_weight = 100;
  OfflineOptions offline;
  // Depth edges: a pixel is not fused when, within edge_radius_px (Chebyshev), a pixel's ray
  // meets the model nowhere, or nearer or farther than any surface fused could place it: a
  // surface at confidence.max_angle_deg (80°) to the ray changes the range by r·α·tan 80°
  // between rays α apart, so a larger jump is a silhouette. Its value mixes the two sides —
  // the optics' blur and the bolometer's lag spread a pixel over about one more — and the
  // model's silhouette is not where the image's is: the TSDF's zero crossing at a voxel's
  // resolution, the depth camera's edge artefacts, the residual misregistration of the two
  // cameras (together about one pixel more). Its rays would paint the background's
  // temperature on an object's rim and the object's on the background (on a 6 s fixture
  // scan: 12 of 14 false spots). 2 px covers both; it is the thermographer's rule that an
  // object must fill a few pixels around the spot measured.
  int edge_radius_px = 2;  // px, [0, 10]; 0: off
  // Transient occluders: given the depth frames around the thermal frame's time (AddFrame's
  // `live`), a ray is not fused when, within max(edge_radius_px, 1) pixels of it, a ray's
  // model surface lies behind what a depth frame saw along the same line of sight, by more
  // than max(occlusion_margin_m, occlusion_margin_fraction · that depth). The model holds what stayed; a person walking
  // by (reconstruction leaves them out: dynamic_mask.h) or a hand in front of the lens is in
  // the thermal image but not in the model, and their 31–34 °C would be laid on the surface
  // behind them. Margins as DynamicMaskOptions (depth noise, uncalibrated distortion, a
  // pixel's misregistration at silhouettes). m, >= 0; fraction in [0, 1); both 0: off.
  double occlusion_margin_m = 0.1;
  double occlusion_margin_fraction = 0.05;
  // Rays whose confidence is below this are not fused at all: a zero-confidence view can
  // still move the online estimate (Q = b − C_A > 0), and it carries no information. [0, 1).
  double min_ray_confidence = 0.01;
  // A thermal frame is fused only between two fused depth poses at most this far apart
  // (depth clock): a tracking gap or the ends of the trajectory are not bridged. s, > 0.
  // `heatwave reconstruct` raises it to PoseGapLimitS (three depth frame periods).
  double max_pose_gap_s = 0.1;
  // The thermal camera's vignetting left after its own radiometric calibration, as the
  // radiance lost at the image corners: pixels read L·(1 − v·r²), r the pixel centre's
  // distance from the principal point over the farthest corner's. Microbolometer optics lose
  // 2–10 % at the corners (cos⁴ falloff, housing emission), which is 1–3 K at room
  // temperature; uncorrected, it biases every view by where in the image it saw a surface.
  // 0: none (the camera's calibration removed it); the calibration bench measures it. [0, 1).
  double vignetting = 0;
  // Scene-based correction of the camera's frame and pixel offsets against the model
  // (thermal_scene_correction.h), applied to every frame before its rays are fused.
  SceneCorrectionOptions scene_correction;
  // The mirror part of each ray's reflection traced on the model (thermal_reflections.h):
  // the operator's body, a surface the mirror ray meets, or the room.
  ThermalReflectionOptions reflections;
  // The estimate written to temperature_c / temperature_apparent_c.
  ThermalMethod method = ThermalMethod::kOffline;
  // Keep the per-frame region observations for the offline estimate (16 bytes each, 2–5 MB
  // per 320×240 thermal frame at 5 mm voxels); false: only the streaming rules (live use).
  bool keep_observations = true;
  // The offline estimate uses each region's max_views_per_region most confident views
  // (ties: the earlier), and fewer are kept: the kept observations are compacted to them
  // whenever that would drop at least half of them, so memory is bounded per region rather
  // than growing with the time spent on it (unbounded, a 30 Hz camera keeps 0.8–1 GB per
  // 4 s of scanning). 64: two seconds of views at 30 Hz, enough for the median and MAD of
  // the robust estimate; the views dropped are the least confident ones, which weigh least.
  // 0: every view (memory unbounded). >= 0.
  int max_views_per_region = 64;
  // Frame selection: the frames that have a pose (frozen ones do not count) are taken in
  // windows of frame_interval_s — a window opens with its first frame and holds the frames
  // less than frame_interval_s after it — and only the window's most confident frame is
  // fused: highest c1^p1 · c5^p5 (thermal_confidence.h) at a 3×3 grid of pixels at the last
  // fused frame's median range, i.e. the least blurred, the farthest from a shutter event;
  // ties go to the earlier. The others are skipped (ThermalFrameStatus::kSkipped). A frame
  // costs its raycast and splatting (~100 ms for 320×240 on two cores, README), so a 30 Hz
  // camera's stream costs 3 s per second of scanning; its consecutive frames are nearly the
  // same view, and the ones skipped are those the confidence would have discounted. 0.09 s:
  // about 10 fused frames a second — three frames per window at 30 Hz, six at 60 Hz, each
  // window's end 10 and 7 ms from a frame, so timestamp jitter does not move frames across
  // it — and every frame of a 9 Hz camera (a Lepton: 21 ms of margin). Measured on
  // full-size 4 s sweeps (README, Frame selection, measured): the smooth ones' error
  // unchanged (offline 0.588 → 0.569 K after gain/offset) with 1.6–2.6 % fewer vertices
  // observed, the jerky one's +0.04 K, the whole pipeline 1.7–2.1× faster (5.8 → 12.3
  // frames/s).
  // The chosen frame is held until the window closes (the next window's first frame, or
  // Flush): live use fuses it up to frame_interval_s plus a frame period late. 0: every frame
  // as it comes. s, [0, 1].
  double frame_interval_s = 0.09;
  // With frame_interval_s > 0: a fused frame's shading, correction and splatting (everything
  // after its raycast; ~60 % of its cost, README) run on a thread of their own while the
  // caller goes on — the depth pipeline integrating and tracking the next frames — and the
  // next fusion, Flush, Finish or any accessor waits for them. The model and every record
  // are the same bits either way; the depth pipeline alone leaves one of the two cores idle
  // ~30 % of the time, which this fills. AddFrame's record of a frame fused in the
  // background is complete after the next call (frames() waits).
  bool background = true;
  // Depth range of the thermal rays, m (the pipeline sets it from its own).
  double min_depth_m = 0.3;  // >= 0
  double max_depth_m = 5.0;  // > min_depth_m
  int num_threads = 0;       // 0: hardware concurrency

  std::string Check() const;  // names the field (with its group, e.g. "confidence.motion_power")
};

// Why a thermal frame was not fused.
enum class ThermalFrameStatus {
  kFused,
  kNoPose,    // no fused depth poses around its time within max_pose_gap_s
  kFrozen,    // the same pixels as the previous frame (shutter closure: a stale image)
  kNoSurface, // no ray met the model
  kSkipped,   // a more confident frame of its window was fused instead (frame_interval_s)
  kHeld,      // the most confident of its window so far, held until the window closes
};
std::string ThermalFrameStatusName(ThermalFrameStatus status);  // "fused", "no-pose", ...

// What fusion did with one thermal frame.
struct ThermalFrameRecord {
  int index = 0;                 // the scan's thermal frame index (or order of arrival)
  double timestamp_s = 0;        // thermal clock
  double depth_clock_s = 0;      // timestamp_s + the rig's thermal time offset
  ThermalFrameStatus status = ThermalFrameStatus::kNoPose;
  double time_since_ffc_s = 0;   // NaN when unknown (no shutter event listed before it)
  double linear_speed_mps = 0, angular_speed_dps = 0;  // thermal camera, from the trajectory
  // c1^p1 · c5^p5 of the frame, mean over a 3×3 grid of pixels (frame_interval_s), in [0, 1].
  double frame_confidence = 0;
  int rays = 0;                  // pixels with a ray through the lens model
  int hits = 0;                  // rays that met the model
  int fused = 0;                 // hits fused (confidence >= min_ray_confidence, a normal,
                                 // a surface temperature)
  int low_confidence = 0;        // hits rejected for confidence
  int no_normal = 0;             // hits without a normal (rim of the observed surface)
  int depth_edge = 0;            // hits next to a depth edge (edge_radius_px)
  int occluded = 0;              // hits behind something the live depth saw nearer
  bool live_depth = false;       // a depth frame was given for the occlusion test
  int no_surface_temperature = 0;  // emissivity correction impossible (reading colder than
                                   // the reflection alone), core::SurfaceFromApparent
  double mean_confidence = 0;    // over fused rays
  int regions_updated = 0;
  // Reflections (ThermalFusionOptions::reflections): hits whose mirror ray was traced, and of
  // the fused rays among them those whose mirror met the operator's body or a model surface
  // with a temperature (this frame's reading or the fused one); the rest took the room.
  int mirror_traced = 0;
  int mirror_operator = 0;
  int mirror_surface = 0;
  // Scene-based correction (ThermalFusionOptions::scene_correction): rays paired with their
  // region's latest view by a near-same pixel (the frame offset's), rays that met a reference
  // region (the pixel offsets'), each within max_residual_k, whether the pairs sufficed for
  // this frame's own offset, the offset removed (K), and the RMS of the pixel offsets after
  // the frame (K).
  int pair_rays = 0;
  int pair_shift_px = -1;        // the largest pixel shift of the pairs used; -1: not measured
  int reference_rays = 0;
  bool offset_estimated = false;
  double offset_correction_k = 0;
  double pixel_offset_rms_k = 0;
  // The raycast, the emissivity lookup with the mirror rays (ReflectPixels; both in the
  // caller), and the rest (shading, correction, splatting; in the background stage when it
  // runs), ms.
  double raycast_ms = 0, reflect_ms = 0, fuse_ms = 0;
};

// A depth frame near a thermal frame's time, for the occlusion test
// (ThermalFusionOptions::occlusion_margin_m).
struct LiveDepth {
  cv::Mat depth_m;  // CV_32FC1 metres as the rig's depth camera saw it (lens distortion in), 0 = none
  core::Rigid3d world_from_depth;  // its fused pose
};

// One thermal frame as the camera delivered it.
struct ThermalFrameInput {
  int index = 0;
  double timestamp_s = 0;  // thermal clock, s
  cv::Mat apparent_c;      // CV_32FC1 apparent temperature, °C, the rig's thermal size
};

// The estimate of one method at a set of points.
struct PointTemperatures {
  std::vector<float> surface_c;       // NaN where unobserved
  std::vector<float> apparent_c;      // NaN where unobserved
  std::vector<float> confidence;      // 0 where unobserved
  std::vector<float> std_c;           // spread across views, NaN where unobserved
  // Size of a thermal pixel on the surface, m: √(across · along) of the footprint, mean over
  // the views weighted by their confidence (all views, whatever the method); NaN where
  // unobserved. The thermal image's resolution at the point.
  std::vector<float> footprint_m;
  // Where it was seen from: the vector from the point to the thermal camera's centre, world
  // frame, m, mean over the views weighted by their confidence (all views, whatever the
  // method); NaN where unobserved. analyze/ mirrors it about the surface normal to find
  // what a shiny surface reflected into the camera (the operator, a hotter object).
  std::vector<Eigen::Vector3f> view_m;
  // Frames that observed it (offline: the inlier views among the most confident kept,
  // max_views_per_region at most), 0 where unobserved.
  std::vector<uint16_t> views;
};

class ThermalFusion {
 public:
  // Asserts options.Check() is empty and that the rig has a thermal camera and block.
  // ffc_timestamps_s: thermal-clock flat-field events (Scan::ffc_timestamps_s), increasing.
  ThermalFusion(const core::Rig& rig, const ThermalFusionOptions& options, EmissivityMap emissivity,
                std::vector<double> ffc_timestamps_s);
  ~ThermalFusion();
  ThermalFusion(ThermalFusion&&) noexcept;
  ThermalFusion& operator=(ThermalFusion&&) noexcept;

  // Depth-clock time of a thermal frame (timestamp_s + the rig's thermal time offset).
  double DepthClockTime(double thermal_timestamp_s) const;
  // True once `world_from_depth` holds a pose at or after the frame's depth-clock time, so
  // that AddFrame can interpolate (live use: hold frames until then).
  bool PoseAvailable(double thermal_timestamp_s, const core::Trajectory& world_from_depth) const;

  // Fuses one frame: its pose is world_from_depth interpolated at its depth-clock time (a
  // gap above max_pose_gap_s: kNoPose) composed with depth_from_thermal; its velocity the
  // finite difference of the two poses around it. Throws std::invalid_argument when
  // apparent_c is not CV_32FC1 of the rig's thermal size. Frames may come in any order
  // (the online rule then follows arrival order). `live`: the fused depth frames around the
  // frame's time, for the occlusion test (empty: no test); asserts their size and type.
  // With frame_interval_s > 0 a frame may be held (kHeld) and fused by a later call, against
  // the volume that call is given: `live`'s images are kept (shared, not copied) until then,
  // so the caller must not write into them. The reference is valid until the next call.
  // The volume is read only during the calls (ThermalFusionOptions::background runs on
  // without it): the caller may integrate into it between them.
  const ThermalFrameRecord& AddFrame(const TsdfVolume& volume, const ThermalFrameInput& frame,
                                     const core::Trajectory& world_from_depth,
                                     std::span<const LiveDepth> live = {});

  // Fuses the frame held for the current window (frame_interval_s > 0; no-op when none is)
  // and starts a new window. Call after the last AddFrame, before Finish.
  void Flush(const TsdfVolume& volume);

  // Computes the offline estimate from the kept observations (no-op without them). Call
  // after the last frame (and Flush); AddFrame after it invalidates it. Asserts that no
  // frame is held.
  void Finish();

  // Each method's estimate at world points (mesh vertices). kOffline before Finish() or
  // without kept observations: unobserved everywhere.
  PointTemperatures Sample(const std::vector<Eigen::Vector3f>& points_in_world,
                           ThermalMethod method) const;

  const std::vector<ThermalFrameRecord>& frames() const;
  const ThermalFusionOptions& options() const;
  const EmissivityMap& emissivity() const;  // what the correction assumes where
  size_t NumRegions() const;     // voxels with at least one observation
  size_t NumObservations() const;  // kept for the offline estimate
  // Observations dropped by max_views_per_region so far (at compactions and Finish).
  size_t NumObservationsDropped() const;
  size_t MemoryBytes() const;
  // Rejections by the offline estimator over all regions (after Finish).
  int64_t OfflineRejected() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace hw::reconstruct
