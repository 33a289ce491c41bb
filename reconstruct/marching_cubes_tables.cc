#include "reconstruct/marching_cubes_tables.h"

#include <cassert>
#include <vector>

namespace hw::reconstruct::internal {
namespace {

// The six faces, corners counter-clockwise seen from outside the cube.
constexpr int kFaceCorners[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4},
                                    {3, 7, 6, 2}, {0, 4, 7, 3}, {1, 2, 6, 5}};

int EdgeBetween(int a, int b) {
  for (int e = 0; e < 12; ++e) {
    if ((kEdgeCorners[e][0] == a && kEdgeCorners[e][1] == b) ||
        (kEdgeCorners[e][0] == b && kEdgeCorners[e][1] == a)) {
      return e;
    }
  }
  assert(false && "corners not joined by an edge");
  return -1;
}

// Bit mask of the faces holding edge e.
int FacesOfEdge(int e) {
  int mask = 0;
  for (int f = 0; f < 6; ++f) {
    for (int i = 0; i < 4; ++i) {
      if (EdgeBetween(kFaceCorners[f][i], kFaceCorners[f][(i + 1) % 4]) == e) mask |= 1 << f;
    }
  }
  return mask;
}

MarchingCubesTables Build() {
  MarchingCubesTables t{};
  for (int e = 0; e < 12; ++e) {
    const int* a = kCubeCorners[kEdgeCorners[e][0]];
    const int* b = kCubeCorners[kEdgeCorners[e][1]];
    int axis = -1;
    for (int k = 0; k < 3; ++k) {
      if (a[k] != b[k]) axis = k;
      t.edge_origin[e][k] = a[k] < b[k] ? a[k] : b[k];
    }
    t.edge_axis[e] = axis;
  }
  int faces_of_edge[12];
  for (int e = 0; e < 12; ++e) faces_of_edge[e] = FacesOfEdge(e);

  for (int c = 0; c < 256; ++c) {
    const auto inside = [c](int corner) { return ((c >> corner) & 1) != 0; };
    uint16_t mask = 0;
    for (int e = 0; e < 12; ++e) {
      if (inside(kEdgeCorners[e][0]) != inside(kEdgeCorners[e][1])) mask |= 1 << e;
    }
    t.edge_mask[c] = mask;
    // next[e]: the edge the oriented segment starting at cut edge e ends at.
    int next[12];
    for (int& n : next) n = -1;
    const auto add = [&](int from, int to) {
      assert(next[from] == -1);
      next[from] = to;
    };
    for (const auto& face : kFaceCorners) {
      // Edge i of the face joins corners i and i+1 (counter-clockwise seen from outside).
      // Going from edge i−1 to edge i around corner i leaves corner i on the right.
      int in = 0;
      for (int i = 0; i < 4; ++i) in += inside(face[i]);
      for (int i = 0; i < 4; ++i) {
        const int prev_edge = EdgeBetween(face[(i + 3) % 4], face[i]);
        const int edge = EdgeBetween(face[i], face[(i + 1) % 4]);
        const bool here = inside(face[i]);
        const bool before = inside(face[(i + 3) % 4]);
        const bool after = inside(face[(i + 1) % 4]);
        if (here && !before && !after) add(prev_edge, edge);  // a lone inside corner (also both of an ambiguous face)
        if (!here && before && after && in == 3) add(edge, prev_edge);  // a lone outside corner
        if (here && after && !before && in == 2) {
          // Corners i and i+1 inside: from edge i−1 to edge i+1.
          add(prev_edge, EdgeBetween(face[(i + 1) % 4], face[(i + 2) % 4]));
        }
      }
    }
    int n = 0;
    bool used[12] = {};
    for (int start = 0; start < 12; ++start) {
      if (!((mask >> start) & 1) || used[start]) continue;
      std::vector<int> loop;
      for (int e = start; !used[e]; e = next[e]) {
        assert(e >= 0 && next[e] >= 0);
        used[e] = true;
        loop.push_back(e);
      }
      assert(loop.size() >= 3);
      // A fan apex whose diagonals all cross the interior: no two joined edges share a face.
      const int size = static_cast<int>(loop.size());
      int apex = -1;
      for (int a = 0; a < size && apex < 0; ++a) {
        bool ok = true;
        for (int k = 2; k + 1 < size; ++k) {
          if (faces_of_edge[loop[a]] & faces_of_edge[loop[(a + k) % size]]) ok = false;
        }
        if (ok) apex = a;
      }
      assert(apex >= 0 && "every loop of the 256 cases has such a vertex");
      for (int k = 1; k + 1 < size; ++k) {
        assert(n + 3 <= 15);
        t.triangles[c][n++] = static_cast<int8_t>(loop[apex]);
        t.triangles[c][n++] = static_cast<int8_t>(loop[(apex + k) % size]);
        t.triangles[c][n++] = static_cast<int8_t>(loop[(apex + k + 1) % size]);
      }
    }
    for (int i = n; i < 16; ++i) t.triangles[c][i] = -1;
  }
  return t;
}

}  // namespace

const MarchingCubesTables& GetMarchingCubesTables() {
  static const MarchingCubesTables tables = Build();
  return tables;
}

}  // namespace hw::reconstruct::internal
