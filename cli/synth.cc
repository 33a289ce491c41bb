// heatwave synth: renders a synthetic scan (fixtures/synth_scan.h) or a calibration session
// (fixtures/calibration_sessions.h) with exact ground truth.
#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>
#include <numbers>
#include <optional>
#include <set>
#include <string>
#include <system_error>
#include <vector>

#include "cli/command.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/output_folder.h"
#include "core/progress.h"
#include "core/scan.h"
#include "core/strings.h"
#include "fixtures/bench_session.h"
#include "fixtures/calibration_sessions.h"
#include "fixtures/passer.h"
#include "fixtures/scenes.h"
#include "fixtures/synth_scan.h"

namespace hw::cli {

namespace {

namespace fs = std::filesystem;

std::string Join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

std::string FormatBytes(uint64_t bytes) {
  const double b = static_cast<double>(bytes);
  if (b >= 1e9) return core::StringPrintf("%.2f GB", b / 1e9);
  if (b >= 1e6) return core::StringPrintf("%.1f MB", b / 1e6);
  if (b >= 1e3) return core::StringPrintf("%.1f kB", b / 1e3);
  return core::StringPrintf("%llu B", static_cast<unsigned long long>(bytes));
}

// What a bench session folder holds (fixtures/bench_session.h): removed by --overwrite.
std::vector<std::string> BenchEntries() {
  std::vector<std::string> entries = {"rig.yaml", "session.yaml", "truth"};
  for (const fixtures::BenchPartSpec& part : fixtures::BenchParts(fixtures::BenchSessionOptions::Preset(true))) {
    entries.push_back(part.folder);
  }
  return entries;
}

std::unique_ptr<core::OutputFolder> PrepareOutputFolder(const fs::path& out, bool overwrite,
                                                        const std::vector<std::string>& entries = ScanFolderEntries()) {
  return hw::cli::PrepareOutputFolder(out, overwrite, "heatwave synth", entries);
}

// --seed, --rig-seed: a whole number in [0, 2^64 - 1]. CLI11 reads "-1" as 2^64 - 1 and
// saturates values beyond 2^64; both are refused here.
uint64_t ParseSeed(const std::string& text, const std::string& flag = "--seed") {
  uint64_t seed = 0;
  const char* last = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), last, seed);
  if (text.empty() || ec != std::errc() || ptr != last) {
    throw UsageError(flag + ": must be a whole number from 0 to 18446744073709551615, got '" +
                     text + "'");
  }
  return seed;
}

// A progress bar created at the first report, when the total is known.
class LazyProgress {
 public:
  LazyProgress(std::string label, bool quiet) : label_(std::move(label)), quiet_(quiet) {}
  void operator()(int done, int total) {
    if (!bar_) bar_ = std::make_unique<core::ProgressBar>(label_, total, "frames", quiet_);
    bar_->Set(done);
  }
  void Finish() {
    if (bar_) bar_->Finish();
  }

 private:
  std::string label_;
  bool quiet_;
  std::unique_ptr<core::ProgressBar> bar_;
};

std::string StreamLine(const char* name, int frames, double rate_hz, const std::string& extra) {
  if (frames == 0) return core::StringPrintf("  %-8s none\n", name);
  return core::StringPrintf("  %-8s %5d frames at %6.2f Hz%s\n", name, frames, rate_hz, extra.c_str());
}

std::string FormatScanSummary(const fixtures::SynthScanOptions& o,
                              const fixtures::SynthScanSummary& s) {
  std::string out;
  out += core::StringPrintf("Scene      %s  (seed %llu, %s motion, noise %s)\n", s.scene.c_str(),
                static_cast<unsigned long long>(o.seed), fixtures::MotionKindName(o.motion).c_str(),
                o.noise ? "on" : "off");
  out += core::StringPrintf("Folder     %s  (%s)\n", s.folder.string().c_str(),
                FormatBytes(s.bytes_written).c_str());
  out += "Streams\n";
  out += StreamLine("depth", s.depth_frames, o.depth_rate_hz,
                    core::StringPrintf(", %dx%d", static_cast<int>(std::lround(640 * o.image_scale)),
                           static_cast<int>(std::lround(480 * o.image_scale))));
  out += StreamLine("rgb", s.rgb_frames, o.rgb_rate_hz,
                    core::StringPrintf(", clock offset %+.3f s", o.rgb_time_offset_s));
  out += StreamLine("thermal", s.thermal_frames, o.thermal_rate_hz,
                    core::StringPrintf(", %dx%d, clock offset %+.3f s, %s, %d FFC events",
                           static_cast<int>(std::lround(320 * o.image_scale * o.thermal_image_scale)),
                           static_cast<int>(std::lround(240 * o.image_scale * o.thermal_image_scale)),
                           o.thermal_time_offset_s,
                           o.thermal_encoding == core::ThermalEncoding::kRawCounts16 ? "raw counts"
                                                                                     : "float TIFF",
                           s.ffc_events));
  if (s.thermal_frames > 0) {
    out += core::StringPrintf(
        "  %-8s radiometric gain %.4f, offset %+.2f K; %d frames frozen, %d dropped by the "
        "shutter\n",
        "", s.thermal_gain, s.thermal_offset_k, s.thermal_frames_frozen,
        s.thermal_frames_dropped);
  }
  out += core::StringPrintf("Time span  %.6f .. %.6f s on the depth clock (%.3f s)\n", s.start_time_s,
                s.end_time_s, s.end_time_s - s.start_time_s);
  out += core::StringPrintf(
      "Timing     stamps jittered by up to %.2f ms, %lld frames dropped "
      "(truth/frame_times.txt: true times)\n",
      s.max_stamp_jitter_s * 1e3, static_cast<long long>(s.dropped_frames));
  if (s.rgb_frames > 0) {
    out += core::StringPrintf("Colour     auto exposure gain %.2f .. %.2f\n", s.min_exposure_gain,
                              s.max_exposure_gain);
  }
  out += core::StringPrintf("Motion     mean %.2f m/s, max %.2f m/s; mean %.0f deg/s, max %.0f deg/s\n",
                s.motion.mean_speed_m_per_s, s.motion.max_speed_m_per_s,
                s.motion.mean_rate_rad_per_s * 180 / std::numbers::pi,
                s.motion.max_rate_rad_per_s * 180 / std::numbers::pi);
  const bool estimated_reflection = s.written_reflected_c != s.true_reflected_c;
  const std::string rig_state =
      o.perturb_rig ? "rig.yaml perturbed; the true rig is truth/rig.yaml"
      : estimated_reflection
          ? "rig.yaml is the true rig but for reflected_c; the true rig is truth/rig.yaml"
          : "rig.yaml is the true rig";
  out += core::StringPrintf("Rig        unit %llu; %s\n",
                            static_cast<unsigned long long>(o.rig_seed), rig_state.c_str());
  if (estimated_reflection) {
    out += core::StringPrintf("           reflected_c %.2f °C written (an auditor's estimate), "
                              "%.2f °C true\n",
                              s.written_reflected_c, s.true_reflected_c);
  }
  out += core::StringPrintf(
      "Truth      groundtruth.txt (%d poses), truth/scene.ply (%d vertices, %d faces), "
      "truth/hotspots.yaml\n",
      s.depth_frames + s.rgb_frames + s.thermal_frames, s.mesh_vertices, s.mesh_faces);
  out += core::StringPrintf("Hotspots   %zu\n", s.hotspots.size());
  for (const fixtures::HotspotTruth& h : s.hotspots) {
    out += core::StringPrintf("  %-22s %-4s %6.1f °C (%s %5.1f °C)  %9.5f m²  %6.3f x %6.3f m",
                              h.id.c_str(), h.hot ? "hot" : "cold", h.temperature_c,
                              h.hot ? ">=" : "<=", h.threshold_c, h.area_m2, h.length_m,
                              h.width_m);
    if (h.observed_fraction) {
      out += core::StringPrintf("  seen %3.0f %%", 100 * *h.observed_fraction);
    }
    out += "\n";
  }
  if (s.depth_pixels_out_of_range > 0 || s.thermal_pixels_saturated > 0) {
    out += core::StringPrintf(
        "Clipped    %d depth pixels beyond the uint16 range, %d thermal pixels "
        "saturated\n",
        s.depth_pixels_out_of_range, s.thermal_pixels_saturated);
  }
  const int frames = s.depth_frames + s.rgb_frames + s.thermal_frames;
  out += core::StringPrintf("Done       %d frames in %s (%.1f frames/s)\n", frames,
                core::ProgressBar::FormatDuration(s.seconds).c_str(),
                s.seconds > 0 ? frames / s.seconds : 0.0);
  return out;
}

std::string FormatSessionSummary(const fixtures::SessionSummary& s, uint64_t seed,
                                 uint64_t rig_seed, uint64_t bytes, double seconds) {
  std::string out;
  out += core::StringPrintf("Session    %s  (seed %llu)\n", fixtures::CalibrationSessionName(s.kind).c_str(),
                static_cast<unsigned long long>(seed));
  out += core::StringPrintf("Folder     %s  (%s)\n", s.folder.string().c_str(), FormatBytes(bytes).c_str());
  out += core::StringPrintf("Frames     depth %d, rgb %d, thermal %d; %d FFC events; %.3f s\n", s.depth_frames,
                s.rgb_frames, s.thermal_frames, s.ffc_events, s.duration_s);
  out += core::StringPrintf(
      "Rig        unit %llu; rig.yaml is the nominal rig; the true rig is truth/rig.yaml\n",
      static_cast<unsigned long long>(rig_seed));
  const int frames = s.depth_frames + s.rgb_frames + s.thermal_frames;
  out += core::StringPrintf("Done       %d frames in %s (%.1f frames/s)\n", frames,
                core::ProgressBar::FormatDuration(seconds).c_str(),
                seconds > 0 ? frames / seconds : 0.0);
  return out;
}

// What the command line said, before it is turned into typed options.
struct SynthArguments {
  std::string scene;
  std::string session;
  fs::path out;
  std::string seed_text = "1";  // parsed by ParseSeed
  uint64_t seed = 1;
  std::string rig_seed_text = "0";  // parsed by ParseSeed
  uint64_t rig_seed = 0;
  std::string size = "small";
  std::string trajectory = "smooth";
  std::string thermal_format = "raw";
  std::string thermal_camera = "standard";
  std::string ffc_frames = "freeze";
  std::optional<double> duration_s;
  std::optional<double> path_start_s, loop_duration_s;
  std::optional<double> depth_rate_hz, rgb_rate_hz, thermal_rate_hz;
  std::optional<double> rgb_offset_s, thermal_offset_s;
  std::optional<double> scene_scale;
  std::optional<double> image_scale;
  std::string mask_polarity = "hot";
  std::optional<int> views;           // stills: per target part of --session bench, or of a stills session
  std::string colour_target = "chessboard";  // --session bench
  std::optional<int> rooms;
  bool perturb_rig = false;
  bool no_noise = false;
  bool no_rgb = false;
  bool no_thermal = false;
  bool no_jitter = false;
  bool no_drops = false;
  bool no_rolling_shutter = false;
  bool no_specular = false;
  bool no_reflections = false;
  bool no_depth_artefacts = false;
  std::optional<double> reflected_error_k;
  std::optional<double> thermal_vignetting;
  bool no_shadows = false;
  bool no_auto_exposure = false;
  std::optional<double> passer_crossing;
  bool overwrite = false;
  bool list = false;
};

// Default --duration of a full-size --trajectory loop, s.
constexpr double kFullLoopDurationS = 90;

int RunScan(const SynthArguments& args, const CommonOptions& common) {
  fixtures::SynthScanOptions o = args.size == "full"
                                     ? fixtures::SynthScanOptions::Full(args.scene)
                                     : fixtures::SynthScanOptions::Small(args.scene);
  o.seed = args.seed;
  // A full-size loop walks the whole inspection route at an operator's pace.
  if (args.trajectory == "loop" && args.size == "full") o.duration_s = kFullLoopDurationS;
  // The preset first: it sets the thermal rate that --thermal-rate may override.
  if (!fixtures::ApplyThermalCamera(args.thermal_camera, o)) {
    throw UsageError("--thermal-camera: unknown camera '" + args.thermal_camera + "'");
  }
  o.thermal.ffc_drop_frames = args.ffc_frames == "drop";
  o.rig_seed = args.rig_seed;
  if (args.duration_s) o.duration_s = *args.duration_s;
  // A window of a full-size loop keeps the loop's operator pace unless told otherwise.
  if (args.loop_duration_s && args.trajectory != "loop") {
    throw UsageError("--loop-duration: applies to --trajectory loop only");
  }
  if (args.path_start_s && args.trajectory == "loop" && args.size == "full") {
    o.loop_duration_s = kFullLoopDurationS;
  }
  if (args.path_start_s) o.path_start_s = *args.path_start_s;
  if (args.loop_duration_s) o.loop_duration_s = *args.loop_duration_s;
  if (args.depth_rate_hz) o.depth_rate_hz = *args.depth_rate_hz;
  if (args.rgb_rate_hz) o.rgb_rate_hz = *args.rgb_rate_hz;
  if (args.thermal_rate_hz) o.thermal_rate_hz = *args.thermal_rate_hz;
  if (args.rgb_offset_s) o.rgb_time_offset_s = *args.rgb_offset_s;
  if (args.thermal_offset_s) o.thermal_time_offset_s = *args.thermal_offset_s;
  if (args.scene_scale) o.scene_options.scale = *args.scene_scale;
  if (args.image_scale) o.image_scale = *args.image_scale;
  if (args.rooms) o.scene_options.rooms = *args.rooms;
  o.motion = *fixtures::ParseMotionKind(args.trajectory);
  o.thermal_encoding = args.thermal_format == "tiff" ? core::ThermalEncoding::kFloatTiff
                                                     : core::ThermalEncoding::kRawCounts16;
  o.perturb_rig = args.perturb_rig;
  o.noise = !args.no_noise;
  o.write_rgb = !args.no_rgb;
  o.write_thermal = !args.no_thermal;
  if (args.no_jitter) o.timing.jitter_std_s = 0;
  if (args.no_drops) o.timing.drop_probability = o.timing.burst_probability = 0;
  if (args.no_rolling_shutter) o.colour.readout_s = 0;
  if (args.no_specular) o.colour.specular = false;
  if (args.no_reflections) o.thermal.reflections = fixtures::ReflectionOptions::Uniform();
  if (args.reflected_error_k) o.reflected_error_k = *args.reflected_error_k;
  if (args.thermal_vignetting) o.thermal.vignetting = *args.thermal_vignetting;
  if (args.no_depth_artefacts) {
    o.depth.noise_correlation_px = 0;
    o.depth.distortion_radial_px = o.depth.distortion_pattern_px = 0;
    o.depth.fattening_px = 0;
    o.depth.material_response = false;
  }
  if (args.no_shadows) o.colour.shadows = false;
  if (args.no_auto_exposure) o.auto_exposure.exposure = o.auto_exposure.white_balance = false;
  ThrowIfInvalid(o.Check());
  if (args.passer_crossing && !(*args.passer_crossing >= 0 && *args.passer_crossing <= 1)) {
    throw UsageError(core::StringPrintf("--passer: must be in [0, 1], got %g", *args.passer_crossing));
  }
  const std::unique_ptr<core::OutputFolder> folder = PrepareOutputFolder(args.out, args.overwrite);

  LazyProgress progress("render", common.quiet);
  const fixtures::SynthScanSummary summary =
      fixtures::SynthesizeScan(o, args.out, [&](int done, int total) { progress(done, total); });
  progress.Finish();
  folder->Commit();
  std::optional<fixtures::PasserSummary> passer;
  if (args.passer_crossing) {
    // An edit of the finished scan, under its own run marker: interrupted, the folder reads
    // as incomplete, not as a scan with the person in some frames only.
    const core::Scan scan = core::Scan::Open(args.out);
    core::OutputFolder edit(args.out, "heatwave synth --passer");
    fixtures::PasserOptions p;
    p.crossing_fraction = *args.passer_crossing;
    p.seed = args.seed;
    passer = fixtures::AddPasser(scan, p);
    edit.Commit();
  }
  if (!common.quiet) {
    std::cout << FormatScanSummary(o, summary);
    if (passer) {
      std::cout << core::StringPrintf(
          "Passer     crossing the view at %.3f s; in %d depth, %d colour and %d thermal frames "
          "(not in truth/)\n",
          passer->crossing_time_s, passer->depth_frames, passer->rgb_frames, passer->thermal_frames);
    }
    std::cout << std::flush;
  }
  return kExitOk;
}

int RunSession(const SynthArguments& args, const CommonOptions& common) {
  const std::optional<fixtures::CalibrationSessionKind> kind =
      fixtures::ParseCalibrationSessionKind(args.session);
  if (!kind) {
    throw UsageError("--session: unknown session '" + args.session +
                     "' (known: " + Join(fixtures::CalibrationSessionNames()) + ", bench)");
  }
  fixtures::CalibrationSessionOptions o =
      fixtures::CalibrationSessionOptions::Preset(*kind, args.size == "small", args.seed,
                                                  args.rig_seed);
  if (args.duration_s) {
    if (*kind == fixtures::CalibrationSessionKind::kTargetlessExtrinsics) {
      o.targetless.duration_s = *args.duration_s;
    } else if (*kind == fixtures::CalibrationSessionKind::kLatency) {
      o.latency.duration_s = *args.duration_s;
    } else {
      throw UsageError("--duration: does not apply to session '" + args.session +
                       "' (its length is its number of views)");
    }
  }
  if (args.views) {
    fixtures::TargetViewOptions* views =
        *kind == fixtures::CalibrationSessionKind::kThermalSquareGrid   ? &o.thermal_square_grid.views
        : *kind == fixtures::CalibrationSessionKind::kColourChessboard ? &o.chessboard.views
        : *kind == fixtures::CalibrationSessionKind::kColourAprilGrid  ? &o.aprilgrid.views
        : *kind == fixtures::CalibrationSessionKind::kTargetExtrinsics ? &o.target_extrinsics.views
                                                                        : nullptr;
    if (views == nullptr) {
      throw UsageError("--views: does not apply to session '" + args.session + "' (it is a recording, not stills)");
    }
    if (!(*args.views >= 3 && *args.views <= 200)) {
      throw UsageError("--views: must be in [3, 200], got " + std::to_string(*args.views));
    }
    views->num_views = *args.views;
  }
  if (args.image_scale) {
    // Views must still fit the target into the images: a quarter of the full size at least.
    if (!(*args.image_scale >= 0.25 && *args.image_scale <= 1)) {
      throw UsageError(core::StringPrintf(
          "--image-scale: must be in [0.25, 1] for a session, got %g", *args.image_scale));
    }
    fixtures::RigUnitOptions unit;
    unit.rig_seed = args.rig_seed;
    unit.image_scale = *args.image_scale;
    o.common().true_rig = fixtures::SynthRigOfUnit(unit);
  }
  if (args.mask_polarity != "hot" && *kind != fixtures::CalibrationSessionKind::kThermalSquareGrid) {
    throw UsageError("--mask-polarity: applies to session 'intrinsics-thermal' only");
  }
  o.thermal_square_grid.mask.plate_hotter = args.mask_polarity == "hot";
  if (args.thermal_format == "tiff")
    o.common().thermal_encoding = core::ThermalEncoding::kFloatTiff;
  ThrowIfInvalid(o.Check());
  const std::unique_ptr<core::OutputFolder> folder = PrepareOutputFolder(args.out, args.overwrite);

  LazyProgress progress("render", common.quiet);
  const auto started = std::chrono::steady_clock::now();
  const fixtures::SessionSummary summary = fixtures::SynthesizeCalibrationSession(
      o, args.out, [&](int done, int total) { progress(done, total); });
  progress.Finish();
  folder->Commit();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  if (!common.quiet) {
    std::cout << FormatSessionSummary(summary, args.seed, args.rig_seed,
                                      core::FolderSizeBytes(args.out), seconds)
              << std::flush;
  }
  return kExitOk;
}

// --session bench: every part of the calibration bench with one true rig.
int RunBenchSession(const SynthArguments& args, const CommonOptions& common) {
  fixtures::BenchSessionOptions o = fixtures::BenchSessionOptions::Preset(args.size == "small", args.seed, args.rig_seed);
  if (args.views) o.views = *args.views;
  o.colour_target = args.colour_target == "aprilgrid" ? core::TargetType::kAprilGrid : core::TargetType::kChessboard;
  o.rgb_time_offset_s = args.rgb_offset_s;
  o.thermal_time_offset_s = args.thermal_offset_s;
  if (args.depth_rate_hz) o.depth_rate_hz = *args.depth_rate_hz;
  if (args.rgb_rate_hz) o.rgb_rate_hz = *args.rgb_rate_hz;
  if (args.thermal_rate_hz) o.thermal_rate_hz = *args.thermal_rate_hz;
  o.latency_duration_s = args.duration_s;
  const std::string problem = o.Check();
  static const std::pair<const char*, const char*> kFlags[] = {
      {"views", "--views"},           {"rgb_time_offset_s", "--rgb-offset"}, {"thermal_time_offset_s", "--thermal-offset"},
      {"depth_rate_hz", "--depth-rate"}, {"rgb_rate_hz", "--rgb-rate"},        {"thermal_rate_hz", "--thermal-rate"},
      {"latency_duration_s", "--duration"}};
  for (const auto& [field, flag] : kFlags) {
    if (problem.rfind(std::string(field) + ":", 0) == 0) throw UsageError(flag + problem.substr(std::string(field).size()));
  }
  ThrowIfInvalid(problem);
  const std::unique_ptr<core::OutputFolder> folder = PrepareOutputFolder(args.out, args.overwrite, BenchEntries());
  std::unique_ptr<LazyProgress> progress;
  std::string current;
  const fixtures::BenchSessionSummary summary =
      fixtures::SynthesizeBenchSession(o, args.out, [&](const std::string& part, int done, int total) {
        if (part != current) {
          if (progress) progress->Finish();
          progress = std::make_unique<LazyProgress>(part, common.quiet);
          current = part;
        }
        (*progress)(done, total);
      });
  if (progress) progress->Finish();
  folder->Commit();
  if (!common.quiet) {
    std::string out = core::StringPrintf("Session    bench  (seed %llu, %d views per target part)\n",
                                         static_cast<unsigned long long>(args.seed), o.views);
    out += core::StringPrintf("Folder     %s  (%s)\n", args.out.c_str(), FormatBytes(core::FolderSizeBytes(args.out)).c_str());
    for (const fixtures::SessionSummary& p : summary.parts) {
      out += core::StringPrintf("  %-20s %-22s depth %d, rgb %d, thermal %d frames\n", p.folder.filename().c_str(),
                                fixtures::CalibrationSessionName(p.kind).c_str(), p.depth_frames, p.rgb_frames,
                                p.thermal_frames);
    }
    out += core::StringPrintf("Rig        unit %llu; rig.yaml is the nominal rig, truth/rig.yaml the true one every part "
                              "shares (clock offsets rgb %+.6f s, thermal %+.6f s)\n",
                              static_cast<unsigned long long>(args.rig_seed), summary.true_rig.rgb_time_offset_s,
                              summary.true_rig.thermal_time_offset_s);
    out += core::StringPrintf("Done       in %s\n", core::ProgressBar::FormatDuration(summary.seconds).c_str());
    std::cout << out << std::flush;
  }
  return kExitOk;
}

}  // namespace

int RunSynth(int argc, char** argv) {
  CLI::App app(
      "Render a synthetic scan folder (scan-format.md) with exact ground truth — "
      "groundtruth.txt, truth/scene.ply, truth/hotspots.yaml, truth/rig.yaml with "
      "--perturb-rig — from a named scene; or a calibration session (--session).\n"
      "Deterministic: the same options and seed give byte-identical files.",
      "heatwave synth");
  SynthArguments args;
  CommonOptions common;
  CLI::Option* scene =
      app.add_option("--scene", args.scene, "scene to render: " + Join(fixtures::SceneNames()));
  CLI::Option* session = app.add_option(
      "--session", args.session,
      "calibration session to render instead: " + Join(fixtures::CalibrationSessionNames()) +
          ", or bench: every part of `heatwave calibrate bench` with one true rig");
  scene->excludes(session);
  app.add_option("--out", args.out, "output scan folder (created)");
  app.add_option("--seed", args.seed_text, "seed of everything random, 0 to 2^64-1")
      ->capture_default_str();
  app.add_option("--rig-seed", args.rig_seed_text,
                 "unit serial of the rig, 0 to 2^64-1: 0 is the reference unit, others vary "
                 "from unit to unit; a session and a scan of one unit share truth/rig.yaml and "
                 "rig.yaml (--perturb-rig)")
      ->capture_default_str();
  app.add_option("--size", args.size,
                 "small: tiny images and 1 s (tests); full: 640x480 depth and colour, 320x240 "
                 "thermal, 10 s")
      ->check(CLI::IsMember({"small", "full"}))
      ->capture_default_str();
  app.add_option("--duration", args.duration_s,
                 "length of the recording, s (default 1 small, 10 full, 90 for a full loop)");
  app.add_option("--trajectory", args.trajectory,
                 "hand-held motion, aim wandering over the target: smooth sweep with tremor, "
                 "jerky bursts (~1 m/s, ~90°/s), or loop: an inspection walk round the "
                 "equipment back to its start, lasting --duration")
      ->check(CLI::IsMember({"smooth", "jerky", "loop"}))
      ->capture_default_str();
  app.add_option("--path-start", args.path_start_s,
                 "record a window of the motion starting this far into it, s, [0, 3600] (a loop's "
                 "stops in between: --trajectory loop --path-start 3 --duration 30; a full-size "
                 "loop then keeps its 90 s period)");
  app.add_option("--loop-duration", args.loop_duration_s,
                 "period of --trajectory loop, s, (0, 3600] (default: --duration, or 90 for a "
                 "full-size window given by --path-start)");
  app.add_option("--depth-rate", args.depth_rate_hz, "depth frame rate, Hz (default 30)");
  app.add_option("--rgb-rate", args.rgb_rate_hz, "colour frame rate, Hz (default 30)");
  app.add_option("--thermal-camera", args.thermal_camera,
                 "thermal camera: standard (320x240, 30 Hz, accuracy 1-2 K / 2 %), fast (the "
                 "same at 60 Hz), low-cost (160x120 Lepton-class, 9 Hz, 2-5 K / 5 %)")
      ->check(CLI::IsMember(fixtures::ThermalCameraNames()))
      ->capture_default_str();
  app.add_option("--thermal-rate", args.thermal_rate_hz,
                 "thermal frame rate, Hz (default: the camera's; real cameras 9, 27, 30, 60, 80)");
  app.add_option("--ffc-frames", args.ffc_frames,
                 "thermal frames during a flat-field shutter closure: freeze (the last frame "
                 "repeated, as FLIR and Seek cameras do) or drop")
      ->check(CLI::IsMember({"freeze", "drop"}))
      ->capture_default_str();
  app.add_option("--rgb-offset", args.rgb_offset_s,
                 "rig.yaml time_offset_s of the colour stream, s (default +0.012)");
  app.add_option("--thermal-offset", args.thermal_offset_s,
                 "rig.yaml time_offset_s of the thermal stream, s (default -0.040)");
  app.add_option("--thermal-format", args.thermal_format,
                 "thermal frames as raw: 16-bit centikelvin PNG, or tiff: float °C TIFF")
      ->check(CLI::IsMember({"raw", "tiff"}))
      ->capture_default_str();
  app.add_option("--scene-scale", args.scene_scale, "scale the scene's size by this factor");
  app.add_option("--mask-polarity", args.mask_polarity,
                 "session intrinsics-thermal: hot: the mask's plate hotter than the background "
                 "behind its holes; cold: colder")
      ->check(CLI::IsMember({"hot", "cold"}))
      ->capture_default_str();
  app.add_option("--image-scale", args.image_scale,
                 "scale every camera's image size by this factor, (0, 1] (sessions [0.25, 1]); "
                 "default: the --size preset's (scans: small 0.125, full 1; sessions: small "
                 "0.5, full 1)");
  app.add_option("--rooms", args.rooms, "rooms of the 'large' scene");
  app.add_option("--views", args.views,
                 "stills, [3, 200]: per target part of session bench (default 10 small, 20 full), or of an "
                 "intrinsics-* or extrinsics-target session (default: its preset's)");
  app.add_option("--colour-target", args.colour_target, "session bench: the colour intrinsics' target")
      ->check(CLI::IsMember({"chessboard", "aprilgrid"}))
      ->capture_default_str();
  app.add_flag("--perturb-rig", args.perturb_rig,
               "write a deliberately wrong rig.yaml and the true one as truth/rig.yaml");
  app.add_flag("--no-noise", args.no_noise, "ideal sensors: no noise, dropouts, drift, thermal calibration error or frames lost to the shutter");
  app.add_flag("--no-rgb", args.no_rgb, "render no colour stream");
  app.add_flag("--no-thermal", args.no_thermal, "render no thermal stream");
  app.add_flag("--no-jitter", args.no_jitter,
               "stamp every frame at its true time (default: ~2 ms driver jitter)");
  app.add_flag("--no-drops", args.no_drops,
               "deliver every frame (default: ~1.2 % dropped singly, bursts of 3-10)");
  app.add_flag("--no-rolling-shutter", args.no_rolling_shutter,
               "global-shutter colour camera (default: rows read out over 27 ms)");
  app.add_flag("--no-specular", args.no_specular, "no highlights on glossy surfaces");
  app.add_flag("--no-reflections", args.no_reflections,
               "thermal: a uniform room in every reflection (default: mirror rays traced, "
               "the operator's body behind the camera)");
  app.add_option("--reflected-error", args.reflected_error_k,
                 "bound of the error of rig.yaml's reflected_c, K, in [0, 50] (default 3; 0: "
                 "the true value)");
  app.add_option("--thermal-vignetting", args.thermal_vignetting,
                 "thermal radiance lost at the image corners (1 - v r^2, which the camera's "
                 "radiometric calibration does not remove), in [0, 1) (default 0.05)");
  app.add_flag("--no-depth-artefacts", args.no_depth_artefacts,
               "depth noise i.i.d. and unbiased, all materials matte (default: correlated "
               "noise, disparity distortion, edge fattening, glass/metal/dark dropouts)");
  app.add_flag("--no-shadows", args.no_shadows, "no cast shadows in colour frames");
  app.add_flag("--no-auto-exposure", args.no_auto_exposure,
               "fixed colour gains (default: auto exposure and white balance with a lag)");
  app.add_option("--passer", args.passer_crossing,
                 "draw a person walking across the view (a 31 °C capsule at 1.2 m/s, 0.6 of the "
                 "median depth away) into depth, colour and thermal, crossing the optical axis at "
                 "this fraction of the scan, [0, 1]; not part of truth/ (fixtures/passer.h)");
  app.add_flag("--overwrite", args.overwrite,
               "replace the scan in a non-empty --out folder (other files are kept)");
  app.add_flag("--list", args.list, "list the scenes and sessions and exit");
  AddCommonOptions(app, common);
  if (const int code = Parse(app, argc, argv); code >= 0) return code;

  return RunGuarded([&] {
    args.seed = ParseSeed(args.seed_text);
    args.rig_seed = ParseSeed(args.rig_seed_text, "--rig-seed");
    if (args.list) {
      std::cout << "Scenes:   " << Join(fixtures::SceneNames()) << "\n"
                << "Sessions: " << Join(fixtures::CalibrationSessionNames()) << ", bench\n";
      return kExitOk;
    }
    if (scene->count() == 0 && session->count() == 0) {
      throw UsageError("one of --scene or --session is required (--list shows them)");
    }
    if (args.out.empty()) throw UsageError("--out is required");
    if (args.session != "bench" && args.colour_target != "chessboard") {
      throw UsageError("--colour-target: applies to --session bench only");
    }
    if (session->count() > 0) {
      // Scan-only options must not be silently ignored.
      const std::pair<bool, const char*> scan_only[] = {
          {args.trajectory != "smooth", "--trajectory"},
          {args.path_start_s.has_value(), "--path-start"},
          {args.loop_duration_s.has_value(), "--loop-duration"},
          {args.depth_rate_hz.has_value(), "--depth-rate"},
          {args.rgb_rate_hz.has_value(), "--rgb-rate"},
          {args.thermal_rate_hz.has_value(), "--thermal-rate"},
          {args.thermal_camera != "standard", "--thermal-camera"},
          {args.ffc_frames != "freeze", "--ffc-frames"},
          {args.rgb_offset_s.has_value(), "--rgb-offset"},
          {args.thermal_offset_s.has_value(), "--thermal-offset"},
          {args.scene_scale.has_value(), "--scene-scale"},
          {args.rooms.has_value(), "--rooms"},
          {args.perturb_rig, "--perturb-rig"},
          {args.no_noise, "--no-noise"},
          {args.no_rgb, "--no-rgb"},
          {args.no_thermal, "--no-thermal"},
          {args.no_jitter, "--no-jitter"},
          {args.no_drops, "--no-drops"},
          {args.no_rolling_shutter, "--no-rolling-shutter"},
          {args.no_specular, "--no-specular"},
          {args.no_reflections, "--no-reflections"},
          {args.reflected_error_k.has_value(), "--reflected-error"},
          {args.thermal_vignetting.has_value(), "--thermal-vignetting"},
          {args.no_depth_artefacts, "--no-depth-artefacts"},
          {args.no_shadows, "--no-shadows"},
          {args.no_auto_exposure, "--no-auto-exposure"},
          {args.passer_crossing.has_value(), "--passer"}};
      // The bench takes the clock offsets and frame rates as scans do.
      const bool bench = args.session == "bench";
      const std::set<std::string> bench_takes = {"--rgb-offset", "--thermal-offset", "--depth-rate", "--rgb-rate",
                                                 "--thermal-rate"};
      for (const auto& [given, name] : scan_only) {
        if (given && !(bench && bench_takes.count(name))) {
          throw UsageError(std::string(name) + ": applies to --scene" + (bench_takes.count(name) ? " and --session bench" : "") +
                           " only");
        }
      }
      if (bench) {
        const std::pair<bool, const char*> not_bench[] = {{args.image_scale.has_value(), "--image-scale"},
                                                          {args.mask_polarity != "hot", "--mask-polarity"},
                                                          {args.thermal_format != "raw", "--thermal-format"}};
        for (const auto& [given, name] : not_bench) {
          if (given) throw UsageError(std::string(name) + ": does not apply to --session bench");
        }
        return RunBenchSession(args, common);
      }
      return RunSession(args, common);
    }
    if (args.mask_polarity != "hot") throw UsageError("--mask-polarity: applies to --session only");
    if (args.views) throw UsageError("--views: applies to --session only");
    if (args.rooms && args.scene != "large") {
      throw UsageError("--rooms: applies to the 'large' scene only, not '" + args.scene + "'");
    }
    return RunScan(args, common);
  });
}

}  // namespace hw::cli
