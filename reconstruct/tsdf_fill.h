#pragma once

// Internal to the TSDF sources: the voxels of a far block that its coarse update skips.
//
// A block that no camera has seen from nearer than TsdfOptions::CoarseBeyondM is updated on
// its even voxels only (every coordinate even: a lattice of twice the voxel size, 4³ of the
// 8³), where one reading's noise and a depth pixel are both wider than a voxel; its other
// voxels are then filled from them, so that everything reading the volume (raycasting,
// meshing, thermal regions, carving) sees one lattice of the voxel size as before.

#include "reconstruct/tsdf_volume.h"

namespace hw::reconstruct::internal {

// Fills the voxels of a block with an odd coordinate from its even ones, one axis after the
// other (x in the even rows, then y in the even slabs, then z): an odd voxel between two
// even neighbours takes their mean, the one at a block's last index (7: its other neighbour
// is in the next block, which another thread may be updating) the linear extrapolation
// 1.5·v6 − 0.5·v4 — trilinear interpolation of the even lattice, exact for a linear field,
// inside the block. Distance clamped to ±1 and rounded as Voxel::set_sdf; weight the
// smaller of the two; colour the rounded-up mean per channel (at index 7: v6's), colour
// weight the smaller. Where only one neighbour is observed (painted) the voxel copies its
// distance and weight (colour and colour weight); where none is, it is left as it is.
// voxels: kBlockVoxels voxels in VoxelBlock order.
void FillOddVoxelsScalar(Voxel* voxels);
// The same bits with AVX2 where the CPU has it (and integrate_simd is set), else the scalar
// code.
void FillOddVoxels(Voxel* voxels);

}  // namespace hw::reconstruct::internal
