#pragma once

// Surface extraction from the TSDF: marching cubes over the allocated blocks, with shared
// vertices (one per cut voxel edge, none duplicated), per-vertex normals and colours, and
// small disconnected fragments removed (noise specks, floating depth outliers).

#include <string>
#include <vector>

#include <Eigen/Core>

#include "core/ply.h"
#include "reconstruct/tsdf_volume.h"

namespace hw::reconstruct {

struct MeshOptions {
  // Voxels with weight below this are treated as unobserved (seen once from afar is noise);
  // weight 0 is always unobserved. In [0, 65535] (above the volume's max_weight: no mesh).
  double min_weight = 1;
  // Connected components (sharing vertices) with fewer triangles than this are removed.
  int min_component_triangles = 50;  // >= 0 (0: keep all)
  // ... and so are those whose area is below this fraction of the largest one's. In [0, 1).
  double min_component_area_fraction = 0.0;
  int num_threads = 0;  // 0: hardware concurrency

  std::string Check() const;
};

// A triangle mesh in the world frame (metres).
struct TriangleMesh {
  std::vector<Eigen::Vector3f> positions;
  std::vector<Eigen::Vector3f> normals;  // unit, from the TSDF gradient, pointing to free space
  std::vector<Rgb8> colours;
  std::vector<Eigen::Vector3i> faces;    // counter-clockwise seen from free space (outside)

  double AreaM2() const;
};

struct MeshStats {
  int components = 0;          // connected components before removal
  int components_removed = 0;
  int triangles_removed = 0;
};

// Marching cubes over every cube of 8 observed voxels (weight >= min_weight) of `volume`,
// across block borders; the zero crossing of sdf on each edge by linear interpolation.
// Vertices are shared between the triangles of neighbouring cubes. Deterministic: the same
// volume gives the same mesh, vertex order included, whatever num_threads.
//
// Details:
// - One vertex per cut voxel edge (end voxels observed, sdf < 0 at one end and >= 0 at the
//   other), at the linear zero crossing; its colour is interpolated the same way, its normal
//   is the interpolated central-difference gradient of sdf at the two end voxels (one-sided
//   next to unobserved voxels), normalised.
// - Ambiguous cube faces are cut keeping their inside (sdf < 0) corners apart, in every cube
//   alike (marching_cubes_tables.h): no cracks, and a closed sdf surface gives a closed,
//   consistently oriented mesh (every edge shared by two triangles). The topology inside an
//   ambiguous cube is that rule's, not necessarily the trilinear interpolant's.
// - Vertex order: blocks sorted by key (z, then y, then x), and in a block by voxel and axis;
//   faces likewise by block and cube. Removing fragments keeps that order.
// - Reads the volume only (blocks through ForEachBlock); must not run concurrently with
//   calls that modify it.
TriangleMesh ExtractMesh(const TsdfVolume& volume, const MeshOptions& options,
                         MeshStats* stats = nullptr);

// The mesh as PLY: x y z nx ny nz (float) red green blue (uchar) and the faces.
core::PlyMesh ToPly(const TriangleMesh& mesh);

}  // namespace hw::reconstruct
