#include "reconstruct/reconstruction.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "core/error.h"
#include "core/ply.h"
#include "core/scan.h"
#include "reconstruct/reconstruct_test_support.h"
#include "reconstruct/surface_eval.h"
#include "reconstruct/trajectory_eval.h"

namespace hw::reconstruct {
namespace {

using core::Stream;
namespace fs = std::filesystem;
using test::CachedScan;
using test::TestScanOptions;

constexpr double kDeg = std::numbers::pi / 180;

using test::PipelineTestOptions;

using test::Outcome;
using test::ReconstructAndEvaluate;

TEST(Reconstruction, SmoothScanTracksEveryFrameWithinMillimetres) {
  const core::Scan scan = core::Scan::Open(CachedScan("smooth", TestScanOptions()));
  const Outcome run = ReconstructAndEvaluate(scan, PipelineTestOptions());
  int fused = 0;
  for (const FrameRecord& f : run.frames) fused += f.fused;
  EXPECT_EQ(fused, static_cast<int>(run.frames.size()));
  EXPECT_EQ(run.eval.associated_pairs, fused);
  // ATE bound: at 160×120 one pixel spans 7 mm at 1 m and the depth noise is ~3 mm there;
  // ICP over ~10k points averages both down to ~1 mm per frame, and a 1 s smooth sweep
  // accumulates a few of those. 10 mm is 1.4 pixels: a tracker off by more has failed.
  EXPECT_LT(run.eval.ate_m.rmse, 0.010);
  EXPECT_LT(run.eval.rpe_deg.rmse, 1.0);
}

TEST(Reconstruction, ModelSurfaceLiesOnTheTruthMesh) {
  const fs::path folder = CachedScan("smooth", TestScanOptions());
  const core::Scan scan = core::Scan::Open(folder);
  const Outcome run = ReconstructAndEvaluate(scan, PipelineTestOptions());
  ASSERT_GT(run.mesh.faces.size(), 1000u);
  const core::PlyMesh truth = core::ReadPly(folder / "truth" / "scene.ply");
  std::vector<Eigen::Vector3d> points;
  for (const Eigen::Vector3f& p : run.mesh.positions) {
    points.push_back(p.cast<double>());  // started at the true pose: in the truth's frame
  }
  const SurfaceDistanceStats s =
      SummarizeDistances(PointToMeshDistances(points, truth.Positions(), truth.faces, 0.05));
  // Median within half a voxel: the TSDF's zero crossing is interpolated, the remaining
  // error is the depth noise averaged over the frames and the tracking error above.
  EXPECT_LT(s.median_m, 0.005);
  EXPECT_LT(s.p90_m, 0.015);
  // Outliers (vertices > 5 cm from any true surface): edge artefacts that survived.
  EXPECT_LT(s.beyond_search, s.points / 50);
  // Colour: the model is painted (the scene has no black surfaces).
  int dark = 0;
  for (const Rgb8& c : run.mesh.colours) dark += c.cast<int>().sum() < 15;
  EXPECT_LT(dark, static_cast<int>(run.mesh.colours.size()) / 20);
}

// Frames with a known pose, then tracked ones (a motion-capture stretch, then none): the
// posed frames keep a model view for the dynamic mask only, cast without colour; the first
// tracked frame casts its own view, with colour for the photometric term, and tracks.
TEST(Reconstruction, TrackedFramesAfterPosedOnesTrackAgainstAFreshView) {
  const core::Scan scan = core::Scan::Open(CachedScan("smooth", TestScanOptions()));
  Reconstruction reconstruction(scan.rig(), PipelineTestOptions());
  int posed_raycasts = 0;
  for (int i = 0; i < scan.NumFrames(Stream::kDepth); ++i) {
    if (!scan.FrameExists(Stream::kDepth, i)) continue;
    FrameInput frame = LoadScanFrame(scan, i, true);
    if (i < 10) frame.world_from_depth = scan.groundtruth()->At(frame.timestamp_s);
    const FrameRecord& record = reconstruction.AddFrame(frame);
    if (i < 10) {
      EXPECT_EQ(record.status, FrameStatus::kPosed);
      posed_raycasts += record.raycast_ms > 0;
    } else {
      EXPECT_EQ(record.status, FrameStatus::kTracked) << "frame " << i;
    }
  }
  // Cast as for tracking: the first, then whenever the camera moved beyond the reuse limits
  // (at least every raycast_interval-th) — not every frame on this slow sweep.
  EXPECT_GE(posed_raycasts, 2);
  EXPECT_LT(posed_raycasts, 10);
  // As SmoothScanTracksEveryFrameWithinMillimetres: tracked from a posed start, within 1 cm.
  const TrajectoryEval eval = EvaluateTrajectory(reconstruction.trajectory(), *scan.groundtruth(), {});
  EXPECT_LT(eval.ate_m.rmse, 0.010);
}

// The rig's depth_correction is applied to every incoming frame before anything else: a
// rig with one, given raw frames, builds exactly what a rig without one builds from frames
// corrected beforehand (poses and model, bit for bit).
TEST(Reconstruction, RigDepthCorrectionIsAppliedToIncomingDepth) {
  const core::Scan scan = core::Scan::Open(CachedScan("smooth", TestScanOptions()));
  core::Rig corrected_rig = scan.rig();
  core::DepthCorrection correction = core::DepthCorrection::ZeroOver(scan.rig().depth, 5, 4);
  for (size_t k = 0; k < correction.offset_per_m.size(); ++k) {
    correction.offset_per_m[k] = 0.004 * std::cos(1.7 * static_cast<double>(k));  // 36 mm at 3 m
  }
  corrected_rig.depth_correction = correction;
  const cv::Mat offsets = core::DepthOffsetMap(correction, scan.rig().depth);
  Reconstruction with_rig(corrected_rig, PipelineTestOptions());
  Reconstruction beforehand(scan.rig(), PipelineTestOptions());
  Reconstruction uncorrected(scan.rig(), PipelineTestOptions());
  for (int i = 0; i < 8; ++i) {
    if (!scan.FrameExists(Stream::kDepth, i)) continue;
    FrameInput frame = LoadScanFrame(scan, i, true);
    with_rig.AddFrame(frame);
    uncorrected.AddFrame(frame);
    core::CorrectDepth(offsets, &frame.depth_m);
    beforehand.AddFrame(frame);
  }
  ASSERT_EQ(with_rig.trajectory().size(), beforehand.trajectory().size());
  for (size_t i = 0; i < with_rig.trajectory().size(); ++i) {
    const core::PoseError e = core::ComparePoses(with_rig.trajectory().poses()[i].world_from_sensor,
                                                 beforehand.trajectory().poses()[i].world_from_sensor);
    EXPECT_EQ(e.translation_m, 0.0);
  }
  const TriangleMesh a = with_rig.ExtractMesh(), b = beforehand.ExtractMesh(), c = uncorrected.ExtractMesh();
  ASSERT_EQ(a.positions.size(), b.positions.size());
  EXPECT_EQ(a.positions, b.positions);
  // ... and the correction did change the model (the test is not comparing two no-ops).
  EXPECT_TRUE(a.positions.size() != c.positions.size() || a.positions != c.positions);
}

TEST(Reconstruction, GarbageFrameIsLostNotFusedAndTrackingRecovers) {
  const core::Scan scan = core::Scan::Open(CachedScan("smooth", TestScanOptions()));
  Reconstruction reconstruction(scan.rig(), PipelineTestOptions());
  const int n = std::min(20, scan.NumFrames(Stream::kDepth));
  int bad_index = -1;
  for (int i = 0; i < n; ++i) {
    if (!scan.FrameExists(Stream::kDepth, i)) continue;
    FrameInput frame = LoadScanFrame(scan, i, true);
    if (i == 10) {
      // A view of something else: the frame upside down and 60 cm deeper (a person stepping
      // in front of the sensor looks no more like the model than this).
      cv::Mat flipped;
      cv::flip(frame.depth_m, flipped, -1);
      frame.depth_m = flipped + 0.6f;
      frame.depth_m.setTo(0, flipped == 0);
      bad_index = static_cast<int>(reconstruction.frames().size());
    }
    reconstruction.AddFrame(frame);
  }
  ASSERT_GE(bad_index, 0);
  const auto& frames = reconstruction.frames();
  EXPECT_EQ(frames[bad_index].status, FrameStatus::kLost);
  EXPECT_FALSE(frames[bad_index].fused);
  EXPECT_NE(frames[bad_index].icp_status, IcpStatus::kOk);
  ASSERT_GT(frames.size(), size_t(bad_index + 1));
  EXPECT_EQ(frames[bad_index + 1].status, FrameStatus::kRecovered);
  // No pose at the lost frame's time, and every fused pose still on the truth.
  for (const core::TimedPose& p : reconstruction.trajectory().poses()) {
    EXPECT_NE(p.timestamp_s, frames[bad_index].timestamp_s);
  }
  const TrajectoryEval eval = EvaluateTrajectory(reconstruction.trajectory(), *scan.groundtruth(), {});
  EXPECT_LT(eval.ate_m.rmse, 0.010);
}

TEST(Reconstruction, FramesWithoutDepthAreSkipped) {
  const core::Scan scan = core::Scan::Open(CachedScan("smooth", TestScanOptions()));
  Reconstruction reconstruction(scan.rig(), PipelineTestOptions());
  FrameInput frame;
  frame.timestamp_s = 1;
  frame.depth_m = cv::Mat::zeros(scan.rig().depth.height, scan.rig().depth.width, CV_32FC1);
  EXPECT_EQ(reconstruction.AddFrame(frame).status, FrameStatus::kNoDepth);
  frame.timestamp_s = 2;
  frame.depth_m.setTo(std::numeric_limits<float>::quiet_NaN());
  EXPECT_EQ(reconstruction.AddFrame(frame).status, FrameStatus::kNoDepth);
  EXPECT_TRUE(reconstruction.trajectory().empty());
  EXPECT_EQ(reconstruction.volume().NumBlocks(), 0u);
}

TEST(Reconstruction, WrongFramesThrow) {
  const core::Scan scan = core::Scan::Open(CachedScan("smooth", TestScanOptions()));
  Reconstruction reconstruction(scan.rig(), PipelineTestOptions());
  FrameInput frame;
  frame.timestamp_s = 1;
  frame.depth_m = cv::Mat::zeros(10, 10, CV_32FC1);
  EXPECT_THROW(reconstruction.AddFrame(frame), std::invalid_argument);
  frame.depth_m = cv::Mat::zeros(scan.rig().depth.height, scan.rig().depth.width, CV_16UC1);
  EXPECT_THROW(reconstruction.AddFrame(frame), std::invalid_argument);
  frame.depth_m = scan.LoadDepth(0);
  reconstruction.AddFrame(frame);
  EXPECT_THROW(reconstruction.AddFrame(frame), std::invalid_argument);  // same timestamp
}

// Pose errors of a run's fused frames from the truth (no alignment: it started at the
// truth), in fusion order, and the same sorted.
struct PoseErrors {
  std::vector<double> in_order_m, early_m, sorted_m;
};
PoseErrors ErrorsFromTruth(const core::Scan& scan, const Reconstruction& reconstruction) {
  PoseErrors e;
  const double t0 = reconstruction.trajectory().poses().front().timestamp_s;
  for (const core::TimedPose& p : reconstruction.trajectory().poses()) {
    const auto truth = scan.groundtruth()->At(p.timestamp_s);
    EXPECT_TRUE(truth);
    if (!truth) continue;
    e.in_order_m.push_back(core::ComparePoses(*truth, p.world_from_sensor).translation_m);
    if (p.timestamp_s - t0 < 0.5) e.early_m.push_back(e.in_order_m.back());
  }
  e.sorted_m = e.in_order_m;
  std::sort(e.sorted_m.begin(), e.sorted_m.end());
  return e;
}

TEST(Reconstruction, JerkyScanTracksOrReportsLostFramesAndRecovers) {
  const core::Scan scan =
      core::Scan::Open(CachedScan("jerky", TestScanOptions("equipment-small", fixtures::MotionKind::kJerky, 2.0)));
  Reconstruction reconstruction(scan.rig(), PipelineTestOptions());
  ScanReconstructionOptions options;
  options.start_at_groundtruth = true;
  ReconstructScan(scan, reconstruction, options);
  int fused = 0, lost = 0, recovered = 0;
  for (const FrameRecord& f : reconstruction.frames()) {
    fused += f.fused;
    lost += f.status == FrameStatus::kLost;
    recovered += f.status == FrameStatus::kRecovered;
  }
  // The jerky path's bursts (0.3 s shoves at 1–2 m/s, motion-blurred depth) break
  // frame-to-model tracking at 160×120: those frames must be reported lost, and tracking
  // must come back after each run of them.
  EXPECT_GT(fused, static_cast<int>(reconstruction.frames().size()) * 7 / 10);
  EXPECT_GT(lost, 0);
  EXPECT_GT(recovered, 0);
  EXPECT_FALSE(reconstruction.lost());
  // Fused poses: before the first burst (the first 0.5 s) within a centimetre of the truth
  // (the smooth scan's are within 4 mm; measured up to 8.8 mm here). The bursts themselves
  // are not tracked at this size, and where a frame lands after one depends on each burst's
  // chaotic details: measured with stop 43's tracking, a relocalised frame 257 mm off, fused,
  // holding the frames after it (90th percentile 146 mm); since stop 44 (the pre-alignment's
  // depth check, which refuses the first burst's 6° grey alignment) that burst is tracked
  // 180–219 mm off instead of lost, 90th percentile 156 mm, median 68 mm — while over
  // thirteen seeds of the path the changes move the mean ATE 71 → 83 mm (README
  // "Reconstruction", Jerky motion). Beyond the first 0.5 s the bounds say only that tracking
  // has not run away: 0.2 m at the 90th percentile, 0.3 m at worst (the bursts move the rig
  // 0.3–0.6 m).
  const PoseErrors e = ErrorsFromTruth(scan, reconstruction);
  ASSERT_GT(e.early_m.size(), 10u);
  EXPECT_LT(*std::max_element(e.early_m.begin(), e.early_m.end()), 0.010);
  std::printf("jerky 160x120: pose error median %.1f mm, 90th percentile %.1f mm, worst %.1f mm\n",
              e.sorted_m[e.sorted_m.size() / 2] * 1e3, e.sorted_m[e.sorted_m.size() * 9 / 10] * 1e3,
              e.sorted_m.back() * 1e3);
  EXPECT_LT(e.sorted_m[e.sorted_m.size() * 9 / 10], 0.2);
  EXPECT_LT(e.sorted_m.back(), 0.3);
}

// Relocalisation checked against the model's free space (relocalisation_max_conflict), on
// the jerky scan tracked as before stop 44 (the pre-alignment's depth check off), where the
// first burst is lost: its frames' relocalisation candidates converged 0.25 m off, stand in
// front of the model's surfaces and see through them (conflict 5–9 % against 0–2 % at
// tracked poses) and were fused, the worst pose 254 mm off. Refused, the burst recovers
// later and the worst pose is 136 mm; every recovered frame agrees with the model, every
// refused frame stays lost with the reason.
TEST(Reconstruction, ARelocalisationThatContradictsTheModelIsRefused) {
  const core::Scan scan =
      core::Scan::Open(CachedScan("jerky", TestScanOptions("equipment-small", fixtures::MotionKind::kJerky, 2.0)));
  ReconstructionOptions o = PipelineTestOptions();
  o.prealign.max_depth_misfit_ratio = 0;
  Reconstruction reconstruction(scan.rig(), o);
  ScanReconstructionOptions options;
  options.start_at_groundtruth = true;
  ReconstructScan(scan, reconstruction, options);
  int rejected = 0, recovered = 0;
  for (const FrameRecord& f : reconstruction.frames()) {
    rejected += f.conflict_rejections;
    if (f.status == FrameStatus::kRecovered) {
      ++recovered;
      EXPECT_LE(f.model_conflict, o.relocalisation_max_conflict) << f.index;
    }
    if (f.status == FrameStatus::kLost && f.conflict_rejections > 0) {
      EXPECT_EQ(f.icp_status, IcpStatus::kModelConflict) << f.index;
      EXPECT_GT(f.model_conflict, o.relocalisation_max_conflict) << f.index;
    }
    if (f.status == FrameStatus::kTracked && f.integrated) {
      EXPECT_TRUE(std::isfinite(f.model_conflict)) << f.index;
    }
  }
  EXPECT_GT(rejected, 0);
  EXPECT_GT(recovered, 0);
  EXPECT_FALSE(reconstruction.lost());
  const PoseErrors e = ErrorsFromTruth(scan, reconstruction);
  std::printf("jerky 160x120, relocalisations checked: worst pose %.1f mm; %d candidates refused\n",
              e.sorted_m.back() * 1e3, rejected);
  EXPECT_LT(e.sorted_m.back(), 0.2);
}

// 2.5 s of a 10 Hz depth stream at full size (640×480), recorded from the middle of the
// equipment loop's walk past the breakers (0.45 m/s: 45 mm and 1.8° between frames at the
// start), depth only. The 160×120 test scans track such steps from the start at 1 cm voxels;
// at full size and 5 mm voxels the second frame did not (the issue was found on a 31 s
// window of the same walk). Renders in about 15 s, once.
fixtures::SynthScanOptions WalkAt10HzOptions() {
  fixtures::SynthScanOptions o = fixtures::SynthScanOptions::Full("equipment");
  o.motion = fixtures::MotionKind::kLoop;
  o.loop_duration_s = 90;
  o.path_start_s = 4;
  o.duration_s = 2.5;
  o.depth_rate_hz = 10;
  o.write_rgb = false;
  o.write_thermal = false;
  return o;
}

// Every pose within `bound_m` of the truth (the reconstruction started at the true pose).
void ExpectOnTheTruth(const Reconstruction& reconstruction, const core::Scan& scan, double bound_m) {
  for (const core::TimedPose& p : reconstruction.trajectory().poses()) {
    const auto truth = scan.groundtruth()->At(p.timestamp_s);
    ASSERT_TRUE(truth);
    EXPECT_LT(core::ComparePoses(*truth, p.world_from_sensor).translation_m, bound_m)
        << "at " << p.timestamp_s << " s";
  }
}

// The second frame has no velocity to predict from: the view moved further than the
// association gate, ICP from the first pose converged on 13 % of the points (< 15 %) and the
// scan was lost until the rig slowed down 2.5 s later. Now it is retried with the gate
// widened 2× (the jump limits kept) and tracked.
TEST(Reconstruction, ASlowStreamStartedMidWalkTracksFromItsSecondFrame) {
  const core::Scan scan = core::Scan::Open(CachedScan("walk10hz-full", WalkAt10HzOptions()));
  Reconstruction reconstruction(scan.rig(), ReconstructionOptions{});
  ScanReconstructionOptions options;
  options.start_at_groundtruth = true;
  ReconstructScan(scan, reconstruction, options);
  ASSERT_EQ(reconstruction.frames().size(), 25u);
  // Every frame fused, but for those the basin check finds unconstrained (depth alone along
  // the cabinet front; measured: the second frame, against a model of one frame), which are
  // not fused but carry the motion on: the next frame recovers from there. Stop 59 reported
  // such a frame lost, and at 45 mm per frame the walk was then lost to its end.
  int unconstrained = 0;
  for (const FrameRecord& f : reconstruction.frames()) {
    if (f.status == FrameStatus::kUnconstrained) {
      ++unconstrained;
      EXPECT_FALSE(f.fused) << "frame " << f.index;
      ASSERT_LT(f.index + 1, 25);
      const FrameStatus next = reconstruction.frames()[f.index + 1].status;
      EXPECT_TRUE(next == FrameStatus::kRecovered || next == FrameStatus::kUnconstrained) << "frame " << f.index + 1;
      continue;
    }
    EXPECT_TRUE(f.fused) << "frame " << f.index;
  }
  EXPECT_LE(unconstrained, 2);
  EXPECT_GE(static_cast<int>(reconstruction.trajectory().poses().size()), 23);
  // The second frame on the widened gate, from the first pose (there is no velocity yet).
  EXPECT_TRUE(reconstruction.frames()[1].widened_gate);
  EXPECT_TRUE(reconstruction.frames()[1].from_last_pose);
  // Depth alone drifts along the cabinet front: measured at most 22 mm over the 2.5 s.
  ExpectOnTheTruth(reconstruction, scan, 0.035);
}

// A hand over the lens for 0.3 s in that walk (three frames of a flat surface at 0.5 m): they
// are lost, and the next frame relocalises where the rig's motion carried it (10 cm on), not
// one breaker over from where it was last seen — which converged too, 53 mm off on fewer
// inliers with a fine residual, and the tracking then ran away by 0.67 m.
TEST(Reconstruction, AHiddenLensRelocalisesWhereTheWalkCarriedTheRig) {
  const core::Scan scan = core::Scan::Open(CachedScan("walk10hz-full", WalkAt10HzOptions()));
  Reconstruction reconstruction(scan.rig(), ReconstructionOptions{});
  reconstruction.SetInitialPose(*scan.groundtruth()->At(scan.Timestamp(Stream::kDepth, 0)));
  const int n = scan.NumFrames(Stream::kDepth);
  ASSERT_EQ(n, 25);
  int unconstrained = 0;
  bool after_unconstrained = false;
  for (int i = 0; i < n; ++i) {
    ASSERT_TRUE(scan.FrameExists(Stream::kDepth, i));
    FrameInput frame = LoadScanFrame(scan, i, false);
    const bool hidden = i >= 15 && i < 18;
    if (hidden) frame.depth_m.setTo(0.5f);
    const FrameRecord& record = reconstruction.AddFrame(frame);
    // A frame the basin check finds unconstrained (not fused; the next one recovers from its
    // pose) may come anywhere in the walk along the cabinet front (measured: the second).
    if (!hidden && record.status == FrameStatus::kUnconstrained) {
      ++unconstrained;
      after_unconstrained = true;
      continue;
    }
    EXPECT_EQ(record.status, hidden                           ? FrameStatus::kLost
                             : i == 18 || after_unconstrained ? FrameStatus::kRecovered
                             : i == 0                         ? FrameStatus::kInitialised
                                                              : FrameStatus::kTracked)
        << "frame " << i;
    after_unconstrained = false;
    if (i == 18) {
      EXPECT_FALSE(record.from_last_pose);  // the extrapolation won
      EXPECT_TRUE(record.widened_gate);
    }
  }
  EXPECT_LE(unconstrained, 2);
  // As the run without the hand (at most 24 mm off after the loss).
  ExpectOnTheTruth(reconstruction, scan, 0.035);
}

// The lens covered for a second while the operator goes back (frames of nothing the model
// holds meanwhile): when the depth returns, the rig looks at what it saw 1.7 s before,
// 0.4 m and 17° from where tracking was last. The
// returning frames are the scan's first frames again, with fresh sensor noise, starting at
// one that is not itself a keyframe, so ICP has to move from a keyframe's pose.
TEST(Reconstruction, ARigReturningToAMappedPlaceRelocalisesFromAKeyframe) {
  fixtures::SynthScanOptions scan_options = TestScanOptions("equipment-small", fixtures::MotionKind::kSmooth, 2.0);
  scan_options.write_thermal = true;  // the scan of dynamic_scene_test, rendered once for both
  const core::Scan scan = core::Scan::Open(CachedScan("passer-absent", scan_options));
  const int n = scan.NumFrames(Stream::kDepth);
  ASSERT_GT(n, 50);
  int start = 2;
  const auto run = [&](int candidates, bool garbage, std::vector<FrameRecord>* returned,
                       std::vector<core::Rigid3d>* poses, std::vector<core::Rigid3d>* earlier) {
    ReconstructionOptions options = PipelineTestOptions();
    options.keyframes.candidates = candidates;
    Reconstruction reconstruction(scan.rig(), options);
    reconstruction.SetInitialPose(*scan.groundtruth()->At(scan.Timestamp(Stream::kDepth, 0)));
    std::vector<int> index;  // scan frame of each fused pose
    for (int i = 0; i < n; ++i) {
      if (!scan.FrameExists(Stream::kDepth, i)) continue;
      ASSERT_TRUE(reconstruction.AddFrame(LoadScanFrame(scan, i, true)).fused) << "frame " << i;
      index.push_back(i);
    }
    const auto& tracked = reconstruction.trajectory().poses();
    const auto tracked_at = [&](int i) {
      for (size_t k = 0; k < index.size(); ++k) {
        if (index[k] == i) return tracked[k].world_from_sensor;
      }
      return core::Rigid3d::Identity();
    };
    // The first frame from 2 on that is not a keyframe (the run without keyframes: the same).
    const auto is_keyframe = [&](int i) {
      for (int k = 0; k < reconstruction.keyframes().size(); ++k) {
        if (core::ComparePoses(reconstruction.keyframes().pose(k), tracked_at(i)).translation_m < 1e-9) return true;
      }
      return false;
    };
    while (candidates > 0 && (is_keyframe(start) || !scan.FrameExists(Stream::kDepth, start))) ++start;
    const core::Rigid3d last = tracked.back().world_from_sensor;
    const double shift_s = scan.Timestamp(Stream::kDepth, n - 1) + 1.0 - scan.Timestamp(Stream::kDepth, start);
    // While the lens is covered, frames of nothing the model holds (a frame upside down and
    // 60 cm deeper, as in GarbageFrameIsLostNotFusedAndTrackingRecovers), over 0.5 s into
    // the loss so that every keyframe candidate is tried on them: none may be taken.
    for (double t : {0.3, 0.6, 0.8}) {
      if (!garbage) break;
      FrameInput other = LoadScanFrame(scan, n / 2, false);
      cv::Mat flipped;
      cv::flip(other.depth_m, flipped, -1);
      other.depth_m = flipped + 0.6f;
      other.depth_m.setTo(0, flipped == 0);
      other.timestamp_s = scan.Timestamp(Stream::kDepth, n - 1) + t;
      EXPECT_EQ(reconstruction.AddFrame(other).status, FrameStatus::kLost) << t;
    }
    cv::RNG rng(7);
    for (int i = start; i < start + 8; ++i) {
      if (!scan.FrameExists(Stream::kDepth, i)) continue;
      FrameInput frame = LoadScanFrame(scan, i, true);
      frame.timestamp_s += shift_s;
      frame.rgb_timestamp_s += shift_s;
      cv::Mat noise(frame.depth_m.size(), CV_32FC1);
      rng.fill(noise, cv::RNG::NORMAL, 0, 0.003);
      const cv::Mat valid = frame.depth_m > 0;
      cv::Mat noisy = frame.depth_m + noise;
      noisy.copyTo(frame.depth_m, valid);
      returned->push_back(reconstruction.AddFrame(frame));
      earlier->push_back(tracked_at(i));
      poses->push_back(returned->back().fused ? reconstruction.trajectory().poses().back().world_from_sensor
                                              : core::Rigid3d::Identity());
    }
    if (candidates > 0) {
      // A keyframe every 0.1 m or 10° of the 2 s sweep.
      EXPECT_GE(reconstruction.keyframes().size(), 4);
      EXPECT_LE(reconstruction.keyframes().size(), 12);
      EXPECT_GT(core::ComparePoses(earlier->front(), last).translation_m, 0.3);
    }
  };
  std::vector<FrameRecord> returned;
  std::vector<core::Rigid3d> poses, earlier;
  run(ReconstructionOptions{}.keyframes.candidates, true, &returned, &poses, &earlier);
  ASSERT_GE(returned.size(), 6u);
  // The first returning frame relocalises from a keyframe (the loss has lasted over 0.5 s),
  // and the rest track on.
  EXPECT_EQ(returned[0].status, FrameStatus::kRecovered);
  EXPECT_GE(returned[0].keyframe, 0);
  for (size_t j = 1; j < returned.size(); ++j) EXPECT_EQ(returned[j].status, FrameStatus::kTracked) << j;
  // Where the same view was tracked before, to what fresh noise moves it at 160×120: two
  // trackings of the same view, each off by its noise (measured 1.4–6.0 mm, 0.03–0.44°;
  // since stop 45, whose colour registered at ICP's 80×60 level instead of averaged down
  // from 160×120 moves every pose a little, 1.1–8.0 mm and 0.03–0.85°, the 0.85° the frame
  // right after the relocalisation).
  for (size_t j = 0; j < returned.size(); ++j) {
    const core::PoseError e = core::ComparePoses(earlier[j], poses[j]);
    std::printf("with keyframes, frame %zu: %s (keyframe %d), %.1f mm, %.2f° from the earlier pose\n", j,
                FrameStatusName(returned[j].status).c_str(), returned[j].keyframe, 1000 * e.translation_m,
                e.rotation_rad / kDeg);
    EXPECT_LT(e.translation_m, 0.01) << j;
    EXPECT_LT(e.rotation_rad, 1.0 * kDeg) << j;
  }

  // With no frame at all during the gap (a stalled stream; a covered lens gives frames
  // without depth, which are skipped): the first returning frame is already relocalised,
  // since 1 s unobserved leaves no motion to predict from.
  std::vector<FrameRecord> direct;
  std::vector<core::Rigid3d> direct_poses, direct_earlier;
  run(ReconstructionOptions{}.keyframes.candidates, false, &direct, &direct_poses, &direct_earlier);
  ASSERT_FALSE(direct.empty());
  EXPECT_EQ(direct[0].status, FrameStatus::kRecovered);
  EXPECT_GE(direct[0].keyframe, 0);
  EXPECT_LT(core::ComparePoses(direct_earlier[0], direct_poses[0]).translation_m, 0.01);

  // Without keyframes only the last pose is tried (measured: 70 mm off, three frames to
  // come back).
  std::vector<FrameRecord> without;
  poses.clear();
  earlier.clear();
  run(0, true, &without, &poses, &earlier);
  double worst_m = 0;
  int lost = 0;
  for (size_t j = 0; j < without.size(); ++j) {
    std::printf("without keyframes, frame %zu: %s, %.1f mm from the earlier pose\n", j,
                FrameStatusName(without[j].status).c_str(),
                1000 * core::ComparePoses(earlier[j], poses[j]).translation_m);
    lost += without[j].status == FrameStatus::kLost;
    if (without[j].fused) worst_m = std::max(worst_m, core::ComparePoses(earlier[j], poses[j]).translation_m);
  }
  EXPECT_TRUE(lost == static_cast<int>(without.size()) || worst_m > 0.02) << lost << " lost, worst " << worst_m;
}

TEST(ReconstructionOptions, CheckNamesTheField) {
  EXPECT_EQ(ReconstructionOptions().Check(), "");
  ReconstructionOptions o;
  o.max_depth_m = 0.1;
  EXPECT_NE(o.Check().find("max_depth_m"), std::string::npos);
  o = ReconstructionOptions();
  o.tsdf.voxel_size_m = 0;
  EXPECT_EQ(o.Check().rfind("tsdf.voxel_size_m", 0), 0u) << o.Check();
  o = ReconstructionOptions();
  o.relocalisation_widening = 0.5;
  EXPECT_NE(o.Check().find("relocalisation_widening"), std::string::npos);
  for (double conflict : {-0.1, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
    o = ReconstructionOptions();
    o.relocalisation_max_conflict = conflict;
    EXPECT_NE(o.Check().find("relocalisation_max_conflict"), std::string::npos) << conflict;
  }
  o = ReconstructionOptions();
  o.relocalisation_max_conflict = 1;  // off
  EXPECT_EQ(o.Check(), "");
  for (double basin : {-0.001, 0.2, std::numeric_limits<double>::quiet_NaN()}) {
    o = ReconstructionOptions();
    o.basin_check_m = basin;
    EXPECT_NE(o.Check().find("basin_check_m"), std::string::npos) << basin;
  }
  o = ReconstructionOptions();
  o.basin_check_m = 0;  // off
  EXPECT_EQ(o.Check(), "");
  for (int interval : {0, 9}) {
    o = ReconstructionOptions();
    o.raycast_interval = interval;
    EXPECT_NE(o.Check().find("raycast_interval"), std::string::npos) << interval;
  }
  for (double bad : {0.0, -1.0, std::numeric_limits<double>::infinity()}) {
    o = ReconstructionOptions();
    o.reuse_max_motion_m = bad;
    EXPECT_NE(o.Check().find("reuse_max_motion_m"), std::string::npos) << bad;
    o = ReconstructionOptions();
    o.reuse_max_motion_deg = bad;
    EXPECT_NE(o.Check().find("reuse_max_motion_deg"), std::string::npos) << bad;
    o = ReconstructionOptions();
    o.integrate_max_motion_m = bad;
    EXPECT_NE(o.Check().find("integrate_max_motion_m"), std::string::npos) << bad;
    o = ReconstructionOptions();
    o.integrate_max_motion_deg = bad;
    EXPECT_NE(o.Check().find("integrate_max_motion_deg"), std::string::npos) << bad;
  }
  for (double bad : {-0.1, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
    o = ReconstructionOptions();
    o.reuse_lead = bad;
    EXPECT_NE(o.Check().find("reuse_lead"), std::string::npos) << bad;
  }
  ScanReconstructionOptions s;
  s.first_frame = -1;
  EXPECT_NE(s.Check().find("first_frame"), std::string::npos);
}

}  // namespace
}  // namespace hw::reconstruct
