#include "core/frame_clock.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "core/scan.h"
#include "core/scan_test_support.h"
#include "tests/support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using test::Stamp;
using test::TestRig;
using test::Times;
using test::WriteIndexOnlyScan;

// A stream exposed every period_s from t0 (slots kept with probability 1 − drop, plus bursts
// of dropped frames), stamped at exposure + jitter (Gaussian, cut at ±4σ, as the fixtures'
// driver model) + latency.
struct StampedStream {
  std::vector<double> exposure_s, stamp_s;
};
StampedStream MakeStream(int slots, double period_s, double jitter_s, uint32_t seed, double drop = 0.012,
                  double latency_s = 0.004, double t0 = 1000) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0, 1);
  std::uniform_real_distribution<double> uniform(0, 1);
  StampedStream s;
  for (int k = 0; k < slots; ++k) {
    if (uniform(rng) < drop) continue;
    if (uniform(rng) < 0.003) {  // a burst of 3–10 dropped frames
      k += 3 + static_cast<int>(uniform(rng) * 7);
      continue;
    }
    const double e = t0 + k * period_s;
    const double j = std::clamp(noise(rng), -4.0, 4.0) * jitter_s;
    const double stamp = std::round((e + latency_s + j) * 1e6) / 1e6;  // index files: µs
    if (!s.stamp_s.empty() && stamp <= s.stamp_s.back()) continue;
    s.exposure_s.push_back(e + latency_s);  // the latency is a clock offset (rig.yaml's), not jitter
    s.stamp_s.push_back(stamp);
  }
  return s;
}

double Rms(const std::vector<double>& a, const std::vector<double>& b) {
  double sum = 0;
  for (size_t i = 0; i < a.size(); ++i) sum += (a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(sum / a.size());
}

TEST(RegulariseStamps, RecoversExposureTimesWithinTheirReportedError) {
  // 30 Hz, 2 ms of jitter, drops and bursts: a fitted time averages ~120 stamps, so its error
  // is ~2 ms / √120 ≈ 0.2 ms (0.3 at a segment's ends): within 0.35 ms RMS, against the
  // stamps' 2 ms; and the reported error is the measured one within 30 % (20 seeds' worth).
  std::vector<double> measured, reported;
  for (uint32_t seed = 1; seed <= 20; ++seed) {
    const StampedStream s = MakeStream(600, 1.0 / 30, 0.002, seed);
    const StampFit fit = RegulariseStamps(s.stamp_s);
    ASSERT_TRUE(fit.applied) << fit.reason;
    EXPECT_NEAR(fit.period_s, 1.0 / 30, 1e-5);
    EXPECT_NEAR(fit.jitter_s, 0.002, 0.0003);
    EXPECT_GT(Rms(s.stamp_s, s.exposure_s), 0.0018);
    const double error = Rms(fit.times_s, s.exposure_s);
    EXPECT_LT(error, 0.00035) << "seed " << seed;
    EXPECT_EQ(fit.segments, 1);
    EXPECT_EQ(fit.unfitted, 0);
    measured.push_back(error);
    reported.push_back(fit.time_std_s);
  }
  double m = 0, r = 0;
  for (size_t i = 0; i < measured.size(); ++i) m += measured[i] * measured[i], r += reported[i] * reported[i];
  EXPECT_NEAR(std::sqrt(m / r), 1.0, 0.3);
}

TEST(RegulariseStamps, CountsDroppedFramesAsEmptySlots) {
  std::vector<double> stamps;
  for (int k = 0; k < 100; ++k) {
    if (k % 10 == 3 || (k >= 50 && k < 58)) continue;  // 10 single drops and a burst of 8
    stamps.push_back(5 + k / 30.0);
  }
  const StampFit fit = RegulariseStamps(stamps);
  ASSERT_TRUE(fit.applied) << fit.reason;
  EXPECT_EQ(fit.empty_slots, 10 + 8 - 1);  // slot 53 is one of the burst's
  // Without jitter the fit returns the stamps (to rounding).
  for (size_t i = 0; i < stamps.size(); ++i) EXPECT_NEAR(fit.times_s[i], stamps[i], 1e-9);
  EXPECT_LT(fit.max_shift_s, 1e-9);
}

TEST(RegulariseStamps, FollowsADriftingClock) {
  // The period drifting by 200 ppm over 60 s and wobbling ±100 µs: the local fits follow.
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0, 0.002);
  std::vector<double> exposure, stamps;
  double t = 100;
  for (int k = 0; k < 1800; ++k) {
    const double period = (1.0 / 30) * (1 + 200e-6 * k / 1800.0);
    t += period;
    const double e = t + 1e-4 * std::sin(k / 300.0);
    exposure.push_back(e);
    stamps.push_back(e + std::clamp(noise(rng), -0.008, 0.008));
  }
  const StampFit fit = RegulariseStamps(stamps);
  ASSERT_TRUE(fit.applied) << fit.reason;
  EXPECT_LT(Rms(fit.times_s, exposure), 0.0003);
}

TEST(RegulariseStamps, PutsALateDeliveryInItsSlot) {
  // A frame 25 ms late (3/4 of a period) lands on the next frame's slot; the next frame,
  // on time, moves it back. Also a stall: three frames delivered together 1 ms apart.
  StampedStream s = MakeStream(300, 1.0 / 30, 0.001, 3, 0);
  s.stamp_s[100] += 0.025;
  s.stamp_s[200] = s.stamp_s[202] - 0.002;
  s.stamp_s[201] = s.stamp_s[202] - 0.001;
  const StampFit fit = RegulariseStamps(s.stamp_s);
  ASSERT_TRUE(fit.applied) << fit.reason;
  EXPECT_GE(fit.outliers, 3);
  EXPECT_EQ(fit.empty_slots, 0);
  for (const int i : {100, 200, 201}) EXPECT_NEAR(fit.times_s[i], s.exposure_s[i], 0.0006) << i;
}

TEST(RegulariseStamps, StartsASegmentAfterAPause) {
  // Two runs 3 s apart, the second on another phase (a restarted stream).
  std::vector<double> exposure, stamps;
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0, 0.0015);
  for (int k = 0; k < 150; ++k) exposure.push_back(10 + k / 30.0);
  for (int k = 0; k < 150; ++k) exposure.push_back(18.0123 + k / 30.0);
  for (const double e : exposure) stamps.push_back(e + std::clamp(noise(rng), -0.006, 0.006));
  const StampFit fit = RegulariseStamps(stamps);
  ASSERT_TRUE(fit.applied) << fit.reason;
  EXPECT_EQ(fit.segments, 2);
  EXPECT_LT(Rms(fit.times_s, exposure), 0.0004);
}

TEST(RegulariseStamps, LeavesAnIrregularStreamAsStamped) {
  // Intervals anywhere in [0.5, 1.5] periods: a camera without a regular clock.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> interval(0.5 / 30, 1.5 / 30);
  std::vector<double> stamps{0};
  for (int k = 0; k < 300; ++k) stamps.push_back(stamps.back() + interval(rng));
  const StampFit fit = RegulariseStamps(stamps);
  EXPECT_FALSE(fit.applied);
  EXPECT_FALSE(fit.reason.empty());
  EXPECT_EQ(fit.times_s, stamps);
  // Jitter of a third of the period: slots ambiguous.
  const StampedStream s = MakeStream(300, 1.0 / 30, 0.011, 9, 0);
  const StampFit noisy = RegulariseStamps(s.stamp_s);
  EXPECT_FALSE(noisy.applied);
  EXPECT_EQ(noisy.times_s, s.stamp_s);
  // A stream delivering every frame twice, 1 ms apart.
  std::vector<double> doubled;
  for (int k = 0; k < 100; ++k) doubled.insert(doubled.end(), {k / 9.0, k / 9.0 + 0.001});
  const StampFit twice = RegulariseStamps(doubled);
  EXPECT_FALSE(twice.applied) << twice.period_s;
  EXPECT_EQ(twice.times_s, doubled);
  // Too few frames.
  const StampFit few = RegulariseStamps(std::vector<double>{1, 2, 3});
  EXPECT_FALSE(few.applied);
  EXPECT_EQ(few.times_s, (std::vector<double>{1, 2, 3}));
}

TEST(ScanClock, RegularisedStampsReplaceTimesAndKeepTheIndex) {
  // Depth at 30 Hz and thermal at 9 Hz exposed on regular clocks, stamped with 2 ms of
  // jitter; colour stamped at irregular intervals (no clock to fit).
  std::mt19937 rng(3);
  std::normal_distribution<double> jitter(0, 0.002);
  std::uniform_real_distribution<double> interval(0.5 / 30, 1.5 / 30);
  const std::vector<double> depth_exposure = Times(150, 100.0, 1.0 / 30.0);
  const std::vector<double> thermal_exposure = Times(45, 100.01, 1.0 / 9.0);
  std::vector<double> depth, thermal, rgb{100.0};
  for (const double t : depth_exposure) depth.push_back(t + std::clamp(jitter(rng), -0.008, 0.008));
  for (const double t : thermal_exposure) thermal.push_back(t + std::clamp(jitter(rng), -0.008, 0.008));
  for (int k = 0; k < 150; ++k) rgb.push_back(rgb.back() + interval(rng));
  const fs::path folder = hw::test::TestFolder() / "jitter";
  Rig rig = TestRig();
  rig.thermal_time_offset_s = -0.02;
  WriteIndexOnlyScan(folder, rig, depth, rgb, thermal);

  const Scan stamped = Scan::Open(folder);
  EXPECT_FALSE(stamped.StampRegularisation(Stream::kDepth).applied);
  EXPECT_TRUE(stamped.StampRegularisation(Stream::kDepth).reason.empty());
  EXPECT_DOUBLE_EQ(stamped.Timestamp(Stream::kDepth, 10), std::stod(Stamp(depth[10])));

  ScanOptions options;
  options.regularise_stamps = true;
  const Scan scan = Scan::Open(folder, options);
  const auto rms = [](const std::vector<double>& a, const std::vector<double>& b) {
    double sum = 0;
    for (size_t i = 0; i < a.size(); ++i) sum += (a[i] - b[i]) * (a[i] - b[i]);
    return std::sqrt(sum / static_cast<double>(a.size()));
  };
  ASSERT_TRUE(scan.StampRegularisation(Stream::kDepth).applied) << scan.StampRegularisation(Stream::kDepth).reason;
  ASSERT_TRUE(scan.StampRegularisation(Stream::kThermal).applied);
  EXPECT_FALSE(scan.StampRegularisation(Stream::kRgb).applied);
  EXPECT_FALSE(scan.StampRegularisation(Stream::kRgb).reason.empty());
  // 2 ms of jitter → ~0.3 ms (150 depth frames: a 4 s window holds all; 45 thermal ones).
  EXPECT_GT(rms(stamped.Timestamps(Stream::kDepth), depth_exposure), 0.0015);
  EXPECT_LT(rms(scan.Timestamps(Stream::kDepth), depth_exposure), 0.0005);
  EXPECT_LT(rms(scan.Timestamps(Stream::kThermal), thermal_exposure), 0.0008);
  // The depth clock follows, the index keeps the stamps, the unfitted stream is unchanged.
  EXPECT_DOUBLE_EQ(scan.DepthClockTime(Stream::kThermal, 5), scan.Timestamp(Stream::kThermal, 5) - 0.02);
  EXPECT_DOUBLE_EQ(scan.Entries(Stream::kDepth)[10].timestamp_s, std::stod(Stamp(depth[10])));
  EXPECT_EQ(scan.Timestamps(Stream::kRgb), stamped.Timestamps(Stream::kRgb));
}

TEST(RegulariseStamps, OptionsCheckNamesTheField) {
  StampRegularisationOptions o;
  EXPECT_EQ(o.Check(), "");
  o.window_s = 0;
  EXPECT_NE(o.Check().find("window_s"), std::string::npos);
  o = {};
  o.max_jitter_fraction = 0.6;
  EXPECT_NE(o.Check().find("max_jitter_fraction"), std::string::npos);
  o = {};
  o.min_frames = 2;
  EXPECT_NE(o.Check().find("min_frames"), std::string::npos);
  o = {};
  o.max_outlier_fraction = 1;
  EXPECT_NE(o.Check().find("max_outlier_fraction"), std::string::npos);
}

}  // namespace
}  // namespace hw::core
