#pragma once

// heatwave calibrate extrinsics: depth_from_thermal and depth_from_rgb (rig.yaml) from a
// scan — with a target (a square_grid heated mask seen by all three cameras,
// calibrate/extrinsics_target.h) or without (calibrate/extrinsics_targetless.h) — checked
// against --max-rotation-sigma-deg / --max-translation-sigma-mm; writes extrinsics.json,
// rig.yaml with the extrinsics replaced, diagnostics/.

#include <filesystem>
#include <string>
#include <vector>

#include "calibrate/extrinsics.h"
#include "calibrate/extrinsics_target.h"
#include "calibrate/extrinsics_targetless.h"
#include "calibrate/qa_profile.h"
#include "cli/command.h"
#include "core/rig.h"

namespace hw::cli {

enum class ExtrinsicsMethod {
  kAuto,        // target when the scan has target.yaml, else targetless
  kTarget,      // square_grid seen by depth, colour and thermal
  kTargetless,  // edges of the scene, depth vs thermal (and colour)
};

struct ExtrinsicsCommandOptions {
  std::filesystem::path scan;        // scan folder
  std::filesystem::path rig_path;    // rig.yaml read (and rewritten) instead of the scan's; "" = the scan's
  std::filesystem::path out_folder;  // output folder
  bool overwrite = false;            // replace an earlier extrinsic calibration in out_folder
  ExtrinsicsMethod method = ExtrinsicsMethod::kAuto;
  // QA: each estimate's largest per-axis 1σ at most these, degrees (0, 90] and mm (0, 1000];
  // 0: the method's default — target 0.1° / 2 mm, targetless 0.5° / 10 mm (the issue's
  // accuracy goals of each method).
  double max_rotation_sigma_deg = 0;
  double max_translation_sigma_mm = 0;
  // Method target, with a calibrated depth_correction in the rig: fold the affine part of
  // the depth error measured on the plate (TargetExtrinsicsOptions::depth_affine: the depth
  // scale and tilt no wall shows) into rig.yaml's depth_correction. false (--keep-depth-
  // correction): the correction is written as read. Only terms the stills determine are
  // folded (calibrate_extrinsics.cc); the bowl the plate also measures is not: the wall sees
  // it, and better.
  bool fold_depth_affine = true;
  calibrate::TargetExtrinsicsOptions target;  // method target
  calibrate::TargetlessOptions targetless;    // method targetless
  // Method targetless: world_from_depth of the scan (TUM, e.g. heatwave reconstruct's
  // trajectory.txt); "" = pair each thermal frame with the nearest depth frame only.
  std::filesystem::path trajectory;

  // "" or "--flag: must be ..., got ..." (--scan, --out given; the ranges; target.Check()).
  std::string Check() const;
};

struct ExtrinsicsCommandResult {
  std::string method;                                  // "target" or "targetless"
  std::vector<calibrate::ExtrinsicsEstimate> estimates;  // one per camera calibrated
  std::vector<std::string> notes;                      // method-specific summary lines
  core::Rig rig_in;   // the rig read (the scan's or --rig)
  core::Rig rig_out;  // rig_in with the estimated extrinsics replaced (and the depth affine part folded)
  // What rig_out's depth_correction gained of the plate's affine part (a, c_x, c_y), 1/m:
  // the terms the stills measured (ExtrinsicsCommandOptions::fold_depth_affine), 0 others.
  Eigen::Vector3d depth_affine_folded_per_m = Eigen::Vector3d::Zero();
  std::vector<calibrate::QaCheck> checks;
  bool pass = false;
  std::vector<std::string> written;  // files, relative to out_folder
  double seconds = 0;
  double detect_seconds = 0;  // of which target detection, s (targetless: 0, its line extraction and fit interleave)
};

// Estimates and writes out_folder/{extrinsics.json, rig.yaml, diagnostics/...}; the folder
// is touched only once everything is estimated. Throws core::InputError (scan, rig or
// target unreadable, too few stills, detections or lines, a degenerate configuration — the
// method's solver) and UsageError (out_folder not empty without overwrite; --trajectory
// with the target method). A failed QA check is not an error: result.pass.
ExtrinsicsCommandResult CalibrateExtrinsics(const ExtrinsicsCommandOptions& options, bool quiet);

std::string FormatExtrinsicsSummary(const ExtrinsicsCommandResult& result, const std::filesystem::path& out_folder);

// `heatwave calibrate extrinsics`: registers the subcommand and its options on the
// `calibrate` app; after parsing, Chosen() says whether it was given and Run() runs it.
class ExtrinsicsSubcommand {
 public:
  explicit ExtrinsicsSubcommand(CLI::App& calibrate);
  bool Chosen() const;
  int Run();

 private:
  CLI::App* app_ = nullptr;
  ExtrinsicsCommandOptions options_;
  std::string method_ = "auto";
  CommonOptions common_;
};

}  // namespace hw::cli
