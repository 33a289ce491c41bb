// heatwave eval-trajectory: ATE and RPE of a TUM trajectory against a ground truth, as the
// TUM RGB-D benchmark's evaluate_ate.py / evaluate_rpe.py measure them.
#include "cli/eval_trajectory.h"

#include <cassert>
#include <charconv>
#include <cmath>
#include <iostream>
#include <numbers>
#include <stdexcept>
#include <utility>
#include <vector>

#include "cli/command.h"
#include "core/json.h"
#include "core/strings.h"
#include "core/trajectory.h"

namespace hw::cli {

namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;

using core::JsonNumber;

std::string JsonNumbers(const std::vector<double>& values) {
  std::string out = "[";
  for (size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + JsonNumber(values[i]);
  return out + "]";
}

// Statistics as a JSON object; without samples the values are null, not a misleading 0.
std::string JsonStats(const reconstruct::ErrorStats& s) {
  const auto value = [&](double v) { return s.count > 0 ? JsonNumber(v) : std::string("null"); };
  return "{\"rmse\": " + value(s.rmse) + ", \"mean\": " + value(s.mean) +
         ", \"median\": " + value(s.median) + ", \"std\": " + value(s.std) +
         ", \"min\": " + value(s.min) + ", \"max\": " + value(s.max) +
         ", \"count\": " + std::to_string(s.count) + "}";
}

// "rmse 1.234  mean 1.100  median 1.000  std 0.500  min 0.100  max 3.210": values times `scale`.
std::string TextStats(const reconstruct::ErrorStats& s, double scale, int decimals) {
  std::string out;
  const std::pair<const char*, double> fields[] = {{"rmse", s.rmse},     {"mean", s.mean},
                                                   {"median", s.median}, {"std", s.std},
                                                   {"min", s.min},       {"max", s.max}};
  for (const auto& [name, value] : fields) {
    out += (out.empty() ? "" : "  ") + std::string(name) + " " +
           core::StringPrintf("%.*f", decimals, value * scale);
  }
  return out;
}

}  // namespace

std::string EvalTrajectoryOptions::Check() const {
  if (estimated_path.empty()) return "estimated trajectory (EST): must be given";
  if (groundtruth_path.empty()) return "ground truth trajectory (GT): must be given";
  if (!(std::isfinite(eval.max_time_difference_s) && eval.max_time_difference_s > 0)) {
    return "--max-dt: must be > 0 s, got " + core::StringPrintf("%g", eval.max_time_difference_s);
  }
  if (!(std::isfinite(eval.rpe_delta_s) && eval.rpe_delta_s > 0)) {
    return "--rpe-delta: must be > 0 s, got " + core::StringPrintf("%g", eval.rpe_delta_s);
  }
  // Whatever the library checks beyond these (it names its own fields).
  return eval.Check();
}

EvalTrajectoryReport EvaluateTrajectoryFiles(const EvalTrajectoryOptions& options) {
  assert(options.Check().empty());
  const core::Trajectory estimated = core::ReadTumTrajectory(options.estimated_path);
  const core::Trajectory groundtruth = core::ReadTumTrajectory(options.groundtruth_path);
  EvalTrajectoryReport report;
  report.options = options;
  try {
    report.eval = reconstruct::EvaluateTrajectory(estimated, groundtruth, options.eval);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(options.estimated_path.string() + " against " +
                                options.groundtruth_path.string() + ": " + e.what());
  }
  return report;
}

std::string FormatEvalTrajectory(const EvalTrajectoryReport& report) {
  const reconstruct::TrajectoryEval& e = report.eval;
  const EvalTrajectoryOptions& o = report.options;
  std::string out;
  out += core::StringPrintf("Estimated     %s  (%d poses)\n", o.estimated_path.c_str(),
                            e.estimated_poses);
  out += core::StringPrintf("Ground truth  %s  (%d poses)\n", o.groundtruth_path.c_str(),
                            e.groundtruth_poses);
  out += core::StringPrintf("Associated    %d pairs, |dt| <= %g s\n", e.associated_pairs,
                            o.eval.max_time_difference_s);
  out += "\n";
  out += "ATE (mm)      " + TextStats(e.ate_m, 1e3, 3) + "\n";
  const std::string rpe_title = core::StringPrintf("RPE over %g s", o.eval.rpe_delta_s);
  if (e.rpe_m.count == 0) {
    out += core::StringPrintf("%-13s none: no associated poses %g s apart\n", rpe_title.c_str(),
                              o.eval.rpe_delta_s);
  } else {
    out += core::StringPrintf("%-13s %d pose pairs\n", rpe_title.c_str(), e.rpe_m.count);
    out += "  trans (mm)  " + TextStats(e.rpe_m, 1e3, 3) + "\n";
    out += "  rot (deg)   " + TextStats(e.rpe_deg, 1.0, 4) + "\n";
  }
  out += "\n";
  const core::Rigid3d& t = e.groundtruth_from_estimate;
  const Eigen::AngleAxisd angle_axis(t.rotation);
  const Eigen::Vector3d axis =
      angle_axis.angle() > 0 ? angle_axis.axis() : Eigen::Vector3d::UnitZ();
  out += core::StringPrintf(
      "Alignment     groundtruth_from_estimate: translation (%.4f, %.4f, %.4f) m,\n",
      t.translation.x(), t.translation.y(), t.translation.z());
  out += core::StringPrintf("              rotation %.3f deg about (%.4f, %.4f, %.4f)\n",
                            t.RotationAngle() * kDegPerRad, axis.x(), axis.y(), axis.z());
  out += core::StringPrintf("              quaternion xyzw (%.6f, %.6f, %.6f, %.6f)\n",
                            t.rotation.x(), t.rotation.y(), t.rotation.z(), t.rotation.w());
  return out;
}

std::string FormatEvalTrajectoryJson(const EvalTrajectoryReport& report) {
  const reconstruct::TrajectoryEval& e = report.eval;
  const EvalTrajectoryOptions& o = report.options;
  const core::Rigid3d& t = e.groundtruth_from_estimate;
  std::string out = "{\n";
  out += "  \"estimated\": " + core::JsonString(o.estimated_path.string()) + ",\n";
  out += "  \"groundtruth\": " + core::JsonString(o.groundtruth_path.string()) + ",\n";
  out += "  \"max_time_difference_s\": " + JsonNumber(o.eval.max_time_difference_s) + ",\n";
  out += "  \"rpe_delta_s\": " + JsonNumber(o.eval.rpe_delta_s) + ",\n";
  out += "  \"estimated_poses\": " + std::to_string(e.estimated_poses) + ",\n";
  out += "  \"groundtruth_poses\": " + std::to_string(e.groundtruth_poses) + ",\n";
  out += "  \"associated_pairs\": " + std::to_string(e.associated_pairs) + ",\n";
  out += "  \"ate_m\": " + JsonStats(e.ate_m) + ",\n";
  out += "  \"rpe_m\": " + JsonStats(e.rpe_m) + ",\n";
  out += "  \"rpe_deg\": " + JsonStats(e.rpe_deg) + ",\n";
  out += "  \"groundtruth_from_estimate\": {\"translation_m\": " +
         JsonNumbers({t.translation.x(), t.translation.y(), t.translation.z()}) +
         ", \"rotation_xyzw\": " +
         JsonNumbers({t.rotation.x(), t.rotation.y(), t.rotation.z(), t.rotation.w()}) +
         ", \"rotation_deg\": " + JsonNumber(t.RotationAngle() * kDegPerRad) + "}\n";
  out += "}\n";
  return out;
}

int RunEvalTrajectory(int argc, char** argv) {
  CLI::App app(
      "Measure a trajectory against a ground truth as the TUM RGB-D benchmark does: poses "
      "associated by timestamp (greedily by smallest |dt|, each used once; both files on the "
      "same clock), ATE after a rigid alignment (Horn/Umeyama, no scale) and RPE "
      "(translation and rotation) over --rpe-delta seconds. Files: TUM format, "
      "'timestamp tx ty tz qx qy qz qw' per line.\n"
      "Exit code 0: evaluated; 1: unreadable or malformed file, or fewer than 3 associated "
      "poses; 2: bad usage.",
      "heatwave eval-trajectory");
  EvalTrajectoryOptions options;
  CommonOptions common;
  app.add_option("EST", options.estimated_path, "estimated trajectory (TUM format)")->required();
  app.add_option("GT", options.groundtruth_path, "ground-truth trajectory (TUM format)")
      ->required();
  app.add_option("--max-dt", options.eval.max_time_difference_s,
                 "largest |dt| in seconds pairing an estimated with a true pose")
      ->capture_default_str();
  app.add_option("--rpe-delta", options.eval.rpe_delta_s,
                 "RPE: time between the two poses of a relative motion, seconds")
      ->capture_default_str();
  app.add_flag("--json", options.json,
               "print the report as JSON on stdout, errors in m and degrees (also with --quiet)");
  AddCommonOptions(app, common);
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  options.quiet = common.quiet;

  return RunGuarded([&] {
    ThrowIfInvalid(options.Check());
    const EvalTrajectoryReport report = EvaluateTrajectoryFiles(options);
    if (options.json) {
      std::cout << FormatEvalTrajectoryJson(report) << std::flush;
    } else if (!options.quiet) {
      std::cout << FormatEvalTrajectory(report) << std::flush;
    }
    return kExitOk;
  });
}

}  // namespace hw::cli
