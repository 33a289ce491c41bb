#include "reconstruct/marching_cubes.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <thread>
#include <tuple>
#include <unordered_map>
#include <utility>

#include "reconstruct/marching_cubes_tables.h"
#include "reconstruct/option_check.h"

namespace hw::reconstruct {

using internal::Fail;
using internal::InRange;

std::string MeshOptions::Check() const {
  if (!InRange(min_weight, 0, 65535)) return Fail("min_weight", min_weight, "in [0, 65535]");
  if (min_component_triangles < 0) {
    return Fail("min_component_triangles", min_component_triangles, ">= 0");
  }
  if (!(min_component_area_fraction >= 0 && min_component_area_fraction < 1)) {
    return Fail("min_component_area_fraction", min_component_area_fraction, "in [0, 1)");
  }
  if (num_threads < 0) return Fail("num_threads", num_threads, ">= 0");
  return "";
}

double TriangleMesh::AreaM2() const {
  double area = 0;
  for (const Eigen::Vector3i& f : faces) {
    const Eigen::Vector3d a = positions[f[0]].cast<double>();
    area += 0.5 * (positions[f[1]].cast<double>() - a).cross(positions[f[2]].cast<double>() - a).norm();
  }
  return area;
}

core::PlyMesh ToPly(const TriangleMesh& mesh) {
  assert(mesh.normals.size() == mesh.positions.size() && mesh.colours.size() == mesh.positions.size());
  std::vector<Eigen::Vector3d> positions(mesh.positions.size()), normals(mesh.normals.size());
  for (size_t i = 0; i < positions.size(); ++i) {
    positions[i] = mesh.positions[i].cast<double>();
    normals[i] = mesh.normals[i].cast<double>();
  }
  core::PlyMesh ply;
  ply.SetPositions(positions, core::PlyType::kFloat32);
  ply.SetNormals(normals, core::PlyType::kFloat32);
  ply.SetColors(mesh.colours);
  ply.faces = mesh.faces;
  return ply;
}

namespace {

// Voxels of a block plus a border of one voxel below and two above on every axis: the cube
// corners (+1) and the central differences of their gradients (−1, +2).
constexpr int kCacheMin = -1;
constexpr int kCacheSide = kBlockSide + 3;  // voxels −1 .. 9
constexpr int kCacheCells = kCacheSide * kCacheSide * kCacheSide;
constexpr int kCacheStride[3] = {1, kCacheSide, kCacheSide * kCacheSide};

constexpr int CacheIndex(int x, int y, int z) {
  return (x - kCacheMin) + kCacheSide * ((y - kCacheMin) + kCacheSide * (z - kCacheMin));
}

// What one block contributes, before vertex ids are made global.
struct BlockResult {
  // Index of the vertex on the edge from voxel (x, y, z) of this block along each axis, at
  // [3 · (x + 8 (y + 8 z)) + axis]; −1 where the edge is not cut. Empty without vertices.
  std::vector<int32_t> edge_vertex;
  std::vector<Eigen::Vector3f> positions;
  std::vector<Eigen::Vector3f> normals;
  std::vector<Rgb8> colours;
  // Cubes (origin voxel x + 8 (y + 8 z) of this block) with a surface, and their case.
  std::vector<std::pair<uint16_t, uint8_t>> cubes;
  // Sorted indices of the blocks at key + (dx, dy, dz), d in {0, 1}, at dx + 2 dy + 4 dz.
  std::array<int, 8> forward;
};

struct BlockKeyHash {
  size_t operator()(const BlockKey& k) const {
    return static_cast<size_t>((static_cast<uint64_t>(k.x()) * 73856093u) ^
                               (static_cast<uint64_t>(k.y()) * 19349669u) ^
                               (static_cast<uint64_t>(k.z()) * 83492791u));
  }
};
using BlockIndex = std::unordered_map<BlockKey, int, BlockKeyHash>;

// Runs fn(begin, end) over num_threads contiguous ranges of [0, n).
template <typename Fn>
void ParallelRanges(int n, int num_threads, const Fn& fn) {
  num_threads = std::clamp(num_threads, 1, std::max(1, n));
  if (num_threads == 1) {
    fn(0, n);
    return;
  }
  std::vector<std::thread> threads;
  for (int t = 1; t < num_threads; ++t) {
    threads.emplace_back([&fn, t, n, num_threads] {
      fn(static_cast<int>(int64_t{n} * t / num_threads), static_cast<int>(int64_t{n} * (t + 1) / num_threads));
    });
  }
  fn(0, static_cast<int>(int64_t{n} / num_threads));
  for (std::thread& thread : threads) thread.join();
}

// The block's voxels with their borders: sdf, and the voxel when observed (else nullptr).
struct VoxelCache {
  std::array<float, kCacheCells> sdf;
  std::array<const Voxel*, kCacheCells> voxel;

  void Load(const std::vector<const VoxelBlock*>& blocks, const BlockIndex& index, const BlockKey& key,
            float min_weight) {
    // The 27 blocks around, at (dx + 1) + 3 (dy + 1) + 9 (dz + 1).
    std::array<const VoxelBlock*, 27> around;
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const auto it = index.find(key + BlockKey(dx, dy, dz));
          around[(dx + 1) + 3 * (dy + 1) + 9 * (dz + 1)] = it == index.end() ? nullptr : blocks[it->second];
        }
      }
    }
    // Per cache coordinate: which neighbour (0, 1, 2) and the voxel coordinate inside it.
    int which[kCacheSide], local[kCacheSide];
    for (int l = kCacheMin; l < kCacheMin + kCacheSide; ++l) {
      which[l - kCacheMin] = l < 0 ? 0 : (l < kBlockSide ? 1 : 2);
      local[l - kCacheMin] = l - (which[l - kCacheMin] - 1) * kBlockSide;
    }
    int c = 0;
    for (int z = 0; z < kCacheSide; ++z) {
      for (int y = 0; y < kCacheSide; ++y) {
        for (int x = 0; x < kCacheSide; ++x, ++c) {
          const VoxelBlock* block = around[which[x] + 3 * which[y] + 9 * which[z]];
          const Voxel* v = nullptr;
          if (block != nullptr) {
            v = &block->voxels[local[x] + kBlockSide * (local[y] + kBlockSide * local[z])];
            // Weight 0 is never observed, whatever min_weight says.
            if (!(v->weight > 0 && v->weight >= min_weight)) v = nullptr;
          }
          voxel[c] = v;
          sdf[c] = v != nullptr ? v->sdf : 0.0f;
        }
      }
    }
  }

  // The sdf gradient at a cell (per voxel): central difference, one-sided next to an
  // unobserved voxel, 0 along an axis with no observed neighbour.
  Eigen::Vector3f Gradient(int c) const {
    Eigen::Vector3f g;
    for (int axis = 0; axis < 3; ++axis) {
      const int s = kCacheStride[axis];
      const bool plus = voxel[c + s] != nullptr, minus = voxel[c - s] != nullptr;
      g[axis] = plus && minus ? 0.5f * (sdf[c + s] - sdf[c - s])
                : plus        ? sdf[c + s] - sdf[c]
                : minus       ? sdf[c] - sdf[c - s]
                              : 0.0f;
    }
    return g;
  }
};

// Vertices on the cut edges owned by the block (starting at its voxels) and its cube cases.
void ExtractBlockVertices(const VoxelCache& cache, const BlockKey& key, float voxel_size_m,
                          const internal::MarchingCubesTables& tables, BlockResult& out) {
  const Eigen::Vector3i origin = key * kBlockSide;
  for (int z = 0; z < kBlockSide; ++z) {
    for (int y = 0; y < kBlockSide; ++y) {
      for (int x = 0; x < kBlockSide; ++x) {
        const int c = CacheIndex(x, y, z);
        const Voxel* v0 = cache.voxel[c];
        const int voxel_index = x + kBlockSide * (y + kBlockSide * z);
        if (v0 == nullptr) continue;
        const float s0 = cache.sdf[c];
        for (int axis = 0; axis < 3; ++axis) {
          const int c1 = c + kCacheStride[axis];
          const Voxel* v1 = cache.voxel[c1];
          if (v1 == nullptr) continue;
          const float s1 = cache.sdf[c1];
          if ((s0 < 0) == (s1 < 0)) continue;
          // The signs differ, so s0 − s1 is not 0 and t is in [0, 1].
          const float t = s0 / (s0 - s1);
          if (out.edge_vertex.empty()) out.edge_vertex.assign(3 * kBlockVoxels, -1);
          out.edge_vertex[3 * voxel_index + axis] = static_cast<int32_t>(out.positions.size());
          Eigen::Vector3f p = (origin + Eigen::Vector3i(x, y, z)).cast<float>();
          p[axis] += t;
          out.positions.push_back(p * voxel_size_m);
          const Eigen::Vector3f g = (1 - t) * cache.Gradient(c) + t * cache.Gradient(c1);
          const float norm = g.norm();
          Eigen::Vector3f n = Eigen::Vector3f::Zero();
          if (norm > 1e-12f) {
            n = g / norm;
          } else {
            n[axis] = s1 > s0 ? 1.0f : -1.0f;  // the edge itself crosses towards free space
          }
          out.normals.push_back(n);
          const Eigen::Vector3f rgb = (1 - t) * v0->colour.cast<float>() + t * v1->colour.cast<float>();
          out.colours.push_back((rgb.array() + 0.5f).min(255.0f).max(0.0f).matrix().cast<std::uint8_t>());
        }
      }
    }
  }
  for (int z = 0; z < kBlockSide; ++z) {
    for (int y = 0; y < kBlockSide; ++y) {
      for (int x = 0; x < kBlockSide; ++x) {
        const int c = CacheIndex(x, y, z);
        int cube = 0;
        bool observed = true;
        for (int k = 0; k < 8 && observed; ++k) {
          const int* d = internal::kCubeCorners[k];
          const int ck = c + d[0] * kCacheStride[0] + d[1] * kCacheStride[1] + d[2] * kCacheStride[2];
          observed = cache.voxel[ck] != nullptr;
          if (cache.sdf[ck] < 0) cube |= 1 << k;
        }
        if (!observed || tables.edge_mask[cube] == 0) continue;
        out.cubes.emplace_back(static_cast<uint16_t>(x + kBlockSide * (y + kBlockSide * z)),
                               static_cast<uint8_t>(cube));
      }
    }
  }
}

// Triangles of the block's cubes, with global vertex ids.
void ExtractBlockFaces(const std::vector<BlockResult>& results, const std::vector<int32_t>& first_vertex,
                       const internal::MarchingCubesTables& tables, int b, std::vector<Eigen::Vector3i>& faces) {
  const BlockResult& out = results[b];
  for (const auto& [voxel_index, cube] : out.cubes) {
    const int x = voxel_index % kBlockSide, y = (voxel_index / kBlockSide) % kBlockSide,
              z = voxel_index / (kBlockSide * kBlockSide);
    const auto& tri = tables.triangles[cube];
    for (int i = 0; tri[i] >= 0; i += 3) {
      Eigen::Vector3i face;
      for (int k = 0; k < 3; ++k) {
        const int e = tri[i + k];
        const auto& d = tables.edge_origin[e];
        int lx = x + d[0], ly = y + d[1], lz = z + d[2];
        const int nx = lx >= kBlockSide, ny = ly >= kBlockSide, nz = lz >= kBlockSide;
        const int owner = out.forward[nx + 2 * ny + 4 * nz];
        // All 8 corners were observed, so the owner exists and cut this edge.
        assert(owner >= 0);
        lx -= nx * kBlockSide;
        ly -= ny * kBlockSide;
        lz -= nz * kBlockSide;
        const BlockResult& o = results[owner];
        const int32_t local = o.edge_vertex[3 * (lx + kBlockSide * (ly + kBlockSide * lz)) + tables.edge_axis[e]];
        assert(local >= 0);
        face[k] = first_vertex[owner] + local;
      }
      faces.push_back(face);
    }
  }
}

int Find(std::vector<int32_t>& parent, int32_t v) {
  while (parent[v] != v) {
    parent[v] = parent[parent[v]];  // path halving
    v = parent[v];
  }
  return v;
}

// Removes small components (options), drops unused vertices and remaps the faces.
void RemoveFragments(TriangleMesh& mesh, const MeshOptions& options, MeshStats& stats) {
  const int32_t num_vertices = static_cast<int32_t>(mesh.positions.size());
  std::vector<int32_t> parent(num_vertices);
  for (int32_t v = 0; v < num_vertices; ++v) parent[v] = v;
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 1; k < 3; ++k) {
      const int a = Find(parent, f[0]), b = Find(parent, f[k]);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);  // root: the smallest vertex id
    }
  }
  std::vector<int32_t> triangles(num_vertices, 0);
  std::vector<double> area(num_vertices, 0.0);
  std::vector<int32_t> face_root(mesh.faces.size());
  for (size_t i = 0; i < mesh.faces.size(); ++i) {
    const Eigen::Vector3i& f = mesh.faces[i];
    const int root = Find(parent, f[0]);
    face_root[i] = root;
    ++triangles[root];
    const Eigen::Vector3d a = mesh.positions[f[0]].cast<double>();
    area[root] += 0.5 * (mesh.positions[f[1]].cast<double>() - a).cross(mesh.positions[f[2]].cast<double>() - a).norm();
  }
  double largest = 0;
  stats = MeshStats{};
  for (int32_t v = 0; v < num_vertices; ++v) {
    if (triangles[v] == 0) continue;
    ++stats.components;
    largest = std::max(largest, area[v]);
  }
  std::vector<uint8_t> keep(num_vertices, 0);
  for (int32_t v = 0; v < num_vertices; ++v) {
    if (triangles[v] == 0) continue;
    keep[v] = triangles[v] >= options.min_component_triangles &&
              area[v] >= options.min_component_area_fraction * largest;
    if (!keep[v]) {
      ++stats.components_removed;
      stats.triangles_removed += triangles[v];
    }
  }
  // New ids in the old order, for the vertices of kept faces only.
  std::vector<int32_t> new_id(num_vertices, -1);
  size_t kept_faces = 0;
  for (size_t i = 0; i < mesh.faces.size(); ++i) {
    if (!keep[face_root[i]]) continue;
    mesh.faces[kept_faces++] = mesh.faces[i];
    for (int k = 0; k < 3; ++k) new_id[mesh.faces[i][k]] = 0;
  }
  mesh.faces.resize(kept_faces);
  int32_t next = 0;
  for (int32_t v = 0; v < num_vertices; ++v) {
    if (new_id[v] < 0) continue;
    new_id[v] = next;
    mesh.positions[next] = mesh.positions[v];
    mesh.normals[next] = mesh.normals[v];
    mesh.colours[next] = mesh.colours[v];
    ++next;
  }
  mesh.positions.resize(next);
  mesh.normals.resize(next);
  mesh.colours.resize(next);
  for (Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) f[k] = new_id[f[k]];
  }
}

}  // namespace

TriangleMesh ExtractMesh(const TsdfVolume& volume, const MeshOptions& options, MeshStats* stats) {
  assert(options.Check().empty());
  const internal::MarchingCubesTables& tables = internal::GetMarchingCubesTables();
  const int num_threads =
      options.num_threads > 0 ? options.num_threads : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  const float min_weight = static_cast<float>(options.min_weight);
  const float voxel_size_m = volume.voxel_size_m();

  // Blocks in key order (z, y, x), so that the output does not depend on the hash table.
  std::vector<const VoxelBlock*> blocks;
  blocks.reserve(volume.NumBlocks());
  volume.ForEachBlock([&blocks](const VoxelBlock& block) { blocks.push_back(&block); });
  std::sort(blocks.begin(), blocks.end(), [](const VoxelBlock* a, const VoxelBlock* b) {
    const BlockKey& p = a->key;
    const BlockKey& q = b->key;
    return std::tie(p.z(), p.y(), p.x()) < std::tie(q.z(), q.y(), q.x());
  });
  const int num_blocks = static_cast<int>(blocks.size());
  BlockIndex index;
  index.reserve(blocks.size());
  for (int b = 0; b < num_blocks; ++b) index.emplace(blocks[b]->key, b);

  std::vector<BlockResult> results(blocks.size());
  ParallelRanges(num_blocks, num_threads, [&](int begin, int end) {
    auto cache = std::make_unique<VoxelCache>();
    for (int b = begin; b < end; ++b) {
      const BlockKey& key = blocks[b]->key;
      BlockResult& out = results[b];
      for (int d = 0; d < 8; ++d) {
        const auto it = index.find(key + BlockKey(d & 1, (d >> 1) & 1, (d >> 2) & 1));
        out.forward[d] = it == index.end() ? -1 : it->second;
      }
      cache->Load(blocks, index, key, min_weight);
      ExtractBlockVertices(*cache, key, voxel_size_m, tables, out);
    }
  });
  // Vertex ids: blocks in key order, vertices in the order each block made them.
  std::vector<int32_t> first_vertex(blocks.size() + 1, 0);
  for (int b = 0; b < num_blocks; ++b) {
    const size_t total = static_cast<size_t>(first_vertex[b]) + results[b].positions.size();
    assert(total <= static_cast<size_t>(std::numeric_limits<int32_t>::max()));
    first_vertex[b + 1] = static_cast<int32_t>(total);
  }
  std::vector<std::vector<Eigen::Vector3i>> block_faces(blocks.size());
  ParallelRanges(num_blocks, num_threads, [&](int begin, int end) {
    for (int b = begin; b < end; ++b) ExtractBlockFaces(results, first_vertex, tables, b, block_faces[b]);
  });

  TriangleMesh mesh;
  size_t num_faces = 0;
  for (const auto& f : block_faces) num_faces += f.size();
  mesh.positions.reserve(first_vertex.back());
  mesh.normals.reserve(first_vertex.back());
  mesh.colours.reserve(first_vertex.back());
  mesh.faces.reserve(num_faces);
  for (int b = 0; b < num_blocks; ++b) {
    BlockResult& r = results[b];
    mesh.positions.insert(mesh.positions.end(), r.positions.begin(), r.positions.end());
    mesh.normals.insert(mesh.normals.end(), r.normals.begin(), r.normals.end());
    mesh.colours.insert(mesh.colours.end(), r.colours.begin(), r.colours.end());
    mesh.faces.insert(mesh.faces.end(), block_faces[b].begin(), block_faces[b].end());
    r = BlockResult{};  // release as we go
    block_faces[b] = {};
  }
  MeshStats local_stats;
  RemoveFragments(mesh, options, local_stats);
  if (stats != nullptr) *stats = local_stats;
  return mesh;
}

}  // namespace hw::reconstruct
