#pragma once

// Where a camera sees the corner of a square hole cut through a plate of some thickness
// (a square_grid heated mask, target.yaml `thickness_m`).
//
// The plate spans z in [0, t] of the target frame (front face z = 0, towards the cameras;
// target.yaml's corners lie on it). Through the hole a camera sees the background only
// along rays that pass both the front opening (z = 0) and the back opening (z = t). Seen
// head-on the two coincide; at a tilt the back opening, projected from the camera centre C
// onto the front plane, is the same square scaled by k = −C.z / (t − C.z) < 1 towards
// C's foot and so shifted away from the camera's side: on the sides the camera looks past,
// the hole wall shows and the visible edge is the back one. The visible aperture is the
// intersection of the two rectangles on the front plane, and the corner a detector finds is
// that intersection's corner — as a point ON THE FRONT PLANE, which projects exactly where
// the image corner is (both edges are on the ray through it).
//
// This assumes the detector draws the hole's outline between the background and what is
// not background: the hole walls, part of the plate, look like the plate (in thermal a
// heated plate's walls are near its temperature). On the fixtures' 3 mm mask, ignoring the
// thickness biased the extrinsics' translation by 1.5 mm along the view axis (both
// cameras' alike), see calibrate/extrinsics_target.h.

#include <algorithm>

namespace hw::calibrate {

// The visible corner of a hole on the front plane, target frame, metres.
// corner_xy: the corner of the hole's front opening (x, y), m; outward_xy: its direction
// from the hole's centre, each ±1; thickness_m >= 0; camera_in_target: the camera centre
// in the target frame (z < 0: in front of the plate), m. Writes (x, y) of the visible
// corner (z = 0). Templated for Ceres' Jets: the choice of edge is made on the values, and
// the result is continuous across it (both edges project to one line when the camera is
// in the wall's plane). thickness 0 returns corner_xy. Undefined for camera_in_target z >= 0.
template <typename T>
void VisibleHoleCorner(const T corner_xy[2], const double outward_xy[2], double thickness_m,
                       const T camera_in_target[3], T visible_xy[2]) {
  // Scale of the back opening projected from C onto z = 0: a back point P (z = t) lands at
  // C + (P − C)·k, k = −C.z / (t − C.z).
  const T k = -camera_in_target[2] / (T(thickness_m) - camera_in_target[2]);
  for (int i = 0; i < 2; ++i) {
    const T back = camera_in_target[i] + (corner_xy[i] - camera_in_target[i]) * k;
    // The inward one of the front and projected back edges bounds the aperture.
    visible_xy[i] = outward_xy[i] > 0 ? std::min(corner_xy[i], back) : std::max(corner_xy[i], back);
  }
}

}  // namespace hw::calibrate
