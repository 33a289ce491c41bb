#pragma once

#include <filesystem>
#include <string>

#include "reconstruct/trajectory_eval.h"

namespace hw::cli {

// Options of `heatwave eval-trajectory`.
struct EvalTrajectoryOptions {
  std::filesystem::path estimated_path;     // TUM trajectory to evaluate
  std::filesystem::path groundtruth_path;   // TUM trajectory taken as the truth
  reconstruct::TrajectoryEvalOptions eval;  // association limit (--max-dt), RPE delta
  bool json = false;                        // print the report as JSON instead of text
  bool quiet = false;                       // no text report (JSON is still printed)

  // "" when valid, else a message naming the option, value and constraint.
  std::string Check() const;
};

struct EvalTrajectoryReport {
  EvalTrajectoryOptions options;
  reconstruct::TrajectoryEval eval;
};

// Reads both files (core::ReadTumTrajectory: InputError naming the file and line) and
// evaluates. Trajectories that do not associate in at least 3 non-collinear poses throw
// std::invalid_argument, its message naming both files. Asserts options.Check() is empty.
EvalTrajectoryReport EvaluateTrajectoryFiles(const EvalTrajectoryOptions& options);

// The one-screen text report: pairs, ATE and RPE statistics (mm, degrees), the alignment.
std::string FormatEvalTrajectory(const EvalTrajectoryReport& report);
// The same as one JSON object, errors in metres and degrees (SI in the keys' names).
std::string FormatEvalTrajectoryJson(const EvalTrajectoryReport& report);

}  // namespace hw::cli
