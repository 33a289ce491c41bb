#pragma once

// heatwave calibrate intrinsics: one camera of the rig from images of a calibration target —
// detect, solve (mrcal), check, give PASS/FAIL verdicts, write the camera and diagnostics.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "calibrate/detection.h"
#include "calibrate/intrinsics_solver.h"
#include "calibrate/square_grid.h"
#include "calibrate/qa_profile.h"
#include "core/rig.h"

namespace hw::cli {

struct IntrinsicsCommandOptions {
  std::filesystem::path images;       // folder of images, or a scan folder (its `camera` stream)
  std::filesystem::path target_path;  // target.yaml; "" = <images>/target.yaml
  std::string camera = "thermal";     // thermal | rgb | depth: the rig camera calibrated
  calibrate::IntrinsicsOptions solver;
  calibrate::SquareGridOptions grid;   // the square_grid detector (--edge-sigma-px)
  std::filesystem::path profile_path;  // qa.yaml; "" = the defaults (calibrate/qa_profile.h)
  std::filesystem::path rig_path;      // rig.yaml to merge the camera into; "" = the scan's, if any
  std::filesystem::path out_folder;
  bool overwrite = false;

  std::string Check() const;
};

struct IntrinsicsCommandResult {
  core::Target target;
  std::vector<calibrate::Detection> detections;  // every image, accepted or not
  calibrate::IntrinsicsResult solve;
  std::vector<int> solved_views;                 // index into detections of each solved view
  int grid_cols = 0, grid_rows = 0;              // of the uncertainty map
  std::vector<double> uncertainty_px;            // row-major
  double coverage = 0;                           // fraction of 8 × 6 cells observed
  // --model splined: the splined camera against the opencv8 fit that seeded it over the
  // covered cells (calibrate::ProjectionDifference, pixels unprojected by the spline): how
  // far the parametric model was from the data's lens. nullopt for the parametric models.
  std::optional<calibrate::ModelDifference> model_difference;
  calibrate::QaProfile profile;
  std::vector<calibrate::QaCheck> checks;
  bool pass = false;
  std::vector<std::string> written;              // files, relative to out_folder
  double seconds = 0;
  double detect_seconds = 0;                     // of `seconds`: reading the images and detecting the target
};

// Runs the calibration and writes into out_folder: intrinsics.json, camera.cameramodel
// (any model: opencv5/8 or mrcal's splined LENSMODEL_SPLINED_STEREOGRAPHIC),
// rig.yaml (when a rig to merge into is known), diagnostics/ (detections/*.png,
// residuals.png, histogram.png, uncertainty.png). Everything is read and solved before the
// folder is touched. Throws core::InputError (unreadable image or target, images of mixed
// sizes, no target found, too few usable views, degenerate views), UsageError (a
// non-empty out_folder without overwrite). A failed QA check is not an error: result.pass.
IntrinsicsCommandResult CalibrateIntrinsics(const IntrinsicsCommandOptions& options, bool quiet);

// The end of every calibrate command's summary: the QA verdict, each check on its line,
// and the files written ("Wrote      DIR/{a, b} in 1.2 s").
std::string FormatQaAndWritten(bool pass, const std::vector<calibrate::QaCheck>& checks,
                               const std::vector<std::string>& written, const std::filesystem::path& out_folder,
                               double seconds);

std::string FormatIntrinsicsSummary(const IntrinsicsCommandResult& result, const std::filesystem::path& out_folder);

}  // namespace hw::cli
