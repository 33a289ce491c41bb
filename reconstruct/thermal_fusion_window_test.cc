// ThermalFusionOptions::frame_interval_s: of each window of frames, only the most confident is
// fused.

#include <cmath>
#include <cstring>
#include <random>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "reconstruct/thermal_fusion.h"
#include "reconstruct/thermal_fusion_test_support.h"

namespace hw::reconstruct {
namespace {

using namespace test;  // the scene: thermal_fusion_test_support.h

// A sideways sweep over the plane whose speed changes from one depth interval to the next:
// thermal frame i lies in the middle of interval i, so its velocity is that interval's.
Views SweepWithSpeeds(const std::vector<double>& speeds_mps) {
  Views v;
  std::vector<core::Rigid3d> poses;
  double x = -0.08;
  for (size_t i = 0; i <= speeds_mps.size(); ++i) {
    poses.push_back(LookAt(Eigen::Vector3d(x, 0.02, 0.2), Eigen::Vector3d(x, 0.0, kPlaneZ)));
    if (i < speeds_mps.size()) x += speeds_mps[i] / 30.0;
  }
  v.trajectory = TrajectoryThrough(poses);
  for (size_t i = 0; i < speeds_mps.size(); ++i) v.thermal_times_s.push_back((i + 0.5) / 30.0);
  return v;
}

// Adds every frame of `views` (rendered with noise of std netd_k) and returns each AddFrame's
// status.
std::vector<ThermalFrameStatus> AddAll(ThermalFusion& fusion, const core::Rig& rig, const TsdfVolume& volume,
                                       const Views& views, double netd_k = 0) {
  std::mt19937_64 rng(3);
  std::vector<ThermalFrameStatus> statuses;
  for (size_t i = 0; i < views.thermal_times_s.size(); ++i) {
    const double t = views.thermal_times_s[i];
    const core::Rigid3d world_from_thermal = *views.trajectory.At(t) * rig.depth_from_thermal;
    statuses.push_back(
        fusion.AddFrame(volume, {static_cast<int>(i), t, RenderThermal(rig, world_from_thermal, netd_k, rng)},
                        views.trajectory)
            .status);
  }
  return statuses;
}

TEST(ThermalFusionWindowTest, FusesTheLeastBlurredFrameOfEachWindow) {
  const core::Rig rig = ThermalRig(false);
  const TsdfVolume volume = PlaneVolume();
  ThermalFusionOptions options = TestOptions();
  options.frame_interval_s = 0.09;  // frames 1/30 s apart: windows of three
  ThermalFusion fusion(rig, options, EmissivityMap(*rig.thermal_settings), {});
  // 1 m/s blurs a point 0.8 m away by 64 px · 1.25 /s · 10 ms = 0.8 px (c1 ≈ 0.73); 0.1 m/s
  // by 0.08 px (c1 ≈ 0.997). Windows {0 1 2} {3 4 5} {6}: the slow frames 1 and 5, and 6,
  // alone in the last window, fused when it is flushed.
  const Views views = SweepWithSpeeds({1.0, 0.1, 1.0, 1.0, 1.0, 0.1, 1.0});
  using S = ThermalFrameStatus;
  const std::vector<S> on_arrival = AddAll(fusion, rig, volume, views);
  // On arrival: a window's first frame is held; a more confident one takes its place; the
  // next window's first frame closes it (the held one is fused then).
  EXPECT_EQ(on_arrival, (std::vector<S>{S::kHeld, S::kHeld, S::kSkipped, S::kHeld, S::kSkipped, S::kHeld, S::kHeld}));
  EXPECT_EQ(fusion.frames()[1].status, S::kFused);  // when frame 3 closed its window
  EXPECT_EQ(fusion.frames()[5].status, S::kFused);  // frame 6
  EXPECT_EQ(fusion.frames()[6].status, S::kHeld);   // until the flush
  fusion.Flush(volume);
  fusion.Finish();
  const std::vector<ThermalFrameRecord>& frames = fusion.frames();
  ASSERT_EQ(frames.size(), 7u);
  const std::vector<S> expected{S::kSkipped, S::kFused, S::kSkipped, S::kSkipped, S::kSkipped, S::kFused, S::kFused};
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].status, expected[i]) << "frame " << i << ": " << ThermalFrameStatusName(frames[i].status);
    // Skipped frames cost no raycast; fused ones were cast and met the plane.
    EXPECT_EQ(frames[i].rays > 0, expected[i] == S::kFused) << "frame " << i;
    if (expected[i] == S::kFused) {
      EXPECT_GT(frames[i].fused, frames[i].rays / 2) << "frame " << i;
    }
  }
  // The frame confidence is the motion term here (no shutter events), at the grid's pixels
  // at the last fused frame's median range: 1.5 m before any (frames 0–2: 1 m/s blurs by
  // 0.43 px, c1 ≈ 0.91), then about the plane's 0.8 m (frames 3–6: c1 ≈ 0.73, a little less
  // off-axis, where the median range puts the point nearer).
  EXPECT_NEAR(frames[0].frame_confidence, std::exp(-0.5 * std::pow(64 / 1.5 * 0.01, 2)), 0.01);
  EXPECT_NEAR(frames[0].frame_confidence, frames[2].frame_confidence, 1e-6);
  EXPECT_GT(frames[1].frame_confidence, 0.99);
  for (int i : {3, 4, 6}) {
    EXPECT_LT(frames[i].frame_confidence, 0.78) << "frame " << i;
    EXPECT_GT(frames[i].frame_confidence, 0.6) << "frame " << i;
  }
  EXPECT_GT(frames[5].frame_confidence, 0.99);
  // The temperature is right where the fused frames saw the plane.
  const std::vector<Eigen::Vector3f> points = PlanePoints();
  const PointTemperatures t = fusion.Sample(points, ThermalMethod::kOffline);
  int observed = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    if (t.views[i] == 0) continue;
    ++observed;
    EXPECT_NEAR(t.surface_c[i], TrueSurfaceC(points[i].cast<double>()), 0.06) << "point " << i;
    EXPECT_LE(t.views[i], 3);
  }
  EXPECT_GT(observed, static_cast<int>(points.size()) / 2);
}

TEST(ThermalFusionWindowTest, AFrameRightAfterAShutterEventLosesToALaterOneAndTiesKeepTheEarlier) {
  const core::Rig rig = ThermalRig(false);
  const TsdfVolume volume = PlaneVolume();
  ThermalFusionOptions options = TestOptions();
  options.frame_interval_s = 0.09;
  // c5 0 until 0.05 s after the event at 0, rising to 1 at 0.13 s.
  options.confidence.ffc_settle_s = 0.05;
  options.confidence.ffc_ramp_s = 0.08;
  ThermalFusion fusion(rig, options, EmissivityMap(*rig.thermal_settings), {0.0});
  // A still camera (c1 = 1): frames at 1/60, 3/60, ... s; c5 = 0, 0, 0.42 | 0.83, 1, 1. (With
  // noise: identical images would be taken for a frozen camera.)
  const Views views = SweepWithSpeeds(std::vector<double>(6, 0.0));
  AddAll(fusion, rig, volume, views, 0.04);
  fusion.Flush(volume);
  fusion.Finish();
  const std::vector<ThermalFrameRecord>& frames = fusion.frames();
  ASSERT_EQ(frames.size(), 6u);
  using S = ThermalFrameStatus;
  const std::vector<S> expected{S::kSkipped, S::kSkipped, S::kFused, S::kSkipped, S::kFused, S::kSkipped};
  for (size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(frames[i].status, expected[i]) << "frame " << i << ": " << ThermalFrameStatusName(frames[i].status);
  }
  EXPECT_EQ(frames[0].frame_confidence, 0.0);
  EXPECT_NEAR(frames[2].frame_confidence, (2.5 / 30 - 0.05) / 0.08, 1e-9);
  EXPECT_EQ(frames[4].frame_confidence, 1.0);
  EXPECT_EQ(frames[5].frame_confidence, 1.0);
}

TEST(ThermalFusionWindowTest, IntervalZeroFusesEveryFrameAsItComes) {
  const core::Rig rig = ThermalRig(false);
  const TsdfVolume volume = PlaneVolume();
  ThermalFusionOptions options = TestOptions();
  ASSERT_EQ(options.frame_interval_s, 0.0);
  ThermalFusion fusion(rig, options, EmissivityMap(*rig.thermal_settings), {});
  const Views views = SweepWithSpeeds({1.0, 0.1, 1.0});
  const std::vector<ThermalFrameStatus> statuses = AddAll(fusion, rig, volume, views);
  EXPECT_EQ(statuses, std::vector<ThermalFrameStatus>(3, ThermalFrameStatus::kFused));
  fusion.Flush(volume);  // nothing held: no-op
  fusion.Finish();
  EXPECT_EQ(fusion.frames().size(), 3u);
}

// ThermalFusionOptions::background: the stage after each raycast on a thread of its own gives
// the same bits as inline — every record (timings aside) and every method's estimate — with
// the scene correction on (its state is the stage's), a shutter event, frozen frames added
// while a stage may run (CorrectFrame reads the last frozen frame's time as it was when the
// frame's fusion began), and the volume integrated between the calls as the depth pipeline
// does, on the same thread pool (the stage must not read it; run under ThreadSanitizer too).
TEST(ThermalFusionWindowTest, TheBackgroundStageGivesTheSameBits) {
  const core::Rig rig = ThermalRig(false);
  const PinholeCamera depth_camera = SmallCamera();
  const Views views = SweepWithSpeeds({0.3, 0.1, 0.5, 0.2, 0.1, 0.4, 0.3, 0.1, 0.6, 0.2, 0.1, 0.3});
  const std::vector<Eigen::Vector3f> points = PlanePoints();
  struct Run {
    std::vector<ThermalFrameRecord> frames;
    std::vector<PointTemperatures> estimates;
  };
  auto run = [&](bool background) {
    ThermalFusionOptions options = TestOptions();
    options.frame_interval_s = 0.09;
    options.background = background;
    options.scene_correction.frame_offset = options.scene_correction.pixel_offset = true;
    ThermalFusion fusion(rig, options, EmissivityMap(*rig.thermal_settings), {0.15});
    TsdfVolume volume = PlaneVolume();
    std::mt19937_64 rng(5);
    cv::Mat previous;
    for (size_t i = 0; i < views.thermal_times_s.size(); ++i) {
      const double t = views.thermal_times_s[i];
      const core::Rigid3d world_from_thermal = *views.trajectory.At(t) * rig.depth_from_thermal;
      // Frames 4 and 8 repeat the one before (frozen: a shutter closure).
      cv::Mat image = (i == 4 || i == 8) ? previous.clone() : RenderThermal(rig, world_from_thermal, 0.04, rng);
      previous = image;
      fusion.AddFrame(volume, {static_cast<int>(i), t, image}, views.trajectory);
      // The depth frame after it, integrated while the stage of a frame fused above may run.
      const core::Rigid3d world_from_depth = *views.trajectory.At(t + 1 / 60.0);
      volume.Integrate(RenderPlane(depth_camera, world_from_depth, Eigen::Vector3d(0, 0, 1), kPlaneZ), depth_camera,
                       world_from_depth);
    }
    fusion.Flush(volume);
    fusion.Finish();
    Run r;
    r.frames = fusion.frames();
    for (ThermalMethod method : {ThermalMethod::kLatest, ThermalMethod::kMean, ThermalMethod::kCappedMean,
                                 ThermalMethod::kOnline, ThermalMethod::kOffline}) {
      r.estimates.push_back(fusion.Sample(points, method));
    }
    return r;
  };
  const Run inline_run = run(false), background_run = run(true);
  ASSERT_EQ(inline_run.frames.size(), background_run.frames.size());
  int fused = 0;
  for (size_t i = 0; i < inline_run.frames.size(); ++i) {
    const ThermalFrameRecord& a = inline_run.frames[i];
    const ThermalFrameRecord& b = background_run.frames[i];
    fused += a.status == ThermalFrameStatus::kFused;
    auto fields = [](const ThermalFrameRecord& r) {
      return std::make_tuple(r.index, r.timestamp_s, r.status, r.frame_confidence, r.rays, r.hits, r.fused,
                             r.low_confidence, r.no_normal, r.depth_edge, r.occluded, r.live_depth,
                             r.no_surface_temperature, r.mean_confidence, r.regions_updated, r.pair_rays,
                             r.pair_shift_px, r.reference_rays, r.offset_estimated, r.offset_correction_k,
                             r.pixel_offset_rms_k);
    };
    EXPECT_TRUE(fields(a) == fields(b)) << "frame " << i;
  }
  EXPECT_GE(fused, 4);
  auto same = [](const auto& x, const auto& y) {
    return x.size() == y.size() && std::memcmp(x.data(), y.data(), x.size() * sizeof(x[0])) == 0;
  };
  for (size_t m = 0; m < inline_run.estimates.size(); ++m) {
    const PointTemperatures& a = inline_run.estimates[m];
    const PointTemperatures& b = background_run.estimates[m];
    EXPECT_TRUE(same(a.surface_c, b.surface_c)) << m;
    EXPECT_TRUE(same(a.apparent_c, b.apparent_c)) << m;
    EXPECT_TRUE(same(a.confidence, b.confidence)) << m;
    EXPECT_TRUE(same(a.std_c, b.std_c)) << m;
    EXPECT_TRUE(same(a.footprint_m, b.footprint_m)) << m;
    EXPECT_TRUE(same(a.view_m, b.view_m)) << m;
    EXPECT_TRUE(same(a.views, b.views)) << m;
  }
}

TEST(ThermalFusionWindowTest, CheckNamesTheField) {
  ThermalFusionOptions o;
  EXPECT_EQ(o.frame_interval_s, 0.09);
  o.frame_interval_s = -0.01;
  EXPECT_EQ(o.Check().rfind("frame_interval_s", 0), 0u) << o.Check();
  o.frame_interval_s = 1.5;
  EXPECT_EQ(o.Check().rfind("frame_interval_s", 0), 0u) << o.Check();
  o.frame_interval_s = std::nan("");
  EXPECT_EQ(o.Check().rfind("frame_interval_s", 0), 0u) << o.Check();
  o.frame_interval_s = 0;
  EXPECT_EQ(o.Check(), "");
}

}  // namespace
}  // namespace hw::reconstruct
