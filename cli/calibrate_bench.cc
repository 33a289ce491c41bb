#include "cli/calibrate_bench.h"

#include <chrono>
#include <cmath>
#include <ctime>
#include <functional>
#include <iostream>
#include <map>
#include <optional>

#include "calibrate/qa_profile.h"
#include "cli/calibrate.h"
#include "cli/calibrate_depth.h"
#include "cli/calibrate_extrinsics.h"
#include "cli/calibrate_latency.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/option_check.h"
#include "core/output_folder.h"
#include "core/strings.h"
#include "core/yaml_reader.h"

namespace hw::cli {
namespace {

namespace fs = std::filesystem;
using core::StringPrintf;

std::string Join(const std::vector<std::string>& items, const std::string& separator) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : separator) + item;
  return out;
}

// What a part needs: where its scan is, where its outputs go, the rig it starts from.
struct PartContext {
  const BenchCommandOptions& options;
  fs::path scan;     // SESSION/<part>
  fs::path out;      // DIR/<part>
  fs::path rig_in;   // the rig the previous parts calibrated
  bool quiet = false;
};

// What a part gives back. A part that throws core::InputError is recorded as ERROR.
struct PartOutcome {
  std::vector<calibrate::QaCheck> checks;
  bool pass = false;
  std::string note;                                   // one line for the certificate
  std::vector<report::CertificateImage> images;       // paths relative to the part's folder
  std::map<std::string, double> sigmas;               // 1σ of the rig quantities it calibrated (RigItem names)
  std::string summary;                                // the command's own summary, for the log
  double detect_seconds = 0;                          // reading images, finding targets / the blob
};

PartOutcome Intrinsics(const PartContext& c, const std::string& camera) {
  IntrinsicsCommandOptions o;
  o.images = c.scan;
  o.camera = camera;
  o.profile_path = c.options.profile_path;
  o.rig_path = c.rig_in;
  o.out_folder = c.out;
  o.overwrite = true;  // the bench emptied DIR first
  const IntrinsicsCommandResult r = CalibrateIntrinsics(o, c.quiet);
  PartOutcome out;
  out.checks = r.checks;
  out.pass = r.pass;
  out.note = StringPrintf("%s %dx%d from %zu of %zu views: RMS %.3f px, worst %.3f px", r.solve.mrcal_lensmodel.c_str(),
                          r.solve.camera.width, r.solve.camera.height, r.solved_views.size(), r.detections.size(),
                          r.solve.rms_px, r.solve.worst_px);
  out.images = {{"diagnostics/residuals.png", "Residuals (20x)"},
                {"diagnostics/histogram.png", "Residual histogram"},
                {"diagnostics/uncertainty.png", "Projection uncertainty"}};
  const char* names[] = {"fx", "fy", "cx", "cy"};
  for (Eigen::Index i = 0; i < 4 && i < r.solve.intrinsics_covariance.rows(); ++i) {
    out.sigmas[camera + " " + names[i]] = std::sqrt(std::max(0.0, r.solve.intrinsics_covariance(i, i)));
  }
  out.summary = FormatIntrinsicsSummary(r, c.out);
  out.detect_seconds = r.detect_seconds;
  return out;
}

PartOutcome Latency(const PartContext& c) {
  LatencyCommandOptions o;
  o.scan = c.scan;
  o.rig_path = c.rig_in;
  o.out_folder = c.out;
  o.overwrite = true;
  o.max_sigma_ms = c.options.max_latency_sigma_ms;
  const LatencyCommandResult r = CalibrateLatency(o, c.quiet);
  PartOutcome out;
  out.checks = r.checks;
  out.pass = r.pass;
  const calibrate::LatencyResult& e = r.estimate;
  out.note = StringPrintf("rgb %+.3f ± %.3f ms, thermal %+.3f ± %.3f ms against depth; closure %+.3f ± %.3f ms",
                          1e3 * e.rgb.offset_s, 1e3 * e.rgb.sigma_s, 1e3 * e.thermal.offset_s, 1e3 * e.thermal.sigma_s,
                          1e3 * e.closure_s, 1e3 * e.closure_sigma_s);
  out.images = {{"diagnostics/signals.png", "Blob signals, aligned"}};
  out.sigmas["rgb time offset"] = 1e3 * e.rgb.sigma_s;
  out.sigmas["thermal time offset"] = 1e3 * e.thermal.sigma_s;
  out.summary = FormatLatencySummary(r, c.out);
  out.detect_seconds = r.track_seconds;
  return out;
}

// The depth camera's disparity distortion from the wall recording: the rig it writes
// carries depth_correction, which the extrinsics part then applies to the depth plate.
PartOutcome Depth(const PartContext& c) {
  DepthCommandOptions o;
  o.scan = c.scan;
  o.rig_path = c.rig_in;
  o.out_folder = c.out;
  o.overwrite = true;
  o.max_sigma_mm = c.options.max_depth_sigma_mm;
  o.min_coverage = c.options.min_depth_coverage;
  const DepthCommandResult r = CalibrateDepth(o, c.quiet);
  PartOutcome out;
  out.checks = r.checks;
  out.pass = r.pass;
  const calibrate::DepthCorrectionResult& e = r.estimate;
  out.note = StringPrintf("%d of %zu frames (%.2f-%.2f m): field %.2f mm RMS as depth at 3 m, largest 1σ %.2f mm, "
                          "%.0f %% of nodes covered; residual %.2f → %.2f mm RMS",
                          e.frames_used, e.frames.size(), e.distance_min_m, e.distance_max_m, e.field_rms_mm_at_3m,
                          e.max_sigma_mm_at_3m, 100 * e.coverage, e.rms_before_mm, e.rms_after_mm);
  out.images = {{"diagnostics/field.png", "Depth correction as depth error at 3 m"},
                {"diagnostics/sigma.png", "Its uncertainty (1σ) at 3 m"}};
  out.summary = FormatDepthSummary(r, c.out);
  out.detect_seconds = r.read_seconds;
  return out;
}

// The target-based extrinsics with the intrinsics the previous parts calibrated.
PartOutcome Extrinsics(const PartContext& c) {
  ExtrinsicsCommandOptions o;
  o.scan = c.scan;
  o.rig_path = c.rig_in;
  o.out_folder = c.out;
  o.overwrite = true;
  o.method = ExtrinsicsMethod::kTarget;
  o.max_rotation_sigma_deg = c.options.max_rotation_sigma_deg;
  o.max_translation_sigma_mm = c.options.max_translation_sigma_mm;
  const ExtrinsicsCommandResult r = CalibrateExtrinsics(o, c.quiet);
  PartOutcome out;
  out.checks = r.checks;
  out.pass = r.pass;
  std::vector<std::string> notes;
  for (const calibrate::ExtrinsicsEstimate& e : r.estimates) {
    const Eigen::Vector3d rot = e.RotationSigmaDeg(), tr = e.TranslationSigmaMm();
    notes.push_back(StringPrintf("%s: 1σ %.3f° / %.2f mm (largest axis), RMS %.3f %s", e.camera.c_str(),
                                 rot.maxCoeff(), tr.maxCoeff(), e.rms_residual, e.residual_unit.c_str()));
    for (int axis = 0; axis < 3; ++axis) {
      out.sigmas["depth_from_" + e.camera + " t" + "xyz"[axis]] = tr[axis];
    }
    // The rotation angle's σ: the rotation vector's largest-axis σ bounds it.
    out.sigmas["depth_from_" + e.camera + " rotation"] = rot.maxCoeff();
  }
  out.note = Join(notes, "; ");
  out.images = {{"diagnostics/thermal_residuals.png", "Thermal corner residuals"},
                {"diagnostics/rgb_residuals.png", "Colour corner residuals"},
                {"diagnostics/plane_residuals.png", "Depth plate residuals"}};
  out.summary = FormatExtrinsicsSummary(r, c.out);
  out.detect_seconds = r.detect_seconds;
  return out;
}

// The parts in bench order.
struct PartDef {
  const char* id;
  const char* title;
  std::function<PartOutcome(const PartContext&)> run;
};
const std::vector<PartDef>& Parts() {
  static const std::vector<PartDef> parts = {
      {"intrinsics-thermal", "Thermal camera intrinsics", [](const PartContext& c) { return Intrinsics(c, "thermal"); }},
      {"intrinsics-rgb", "Colour camera intrinsics", [](const PartContext& c) { return Intrinsics(c, "rgb"); }},
      {"depth", "Depth camera distortion (flat wall)", [](const PartContext& c) { return Depth(c); }},
      {"extrinsics", "Extrinsics (depth ← thermal, depth ← colour)", [](const PartContext& c) { return Extrinsics(c); }},
      {"latency", "Clock offsets (latency)", [](const PartContext& c) { return Latency(c); }},
  };
  return parts;
}

// A number of the rig the certificate shows, with the part that calibrates it.
struct RigItem {
  std::string name;
  std::string unit;
  std::string part;
  std::function<double(const core::Rig&)> get;  // NaN when the rig lacks it
  // Whether the fixture check compares it with the truth: not the depth correction's size,
  // whose affine part the wall cannot observe (the truth has one; the estimate has the
  // plate's measure of its scale only when the extrinsics' stills determined it).
  bool compare_to_truth = true;
};
std::vector<RigItem> RigItems() {
  const double nan = std::nan("");
  std::vector<RigItem> items;
  for (const char* camera : {"thermal", "rgb"}) {
    const std::string cam = camera;
    auto model = [cam](const core::Rig& r) { return cam == "thermal" ? r.thermal : r.rgb; };
    const std::string part = "intrinsics-" + cam;
    items.push_back({cam + " fx", "px", part, [=](const core::Rig& r) { return model(r) ? model(r)->fx : nan; }});
    items.push_back({cam + " fy", "px", part, [=](const core::Rig& r) { return model(r) ? model(r)->fy : nan; }});
    items.push_back({cam + " cx", "px", part, [=](const core::Rig& r) { return model(r) ? model(r)->cx : nan; }});
    items.push_back({cam + " cy", "px", part, [=](const core::Rig& r) { return model(r) ? model(r)->cy : nan; }});
  }
  // Calibrated by the "extrinsics" part; its sigmas go under these names (mm, deg).
  for (const auto& [camera, sel] : {std::pair{"thermal", true}, std::pair{"rgb", false}}) {
    const bool thermal = sel;
    auto pose = [thermal](const core::Rig& r) { return thermal ? r.depth_from_thermal : r.depth_from_rgb; };
    for (int axis = 0; axis < 3; ++axis) {
      items.push_back({std::string("depth_from_") + camera + " t" + "xyz"[axis], "mm", "extrinsics",
                       [=](const core::Rig& r) { return 1e3 * pose(r).translation[axis]; }});
    }
    items.push_back({std::string("depth_from_") + camera + " rotation", "deg", "extrinsics", [=](const core::Rig& r) {
                       return Eigen::AngleAxisd(pose(r).rotation).angle() * 180 / M_PI;
                     }});
  }
  // Calibrated by the "depth" part: the size of the field, as depth error at 3 m (z²·δ).
  items.push_back({"depth field RMS at 3 m", "mm", "depth", [=](const core::Rig& r) {
                     if (!r.depth_correction || r.depth_correction->offset_per_m.empty()) return nan;
                     return 1e3 * 9 * r.depth_correction->RmsPerM();
                   }, false});
  items.push_back({"rgb time offset", "ms", "latency", [](const core::Rig& r) { return 1e3 * r.rgb_time_offset_s; }});
  items.push_back({"thermal time offset", "ms", "latency", [](const core::Rig& r) { return 1e3 * r.thermal_time_offset_s; }});
  return items;
}

std::vector<std::pair<std::string, std::string>> ReadIds(const fs::path& path) {
  const core::YamlReader reader(path);
  const YAML::Node root = reader.LoadMapping(core::ReadFile(path, core::kMaxConfigFileBytes));
  reader.CheckVersion(root, 1);
  const char* keys[] = {"rig_serial", "depth_serial", "rgb_serial", "thermal_serial", "operator"};
  const core::YamlReader::Fields f =
      reader.Mapping(root, "", {"version", "rig_serial", "depth_serial", "rgb_serial", "thermal_serial", "operator"});
  std::vector<std::pair<std::string, std::string>> ids;
  for (const char* key : keys) {
    if (f.Has(key)) ids.push_back({key, reader.String(f.Required(key), key)});
  }
  return ids;
}

std::string NowUtc() {
  const std::time_t now = std::time(nullptr);
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buf[32];
  std::strftime(buf, sizeof(buf), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

double Since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace

std::vector<std::string> BenchPartFolders() {
  std::vector<std::string> ids;
  for (const PartDef& p : Parts()) ids.push_back(p.id);
  return ids;
}

std::string BenchCommandOptions::Check() const {
  if (session.empty()) return "SESSION: must be given";
  if (out_folder.empty()) return "--out: must be given";
  if (!(max_latency_sigma_ms > 0 && max_latency_sigma_ms <= 1000)) {
    return core::OptionFail("--max-latency-sigma-ms", max_latency_sigma_ms, "in (0, 1000] ms");
  }
  if (!(max_rotation_sigma_deg > 0 && max_rotation_sigma_deg <= 90)) {
    return core::OptionFail("--max-rotation-sigma-deg", max_rotation_sigma_deg, "in (0, 90] deg");
  }
  if (!(max_translation_sigma_mm > 0 && max_translation_sigma_mm <= 1000)) {
    return core::OptionFail("--max-translation-sigma-mm", max_translation_sigma_mm, "in (0, 1000] mm");
  }
  if (!(max_depth_sigma_mm > 0 && max_depth_sigma_mm <= 1000)) {
    return core::OptionFail("--max-depth-sigma-mm", max_depth_sigma_mm, "in (0, 1000] mm");
  }
  if (!core::InRange(min_depth_coverage, 0, 1)) return core::OptionFail("--min-depth-coverage", min_depth_coverage, "in [0, 1]");
  return "";
}

BenchResult RunBench(const BenchCommandOptions& o, bool quiet) {
  const auto start = std::chrono::steady_clock::now();
  if (!fs::is_directory(o.session)) throw core::InputError(o.session, "no session folder there");
  // Everything that can be refused is refused before the output folder is touched.
  std::vector<std::string> missing;
  for (const PartDef& p : Parts()) {
    if (!fs::is_directory(o.session / p.id)) missing.push_back(std::string(p.id) + "/");
  }
  if (missing.size() == Parts().size()) {
    throw core::InputError(o.session, "not a bench session: none of the part folders " + Join(BenchPartFolders(), ", ") +
                                          " is there");
  }
  if (!missing.empty() && !o.partial) {
    throw core::InputError(o.session, "missing part" + std::string(missing.size() > 1 ? "s " : " ") + Join(missing, ", ") +
                                          " (pass --partial to run the other parts; the verdict is then INCOMPLETE)");
  }
  if (!o.profile_path.empty()) calibrate::ReadQaProfile(o.profile_path);  // throws on a bad one
  BenchResult result;
  report::Certificate& c = result.certificate;
  c.software = std::string("heatwave ") + HW_VERSION;
  c.created_utc = NowUtc();
  c.session = o.session.string();
  c.profile = o.profile_path.empty() ? "defaults (calibrate/qa_profile.h)" : o.profile_path.string();
  if (fs::exists(o.session / "session.yaml")) c.ids = ReadIds(o.session / "session.yaml");
  fs::path rig_in = o.session / "rig.yaml";
  if (!fs::exists(rig_in)) {
    rig_in.clear();
    for (const PartDef& p : Parts()) {
      if (rig_in.empty() && fs::exists(o.session / p.id / "rig.yaml")) rig_in = o.session / p.id / "rig.yaml";
    }
    if (rig_in.empty()) throw core::InputError(o.session, "no rig.yaml: neither the session's nor a part's");
  }
  core::ReadRig(rig_in);  // a bad nominal rig is refused before anything runs
  std::optional<core::Rig> truth;
  if (fs::exists(o.session / "truth" / "rig.yaml")) {
    c.truth_file = (o.session / "truth" / "rig.yaml").string();
    truth = core::ReadRig(c.truth_file);
  }

  core::OutputFolder folder(o.out_folder, "heatwave calibrate bench");
  if (!folder.IsEmpty()) {
    if (!o.overwrite) {
      folder.Abandon();
      throw UsageError("--out " + o.out_folder.string() + ": folder is not empty; pass --overwrite to replace the bench run in it");
    }
    std::vector<std::string> entries = {"rig.yaml", "certificate.json", "certificate.html", "certificate.pdf"};
    for (const PartDef& p : Parts()) entries.push_back(p.id);
    folder.Remove(entries);
  }

  std::map<std::string, double> sigmas;
  std::map<std::string, bool> calibrated;  // part id -> ran and produced numbers
  for (const PartDef& p : Parts()) {
    report::CertificatePart part{p.id, p.title, report::PartStatus::kNotRun, "", {}, {}, 0};
    if (!fs::is_directory(o.session / p.id)) {
      part.note = "not run: the session has no " + std::string(p.id) + "/ folder";
      c.parts.push_back(part);
      if (!quiet) std::cerr << "bench: " << p.id << ": NOT RUN (missing)\n";
      continue;
    }
    if (!quiet) std::cerr << "bench: " << p.id << "\n";
    const auto part_start = std::chrono::steady_clock::now();
    try {
      const PartOutcome out = p.run(PartContext{o, o.session / p.id, o.out_folder / p.id, rig_in, quiet});
      part.status = out.pass ? report::PartStatus::kPassed : report::PartStatus::kFailed;
      part.note = out.note;
      for (const calibrate::QaCheck& q : out.checks) {
        part.checks.push_back({q.name, q.what, q.measured, q.at_most ? "<=" : ">=", q.threshold, q.unit, q.pass});
      }
      for (const report::CertificateImage& im : out.images) {
        if (fs::exists(o.out_folder / p.id / im.path)) part.images.push_back({std::string(p.id) + "/" + im.path, im.caption});
      }
      sigmas.insert(out.sigmas.begin(), out.sigmas.end());
      calibrated[p.id] = true;
      result.detect_seconds += out.detect_seconds;
      if (fs::exists(o.out_folder / p.id / "rig.yaml")) rig_in = o.out_folder / p.id / "rig.yaml";
    } catch (const core::InputError& e) {
      part.status = report::PartStatus::kError;
      part.note = std::string("could not be computed: ") + e.what();
      if (!quiet) std::cerr << "bench: " << p.id << ": ERROR " << e.what() << "\n";
    }
    part.seconds = Since(part_start);
    c.parts.push_back(part);
  }
  c.verdict = report::CertificateVerdict(c.parts);
  result.pass = c.verdict == "PASS";

  // The final rig: the last one a part wrote (each part merged its numbers into the rig it
  // was given), or the nominal one when no part wrote one.
  result.rig = core::ReadRig(rig_in);
  for (const RigItem& item : RigItems()) {
    const double value = item.get(result.rig);
    if (!std::isfinite(value)) continue;
    const bool done = calibrated.count(item.part) > 0;
    report::RigQuantity q{item.name, value, std::nullopt, item.unit, done ? item.part : "nominal (not calibrated)"};
    if (done && sigmas.count(item.name)) q.sigma = sigmas.at(item.name);
    c.rig.push_back(q);
    if (truth && done && item.compare_to_truth) c.truth.push_back({item.name, value, item.get(*truth), q.sigma, item.unit});
  }
  core::WriteRig(o.out_folder / "rig.yaml", result.rig);
  result.written.push_back("rig.yaml");
  for (const PartDef& p : Parts()) {
    if (fs::is_directory(o.out_folder / p.id)) result.written.push_back(std::string(p.id) + "/");
  }
  for (const std::string& f : report::WriteCertificate(c, o.out_folder)) result.written.push_back(f);
  folder.Commit();
  result.seconds = Since(start);
  return result;
}

std::string FormatBenchSummary(const BenchResult& r, const fs::path& out_folder) {
  const report::Certificate& c = r.certificate;
  std::string out;
  for (const auto& [key, value] : c.ids) out += StringPrintf("%-14s %s\n", key.c_str(), value.c_str());
  for (const report::CertificatePart& p : c.parts) {
    int passed = 0;
    std::string failed;
    for (const report::CertificateCheck& q : p.checks) {
      passed += q.pass;
      if (!q.pass) failed += (failed.empty() ? "" : ", ") + q.name;
    }
    out += StringPrintf("%-7s %-19s %d/%zu checks  %.1f s%s\n", report::PartStatusName(p.status).c_str(), p.id.c_str(), passed,
                        p.checks.size(), p.seconds, failed.empty() ? "" : ("  failed: " + failed).c_str());
    if (!p.note.empty()) out += "        " + p.note + "\n";
  }
  out += "Rig\n";
  for (const report::RigQuantity& q : c.rig) {
    if (q.source.rfind("nominal", 0) == 0) continue;
    out += StringPrintf("  %-22s %12.4f %-3s", q.name.c_str(), q.value, q.unit.c_str());
    if (q.sigma) out += StringPrintf(" ± %.4f", *q.sigma);
    out += "\n";
  }
  int nominal = 0;
  for (const report::RigQuantity& q : c.rig) nominal += q.source.rfind("nominal", 0) == 0;
  if (nominal > 0) out += StringPrintf("  (%d more values are the nominal rig's: not calibrated by this bench)\n", nominal);
  if (!c.truth.empty()) {
    double worst = 0;
    std::string worst_name;
    for (const report::TruthRow& t : c.truth) {
      if (t.sigma && *t.sigma > 0 && std::abs(t.value - t.truth) / *t.sigma > worst) {
        worst = std::abs(t.value - t.truth) / *t.sigma;
        worst_name = t.name;
      }
    }
    out += StringPrintf("Truth      (fixture check, not QA) worst error %.2f sigma (%s)\n", worst, worst_name.c_str());
  }
  out += "Verdict    " + c.verdict + "\n";
  out += StringPrintf("Wrote      %s/{%s} in %.1f s (%.1f s after detection)\n", out_folder.c_str(),
                      Join(r.written, ", ").c_str(), r.seconds, r.seconds - r.detect_seconds);
  return out;
}

BenchSubcommand::BenchSubcommand(CLI::App& calibrate) {
  app_ = calibrate.add_subcommand("bench",
                                  "the whole rig from one session folder: intrinsics of each camera, the depth "
                                  "camera's distortion, extrinsics, clock offsets; rig.yaml and a PASS/FAIL certificate (JSON, HTML, PDF)");
  AddCommonOptions(*app_, common_);
  app_->add_option("session", options_.session, "session folder: one sub-folder per part (" +
                                                    Join(BenchPartFolders(), ", ") + ")")
      ->required();
  app_->add_option("--out", options_.out_folder, "output folder")->required();
  app_->add_option("--profile", options_.profile_path, "qa.yaml: the intrinsics' QA thresholds (README)");
  app_->add_option("--max-latency-sigma-ms", options_.max_latency_sigma_ms,
                   "QA of the latency part: largest accepted 1-sigma uncertainty of a clock offset, ms")
      ->capture_default_str();
  app_->add_option("--max-rotation-sigma-deg", options_.max_rotation_sigma_deg,
                   "QA of the extrinsics: largest accepted 1-sigma rotation uncertainty about any axis, degrees")
      ->capture_default_str();
  app_->add_option("--max-translation-sigma-mm", options_.max_translation_sigma_mm,
                   "QA of the extrinsics: largest accepted 1-sigma translation uncertainty along any axis, mm")
      ->capture_default_str();
  app_->add_option("--max-depth-sigma-mm", options_.max_depth_sigma_mm,
                   "QA of the depth part: largest accepted 1-sigma uncertainty of a correction node, as depth at 3 m, mm")
      ->capture_default_str();
  app_->add_option("--min-depth-coverage", options_.min_depth_coverage,
                   "QA of the depth part: smallest accepted fraction of correction nodes the wall covered, [0, 1]")
      ->capture_default_str();
  app_->add_flag("--partial", options_.partial,
                 "run the parts the session has when some are missing (the verdict is then INCOMPLETE, exit 1)");
  app_->add_flag("--overwrite", options_.overwrite, "replace an earlier bench run in --out");
}

bool BenchSubcommand::Chosen() const { return app_->parsed(); }

int BenchSubcommand::Run() {
  return RunGuarded([&] {
    ThrowIfInvalid(options_.Check());
    const BenchResult result = RunBench(options_, common_.quiet);
    if (!common_.quiet) std::cout << FormatBenchSummary(result, options_.out_folder) << std::flush;
    if (!result.pass) {
      PrintError("the rig is not certified: " + result.certificate.verdict + " (certificate.json has every check)");
      return kExitFailure;
    }
    return kExitOk;
  });
}

}  // namespace hw::cli
