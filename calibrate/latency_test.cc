// Stream latency calibration (calibrate/latency.h): the pair estimator on synthetic signals
// with known offsets and noise (is σ honest?), then the whole estimate on the fixtures'
// latency sessions against their true rig, over seeds, true offsets, a slow bolometer,
// irregular motion with dropped frames, and the errors.
#include "calibrate/latency.h"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>

#include <gtest/gtest.h>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/rig.h"
#include "core/scan.h"
#include "fixtures/cached_test_data.h"
#include "fixtures/calibration_sessions.h"
#include "tests/support.h"

namespace hw::calibrate {
namespace {

namespace fs = std::filesystem;
using fixtures::CalibrationSessionKind;
using fixtures::CalibrationSessionOptions;

// ---------------------------------------------------------------------------------------
// The pair estimator on synthetic signals

// A smooth irregular motion (sum of incommensurate sines), sampled at `rate_hz` from t0 on
// the stream's own clock, seen at depth-clock time t + offset_s, with white noise.
LatencySignal Sampled(const std::string& name, double rate_hz, double t0, double duration_s, double offset_s,
                      double noise, std::mt19937_64& rng) {
  std::normal_distribution<double> gauss(0, noise);
  LatencySignal s;
  s.name = name;
  s.period_s = 1 / rate_hz;
  for (double t = t0; t < t0 + duration_s; t += s.period_s) {
    const double true_t = t + offset_s;
    s.time_s.push_back(t);
    s.value.push_back(std::sin(2.1 * true_t) + 0.5 * std::sin(5.3 * true_t + 1) + 0.3 * std::sin(8.9 * true_t + 2) +
                      gauss(rng));
  }
  return s;
}

TEST(LatencyPair, RecoversKnownOffsetsWithAnHonestSigma) {
  LatencyOptions options;
  options.bootstrap_samples = 100;
  std::mt19937_64 rng(7);
  double z2 = 0;
  const int trials = 30;
  for (int trial = 0; trial < trials; ++trial) {
    const double offset_s = -0.2 + 0.4 * trial / trials;
    const LatencySignal depth = Sampled("depth", 30, 100, 8, 0, 0.01, rng);
    const LatencySignal other = Sampled("thermal", 27, 100.013, 8, offset_s, 0.01, rng);
    const PairOffset p = EstimatePairOffset(depth, other, options, "synthetic");
    EXPECT_NEAR(p.offset_s, offset_s, 1e-3) << trial;
    EXPECT_GT(p.peak_correlation, 0.99);
    EXPECT_NEAR(p.gain, 1, 0.02);
    EXPECT_GT(p.sigma_s, 0);
    z2 += std::pow((p.offset_s - offset_s) / p.sigma_s, 2);
  }
  // σ is the larger of two estimates of the error: the RMS z-score is at most ~1 (here
  // ~0.5–1: both noises enter the residual, and the max of two estimates is conservative)
  // and not wildly pessimistic (> 0.3).
  const double z_rms = std::sqrt(z2 / trials);
  std::printf("synthetic pairs: RMS z-score %.2f over %d trials\n", z_rms, trials);
  EXPECT_LT(z_rms, 1.5);
  EXPECT_GT(z_rms, 0.3);
}

TEST(LatencyPair, GapsAreNeverInterpolatedAcross) {
  std::mt19937_64 rng(3);
  LatencySignal s = Sampled("rgb", 30, 0, 2, 0, 0, rng);
  s.value[10] = std::nan("");
  EXPECT_FALSE(SampleSignal(s, s.time_s[10] - 0.01, 1.5));
  EXPECT_FALSE(SampleSignal(s, s.time_s[10] + 0.01, 1.5));
  EXPECT_TRUE(SampleSignal(s, s.time_s[12] + 0.01, 1.5));
  EXPECT_NEAR(*SampleSignal(s, s.time_s[12], 1.5), s.value[12], 1e-12);
  EXPECT_FALSE(SampleSignal(s, s.time_s.back() + 0.001, 1.5));
}

TEST(LatencyPair, PeriodicMotionWithinTheSearchRangeIsAmbiguous) {
  // A pure swing of period 0.8 s, 0.03 s apart: over ±0.5 s the only peak is at 0.03 s (the
  // next ones, 0.8 s away, are outside); over ±1 s the one at −0.77 s is inside.
  LatencySignal a, b;
  a.name = "depth", b.name = "rgb";
  a.period_s = b.period_s = 1 / 30.0;
  for (int i = 0; i < 300; ++i) {
    const double t = i / 30.0;
    a.time_s.push_back(t), b.time_s.push_back(t);
    a.value.push_back(std::sin(2 * M_PI * t / 0.8));
    b.value.push_back(std::sin(2 * M_PI * (t + 0.03) / 0.8));
  }
  LatencyOptions options;
  options.bootstrap_samples = 0;
  EXPECT_NEAR(EstimatePairOffset(a, b, options, "x").offset_s, 0.03, 1e-4);
  options.max_offset_s = 1.0;
  try {
    EstimatePairOffset(a, b, options, "x");
    ADD_FAILURE() << "no error";
  } catch (const core::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("ambiguous"), std::string::npos) << e.what();
  }
}

TEST(LatencyOptions, CheckNamesTheField) {
  EXPECT_EQ(LatencyOptions().Check(), "");
  LatencyOptions o;
  o.max_offset_s = 0;
  EXPECT_NE(o.Check().find("max_offset_s"), std::string::npos);
  o = {};
  o.ambiguity_ratio = 1;
  EXPECT_NE(o.Check().find("ambiguity_ratio"), std::string::npos);
  o = {};
  o.threshold_sigmas = 1;
  EXPECT_NE(o.Check().find("threshold_sigmas"), std::string::npos);
}

// ---------------------------------------------------------------------------------------
// The fixtures' latency sessions

// The small latency session (depth and colour 320 × 240, thermal 160 × 120) lengthened to
// `duration_s` (the preset's 0.5 s holds half a swing), with the given seed, true clock
// offsets and motion; rendered once per build.
CalibrationSessionOptions Session(uint64_t seed, double rgb_offset_s, double thermal_offset_s, double duration_s,
                                  fixtures::LatencyMotion motion = fixtures::LatencyMotion::kSine, double tau_s = 0.010) {
  CalibrationSessionOptions o = CalibrationSessionOptions::Preset(CalibrationSessionKind::kLatency, true, seed);
  o.latency.duration_s = duration_s;
  // Test cost: every camera at half the small preset's size — depth and colour 160 × 120,
  // thermal 80 × 60 (a FLIR Lepton 2's), the disc 9–20 px wide — and at most 4
  // sub-exposures per frame (the thermal lag kernel's 4τ in 4 slices).
  core::Rig& rig = o.latency.common.true_rig;
  rig.depth = rig.depth.Scaled(0.5);
  rig.rgb = rig.rgb->Scaled(0.5);
  rig.thermal = rig.thermal->Scaled(0.5);
  o.latency.common.motion_blur_samples = 4;
  o.latency.motion = motion;
  // A 30 cm swing at 1 m (the preset's 15 cm doubled: the disc stays in every camera's view):
  // twice the speed, half the timing noise of a centroid.
  o.latency.amplitude_m = 0.3;
  o.latency.common.thermal.time_constant_s = tau_s;
  o.latency.common.true_rig.rgb_time_offset_s = rgb_offset_s;
  o.latency.common.true_rig.thermal_time_offset_s = thermal_offset_s;
  return o;
}

fs::path Render(const std::string& name, const CalibrationSessionOptions& options) {
  return fixtures::test::CachedSession(name, options, "thermal.txt");
}

// The estimate against the true rig. Tolerance: 3σ (the estimate's own uncertainty), and in
// any case 1.5 ms — a sixth of a 27 Hz thermal frame period, the accuracy thermal fusion
// needs (at 1 m/s hand speed 1.5 ms is 1.5 mm) and an order of magnitude above what the
// clean sessions give (~0.1–0.3 ms), so that a sign or lag-convention error (10 ms) fails.
void ExpectMatchesTruth(const LatencyResult& r, const fs::path& scan_folder, const std::string& label) {
  const core::Rig truth = core::ReadRig(scan_folder / "truth" / "rig.yaml");
  const double rgb_error = r.rgb.offset_s - truth.rgb_time_offset_s;
  const double thermal_error = r.thermal.offset_s - truth.thermal_time_offset_s;
  std::printf("%s: rgb %+.3f ms (truth %+.3f, error %+.3f, sigma %.3f: fit %.3f boot %.3f), thermal %+.3f ms (truth "
              "%+.3f, error %+.3f, sigma %.3f: fit %.3f boot %.3f), closure %+.3f ms, %.2f s\n",
              label.c_str(), 1e3 * r.rgb.offset_s, 1e3 * truth.rgb_time_offset_s, 1e3 * rgb_error, 1e3 * r.rgb.sigma_s,
              1e3 * r.rgb.sigma_fit_s, 1e3 * r.rgb.sigma_bootstrap_s, 1e3 * r.thermal.offset_s,
              1e3 * truth.thermal_time_offset_s, 1e3 * thermal_error, 1e3 * r.thermal.sigma_s,
              1e3 * r.thermal.sigma_fit_s, 1e3 * r.thermal.sigma_bootstrap_s, 1e3 * r.closure_s, r.seconds);
  EXPECT_LT(std::abs(rgb_error), 1.5e-3) << label;
  EXPECT_LT(std::abs(thermal_error), 1.5e-3) << label;
  EXPECT_LT(std::abs(rgb_error), 3 * r.rgb.sigma_s) << label;
  EXPECT_LT(std::abs(thermal_error), 3 * r.thermal.sigma_s) << label;
  EXPECT_LT(std::abs(r.closure_s), 3 * r.closure_sigma_s + 1e-4) << label;
}

TEST(LatencySession, OffsetsMatchTheTruthOverSeedsClocksAndBolometers) {
  // Three seeds (noise, clock phases), each with its own true offsets: the estimate follows
  // the truth, not a constant. The third has a slow bolometer (τ = 20 ms, 2× the preset's):
  // its frames follow the disc τ late behind their readout, and the fixtures put a thermal
  // frame's true time at the centroid of its lag kernel (fixtures/exposure.h). The estimate
  // is that effective offset — equal to the true rig's, not shifted by τ (a 10 or 20 ms
  // shift fails by far). (A first-order lag delays a sine of angular frequency ω by
  // atan(ωτ)/ω, not exactly τ: 0.1 ms less at τ = 20 ms and 1 Hz, negligible here; at
  // τ = 40 ms it is 0.8 ms, see calibrate/latency.h.)
  const double rgb_s[] = {0.012, -0.023, 0.051}, thermal_s[] = {-0.040, -0.071, 0.017}, tau_s[] = {0.010, 0.010, 0.020};
  const double duration_s[] = {1.5, 1.0, 1.0};  // the first also serves ErrorsNameTheProblem
  for (int k = 0; k < 3; ++k) {
    const std::string name = "latency-160px-a30-v2-sine-seed" + std::to_string(k + 1);
    const fs::path folder = Render(name, Session(static_cast<uint64_t>(k + 1), rgb_s[k], thermal_s[k], duration_s[k],
                                                 fixtures::LatencyMotion::kSine, tau_s[k]));
    const LatencyResult r = EstimateLatency(core::Scan::Open(folder), LatencyOptions());
    ExpectMatchesTruth(r, folder, name);
    EXPECT_EQ(r.depth_track.missing, 0);
    EXPECT_GT(r.rgb.peak_correlation, 0.99);
    EXPECT_GT(r.thermal.peak_correlation, 0.99);
    // One motion axis for all cameras: the signals agree in sign (a flipped one would
    // correlate at -1 and be rejected).
    EXPECT_GT(r.rgb.gain, 0);
    EXPECT_GT(r.thermal.gain, 0);
  }
}

// Removes the lines of frames (0-based) `drop` from a stream index.
void DropIndexLines(const fs::path& index, const std::vector<int>& drop) {
  const std::vector<core::IndexEntry> entries = core::ReadStreamIndex(index);
  std::string text;
  for (size_t i = 0; i < entries.size(); ++i) {
    if (std::find(drop.begin(), drop.end(), static_cast<int>(i)) != drop.end()) continue;
    char stamp[64];
    std::snprintf(stamp, sizeof(stamp), "%.6f", entries[i].timestamp_s);
    text += std::string(stamp) + " " + entries[i].path + "\n";
  }
  core::WriteFileAtomically(index, text);
}

fs::path CopyOf(const fs::path& session, const std::string& name) {
  const fs::path copy = test::TestFolder(name);
  fs::copy(session, copy, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
  return copy;
}

TEST(LatencySession, IrregularMotionWithDroppedFramesAndMissingFiles) {
  const fs::path session =
      Render("latency-160px-a30-v2-irregular", Session(5, -0.031, -0.055, 1.2, fixtures::LatencyMotion::kIrregular));
  const fs::path folder = CopyOf(session, "dropped");
  // A burst of 6 thermal frames and every 7th rgb frame lost (index lines gone), and 4 depth
  // frame files deleted (listed but missing: Scan warns, the tracker must not choke).
  DropIndexLines(folder / "thermal.txt", {15, 16, 17, 18, 19, 20});
  std::vector<int> every7;
  for (int i = 3; i < 36; i += 7) every7.push_back(i);
  DropIndexLines(folder / "rgb.txt", every7);
  const core::Scan scan_before = core::Scan::Open(folder);
  for (int i : {8, 9, 20, 30}) fs::remove(scan_before.FramePath(core::Stream::kDepth, i));
  const core::Scan scan = core::Scan::Open(folder);
  LatencyResult r;
  try {
    r = EstimateLatency(scan, LatencyOptions());
  } catch (const std::exception& e) {
    FAIL() << e.what();
  }
  ExpectMatchesTruth(r, folder, "irregular, dropped frames");
  EXPECT_EQ(r.depth_track.missing, 4);
}

// The second rate: a low-cost 9 Hz thermal core (Lepton-class: 9 Hz export limit,
// bolometer τ ≈ 12 ms) against 30 Hz depth and colour. A thermal frame then spans 111 ms,
// 3.7 depth frames: the offset must still come to a fraction of a millisecond, not of a
// frame. Its own bound is the 2 ms (and 3σ): with 3× fewer thermal samples over the
// 3 s, the thermal σ is larger than at 27 Hz.
TEST(LatencySession, ANineHertzThermalCameraIsTimedToWithinTwoMilliseconds) {
  CalibrationSessionOptions options = Session(4, 0.020, -0.063, 3.0, fixtures::LatencyMotion::kSine, 0.012);
  options.latency.thermal_rate_hz = 9;
  const fs::path folder = Render("latency-160px-a30-v2-sine-9hz", options);
  const LatencyResult r = EstimateLatency(core::Scan::Open(folder), LatencyOptions());
  const core::Rig truth = core::ReadRig(folder / "truth" / "rig.yaml");
  const double rgb_error = r.rgb.offset_s - truth.rgb_time_offset_s;
  const double thermal_error = r.thermal.offset_s - truth.thermal_time_offset_s;
  std::printf("9 Hz thermal: %d frames; rgb error %+.3f ms (sigma %.3f), thermal error %+.3f ms (sigma %.3f), "
              "closure %+.3f ms\n",
              r.thermal_track.frames, 1e3 * rgb_error, 1e3 * r.rgb.sigma_s, 1e3 * thermal_error, 1e3 * r.thermal.sigma_s,
              1e3 * r.closure_s);
  EXPECT_LT(std::abs(thermal_error), 2e-3);
  EXPECT_LT(std::abs(thermal_error), 3 * r.thermal.sigma_s);
  EXPECT_LT(std::abs(rgb_error), 1.5e-3);
  EXPECT_LT(std::abs(rgb_error), 3 * r.rgb.sigma_s);
  EXPECT_GT(r.thermal.peak_correlation, 0.99);
}

TEST(LatencySession, ErrorsNameTheProblem) {
  const fs::path session = Render("latency-160px-a30-v2-sine-seed1", Session(1, 0.012, -0.040, 1.5));
  auto expect_error = [](const fs::path& folder, const std::string& needle) {
    try {
      EstimateLatency(core::Scan::Open(folder), LatencyOptions());
      ADD_FAILURE() << "no error, expected: " << needle;
    } catch (const core::InputError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  // No thermal stream.
  fs::path folder = CopyOf(session, "no-thermal");
  fs::remove(folder / "thermal.txt");
  expect_error(folder, "no thermal stream");
  // A static scene: every frame of every stream is its stream's first one.
  folder = CopyOf(session, "static");
  for (core::Stream s : core::kAllStreams) {
    const fs::path index = folder / (core::StreamName(s) + ".txt");
    const std::vector<core::IndexEntry> entries = core::ReadStreamIndex(index);
    std::string text;
    for (const core::IndexEntry& e : entries) text += std::to_string(e.timestamp_s) + " " + entries.front().path + "\n";
    core::WriteFileAtomically(index, text);
  }
  expect_error(folder, "no moving blob in enough depth frames");
  // Motion below what the options ask for (the 30 cm swing is ~30 px RMS in 160 × 120 depth).
  LatencyOptions still;
  still.min_motion_px = 1000;
  try {
    EstimateLatency(core::Scan::Open(session), still);
    ADD_FAILURE() << "no error";
  } catch (const core::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("the blob barely moves in depth"), std::string::npos) << e.what();
  }
  // The 1 Hz swing searched over ±1 s: it repeats within the range (the 1.5 s session
  // overlaps itself by 0.5 s at a 1 s shift).
  LatencyOptions wide;
  wide.max_offset_s = 1.0;
  try {
    EstimateLatency(core::Scan::Open(session), wide);
    ADD_FAILURE() << "no error";
  } catch (const core::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("ambiguous"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace hw::calibrate
