#pragma once

// Rigid alignment of two models of the same asset scanned at different times (heatwave
// compare BEFORE AFTER): a coarse start (identity, and the principal axes of the two
// surfaces), then robust point-to-plane ICP of samples of BEFORE's surface against AFTER's
// vertices. Two scans of a room overlap only in part: correspondences are gated by
// distance and normal angle, those landing on AFTER's open boundary are dropped, and the
// residuals are weighted with Tukey's biweight.

#include <string>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "analyze/thermal_mesh.h"

namespace hw::analyze {

struct AlignOptions {
  // Points sampled uniformly by area on BEFORE's surface for the final ICP, [100, 1e7].
  int samples = 20000;
  // Points per coarse candidate (fewer: the candidates are only ranked), [100, samples].
  int coarse_samples = 3000;
  // ICP iterations per coarse candidate, [1, 1000]; the gate shrinks geometrically over
  // them from coarse_correspondence_distance_m to max_correspondence_distance_m.
  int coarse_iterations = 20;
  // Final ICP iterations at most, [1, 10000].
  int max_iterations = 60;
  // m, the coarse stage's first gate: how far off a candidate start may be,
  // [max_correspondence_distance_m, 1000].
  double coarse_correspondence_distance_m = 1.0;
  // m, no correspondence between a sample and an AFTER vertex farther apart than this in
  // the final ICP (Euclidean), (0, 100]. At least the AFTER mesh's vertex spacing.
  double max_correspondence_distance_m = 0.1;
  // m, Tukey biweight scale on the point-to-plane residual in the final ICP: residuals
  // beyond it get weight 0, (0, 100]. Several times the scans' noise.
  double robust_loss_scale_m = 0.02;
  // degrees, no correspondence when the normals differ by more, [1, 180].
  double max_normal_angle_deg = 60;
  // Converged when an ICP update rotates less than this (rad) and translates less than
  // translation_tolerance_m (m); both in (0, 1].
  double rotation_tolerance_rad = 1e-7;
  double translation_tolerance_m = 1e-7;
  // Seed of the surface sampling (the result is deterministic for a seed), any value.
  unsigned seed = 1;
  // Worker threads for the correspondence search, [0, 256]; 0 = one per hardware thread.
  // The result does not depend on it.
  int threads = 0;

  // "" or "field: must be …, got …".
  std::string Check() const;
};

struct Alignment {
  Eigen::Isometry3d after_from_before = Eigen::Isometry3d::Identity();
  double rms_residual_m = 0;   // point-to-plane RMS over inliers at the end
  double inlier_fraction = 0;  // of the samples, within the correspondence gate
  int iterations = 0;          // of the final ICP (after the coarse stage)
  bool converged = false;      // the last update was below the tolerances
  // How the start was found: "identity" or "principal axes (flip k of 4)".
  std::string coarse;
  // Covariance of the final pose as a small correction x = (ω rad, δ m) applied on the left
  // in AFTER's frame, about AFTER's origin: true ≈ [exp(ω) | δ] · after_from_before. From the
  // ICP normal equations scaled by the weighted residual variance; +Inf on the diagonal
  // (0 elsewhere) when the geometry leaves a direction unconstrained (a lone plane).
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
};

// Finds after_from_before, the rigid transform taking BEFORE's points into AFTER's frame
// (metres). Uses BEFORE's faces (sampled) and AFTER's vertices and normals (vertices no
// face uses are ignored). Does not throw for meshes that do not overlap: the result then
// has a low inlier_fraction (0 when nothing corresponded) and converged may be false; the
// caller decides what fraction is acceptable. Throws std::invalid_argument when
// options.Check() fails.
Alignment AlignMeshes(const ThermalMesh& before, const ThermalMesh& after, const AlignOptions& options);

}  // namespace hw::analyze
