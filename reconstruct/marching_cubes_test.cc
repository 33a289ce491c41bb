#include "reconstruct/marching_cubes.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "core/ply.h"
#include "reconstruct/marching_cubes_tables.h"
#include "tests/support.h"

namespace hw::reconstruct {
namespace {

constexpr double kPi = 3.14159265358979323846;

TsdfOptions VolumeOptions(double voxel_size_m, double truncation_m) {
  TsdfOptions o;
  o.voxel_size_m = voxel_size_m;
  o.truncation_m = truncation_m;
  return o;
}

// Writes every voxel of the blocks with keys in [lo, hi] (inclusive) as f(voxel index, voxel
// centre in the world). Blocks are created in key order, or reversed.
void Fill(TsdfVolume& volume, const BlockKey& lo, const BlockKey& hi,
          const std::function<Voxel(const Eigen::Vector3i&, const Eigen::Vector3f&)>& f,
          bool reverse = false) {
  std::vector<BlockKey> keys;
  for (int z = lo.z(); z <= hi.z(); ++z) {
    for (int y = lo.y(); y <= hi.y(); ++y) {
      for (int x = lo.x(); x <= hi.x(); ++x) keys.emplace_back(x, y, z);
    }
  }
  if (reverse) std::reverse(keys.begin(), keys.end());
  const float h = volume.voxel_size_m();
  for (const BlockKey& key : keys) {
    VoxelBlock& block = volume.GetOrCreateBlock(key);
    for (int z = 0; z < kBlockSide; ++z) {
      for (int y = 0; y < kBlockSide; ++y) {
        for (int x = 0; x < kBlockSide; ++x) {
          const Eigen::Vector3i voxel = key * kBlockSide + Eigen::Vector3i(x, y, z);
          block.voxels[x + kBlockSide * (y + kBlockSide * z)] = f(voxel, voxel.cast<float>() * h);
        }
      }
    }
  }
}

// Keys of the blocks holding every voxel within `margin_m` of the box [lo_m, hi_m].
std::pair<BlockKey, BlockKey> BlocksAround(const Eigen::Vector3f& lo_m, const Eigen::Vector3f& hi_m, float margin_m,
                                           float voxel_size_m) {
  const float block_m = voxel_size_m * kBlockSide;
  const Eigen::Vector3f lo = ((lo_m.array() - margin_m) / block_m).floor();
  const Eigen::Vector3f hi = ((hi_m.array() + margin_m) / block_m).floor();
  return {lo.cast<int>(), hi.cast<int>()};
}

float Clamp1(float x) { return std::clamp(x, -1.0f, 1.0f); }

Voxel Observed(float sdf, float weight = 1, Rgb8 colour = Rgb8(128, 128, 128)) {
  Voxel v;
  v.set_sdf(sdf);
  v.set_weight(weight);
  v.colour = colour;
  return v;
}

// A sphere volume: sdf = (|p − c| − r) / truncation, positive outside (free space).
struct SphereScene {
  float voxel_size_m = 0.01f;
  float truncation_m = 0.04f;
  Eigen::Vector3f centre{0.0123f, -0.0071f, 0.0049f};  // off the grid, across negative keys
  float radius_m = 0.1f;
};

float SphereSdf(const SphereScene& s, const Eigen::Vector3f& p) {
  return Clamp1(((p - s.centre).norm() - s.radius_m) / s.truncation_m);
}

TsdfVolume MakeSphereVolume(const SphereScene& s, bool reverse = false) {
  TsdfVolume volume(VolumeOptions(s.voxel_size_m, s.truncation_m));
  const Eigen::Vector3f r = Eigen::Vector3f::Constant(s.radius_m);
  const auto [lo, hi] = BlocksAround(s.centre - r, s.centre + r, s.truncation_m + 2 * s.voxel_size_m, s.voxel_size_m);
  Fill(volume, lo, hi, [&](const Eigen::Vector3i&, const Eigen::Vector3f& p) { return Observed(SphereSdf(s, p)); },
       reverse);
  return volume;
}

MeshOptions KeepAll() {
  MeshOptions o;
  o.min_component_triangles = 0;
  o.num_threads = 2;
  return o;
}

// Directed edge (a, b) → number of faces having it, counter-clockwise.
std::map<std::pair<int, int>, int> DirectedEdges(const TriangleMesh& mesh) {
  std::map<std::pair<int, int>, int> edges;
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) ++edges[{f[k], f[(k + 1) % 3]}];
  }
  return edges;
}

// Closed and consistently oriented: every directed edge once, and its reverse once too (so
// every undirected edge is shared by exactly two triangles that agree on the orientation).
// Returns the number of directed edges that break that.
int OrientedManifoldViolations(const TriangleMesh& mesh) {
  const auto edges = DirectedEdges(mesh);
  int bad = 0;
  for (const auto& [edge, count] : edges) {
    const auto reverse = edges.find({edge.second, edge.first});
    if (count != 1 || reverse == edges.end() || reverse->second != 1) ++bad;
  }
  return bad;
}

int CountUndirectedEdges(const TriangleMesh& mesh) {
  std::set<std::pair<int, int>> edges;
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) edges.insert(std::minmax(f[k], f[(k + 1) % 3]));
  }
  return static_cast<int>(edges.size());
}

Eigen::Vector3f FaceNormal(const TriangleMesh& mesh, const Eigen::Vector3i& f) {
  return (mesh.positions[f[1]] - mesh.positions[f[0]]).cross(mesh.positions[f[2]] - mesh.positions[f[0]]);
}

void ExpectSameMesh(const TriangleMesh& a, const TriangleMesh& b) {
  ASSERT_EQ(a.positions.size(), b.positions.size());
  ASSERT_EQ(a.faces.size(), b.faces.size());
  EXPECT_TRUE(a.positions == b.positions);
  EXPECT_TRUE(a.normals == b.normals);
  EXPECT_TRUE(a.colours == b.colours);
  EXPECT_TRUE(a.faces == b.faces);
}

TEST(MarchingCubesTablesTest, EdgesAndTrianglesAgree) {
  const internal::MarchingCubesTables& t = internal::GetMarchingCubesTables();
  // Bourke's numbering: corner 0 alone cuts edges 0, 3, 8; corner 1 alone 0, 1, 9; ...
  EXPECT_EQ(t.edge_mask[0], 0);
  EXPECT_EQ(t.edge_mask[1], 0x109);
  EXPECT_EQ(t.edge_mask[2], 0x203);
  EXPECT_EQ(t.edge_mask[3], 0x30a);
  EXPECT_EQ(t.edge_mask[0x80], 0x8c0);
  EXPECT_EQ(t.edge_mask[255], 0);
  for (int c = 0; c < 256; ++c) {
    EXPECT_EQ(t.edge_mask[c], t.edge_mask[255 - c]) << c;
    int used = 0, n = 0;
    while (n < 16 && t.triangles[c][n] >= 0) used |= 1 << t.triangles[c][n++];
    EXPECT_EQ(n % 3, 0) << c;
    EXPECT_LE(n, 15) << c;
    EXPECT_EQ(used, t.edge_mask[c]) << "case " << c << ": every cut edge has a vertex, no other";
  }
  for (int e = 0; e < 12; ++e) {
    const auto& a = internal::kCubeCorners[internal::kEdgeCorners[e][0]];
    const auto& b = internal::kCubeCorners[internal::kEdgeCorners[e][1]];
    for (int k = 0; k < 3; ++k) {
      EXPECT_EQ(t.edge_origin[e][k], std::min(a[k], b[k]));
      EXPECT_EQ(std::abs(a[k] - b[k]), k == t.edge_axis[e] ? 1 : 0);
    }
  }
}

// Every sign pattern, in every neighbourhood: random sdf inside a positive shell. Whatever
// the ambiguous faces, the surface must close and keep one orientation.
TEST(MarchingCubesTest, RandomFieldGivesClosedOrientedSurface) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> uniform(-1.0f, 1.0f);
  TsdfVolume volume(VolumeOptions(0.01, 0.02));
  const int last = 3 * kBlockSide - 1;
  Fill(volume, BlockKey(0, 0, 0), BlockKey(2, 2, 2), [&](const Eigen::Vector3i& v, const Eigen::Vector3f&) {
    const bool shell = (v.array() == 0).any() || (v.array() == last).any();
    float sdf = uniform(rng);
    if (sdf > 0.9f) sdf = 0.0f;  // exact zeros too (they count as outside)
    return Observed(shell ? 1.0f : sdf);
  });
  MeshStats stats;
  const TriangleMesh mesh = ExtractMesh(volume, KeepAll(), &stats);
  ASSERT_GT(mesh.faces.size(), 10000u);
  EXPECT_EQ(OrientedManifoldViolations(mesh), 0);
  EXPECT_EQ(stats.components_removed, 0);
  EXPECT_GT(stats.components, 1);
}

TEST(MarchingCubesTest, SphereIsAccurateClosedAndOutward) {
  const SphereScene s;
  const TsdfVolume volume = MakeSphereVolume(s);
  MeshStats stats;
  const TriangleMesh mesh = ExtractMesh(volume, MeshOptions{}, &stats);
  ASSERT_GT(mesh.faces.size(), 1000u);
  EXPECT_EQ(stats.components, 1);
  EXPECT_EQ(stats.components_removed, 0);
  EXPECT_EQ(stats.triangles_removed, 0);
  EXPECT_EQ(OrientedManifoldViolations(mesh), 0);
  // Euler characteristic of a sphere.
  const int euler = static_cast<int>(mesh.positions.size()) - CountUndirectedEdges(mesh) +
                    static_cast<int>(mesh.faces.size());
  EXPECT_EQ(euler, 2);
  // No duplicate vertices: every vertex is on its own voxel edge, so positions are distinct.
  std::set<std::tuple<float, float, float>> distinct;
  for (const auto& p : mesh.positions) distinct.emplace(p.x(), p.y(), p.z());
  EXPECT_EQ(distinct.size(), mesh.positions.size());

  // The zero of the linear interpolant of d = |p − c| − r along an edge: |d| there is at most
  // the interpolation error h²/8 · max d'' <= h² / (8 (r − h)) = 0.14 mm (d'' <= 1/|p − c|).
  const float h = s.voxel_size_m;
  const float position_tolerance_m = h * h / (8 * (s.radius_m - h)) + 1e-6f;
  float worst_m = 0, worst_normal_deg = 0;
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    const Eigen::Vector3f radial = mesh.positions[i] - s.centre;
    worst_m = std::max(worst_m, std::abs(radial.norm() - s.radius_m));
    EXPECT_NEAR(mesh.normals[i].norm(), 1.0f, 1e-5f);
    const float cosine = std::clamp(mesh.normals[i].dot(radial.normalized()), -1.0f, 1.0f);
    worst_normal_deg = std::max(worst_normal_deg, static_cast<float>(std::acos(double{cosine}) * 180 / kPi));
  }
  EXPECT_LE(worst_m, position_tolerance_m);
  // The corners' radials differ by up to h/r = 0.1 rad; interpolating them linearly errs by
  // about (h/r)²/8 rad = 0.07°, and the central differences of |p − c| by O((h/r)²) too
  // (~0.1°): 0.5° bounds both.
  EXPECT_LE(worst_normal_deg, 0.5f);
  // Vertices up to h²/(8r) inside the sphere shrink the area by at most (h/r)²/4 = 0.25%,
  // and flat triangles of circumradius ρ <~ h under-cover their spherical caps by about
  // ρ²/(4r²) <~ 0.25%: within 1%.
  const double area_m2 = mesh.AreaM2();
  const double truth_m2 = 4 * kPi * double{s.radius_m} * double{s.radius_m};
  EXPECT_NEAR(area_m2 / truth_m2, 1.0, 0.01);
  std::printf("sphere r=0.1 m at 1 cm: %zu vertices, %zu faces, area/truth %.5f, worst |d| %.3f mm, normal %.2f deg\n",
              mesh.positions.size(), mesh.faces.size(), area_m2 / truth_m2, double{worst_m} * 1e3, double{worst_normal_deg});

  // Winding: counter-clockwise from free space, i.e. the geometric normal points outward and
  // agrees with the vertex normals.
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3f n = FaceNormal(mesh, f);
    if (n.norm() < 1e-10f) continue;  // degenerate slivers carry no orientation
    const Eigen::Vector3f centroid = (mesh.positions[f[0]] + mesh.positions[f[1]] + mesh.positions[f[2]]) / 3;
    EXPECT_GT(n.dot(centroid - s.centre), 0) << f.transpose();
    EXPECT_GT(n.dot(mesh.normals[f[0]] + mesh.normals[f[1]] + mesh.normals[f[2]]), 0) << f.transpose();
  }
}

// A tilted plane through 2×2×2 blocks, crossing block borders along every axis.
struct PlaneScene {
  float voxel_size_m = 0.01f;
  Eigen::Vector3f normal = Eigen::Vector3f(0.2f, -0.3f, 1.0f).normalized();
  Eigen::Vector3f point{0.08f, 0.08f, 0.075f};
};

Rgb8 PlaneColour(const Eigen::Vector3i& v) {
  return Rgb8(static_cast<uint8_t>(40 + 8 * v.x()), static_cast<uint8_t>(30 + 5 * v.y()),
              static_cast<uint8_t>(20 + 10 * v.z()));
}

TEST(MarchingCubesTest, PlaneAcrossBlocksIsOneExactPatch) {
  const PlaneScene s;
  // Truncation wider than the volume: no clamping, the sdf is exactly linear.
  TsdfVolume volume(VolumeOptions(s.voxel_size_m, 0.5));
  Fill(volume, BlockKey(0, 0, 0), BlockKey(1, 1, 1), [&](const Eigen::Vector3i& v, const Eigen::Vector3f& p) {
    return Observed((p - s.point).dot(s.normal) / 0.5f, 1, PlaneColour(v));
  });
  MeshStats stats;
  const TriangleMesh mesh = ExtractMesh(volume, MeshOptions{}, &stats);
  ASSERT_GT(mesh.faces.size(), 100u);
  EXPECT_EQ(stats.components, 1) << "cracks at block borders";
  EXPECT_EQ(stats.components_removed, 0);

  const float h = s.voxel_size_m;
  const float extent_m = (2 * kBlockSide - 1) * h;  // voxel centres 0 .. 15
  // The mesh covers the plane over the square [0, extent]² of x, y exactly.
  const double extent2_m2 = double{extent_m} * double{extent_m};
  EXPECT_NEAR(mesh.AreaM2(), extent2_m2 / double{s.normal.z()}, 1e-5 * extent2_m2);
  int crossing_z_border = 0;
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    const Eigen::Vector3f& p = mesh.positions[i];
    // Linear interpolation of a linear function is exact but for the voxels' storage (half a
    // step of 2^-14 of the 0.5 m band: 15 µm) and float rounding (1e-6).
    EXPECT_NEAR((p - s.point).dot(s.normal), 0.0f, 0.5f * 0.5f / Voxel::kSdfUnit + 1e-6f);
    EXPECT_NEAR(mesh.normals[i].dot(s.normal), 1.0f, 1e-5f);
    // Colour: linear in the voxel index, interpolated and rounded (±0.5, plus the inputs'
    // rounding, none here: integers).
    const Eigen::Vector3f g = p / h;
    EXPECT_NEAR(mesh.colours[i].x(), 40 + 8 * g.x(), 0.51f);
    EXPECT_NEAR(mesh.colours[i].y(), 30 + 5 * g.y(), 0.51f);
    EXPECT_NEAR(mesh.colours[i].z(), 20 + 10 * g.z(), 0.51f);
    if (g.z() > 7 && g.z() < 8) ++crossing_z_border;
  }
  EXPECT_GT(crossing_z_border, 0);
  for (const Eigen::Vector3i& f : mesh.faces) {
    const Eigen::Vector3f n = FaceNormal(mesh, f);
    if (n.norm() > 1e-10f) {
      EXPECT_GT(n.dot(s.normal), 0);
    }
  }
  // Open only along the sides of the volume.
  const auto edges = DirectedEdges(mesh);
  int boundary = 0;
  for (const auto& [edge, count] : edges) {
    EXPECT_EQ(count, 1);
    if (edges.count({edge.second, edge.first}) != 0) continue;
    ++boundary;
    const Eigen::Vector3f& a = mesh.positions[edge.first];
    const Eigen::Vector3f& b = mesh.positions[edge.second];
    const auto on_side = [&](int axis, float value) {
      return std::abs(a[axis] - value) < 1e-6f && std::abs(b[axis] - value) < 1e-6f;
    };
    EXPECT_TRUE(on_side(0, 0) || on_side(0, extent_m) || on_side(1, 0) || on_side(1, extent_m))
        << a.transpose() << " — " << b.transpose();
  }
  EXPECT_GT(boundary, 4 * 15);
}

// Big sphere and a far small one; sdf = min of both (identical to the big one's alone near it).
TsdfVolume MakeTwoSpheres(const SphereScene& big, const SphereScene& small, bool with_small, bool reverse = false) {
  TsdfVolume volume(VolumeOptions(big.voxel_size_m, big.truncation_m));
  const Eigen::Vector3f r = Eigen::Vector3f::Constant(big.radius_m);
  const auto [lo, hi] = BlocksAround((big.centre - r).cwiseMin(small.centre - r), (big.centre + r).cwiseMax(small.centre + r),
                                     big.truncation_m + 2 * big.voxel_size_m, big.voxel_size_m);
  Fill(volume, lo, hi, [&](const Eigen::Vector3i&, const Eigen::Vector3f& p) {
    const float sdf = with_small ? std::min(SphereSdf(big, p), SphereSdf(small, p)) : SphereSdf(big, p);
    return Observed(sdf);
  }, reverse);
  return volume;
}

TEST(MarchingCubesTest, FragmentRemovalDropsTheSmallSphereOnly) {
  const SphereScene big;
  SphereScene small = big;
  small.centre = big.centre + Eigen::Vector3f(0.3f, 0.05f, 0);
  small.radius_m = 0.025f;
  const TriangleMesh big_alone = ExtractMesh(MakeTwoSpheres(big, small, false), KeepAll());
  const TsdfVolume volume = MakeTwoSpheres(big, small, true);
  MeshStats stats;
  const TriangleMesh both = ExtractMesh(volume, KeepAll(), &stats);
  EXPECT_EQ(stats.components, 2);
  EXPECT_EQ(stats.components_removed, 0);
  const int small_triangles = static_cast<int>(both.faces.size() - big_alone.faces.size());
  ASSERT_GT(small_triangles, 20);
  EXPECT_EQ(OrientedManifoldViolations(both), 0);

  // By triangle count.
  MeshOptions by_count = KeepAll();
  by_count.min_component_triangles = small_triangles + 1;
  TriangleMesh kept = ExtractMesh(volume, by_count, &stats);
  EXPECT_EQ(stats.components, 2);
  EXPECT_EQ(stats.components_removed, 1);
  EXPECT_EQ(stats.triangles_removed, small_triangles);
  ExpectSameMesh(kept, big_alone);  // compacted: no vertex of the small sphere left
  // Just at the small one's count, it stays.
  by_count.min_component_triangles = small_triangles;
  EXPECT_EQ(ExtractMesh(volume, by_count, &stats).faces.size(), both.faces.size());
  EXPECT_EQ(stats.components_removed, 0);

  // By area: (0.025 / 0.1)² = 6% of the big one's.
  MeshOptions by_area = KeepAll();
  by_area.min_component_area_fraction = 0.1;
  kept = ExtractMesh(volume, by_area, &stats);
  EXPECT_EQ(stats.components_removed, 1);
  EXPECT_EQ(stats.triangles_removed, small_triangles);
  ExpectSameMesh(kept, big_alone);
  by_area.min_component_area_fraction = 0.05;
  EXPECT_EQ(ExtractMesh(volume, by_area, &stats).faces.size(), both.faces.size());
}

TEST(MarchingCubesTest, DeterministicWhateverThreadsAndInsertionOrder) {
  const SphereScene big;
  SphereScene small = big;
  small.centre = big.centre + Eigen::Vector3f(0.17f, -0.2f, 0.1f);
  small.radius_m = 0.03f;
  const TsdfVolume volume = MakeTwoSpheres(big, small, true);
  MeshOptions options = KeepAll();
  options.num_threads = 1;
  const TriangleMesh reference = ExtractMesh(volume, options);
  ASSERT_GT(reference.faces.size(), 1000u);
  for (const int threads : {2, 3, 5}) {
    options.num_threads = threads;
    SCOPED_TRACE(threads);
    ExpectSameMesh(ExtractMesh(volume, options), reference);
  }
  // Blocks created in the opposite order: another hash history, the same mesh.
  ExpectSameMesh(ExtractMesh(MakeTwoSpheres(big, small, true, /*reverse=*/true), options), reference);
}

TEST(MarchingCubesTest, MinWeightLeavesUnobservedRegionsOpen) {
  const SphereScene s;
  const Eigen::Vector3f r = Eigen::Vector3f::Constant(s.radius_m);
  const auto [lo, hi] = BlocksAround(s.centre - r, s.centre + r, s.truncation_m + 2 * s.voxel_size_m, s.voxel_size_m);
  // The top half (voxel centres above the centre) never seen, or seen once.
  const auto make = [&](float top_weight) {
    TsdfVolume volume(VolumeOptions(s.voxel_size_m, s.truncation_m));
    Fill(volume, lo, hi, [&](const Eigen::Vector3i&, const Eigen::Vector3f& p) {
      return Observed(SphereSdf(s, p), p.z() > s.centre.z() ? top_weight : 3.0f);
    });
    return volume;
  };
  MeshOptions options = KeepAll();
  const TriangleMesh unseen = ExtractMesh(make(0.0f), options);
  options.min_weight = 2;
  const TriangleMesh seen_once = ExtractMesh(make(1.0f), options);
  ExpectSameMesh(seen_once, unseen);
  ASSERT_GT(unseen.faces.size(), 500u);
  const float h = s.voxel_size_m;
  int boundary = 0;
  const auto edges = DirectedEdges(unseen);
  for (const auto& [edge, count] : edges) {
    if (edges.count({edge.second, edge.first}) == 0) ++boundary;
  }
  EXPECT_GT(boundary, 20) << "the mesh is open where the volume is unobserved";
  for (const Eigen::Vector3f& p : unseen.positions) EXPECT_LT(p.z(), s.centre.z() + h) << p.transpose();
  // Seen from every side with enough weight, it is closed again.
  options.min_weight = 1;
  EXPECT_EQ(OrientedManifoldViolations(ExtractMesh(make(1.0f), options)), 0);
}

TEST(MarchingCubesTest, EmptyVolumeGivesEmptyMesh) {
  TsdfVolume volume(VolumeOptions(0.01, 0.04));
  MeshStats stats;
  stats.components = 99;
  TriangleMesh mesh = ExtractMesh(volume, MeshOptions{}, &stats);
  EXPECT_TRUE(mesh.positions.empty());
  EXPECT_TRUE(mesh.faces.empty());
  EXPECT_EQ(stats.components, 0);
  EXPECT_EQ(mesh.AreaM2(), 0.0);
  // Observed but all free space: no surface either.
  Fill(volume, BlockKey(0, 0, 0), BlockKey(1, 0, 0), [](const Eigen::Vector3i&, const Eigen::Vector3f&) {
    return Observed(1.0f);
  });
  EXPECT_TRUE(ExtractMesh(volume, MeshOptions{}, &stats).faces.empty());
}

TEST(MarchingCubesTest, PlyRoundTrip) {
  const PlaneScene s;
  TsdfVolume volume(VolumeOptions(s.voxel_size_m, 0.5));
  Fill(volume, BlockKey(0, 0, 0), BlockKey(1, 1, 1), [&](const Eigen::Vector3i& v, const Eigen::Vector3f& p) {
    return Observed((p - s.point).dot(s.normal) / 0.5f, 1, PlaneColour(v));
  });
  const TriangleMesh mesh = ExtractMesh(volume, MeshOptions{});
  ASSERT_FALSE(mesh.faces.empty());
  const auto path = test::TestFolder() / "model.ply";
  core::WritePly(path, ToPly(mesh));
  const core::PlyMesh read = core::ReadPly(path);
  ASSERT_EQ(read.NumVertices(), mesh.positions.size());
  EXPECT_EQ(read.Get("x").type, core::PlyType::kFloat32);
  EXPECT_EQ(read.Get("nx").type, core::PlyType::kFloat32);
  EXPECT_EQ(read.Get("red").type, core::PlyType::kUInt8);
  const auto positions = read.Positions();
  const auto normals = read.Normals();
  const auto colours = read.Colors();
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    EXPECT_EQ(positions[i], mesh.positions[i].cast<double>());  // float stored exactly
    EXPECT_EQ(normals[i], mesh.normals[i].cast<double>());
    EXPECT_EQ(colours[i], mesh.colours[i]);
  }
  EXPECT_TRUE(read.faces == mesh.faces);
}

TEST(MarchingCubesTest, OptionsCheck) {
  EXPECT_EQ(MeshOptions{}.Check(), "");
  MeshOptions o;
  o.min_weight = -1;
  EXPECT_EQ(o.Check(), "min_weight: must be in [0, 65535], got -1");
  o = MeshOptions{};
  o.min_weight = std::nan("");
  EXPECT_EQ(o.Check(), "min_weight: must be in [0, 65535], got nan");
  o = MeshOptions{};
  o.min_component_triangles = -3;
  EXPECT_EQ(o.Check(), "min_component_triangles: must be >= 0, got -3");
  o = MeshOptions{};
  o.min_component_area_fraction = 1;
  EXPECT_EQ(o.Check(), "min_component_area_fraction: must be in [0, 1), got 1");
  o.min_component_area_fraction = -0.5;
  EXPECT_EQ(o.Check(), "min_component_area_fraction: must be in [0, 1), got -0.5");
  o = MeshOptions{};
  o.num_threads = -1;
  EXPECT_EQ(o.Check(), "num_threads: must be >= 0, got -1");
}

// A 1 m × 1 m wall at 5 mm voxels (~1M voxels allocated): correctness of a large mesh, and
// the time it takes (printed, not asserted; bench/ is where speed is measured).
TEST(MarchingCubesTest, WallOfAMillionVoxels) {
  const float h = 0.005f, truncation_m = 0.02f;
  TsdfVolume volume(VolumeOptions(h, truncation_m));
  const Eigen::Vector3f normal = Eigen::Vector3f(0.05f, 0.03f, 1.0f).normalized();
  const Eigen::Vector3f point(0.5f, 0.5f, 0.5f);
  const float block_m = h * kBlockSide;
  const int blocks_across = static_cast<int>(std::lround(1.0f / block_m));  // 25
  // The blocks within truncation of the wall in each column.
  int64_t voxels = 0;
  for (int by = 0; by < blocks_across; ++by) {
    for (int bx = 0; bx < blocks_across; ++bx) {
      const float x = (bx + 0.5f) * block_m, y = (by + 0.5f) * block_m;
      const float z = point.z() - (normal.x() * (x - point.x()) + normal.y() * (y - point.y())) / normal.z();
      const int z0 = static_cast<int>(std::floor((z - truncation_m - block_m) / block_m));
      const int z1 = static_cast<int>(std::floor((z + truncation_m + block_m) / block_m));
      Fill(volume, BlockKey(bx, by, z0), BlockKey(bx, by, z1), [&](const Eigen::Vector3i&, const Eigen::Vector3f& p) {
        return Observed(Clamp1((p - point).dot(normal) / truncation_m));
      });
      voxels += int64_t{z1 - z0 + 1} * kBlockVoxels;
    }
  }
  TriangleMesh mesh;
  for (const int threads : {1, 2}) {
    MeshOptions options;
    options.num_threads = threads;
    MeshStats stats;
    // The best of 3 (the machine is shared), elapsed and CPU time of the process.
    double ms = 1e9, cpu_ms = 1e9;
    for (int run = 0; run < 3; ++run) {
      const auto start = std::chrono::steady_clock::now();
      const std::clock_t cpu_start = std::clock();
      mesh = ExtractMesh(volume, options, &stats);
      cpu_ms = std::min(cpu_ms, 1e3 * static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC);
      ms = std::min(ms, std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
    }
    std::printf("wall 1 m² at 5 mm: %lld voxels in %zu blocks -> %zu vertices, %zu faces in %.1f ms (CPU %.1f ms), "
                "%d threads\n",
                static_cast<long long>(voxels), volume.NumBlocks(), mesh.positions.size(), mesh.faces.size(), ms,
                cpu_ms, threads);
    EXPECT_EQ(stats.components, 1);
  }
  // Voxel centres span 0 .. 1 − h along x and y.
  const double side_m = 1.0 - double{h};
  EXPECT_NEAR(mesh.AreaM2(), side_m * side_m / double{normal.z()}, 1e-4);
}

}  // namespace
}  // namespace hw::reconstruct
