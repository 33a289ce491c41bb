#pragma once

// Internal to reconstruct/: the marching-cubes case tables (Lorensen & Cline 1987), with the
// corner and edge numbering of Paul Bourke's "Polygonising a scalar field" tables.
//
// Corner c of a cube at offset kCubeCorners[c] from its origin voxel; edge e joins corners
// kEdgeCorners[e]. Case index: bit c set when corner c is inside (sdf < 0).
// For each case, kEdgeMask says which edges the surface cuts, and triangles lists edges in
// threes (−1 terminated, at most 5 triangles), counter-clockwise seen from the outside
// (sdf >= 0 side).
//
// The tables are generated (once, on first use) rather than typed in: on each cube face
// the cut edges are joined by the marching-squares rule, with the face's two inside corners
// kept apart on an ambiguous face (two inside corners on a diagonal). That rule depends
// only on the face's four corners, so two cubes sharing a face cut it the same way and the
// surface has no cracks: a closed sdf gives a closed, consistently oriented mesh. The
// segments, oriented with the inside on their right seen from outside the cube, chain into
// loops; each loop is fanned into triangles from a vertex whose fan diagonals cross the
// cube's interior (none lies in a face, where a neighbour's fan could reuse it).

#include <array>
#include <cstdint>

namespace hw::reconstruct::internal {

inline constexpr int kCubeCorners[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                           {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
inline constexpr int kEdgeCorners[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                                            {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};

struct MarchingCubesTables {
  std::array<uint16_t, 256> edge_mask;                 // bit e: edge e is cut
  std::array<std::array<int8_t, 16>, 256> triangles;  // edges in threes, −1 terminated
  // Edge e runs from voxel origin + edge_origin[e] along axis edge_axis[e] (0 x, 1 y, 2 z).
  std::array<std::array<int, 3>, 12> edge_origin;
  std::array<int, 12> edge_axis;
};

// The tables, built on first call (thread-safe).
const MarchingCubesTables& GetMarchingCubesTables();

}  // namespace hw::reconstruct::internal
