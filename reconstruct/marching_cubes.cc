#include "reconstruct/marching_cubes.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <thread>
#include <tuple>
#include <unordered_map>
#include <utility>

#include <Eigen/Geometry>

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
  // The cut edges starting at this block's voxels, as 3 · (x + 8 (y + 8 z)) + axis, in
  // increasing order; the vertex on edge_keys[i] is vertex i of the block. (A list, not a
  // dense table: a surface block has a few dozen cut edges out of 1536; EdgeIds spreads
  // them into a dense table per thread when the faces are made.)
  std::vector<uint16_t> edge_keys;
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

// Runs fn(begin, end) over chunks of [0, n) on num_threads threads, each taking the next
// chunk when done (surface blocks cluster: equal ranges would leave a thread idle). Chunks
// of a few dozen blocks keep the scheduling coarse.
template <typename Fn>
void ParallelChunks(int n, int num_threads, const Fn& fn) {
  constexpr int kChunk = 32;
  const int num_chunks = (n + kChunk - 1) / kChunk;
  std::atomic<int> next{0};
  const auto work = [&] {
    for (int chunk = next++; chunk < num_chunks; chunk = next++) fn(chunk * kChunk, std::min(n, (chunk + 1) * kChunk));
  };
  num_threads = std::clamp(num_threads, 1, std::max(1, num_chunks));
  std::vector<std::thread> threads;
  for (int t = 1; t < num_threads; ++t) threads.emplace_back(work);
  work();
  for (std::thread& thread : threads) thread.join();
}

// Offsets of the 8 corners of a cube from its origin cell, in kCubeCorners order.
constexpr std::array<int, 8> kCornerOffset = [] {
  std::array<int, 8> offsets{};
  for (int k = 0; k < 8; ++k) {
    for (int axis = 0; axis < 3; ++axis) offsets[k] += internal::kCubeCorners[k][axis] * kCacheStride[axis];
  }
  return offsets;
}();

// Cell codes.
constexpr uint8_t kOutside = 0;     // observed, sdf >= 0 (free space)
constexpr uint8_t kInside = 1;      // observed, sdf < 0 (behind the surface)
constexpr uint8_t kUnobserved = 2;  // missing block, weight 0 or below min_weight

// A block's voxels with their borders, and which blocks are around it.
struct VoxelCache {
  std::array<float, kCacheCells> sdf;
  std::array<const Voxel*, kCacheCells> voxel;  // nullptr when unobserved
  std::array<uint8_t, kCacheCells> code;
  // Sorted indices of the 27 blocks around (−1 when missing) at (dx+1) + 3 (dy+1) + 9 (dz+1).
  std::array<int, 27> around;

  // Loads the block's cells and those of the +1 layer (the cube corners); returns false when
  // no two observed ones have opposite signs, i.e. the block has no surface (the common
  // case away from it). When it has one, loads the −1 and +2 layers too, for the gradients.
  bool Load(const std::vector<const VoxelBlock*>& blocks, const BlockIndex& index, const BlockKey& key,
            float min_weight) {
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const auto it = index.find(key + BlockKey(dx, dy, dz));
          around[(dx + 1) + 3 * (dy + 1) + 9 * (dz + 1)] = it == index.end() ? -1 : it->second;
        }
      }
    }
    // Per cache coordinate: which neighbour (0, 1, 2) and the voxel coordinate inside it.
    int which[kCacheSide], local[kCacheSide];
    for (int l = kCacheMin; l < kCacheMin + kCacheSide; ++l) {
      which[l - kCacheMin] = l < 0 ? 0 : (l < kBlockSide ? 1 : 2);
      local[l - kCacheMin] = l - (which[l - kCacheMin] - 1) * kBlockSide;
    }
    // Weight 0 is never observed, whatever min_weight says.
    const float threshold = std::max(min_weight, std::numeric_limits<float>::denorm_min());
    // Loads cache cells x0..x1 of row (y, z) (cache coordinates, from 0).
    const auto load_row = [&](int y, int z, int x0, int x1, bool& inside, bool& outside) {
      const Voxel* row[3];  // voxel (0, local y, local z) of the three blocks along x
      for (int w = 0; w < 3; ++w) {
        const int b = around[w + 3 * which[y] + 9 * which[z]];
        row[w] = b < 0 ? nullptr : &blocks[b]->voxels[kBlockSide * (local[y] + kBlockSide * local[z])];
      }
      int c = kCacheSide * (y + kCacheSide * z) + x0;
      for (int x = x0; x <= x1; ++x, ++c) {
        const Voxel* v = row[which[x]];
        if (v != nullptr) v += local[x];
        if (v != nullptr && v->weight() >= threshold) {
          voxel[c] = v;
          sdf[c] = v->sdf();
          const bool negative = v->sdf_steps < 0;
          code[c] = negative ? kInside : kOutside;
          inside |= negative;
          outside |= !negative;
        } else {
          voxel[c] = nullptr;
          sdf[c] = 0.0f;
          code[c] = kUnobserved;
        }
      }
    };
    bool inside = false, outside = false;
    for (int z = 1; z <= kBlockSide + 1; ++z) {
      for (int y = 1; y <= kBlockSide + 1; ++y) load_row(y, z, 1, kBlockSide + 1, inside, outside);
    }
    if (!inside || !outside) return false;
    bool unused_inside, unused_outside;
    constexpr int kLast = kCacheSide - 1;
    for (int z = 0; z < kCacheSide; ++z) {
      for (int y = 0; y < kCacheSide; ++y) {
        if (z == 0 || z == kLast || y == 0 || y == kLast) {
          load_row(y, z, 0, kLast, unused_inside, unused_outside);
        } else {
          load_row(y, z, 0, 0, unused_inside, unused_outside);
          load_row(y, z, kLast, kLast, unused_inside, unused_outside);
        }
      }
    }
    return true;
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
        const uint8_t code0 = cache.code[c];
        if (code0 == kUnobserved) continue;
        const int voxel_index = x + kBlockSide * (y + kBlockSide * z);
        for (int axis = 0; axis < 3; ++axis) {
          const int c1 = c + kCacheStride[axis];
          const uint8_t code1 = cache.code[c1];
          if (code1 == kUnobserved || code1 == code0) continue;
          // The signs differ, so s0 − s1 is not 0 and t is in [0, 1].
          const float s0 = cache.sdf[c], s1 = cache.sdf[c1];
          const float t = s0 / (s0 - s1);
          out.edge_keys.push_back(static_cast<uint16_t>(3 * voxel_index + axis));
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
          const Eigen::Vector3f rgb =
              (1 - t) * cache.voxel[c]->colour.cast<float>() + t * cache.voxel[c1]->colour.cast<float>();
          out.colours.push_back((rgb.array() + 0.5f).min(255.0f).max(0.0f).matrix().cast<std::uint8_t>());
        }
      }
    }
  }
  for (int z = 0; z < kBlockSide; ++z) {
    for (int y = 0; y < kBlockSide; ++y) {
      for (int x = 0; x < kBlockSide; ++x) {
        const uint8_t* q = &cache.code[CacheIndex(x, y, z)];
        int cube = 0, any = 0;
        for (int k = 0; k < 8; ++k) {
          cube |= (q[kCornerOffset[k]] & kInside) << k;
          any |= q[kCornerOffset[k]];
        }
        if ((any & kUnobserved) || tables.edge_mask[cube] == 0) continue;
        out.cubes.emplace_back(static_cast<uint16_t>(x + kBlockSide * (y + kBlockSide * z)),
                               static_cast<uint8_t>(cube));
      }
    }
  }
}

// Global ids of the vertices on the edges starting at the voxels 0..8 of a block (its own
// and the first layer of its +x, +y, +z neighbours): a dense scratch table, reset after use.
struct EdgeIds {
  static constexpr int kSide = kBlockSide + 1;
  std::vector<int32_t> id = std::vector<int32_t>(3 * kSide * kSide * kSide, -1);
  std::vector<int> written;

  static int Index(int x, int y, int z, int axis) { return 3 * (x + kSide * (y + kSide * z)) + axis; }
};

// Triangles of the block's cubes, with global vertex ids.
void ExtractBlockFaces(const std::vector<BlockResult>& results, const std::vector<int32_t>& first_vertex,
                       const internal::MarchingCubesTables& tables, int b, EdgeIds& ids,
                       std::vector<Eigen::Vector3i>& faces) {
  const BlockResult& out = results[b];
  if (out.cubes.empty()) return;
  for (int d = 0; d < 8; ++d) {
    const int owner = out.forward[d];
    if (owner < 0) continue;
    const int dx = (d & 1) * kBlockSide, dy = ((d >> 1) & 1) * kBlockSide, dz = ((d >> 2) & 1) * kBlockSide;
    const std::vector<uint16_t>& keys = results[owner].edge_keys;
    for (size_t i = 0; i < keys.size(); ++i) {
      const int voxel_index = keys[i] / 3, axis = keys[i] % 3;
      const int x = voxel_index % kBlockSide + dx, y = (voxel_index / kBlockSide) % kBlockSide + dy,
                z = voxel_index / (kBlockSide * kBlockSide) + dz;
      if (x > kBlockSide || y > kBlockSide || z > kBlockSide) continue;
      const int at = EdgeIds::Index(x, y, z, axis);
      ids.id[at] = first_vertex[owner] + static_cast<int32_t>(i);
      ids.written.push_back(at);
    }
  }
  for (const auto& [voxel_index, cube] : out.cubes) {
    const int x = voxel_index % kBlockSide, y = (voxel_index / kBlockSide) % kBlockSide,
              z = voxel_index / (kBlockSide * kBlockSide);
    const auto& tri = tables.triangles[cube];
    for (int i = 0; tri[i] >= 0; i += 3) {
      Eigen::Vector3i face;
      for (int k = 0; k < 3; ++k) {
        const int e = tri[i + k];
        const auto& o = tables.edge_origin[e];
        face[k] = ids.id[EdgeIds::Index(x + o[0], y + o[1], z + o[2], tables.edge_axis[e])];
      }
      // All 8 corners were observed, so the blocks owning the cut edges exist and made them.
      assert(face.minCoeff() >= 0);
      faces.push_back(face);
    }
  }
  for (const int at : ids.written) ids.id[at] = -1;
  ids.written.clear();
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
  ParallelChunks(num_blocks, num_threads, [&](int begin, int end) {
    auto cache = std::make_unique<VoxelCache>();
    for (int b = begin; b < end; ++b) {
      const BlockKey& key = blocks[b]->key;
      BlockResult& out = results[b];
      const bool surface = cache->Load(blocks, index, key, min_weight);
      for (int d = 0; d < 8; ++d) out.forward[d] = cache->around[13 + (d & 1) + 3 * ((d >> 1) & 1) + 9 * (d >> 2)];
      if (surface) ExtractBlockVertices(*cache, key, voxel_size_m, tables, out);
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
  ParallelChunks(num_blocks, num_threads, [&](int begin, int end) {
    EdgeIds ids;
    for (int b = begin; b < end; ++b) ExtractBlockFaces(results, first_vertex, tables, b, ids, block_faces[b]);
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
