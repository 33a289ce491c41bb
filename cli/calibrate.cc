#include "cli/calibrate.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <tuple>

#include "calibrate/diagnostics.h"
#include "calibrate/image_source.h"
#include "calibrate/square_grid.h"
#include "calibrate/target_detect.h"
#include "cli/calibrate_bench.h"
#include "cli/calibrate_extrinsics.h"
#include "cli/calibrate_depth.h"
#include "cli/calibrate_latency.h"
#include "cli/command.h"
#include "core/atomic_file.h"
#include "core/cameramodel_io.h"
#include "core/error.h"
#include "core/image_io.h"
#include "core/json.h"
#include "core/option_check.h"
#include "core/output_folder.h"
#include "core/progress.h"
#include "core/strings.h"

namespace hw::cli {
namespace {

namespace fs = std::filesystem;
using core::StringPrintf;

constexpr int kCoverageCols = 8, kCoverageRows = 6;    // QA coverage cells
constexpr int kUncertaintyCols = 16, kUncertaintyRows = 12;

core::Stream StreamOf(const std::string& camera) {
  return camera == "thermal" ? core::Stream::kThermal : camera == "rgb" ? core::Stream::kRgb : core::Stream::kDepth;
}

std::string ModelName(calibrate::LensModel m) {
  switch (m) {
    case calibrate::LensModel::kOpenCv5: return "opencv5";
    case calibrate::LensModel::kOpenCv8: return "opencv8";
    case calibrate::LensModel::kSplined: return "splined";
  }
  return "unknown";
}

// Cells of the coverage grid per side sampled for the model difference: 5 × 5 points each.
constexpr int kDifferencePointsPerCell = 5;

calibrate::Detection Detect(const cv::Mat& image, const core::Target& target, const std::string& name,
                            const calibrate::SquareGridOptions& grid) {
  switch (target.type) {
    case core::TargetType::kSquareGrid: return calibrate::DetectSquareGrid(image, target, grid, name);
    case core::TargetType::kChessboard: return calibrate::DetectChessboard(image, target, {}, name);
    case core::TargetType::kAprilGrid: return calibrate::DetectAprilGrid(image, target, {}, name);
  }
  return {};
}

std::string FileSafe(std::string name) {
  for (char& c : name) {
    if (c == '/' || c == '\\' || c == ' ') c = '-';
  }
  return name;
}

std::string ArrayJson(const std::vector<double>& values) {
  std::string out = "[";
  for (size_t i = 0; i < values.size(); ++i) out += (i ? ", " : "") + core::JsonNumber(values[i]);
  return out + "]";
}

std::string IntrinsicsJson(const IntrinsicsCommandOptions& o, const IntrinsicsCommandResult& r) {
  const calibrate::IntrinsicsResult& s = r.solve;
  const core::CameraModel& c = s.camera;
  std::vector<double> sigmas;
  for (Eigen::Index i = 0; i < s.intrinsics_covariance.rows(); ++i) {
    sigmas.push_back(std::sqrt(std::max(0.0, s.intrinsics_covariance(i, i))));
  }
  core::JsonObject camera;
  camera.Int("width", c.width).Int("height", c.height).String("model", core::MrcalLensModelName(c));
  camera.Number("fx", c.fx).Number("fy", c.fy).Number("cx", c.cx).Number("cy", c.cy).Add("distortion", ArrayJson(c.distortion));
  if (c.type == core::CameraModelType::kSplined) {
    camera.Add("splined", core::JsonObject()
                              .Int("order", c.splined.order)
                              .Int("nx", c.splined.nx)
                              .Int("ny", c.splined.ny)
                              .Int("fov_x_deg", c.splined.fov_x_deg)
                              .str());
  }
  core::JsonObject mrcal;
  mrcal.String("lensmodel", s.mrcal_lensmodel).Add("intrinsics", ArrayJson(s.mrcal_intrinsics)).Add("intrinsics_sigma", ArrayJson(sigmas));
  std::vector<std::string> views;
  for (size_t i = 0; i < r.detections.size(); ++i) {
    const calibrate::Detection& d = r.detections[i];
    core::JsonObject v;
    v.String("view", d.view).Bool("accepted", d.accepted).String("reason", d.reason).Int("corners", static_cast<int64_t>(d.pixels.size()));
    v.Number("homography_rms_px", d.homography_rms_px);
    const auto solved = std::find(r.solved_views.begin(), r.solved_views.end(), static_cast<int>(i));
    if (solved != r.solved_views.end()) {
      const size_t k = static_cast<size_t>(solved - r.solved_views.begin());
      v.Number("rms_px", s.view_rms_px[k]);
      const core::Rigid3d& pose = s.camera_from_target[k];
      v.Add("camera_from_target", core::JsonObject()
                                      .Add("q_xyzw", ArrayJson({pose.rotation.x(), pose.rotation.y(), pose.rotation.z(), pose.rotation.w()}))
                                      .Add("t_m", ArrayJson({pose.translation.x(), pose.translation.y(), pose.translation.z()}))
                                      .str());
    }
    views.push_back(v.str());
  }
  core::JsonObject root;
  root.Int("version", 1).String("command", "heatwave calibrate intrinsics");
  root.String("images", o.images.string()).String("camera", o.camera).String("lens_model", ModelName(o.solver.model));
  root.String("target", core::TargetTypeName(r.target.type) + StringPrintf(" %d x %d", r.target.rows, r.target.cols));
  if (r.target.type == core::TargetType::kSquareGrid) {
    root.Add("detector", core::JsonObject()
                             .String("edges", o.grid.edge == calibrate::EdgeLocator::kSteepest ? "steepest" : "mid-level")
                             .Number("edge_sigma_px", o.grid.edge_sigma_px)
                             .str());
  }
  root.Add("camera_model", camera.str()).Add("mrcal", mrcal.str());
  root.Int("views_used", static_cast<int64_t>(r.solved_views.size())).Int("images", static_cast<int64_t>(r.detections.size()));
  root.Number("rms_px", s.rms_px).String("rms_is", "RMS of the inlier corners' residual norms, as mrcal reports");
  root.Number("worst_px", s.worst_px).String("worst_is", "largest 2D residual norm of an inlier corner");
  root.Number("observation_sigma_px", s.observation_sigma_px)
      .String("observation_sigma_is", "per coordinate, from the inlier residuals and the degrees of freedom");
  root.Int("outliers", s.outliers);
  if (std::isfinite(s.edge_shift_px)) {
    root.Add("target_shape",
             core::JsonObject()
                 .String("what", "outward shift of the squares' edges seen by the detector vs the target's, on the "
                                 "target as a function of the tangent of the viewing angle across the edge (> 0: the "
                                 "camera faces that edge's side wall; aprilgrid: one constant), and a shift in the "
                                 "image; estimated with the camera, marginalised out")
                 .Number("edge_shift_px", s.edge_shift_px)
                 .Number("edge_shift_sigma_px", s.edge_shift_sigma_px)
                 .Add("tan_view_angle", ArrayJson(s.edge_shift_knots_u))
                 .Add("edge_shift_m", ArrayJson(s.edge_shift_m))
                 .Add("edge_shift_sigma_m", ArrayJson(s.edge_shift_sigma_m))
                 .str());
  }
  root.Number("coverage", r.coverage).Add("coverage_cells", StringPrintf("[%d, %d]", kCoverageCols, kCoverageRows));
  if (r.model_difference && s.parametric_camera) {
    const calibrate::ModelDifference& d = *r.model_difference;
    root.Add("model_difference", core::JsonObject()
                                     .String("between", s.mrcal_lensmodel + " and " + core::MrcalLensModelName(*s.parametric_camera))
                                     .String("is", "pixel difference over the covered cells, after the best-fitting rotation "
                                                   "(mrcal-show-projection-diff's idea, at infinity): how far the parametric "
                                                   "model is from the splined one where there is data")
                                     .Number("rms_px", d.rms_px)
                                     .Number("worst_px", d.worst_px)
                                     .Int("points", d.points)
                                     .Number("rotation_deg", d.rotation_rad * 180 / M_PI)
                                     .str());
  }
  root.Add("uncertainty", core::JsonObject()
                              .Number("range_m", r.profile.uncertainty_range_m)
                              .Add("grid", StringPrintf("[%d, %d]", r.grid_cols, r.grid_rows))
                              .Add("px", ArrayJson(r.uncertainty_px))
                              .str());
  root.Add("qa", calibrate::QaChecksJson(r.checks)).String("verdict", r.pass ? "PASS" : "FAIL");
  root.Add("views", core::JsonArray(views, "  "));
  root.Number("solve_s", s.solve_seconds).Number("total_s", r.seconds);
  return root.str() + "\n";
}

}  // namespace

std::string IntrinsicsCommandOptions::Check() const {
  if (images.empty()) return "--images: must be given";
  if (out_folder.empty()) return "--out: must be given";
  if (camera != "thermal" && camera != "rgb" && camera != "depth") {
    return "--camera: must be thermal, rgb or depth, got '" + camera + "'";
  }
  // The spline's options by their command-line names (IntrinsicsOptions::Check names fields).
  if (solver.spline_order != 2 && solver.spline_order != 3) {
    return "--spline-order: must be 2 or 3, got " + std::to_string(solver.spline_order);
  }
  const std::array<std::tuple<const char*, int, int>, 3> counts{{{"--spline-nx", solver.spline_nx, 64},
                                                                 {"--spline-ny", solver.spline_ny, 64},
                                                                 {"--spline-fov-deg", solver.spline_fov_x_deg, 179}}};
  for (const auto& [name, value, max] : counts) {
    const int min = std::string(name) == "--spline-fov-deg" ? 1 : 4;
    if (value != 0 && (value < min || value > max)) {
      return std::string(name) + ": must be in [" + std::to_string(min) + ", " + std::to_string(max) +
             "] (or 0: chosen from the image), got " + std::to_string(value);
    }
  }
  if (solver.model != calibrate::LensModel::kSplined &&
      (solver.spline_order != 3 || solver.spline_nx != 0 || solver.spline_ny != 0 || solver.spline_fov_x_deg != 0)) {
    return "--spline-order, --spline-nx, --spline-ny, --spline-fov-deg: apply to --model splined only";
  }
  if (const std::string p = solver.Check(); !p.empty()) return p;
  if (!grid.Check().empty()) {
    return "--edge-sigma-px: must be in [0.3, 3], got " + StringPrintf("%g", grid.edge_sigma_px);
  }
  return "";
}

IntrinsicsCommandResult CalibrateIntrinsics(const IntrinsicsCommandOptions& o, bool quiet) {
  const auto start = std::chrono::steady_clock::now();
  IntrinsicsCommandResult r;
  r.target = core::ReadTarget(o.target_path.empty() ? o.images / "target.yaml" : o.target_path);
  if (!o.profile_path.empty()) r.profile = calibrate::ReadQaProfile(o.profile_path);
  const fs::path rig_path = !o.rig_path.empty() ? o.rig_path : fs::exists(o.images / "rig.yaml") ? o.images / "rig.yaml" : fs::path();
  std::optional<core::Rig> rig;
  if (!rig_path.empty()) rig = core::ReadRig(rig_path);
  const std::vector<calibrate::CalibrationImage> images = calibrate::LoadCalibrationImages(o.images, StreamOf(o.camera));
  const int width = images.front().image.cols, height = images.front().image.rows;

  {
    core::ProgressBar bar("detect", static_cast<int64_t>(images.size()), "images", quiet);
    for (const calibrate::CalibrationImage& im : images) {
      r.detections.push_back(Detect(im.image, r.target, im.name, o.grid));
      bar.Advance();
    }
  }
  r.detect_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::vector<calibrate::ViewObservation> views;
  std::string first_reason;
  for (size_t i = 0; i < r.detections.size(); ++i) {
    const calibrate::Detection& d = r.detections[i];
    if (!d.accepted) {
      if (first_reason.empty()) first_reason = d.view + ": " + d.reason;
      continue;
    }
    views.push_back({d.corner_ids, d.pixels});
    r.solved_views.push_back(static_cast<int>(i));
  }
  const std::string target_text = core::TargetTypeName(r.target.type) + StringPrintf(" %d x %d", r.target.rows, r.target.cols);
  if (views.empty()) {
    throw core::InputError(o.images, StringPrintf("no target found in any of the %zu images (target.yaml: %s — does it "
                                                  "match the images?); %s",
                                                  images.size(), target_text.c_str(), first_reason.c_str()));
  }
  if (views.size() < 3) {
    throw core::InputError(o.images, StringPrintf("too few usable views: %zu of %zu images show the %s target (at least "
                                                  "3 are needed); %s",
                                                  views.size(), images.size(), target_text.c_str(), first_reason.c_str()));
  }
  try {
    r.solve = calibrate::SolveIntrinsics(r.target, width, height, views, o.solver);
  } catch (const std::invalid_argument& e) {
    throw core::InputError(o.images, e.what());
  }
  r.grid_cols = kUncertaintyCols;
  r.grid_rows = kUncertaintyRows;
  r.uncertainty_px = calibrate::ProjectionUncertaintyMap(r.solve, r.grid_cols, r.grid_rows, r.profile.uncertainty_range_m);

  // Coverage: the cells of an 8 × 6 grid over the image holding an inlier corner; the
  // uncertainty check looks at those cells only (outside them it is extrapolation).
  std::vector<bool> covered(kCoverageCols * kCoverageRows, false);
  int corners = 0;
  for (size_t v = 0; v < views.size(); ++v) {
    for (size_t i = 0; i < views[v].pixels.size(); ++i) {
      ++corners;
      if (r.solve.outlier[v][i]) continue;
      const int cx = std::clamp(static_cast<int>(views[v].pixels[i].x() / width * kCoverageCols), 0, kCoverageCols - 1);
      const int cy = std::clamp(static_cast<int>(views[v].pixels[i].y() / height * kCoverageRows), 0, kCoverageRows - 1);
      covered[static_cast<size_t>(cy * kCoverageCols + cx)] = true;
    }
  }
  r.coverage = static_cast<double>(std::count(covered.begin(), covered.end(), true)) / covered.size();
  calibrate::QaMeasurements m;
  m.views = static_cast<int>(views.size());
  m.rms_px = r.solve.rms_px;
  m.worst_px = r.solve.worst_px;
  m.max_view_rms_px = *std::max_element(r.solve.view_rms_px.begin(), r.solve.view_rms_px.end());
  m.outlier_fraction = static_cast<double>(r.solve.outliers) / std::max(corners, 1);
  m.max_uncertainty_px = 0;
  for (int gy = 0; gy < r.grid_rows; ++gy) {
    for (int gx = 0; gx < r.grid_cols; ++gx) {
      const int cx = gx * kCoverageCols / r.grid_cols, cy = gy * kCoverageRows / r.grid_rows;
      if (!covered[static_cast<size_t>(cy * kCoverageCols + cx)]) continue;
      m.max_uncertainty_px = std::max(m.max_uncertainty_px, r.uncertainty_px[static_cast<size_t>(gy * r.grid_cols + gx)]);
    }
  }
  m.coverage = r.coverage;
  if (r.solve.parametric_camera) {
    // Points spread over every covered cell (none elsewhere: there the spline is regularised
    // towards its seed, not fitted).
    std::vector<Eigen::Vector2d> pixels;
    for (int cy = 0; cy < kCoverageRows; ++cy) {
      for (int cx = 0; cx < kCoverageCols; ++cx) {
        if (!covered[static_cast<size_t>(cy * kCoverageCols + cx)]) continue;
        for (int j = 0; j < kDifferencePointsPerCell; ++j) {
          for (int i = 0; i < kDifferencePointsPerCell; ++i) {
            pixels.emplace_back((cx + (i + 0.5) / kDifferencePointsPerCell) * width / kCoverageCols - 0.5,
                                (cy + (j + 0.5) / kDifferencePointsPerCell) * height / kCoverageRows - 0.5);
          }
        }
      }
    }
    r.model_difference = calibrate::ProjectionDifference(r.solve.camera, *r.solve.parametric_camera, pixels);
  }
  r.checks = calibrate::EvaluateQa(r.profile, m);
  r.pass = calibrate::AllPass(r.checks);

  // Everything is known: now the folder.
  core::OutputFolder folder(o.out_folder, "heatwave calibrate intrinsics");
  if (!folder.IsEmpty()) {
    if (!o.overwrite) {
      folder.Abandon();
      throw UsageError("--out " + o.out_folder.string() + ": folder is not empty; pass --overwrite to replace the calibration in it");
    }
    folder.Remove({"intrinsics.json", "camera.cameramodel", "rig.yaml", "diagnostics"});
  }
  const fs::path diag = o.out_folder / "diagnostics";
  fs::create_directories(diag / "detections");
  for (size_t i = 0; i < images.size(); ++i) {
    const std::string file = "diagnostics/detections/" + FileSafe(images[i].name) + ".png";
    core::WriteImageAtomically(o.out_folder / file, calibrate::DrawDetection(images[i].image, r.detections[i]));
  }
  std::vector<std::vector<Eigen::Vector2d>> corner_px;
  for (const calibrate::ViewObservation& v : views) corner_px.push_back(v.pixels);
  core::WriteImageAtomically(diag / "residuals.png",
                             calibrate::DrawResidualField(width, height, corner_px, r.solve.residuals_px, r.solve.outlier, 20));
  core::WriteImageAtomically(diag / "histogram.png", calibrate::DrawResidualHistogram(r.solve.residuals_px, r.solve.outlier,
                                                                                      r.solve.observation_sigma_px));
  const double max_shown = std::max(r.profile.max_uncertainty_px, m.max_uncertainty_px);
  core::WriteImageAtomically(diag / "uncertainty.png",
                             calibrate::DrawUncertaintyMap(width, height, r.uncertainty_px, r.grid_cols, r.grid_rows, max_shown,
                                                           StringPrintf("projection uncertainty (1 sigma) at %g m",
                                                                        r.profile.uncertainty_range_m)));
  r.written = {"diagnostics/"};
  core::WriteMrcalCameraModel(o.out_folder / "camera.cameramodel", r.solve.camera);
  r.written.push_back("camera.cameramodel");
  if (rig) {
    core::Rig merged = *rig;
    if (o.camera == "thermal") {
      merged.thermal = r.solve.camera;
    } else if (o.camera == "rgb") {
      merged.rgb = r.solve.camera;
    } else {
      merged.depth = r.solve.camera;
    }
    if (o.camera == "thermal" && !merged.thermal_settings) merged.thermal_settings = core::ThermalSettings();
    if (const std::string problem = merged.Check(); problem.empty()) {
      core::WriteRig(o.out_folder / "rig.yaml", merged);
      r.written.push_back("rig.yaml");
    }
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  core::WriteFileAtomically(o.out_folder / "intrinsics.json", IntrinsicsJson(o, r));
  r.written.push_back("intrinsics.json");
  folder.Commit();
  return r;
}

std::string FormatQaAndWritten(bool pass, const std::vector<calibrate::QaCheck>& checks,
                               const std::vector<std::string>& written, const std::filesystem::path& out_folder,
                               double seconds) {
  std::string out = StringPrintf("QA         %s\n", pass ? "PASS" : "FAIL");
  for (const calibrate::QaCheck& q : checks) out += "  " + calibrate::FormatQaCheck(q) + "\n";
  std::string files;
  for (const std::string& f : written) files += (files.empty() ? "" : ", ") + f;
  return out + StringPrintf("Wrote      %s/{%s} in %.1f s\n", out_folder.c_str(), files.c_str(), seconds);
}

std::string FormatIntrinsicsSummary(const IntrinsicsCommandResult& r, const fs::path& out_folder) {
  std::string out;
  int accepted = 0;
  for (const calibrate::Detection& d : r.detections) accepted += d.accepted;
  out += StringPrintf("Images     %zu: target found in %d, rejected %zu\n", r.detections.size(), accepted,
                      r.detections.size() - static_cast<size_t>(accepted));
  int listed = 0;
  for (const calibrate::Detection& d : r.detections) {
    if (!d.accepted && listed++ < 4) out += "  " + d.view + ": " + d.reason + "\n";
  }
  const core::CameraModel& c = r.solve.camera;
  out += StringPrintf("Camera     %s %dx%d  fx %.3f  fy %.3f  cx %.3f  cy %.3f px", r.solve.mrcal_lensmodel.c_str(), c.width,
                      c.height, c.fx, c.fy, c.cx, c.cy);
  if (r.solve.intrinsics_covariance.rows() >= 4) {
    out += StringPrintf("  (1 sigma %.3f %.3f %.3f %.3f)", std::sqrt(r.solve.intrinsics_covariance(0, 0)),
                        std::sqrt(r.solve.intrinsics_covariance(1, 1)), std::sqrt(r.solve.intrinsics_covariance(2, 2)),
                        std::sqrt(r.solve.intrinsics_covariance(3, 3)));
  }
  out += "\n";
  if (std::isfinite(r.solve.edge_shift_px)) {
    out += StringPrintf("Target     edge shift in the image %+.3f ± %.3f px (outwards)\n", r.solve.edge_shift_px,
                        r.solve.edge_shift_sigma_px);
  }
  if (!r.solve.edge_shift_m.empty()) {
    out += "           edge shift on the target (mm, 1 sigma)";
    for (size_t j = 0; j < r.solve.edge_shift_m.size(); ++j) {
      out += StringPrintf("%s %+.2f ± %.2f", j == 0 ? "" : ",", 1e3 * r.solve.edge_shift_m[j],
                          1e3 * r.solve.edge_shift_sigma_m[j]);
      if (r.solve.edge_shift_m.size() > 1) out += StringPrintf(" @%+.2g", r.solve.edge_shift_knots_u[j]);
    }
    out += r.solve.edge_shift_m.size() > 1 ? " (@ tan of the viewing angle)\n" : "\n";
  }
  out += StringPrintf("Residuals  RMS %.3f px (corner norms), worst %.3f px, %d outliers; solved in %.2f s\n", r.solve.rms_px,
                      r.solve.worst_px, r.solve.outliers, r.solve.solve_seconds);
  if (r.model_difference) {
    out += StringPrintf("Model diff splined vs its opencv8 seed over the covered cells: RMS %.3f px, worst %.3f px%s\n",
                        r.model_difference->rms_px, r.model_difference->worst_px,
                        r.model_difference->worst_px > 0.5
                            ? " (large: opencv8 misfits the lens, or too few views pin the spline down)"
                            : " (opencv8 would do)");
  }
  return out + FormatQaAndWritten(r.pass, r.checks, r.written, out_folder, r.seconds);
}

int RunCalibrate(int argc, char** argv) {
  CLI::App app("Calibrate the rig: intrinsics, depth error, extrinsics, clock offsets, or all of them on the bench with a certificate.", "heatwave calibrate");
  app.require_subcommand(1);
  CLI::App* intrinsics = app.add_subcommand(
      "intrinsics", "detect the target, solve the intrinsics (mrcal), check them against a QA profile");
  IntrinsicsCommandOptions o;
  CommonOptions common;
  AddCommonOptions(*intrinsics, common);
  intrinsics->add_option("--images", o.images, "folder of images (PNG/JPEG/BMP/TIFF, 8 or 16 bit) or a scan folder")
      ->required();
  intrinsics->add_option("--target", o.target_path, "target.yaml; default: <images>/target.yaml");
  intrinsics->add_option("--camera", o.camera, "thermal | rgb | depth")->capture_default_str();
  std::string model = "opencv5";
  intrinsics->add_option("--model", model, "lens model: opencv5 | opencv8 | splined (mrcal's splined stereographic)")
      ->capture_default_str();
  intrinsics->add_option("--spline-order", o.solver.spline_order, "splined: 2 or 3")->capture_default_str();
  intrinsics->add_option("--spline-nx", o.solver.spline_nx, "splined: knots across, [4, 64]; default ~1 per 40 px in [8, 30]");
  intrinsics->add_option("--spline-ny", o.solver.spline_ny, "splined: knots down, [4, 64]; default: to cover the image");
  intrinsics->add_option("--spline-fov-deg", o.solver.spline_fov_x_deg,
                         "splined: horizontal field of view the spline spans, [1, 179] degrees; default: the lens's + 5 %");
  intrinsics->add_option("--profile", o.profile_path, "qa.yaml: the QA thresholds (README)");
  bool no_target_shape = false;
  intrinsics->add_flag("--no-target-shape", no_target_shape,
                       "do not estimate the squares' apparent edge shift with the camera (square_grid, aprilgrid)");
  intrinsics->add_option("--edge-sigma-px", o.grid.edge_sigma_px,
                         "square_grid: scale of the edge finder's derivative of Gaussian, pixels, [0.3, 3]; larger "
                         "for noisier images")
      ->capture_default_str();
  intrinsics->add_option("--rig", o.rig_path, "rig.yaml to merge the camera into; default: the scan's");
  intrinsics->add_option("--out", o.out_folder, "output folder")->required();
  intrinsics->add_flag("--overwrite", o.overwrite, "replace an earlier calibration in --out");
  LatencySubcommand latency(app);
  DepthSubcommand depth(app);
  ExtrinsicsSubcommand extrinsics(app);
  BenchSubcommand bench(app);
  if (const int code = Parse(app, argc, argv); code >= 0) return code;
  if (latency.Chosen()) return latency.Run();
  if (depth.Chosen()) return depth.Run();
  if (extrinsics.Chosen()) return extrinsics.Run();
  if (bench.Chosen()) return bench.Run();
  return RunGuarded([&] {
    if (model == "opencv5") {
      o.solver.model = calibrate::LensModel::kOpenCv5;
    } else if (model == "opencv8") {
      o.solver.model = calibrate::LensModel::kOpenCv8;
    } else if (model == "splined") {
      o.solver.model = calibrate::LensModel::kSplined;
    } else {
      throw UsageError("--model: must be opencv5, opencv8 or splined, got '" + model + "'");
    }
    o.solver.estimate_target_shape = !no_target_shape;
    ThrowIfInvalid(o.Check());
    const IntrinsicsCommandResult result = CalibrateIntrinsics(o, common.quiet);
    if (!common.quiet) std::cout << FormatIntrinsicsSummary(result, o.out_folder) << std::flush;
    if (!result.pass) {
      PrintError("the camera failed QA: " + calibrate::FailedCheckNames(result.checks) + " (intrinsics.json has every check)");
      return kExitFailure;
    }
    return kExitOk;
  });
}

}  // namespace hw::cli
