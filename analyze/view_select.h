#pragma once

// Automatic views of a model: overviews around it and from above, and close-ups that frame
// a spot without anything in front of it.
//
// World up: the fixtures' scenes (truth/scene.ply) and a model reconstructed with
// --start-at-groundtruth are in the scan's world frame, z up with the floor at z = 0 — the
// default of ViewSelectOptions::up_in_world. A model reconstructed without it is in its
// first depth camera's frame (OpenCV: y down, so up is roughly −y, tilted by however the
// camera was held): pass up_in_world = (0, −1, 0) for it.

#include <string>
#include <vector>

#include <Eigen/Core>

#include "analyze/render.h"
#include "analyze/thermal_mesh.h"

namespace hw::analyze {

struct NamedView {
  std::string name;  // "overview-1" … "overview-N", "top", "close-up"
  Camera camera;
};

struct ViewSelectOptions {
  int width = 1280;       // image width, pixels, in [16, 16384]
  int height = 960;       // image height, pixels, in [16, 16384]
  double fov_y_deg = 40;  // vertical field of view of the perspective views, degrees, in [5, 120]
  // Free border around the framed model in the overviews, as a fraction of the image's
  // width and height on each side, in [0, 0.4].
  double margin_fraction = 0.05;
  int overview_count = 4;  // perspective overviews around the model, in [1, 36]
  // Height of the overview cameras above the horizon seen from the model's centre,
  // degrees, in [0, 89]: 35 looks down into a room over its walls.
  double elevation_deg = 35;
  // Azimuth of the first overview, degrees, from the world's first horizontal axis (x for
  // z up), counter-clockwise seen from above, in [-360, 360]: 45 looks along a room's
  // diagonal, showing two walls, rather than straight at one.
  double first_azimuth_deg = 45;
  // When the surface mostly faces one horizontal direction (its area-weighted normal's
  // horizontal part > 20 % of its area: a partial scan of one side), the first overview looks
  // from that side instead of first_azimuth_deg.
  bool face_scanned_side = true;
  // World up (see the header comment), non-zero; normalised when used.
  Eigen::Vector3d up_in_world = Eigen::Vector3d::UnitZ();
  // Close-ups: the spot's region spans this fraction of the image height, in (0, 1].
  double close_up_fill_fraction = 0.5;
  // Close-ups: the camera is never nearer the spot than this, metres, in (0, 100]: a 1 cm
  // spot is shown in its surroundings, not from 1 cm.
  double close_up_min_distance_m = 0.5;

  std::string Check() const;
};

// options.overview_count perspective views named "overview-1" … at evenly spaced azimuths
// around up_in_world (from first_azimuth_deg), elevation_deg above the horizon, looking at
// the centre of the axis-aligned bounding box of the mesh's face vertices, each from the
// distance at which all 8 corners of that box project inside the image less the margin
// (the nearest such distance: one corner touches the margin); plus "top", an orthographic
// view straight down along −up_in_world framing the box the same way. Asserts
// options.Check() == "" and a mesh with faces.
std::vector<NamedView> OverviewViews(const ThermalMesh& mesh, const ViewSelectOptions& options);

// A perspective close-up ("close-up") of a spot: candidate directions from the centroid
// in cones around the normal (0°; 25° and 50° at 8 azimuths each), each at the distance at
// which the region (the larger of radius_m and the farthest region point from the
// centroid) spans close_up_fill_fraction of the image height (never nearer than
// close_up_min_distance_m), and at 60 % of it (a room's far wall may stand closer than the
// full distance). A candidate's score is the fraction of region_points_in_world that lie in
// the image in front of the camera and are unoccluded from the eye (the last millimetre at
// each end excluded: the points lie on the surface). The best score wins; among equal
// scores the direction nearest the normal, then the farther distance. *visible_fraction
// (optional) receives the winner's score; region_points_in_world empty → the centroid alone
// is scored. Asserts options.Check() == "", a non-zero normal, radius_m >= 0.
NamedView CloseUpView(const MeshRenderer& renderer, const Eigen::Vector3d& centroid_in_world,
                      const Eigen::Vector3d& normal_in_world, double radius_m,
                      const std::vector<Eigen::Vector3d>& region_points_in_world,
                      const ViewSelectOptions& options, double* visible_fraction);

}  // namespace hw::analyze
