#include "analyze/iso_region.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Dense>

#include "core/option_check.h"

namespace hw::analyze {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
constexpr double kTwoPi = 2 * std::numbers::pi;

// Twice the vector area of a planar polygon (fan from its first point).
Vector3d TwiceVectorArea(const ClippedPiece& piece) {
  Vector3d sum = Vector3d::Zero();
  const Vector3d& p0 = piece.points_in_world[0];
  for (int i = 1; i + 1 < piece.num_points; ++i) {
    sum += (piece.points_in_world[i] - p0).cross(piece.points_in_world[i + 1] - p0);
  }
  return sum;
}

// Area-weighted centroid of a planar polygon (fan triangles).
Vector3d PolygonCentroid(const ClippedPiece& piece) {
  Vector3d weighted = Vector3d::Zero();
  double total = 0;
  const Vector3d& p0 = piece.points_in_world[0];
  for (int i = 1; i + 1 < piece.num_points; ++i) {
    const Vector3d& p1 = piece.points_in_world[i];
    const Vector3d& p2 = piece.points_in_world[i + 1];
    const double a = (p1 - p0).cross(p2 - p0).norm();
    weighted += a * (p0 + p1 + p2) / 3;
    total += a;
  }
  return total > 0 ? Vector3d(weighted / total) : p0;
}

// Angle wrapped to [0, 2π).
double Wrap2Pi(double angle) {
  double w = std::fmod(angle, kTwoPi);
  if (w < 0) w += kTwoPi;
  return w >= kTwoPi ? 0.0 : w;
}

// The largest arc of the circle not covered by the intervals [start, start + span] (start in
// [0, 2π), span >= 0). Returns its length (0: covered all round) and its midpoint.
struct Gap {
  double length = 0;
  double middle = 0;
};
Gap LargestUncoveredArc(std::vector<std::pair<double, double>> intervals) {
  Gap best;
  if (intervals.empty()) return {kTwoPi, 0};
  std::sort(intervals.begin(), intervals.end());
  // Gaps below round-off of the angles (pieces sharing an edge, computed from either side)
  // are closed.
  constexpr double kRoundOff = 1e-9;
  double reach = intervals[0].first + intervals[0].second;
  for (size_t i = 1; i < intervals.size(); ++i) {
    const double gap = intervals[i].first - reach;
    if (gap > best.length) best = {gap, reach + gap / 2};
    reach = std::max(reach, intervals[i].first + intervals[i].second);
  }
  const double wrap_gap = intervals[0].first + kTwoPi - reach;
  if (wrap_gap > best.length) best = {wrap_gap, Wrap2Pi(reach + wrap_gap / 2)};
  if (best.length <= kRoundOff) best.length = 0;
  return best;
}

// A region flattened to 2D: one uv per point of `points`, the RMS distance of the points
// from the model, and how a direction in uv maps to the world at the region's centroid.
struct Flattening {
  std::string name;
  double rms_m = std::numeric_limits<double>::infinity();
  std::vector<Vector2d> uv;
  Vector3d u_axis_at_centroid = Vector3d::UnitX();
  Vector3d v_axis_at_centroid = Vector3d::UnitY();
  double radius_m = 0;
  double fold_angle_rad = 0;
  bool full_ring = false;
};

// What MeasureExtent needs of each piece, computed once.
struct PieceData {
  double area = 0;
  Vector3d centroid = Vector3d::Zero();
  Vector3d normal = Vector3d::UnitZ();  // of the face, unit
};

double Rms(double sum_sq, size_t n) { return n > 0 ? std::sqrt(sum_sq / static_cast<double>(n)) : 0.0; }

Flattening FlattenOnPlane(const std::vector<Vector3d>& points, const Vector3d& origin, const Vector3d& normal) {
  Flattening out;
  out.name = "plane";
  // Any orthonormal basis of the plane: the rectangle search is rotation-invariant.
  const Vector3d b1 = normal.unitOrthogonal();
  const Vector3d b2 = normal.cross(b1);
  out.uv.reserve(points.size());
  double sum_sq = 0;
  for (const Vector3d& p : points) {
    const Vector3d d = p - origin;
    out.uv.emplace_back(d.dot(b1), d.dot(b2));
    sum_sq += d.dot(normal) * d.dot(normal);
  }
  out.rms_m = Rms(sum_sq, points.size());
  out.u_axis_at_centroid = b1;
  out.v_axis_at_centroid = b2;
  return out;
}

// Cylinder near `axis_guess`: centre and radius first by least squares on
// centroid = centre + radius·normal in the cross-section (uses the normals, so it is well
// posed on a small arc, where an algebraic circle fit is not), then axis, centre and radius
// refined by Gauss–Newton on the distances of the mesh vertices among the points from the
// axis (the vertices are the surface's samples; a point inside a face lies on a chord, off
// the cylinder by up to the sagitta; all points when fewer than 5 are vertices).
Flattening FlattenOnCylinder(const std::vector<Vector3d>& points, const std::vector<char>& is_vertex,
                             const std::vector<ClippedPiece>& clipped, const std::vector<PieceData>& pieces,
                             const Vector3d& axis_guess, const Vector3d& region_centroid) {
  Flattening out;
  out.name = "cylinder";
  Vector3d axis = axis_guess.normalized();
  Vector3d b1 = axis.unitOrthogonal();
  Vector3d b2 = axis.cross(b1);
  Eigen::Matrix3d normal_matrix = Eigen::Matrix3d::Zero();
  Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
  for (const PieceData& piece : pieces) {
    Vector2d n(piece.normal.dot(b1), piece.normal.dot(b2));
    const double len = n.norm();
    if (len < 1e-9) continue;  // a face normal along the axis says nothing of the circle
    n /= len;
    const Vector2d q(piece.centroid.dot(b1), piece.centroid.dot(b2));
    // Rows [1 0 n.x] and [0 1 n.y] of the design matrix, weighted by area.
    Eigen::Matrix<double, 2, 3> a;
    a << 1, 0, n.x(), 0, 1, n.y();
    normal_matrix += piece.area * a.transpose() * a;
    rhs += piece.area * a.transpose() * q;
  }
  const Eigen::FullPivLU<Eigen::Matrix3d> lu(normal_matrix);
  if (lu.rank() < 3) return out;  // normals in one direction: no circle (rms stays infinite)
  const Eigen::Vector3d solution = lu.solve(rhs);
  Vector3d centre = solution(0) * b1 + solution(1) * b2;  // a point of the axis
  double radius = std::abs(solution(2));

  std::vector<int> fit;
  for (size_t i = 0; i < points.size(); ++i) {
    if (is_vertex[i]) fit.push_back(static_cast<int>(i));
  }
  if (fit.size() < 5) {
    fit.resize(points.size());
    for (size_t i = 0; i < points.size(); ++i) fit[i] = static_cast<int>(i);
  }
  const auto cost = [&](const Vector3d& c, const Vector3d& a, double r) {
    double sum = 0;
    for (const int i : fit) {
      const Vector3d d = points[i] - c;
      const double e = (d - d.dot(a) * a).norm() - r;
      sum += e * e;
    }
    return sum;
  };
  double current = cost(centre, axis, radius);
  for (int iteration = 0; iteration < 20 && current > 0; ++iteration) {
    // Unknowns: centre moves along b1 b2, axis tilts towards b1 b2, radius.
    Eigen::Matrix<double, 5, 5> jtj = Eigen::Matrix<double, 5, 5>::Zero();
    Eigen::Matrix<double, 5, 1> jtr = Eigen::Matrix<double, 5, 1>::Zero();
    for (const int i : fit) {
      const Vector3d d = points[i] - centre;
      const double along = d.dot(axis);
      const Vector3d w = d - along * axis;
      const double rho = w.norm();
      if (rho == 0) continue;
      const Vector3d u = w / rho;
      Eigen::Matrix<double, 5, 1> j;
      j << -u.dot(b1), -u.dot(b2), -along * u.dot(b1), -along * u.dot(b2), -1;
      jtj += j * j.transpose();
      jtr += j * (rho - radius);
    }
    const Eigen::Matrix<double, 5, 1> step = jtj.ldlt().solve(-jtr);
    if (!step.allFinite()) break;
    const Vector3d next_centre = centre + step(0) * b1 + step(1) * b2;
    const Vector3d next_axis = (axis + step(2) * b1 + step(3) * b2).normalized();
    const double next_radius = radius + step(4);
    const double next = cost(next_centre, next_axis, next_radius);
    if (!(next < current)) break;  // converged (or a step that does not help: keep the last)
    centre = next_centre;
    axis = next_axis;
    radius = next_radius;
    current = next;
    b1 = axis.unitOrthogonal();
    b2 = axis.cross(b1);
  }
  radius = std::abs(radius);

  std::vector<double> theta(points.size());
  double sum_sq = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const Vector3d d = points[i] - centre;
    const Vector3d w = d - d.dot(axis) * axis;
    theta[i] = std::atan2(w.dot(b2), w.dot(b1));
    sum_sq += (w.norm() - radius) * (w.norm() - radius);
  }
  out.rms_m = Rms(sum_sq, points.size());
  out.radius_m = radius;

  // Each piece's angular interval (a face spans far less than π around a fitted axis), then
  // the largest arc no piece covers: the cut. None: a full ring.
  std::vector<std::pair<double, double>> intervals;
  intervals.reserve(clipped.size());
  for (const ClippedPiece& piece : clipped) {
    double first = 0, lo = 0, hi = 0;
    for (int i = 0; i < piece.num_points; ++i) {
      const Vector3d d = piece.points_in_world[i] - centre;
      const double angle = std::atan2(d.dot(b2), d.dot(b1));
      if (i == 0) first = angle;
      double delta = angle - first;  // to (−π, π]: a face spans far less than π
      if (delta > std::numbers::pi) delta -= kTwoPi;
      if (delta <= -std::numbers::pi) delta += kTwoPi;
      lo = std::min(lo, delta);
      hi = std::max(hi, delta);
    }
    intervals.emplace_back(Wrap2Pi(first + lo), hi - lo);
  }
  const Gap gap = LargestUncoveredArc(std::move(intervals));
  out.full_ring = gap.length == 0;
  const double cut = out.full_ring ? 0.0 : gap.middle;
  out.uv.resize(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    out.uv[i] = Vector2d(radius * Wrap2Pi(theta[i] - cut), (points[i] - centre).dot(axis));
  }
  // The tangent at the centroid's angle (on the axis for a full ring: any angle will do).
  const Vector3d c = region_centroid - centre;
  const Vector3d w = c - c.dot(axis) * axis;
  const double theta_c = w.norm() > 1e-12 * radius ? std::atan2(w.dot(b2), w.dot(b1)) : 0.0;
  out.u_axis_at_centroid = -std::sin(theta_c) * b1 + std::cos(theta_c) * b2;
  out.v_axis_at_centroid = axis;
  return out;
}

// Two planes whose normals are the two clusters of the face normals' angles around `axis`,
// unfolded about their intersection line.
Flattening FlattenOnFold(const std::vector<Vector3d>& points, const std::vector<PieceData>& pieces,
                         const std::vector<int>& piece_of_point, const Vector3d& axis,
                         const Vector3d& region_centroid) {
  Flattening out;
  out.name = "fold";
  const Vector3d b1 = axis.unitOrthogonal();
  const Vector3d b2 = axis.cross(b1);
  const size_t n = pieces.size();
  if (n < 2) return out;
  // Normal angles around the axis, sorted once, then read from just after their largest gap
  // so the two clusters are intervals of that order.
  std::vector<std::pair<double, int>> sorted(n);
  for (size_t k = 0; k < n; ++k) {
    sorted[k] = {Wrap2Pi(std::atan2(pieces[k].normal.dot(b2), pieces[k].normal.dot(b1))), static_cast<int>(k)};
  }
  std::sort(sorted.begin(), sorted.end());
  size_t first = 0;
  double largest_gap = sorted[0].first + kTwoPi - sorted[n - 1].first;
  for (size_t i = 1; i < n; ++i) {
    if (sorted[i].first - sorted[i - 1].first > largest_gap) {
      largest_gap = sorted[i].first - sorted[i - 1].first;
      first = i;
    }
  }
  std::vector<double> phi(n);  // per piece, from the start of the order: increasing along it
  std::vector<int> order(n);
  for (size_t i = 0; i < n; ++i) {
    const auto& [angle, k] = sorted[(first + i) % n];
    order[i] = k;
    phi[k] = Wrap2Pi(angle - sorted[first].first);
  }
  // Optimal 1D 2-means by prefix sums: split minimising the within-cluster weighted variance.
  double w_total = 0, s_total = 0, q_total = 0;
  for (int k : order) {
    w_total += pieces[k].area;
    s_total += pieces[k].area * phi[k];
    q_total += pieces[k].area * phi[k] * phi[k];
  }
  double w = 0, s = 0, q = 0, best_cost = std::numeric_limits<double>::infinity();
  size_t best_split = 0;
  for (size_t i = 0; i + 1 < n; ++i) {
    const int k = order[i];
    w += pieces[k].area;
    s += pieces[k].area * phi[k];
    q += pieces[k].area * phi[k] * phi[k];
    if (phi[order[i + 1]] <= phi[k] || w <= 0 || w_total - w <= 0) continue;
    const double cost = (q - s * s / w) + ((q_total - q) - (s_total - s) * (s_total - s) / (w_total - w));
    if (cost < best_cost) {
      best_cost = cost;
      best_split = i + 1;
    }
  }
  if (best_split == 0) return out;  // one normal direction: no fold
  std::vector<int> side(n);
  for (size_t i = 0; i < n; ++i) side[order[i]] = i < best_split ? 0 : 1;

  // One plane per cluster: mean normal, offset through the area-weighted centroid.
  std::array<Vector3d, 2> normal{Vector3d::Zero(), Vector3d::Zero()};
  std::array<Vector3d, 2> centroid{Vector3d::Zero(), Vector3d::Zero()};
  std::array<double, 2> area{0, 0};
  for (size_t k = 0; k < n; ++k) {
    normal[side[k]] += pieces[k].area * pieces[k].normal;
    centroid[side[k]] += pieces[k].area * pieces[k].centroid;
    area[side[k]] += pieces[k].area;
  }
  for (int c = 0; c < 2; ++c) {
    if (area[c] <= 0 || normal[c].norm() == 0) return out;
    normal[c].normalize();
    centroid[c] /= area[c];
  }
  Vector3d crease = normal[0].cross(normal[1]);
  if (crease.norm() < 1e-9) return out;  // parallel planes: no crease
  crease.normalize();
  Eigen::Matrix3d m;
  m.row(0) = normal[0];
  m.row(1) = normal[1];
  m.row(2) = crease;
  const Vector3d on_crease =
      m.inverse() * Vector3d(normal[0].dot(centroid[0]), normal[1].dot(centroid[1]), crease.dot(region_centroid));
  // In-plane direction away from the crease, towards the cluster's own part.
  std::array<Vector3d, 2> away;
  for (int c = 0; c < 2; ++c) {
    away[c] = crease.cross(normal[c]).normalized();
    if ((centroid[c] - on_crease).dot(away[c]) < 0) away[c] = -away[c];
  }
  out.uv.resize(points.size());
  double sum_sq = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    const int c = side[piece_of_point[i]];
    const Vector3d d = points[i] - on_crease;
    // Side 0 unrolled to v > 0, side 1 to v < 0: the plane of side 1 rotated onto side 0's.
    out.uv[i] = Vector2d(d.dot(crease), c == 0 ? d.dot(away[0]) : -d.dot(away[1]));
    const double e = (points[i] - centroid[c]).dot(normal[c]);
    sum_sq += e * e;
  }
  out.rms_m = Rms(sum_sq, points.size());
  out.fold_angle_rad = std::acos(std::clamp(normal[0].dot(normal[1]), -1.0, 1.0));
  const bool centroid_on_side0 = (region_centroid - on_crease).dot(away[0]) >= (region_centroid - on_crease).dot(away[1]);
  out.u_axis_at_centroid = crease;
  out.v_axis_at_centroid = centroid_on_side0 ? away[0] : Vector3d(-away[1]);
  return out;
}

double Cross2(const Vector2d& o, const Vector2d& a, const Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

}  // namespace

IsoRegion ClipToLevel(const ThermalMesh& mesh, const std::vector<double>& field, const std::vector<int>& faces,
                      double level, bool above) {
  assert(field.size() == mesh.points_in_world.size());
  assert(std::isfinite(level));
  IsoRegion region;
  region.pieces.reserve(faces.size());
  region.faces.reserve(faces.size());
  const double sign = above ? 1.0 : -1.0;
  Vector3d weighted_centroid = Vector3d::Zero();
  Vector3d weighted_normal = Vector3d::Zero();
  for (const int f : faces) {
    assert(f >= 0 && f < mesh.NumFaces());
    const Eigen::Vector3i& tri = mesh.faces[f];
    std::array<Vector3d, 3> p;
    std::array<double, 3> s;  // signed distance to the level in field units, >= 0 inside
    std::array<double, 3> v;
    bool unobserved = false;
    for (int k = 0; k < 3; ++k) {
      p[k] = mesh.points_in_world[tri[k]];
      v[k] = field[tri[k]];
      unobserved |= !std::isfinite(v[k]);
      s[k] = sign * (v[k] - level);
    }
    if (unobserved) {
      ++region.faces_skipped_unobserved;
      continue;
    }
    // Sutherland–Hodgman against one half-plane: a triangle gives at most 4 points. Vertices
    // at the level are inside and are their own crossing (no duplicate points).
    ClippedPiece piece;
    piece.face = f;
    std::array<Vector3d, 3> zero_set;  // the iso-line's points in this face
    int num_zero = 0;
    for (int k = 0; k < 3; ++k) {
      const int k1 = (k + 1) % 3;
      if (s[k] >= 0) piece.points_in_world[piece.num_points++] = p[k];
      if (s[k] == 0) zero_set[num_zero++] = p[k];
      if (s[k] * s[k1] < 0) {
        const Vector3d x = p[k] + (s[k] / (s[k] - s[k1])) * (p[k1] - p[k]);
        piece.points_in_world[piece.num_points++] = x;
        zero_set[num_zero++] = x;
      }
    }
    const Vector3d face_cross = (p[1] - p[0]).cross(p[2] - p[0]);
    const double twice_face_area = face_cross.norm();
    const bool any_outside = s[0] < 0 || s[1] < 0 || s[2] < 0;
    if (any_outside && num_zero == 2 && zero_set[0] != zero_set[1] && twice_face_area > 0) {
      // ∇v for v linear on the triangle: ((v1−v0)(e2×n) + (v2−v0)(n×e1)) / 2A.
      const Vector3d n = face_cross / twice_face_area;
      const Vector3d gradient =
          ((v[1] - v[0]) * (p[2] - p[0]).cross(n) + (v[2] - v[0]) * n.cross(p[1] - p[0])) / twice_face_area;
      IsoSegment segment;
      segment.a_in_world = zero_set[0];
      segment.b_in_world = zero_set[1];
      segment.gradient_k_per_m = gradient.norm();
      segment.face = f;
      region.perimeter_m += (segment.b_in_world - segment.a_in_world).norm();
      region.boundary.push_back(segment);
    }
    if (piece.num_points < 3) continue;
    const double area = 0.5 * TwiceVectorArea(piece).norm();
    if (!(area > 0)) continue;
    region.area_m2 += area;
    weighted_centroid += area * PolygonCentroid(piece);
    if (twice_face_area > 0) weighted_normal += area * face_cross / twice_face_area;
    region.faces.push_back(f);
    region.pieces.push_back(piece);
  }
  if (region.area_m2 > 0) region.centroid_in_world = weighted_centroid / region.area_m2;
  if (weighted_normal.norm() > 0) region.normal_in_world = weighted_normal.normalized();
  return region;
}

std::string ExtentOptions::Check() const {
  if (!(max_plane_distortion > 0 && max_plane_distortion <= 0.5)) {
    return core::OptionFail("max_plane_distortion", max_plane_distortion, "in (0, 0.5]");
  }
  if (!(min_curved_residual_gain >= 1 && std::isfinite(min_curved_residual_gain))) {
    return core::OptionFail("min_curved_residual_gain", min_curved_residual_gain, ">= 1 and finite");
  }
  return "";
}

std::vector<Vector2d> ConvexHull2d(const std::vector<Vector2d>& points) {
  if (points.empty()) return {};
  // Akl–Toussaint: drop the points strictly inside the octagon of the extreme points in 8
  // directions, which is most of them for a filled region (the sort is the cost).
  std::array<int, 8> extreme{};
  const auto key = [](const Vector2d& p, int dir) {
    switch (dir) {
      case 0: return -p.y();           // bottom
      case 1: return p.x() - p.y();    // bottom-right
      case 2: return p.x();            // right
      case 3: return p.x() + p.y();    // top-right
      case 4: return p.y();            // top
      case 5: return p.y() - p.x();    // top-left
      case 6: return -p.x();           // left
      default: return -p.x() - p.y();  // bottom-left
    }
  };
  for (int dir = 0; dir < 8; ++dir) {
    for (size_t i = 1; i < points.size(); ++i) {
      if (key(points[i], dir) > key(points[extreme[dir]], dir)) extreme[dir] = static_cast<int>(i);
    }
  }
  std::vector<Vector2d> octagon;
  for (int dir = 0; dir < 8; ++dir) {
    const Vector2d& p = points[extreme[dir]];
    if (octagon.empty() || (p != octagon.back() && p != octagon.front())) octagon.push_back(p);
  }
  std::vector<Vector2d> candidates;
  if (octagon.size() >= 3) {
    candidates.reserve(points.size() / 4 + 8);
    for (const Vector2d& p : points) {
      bool inside = true;
      for (size_t i = 0; i < octagon.size() && inside; ++i) {
        inside = Cross2(octagon[i], octagon[(i + 1) % octagon.size()], p) > 0;
      }
      if (!inside) candidates.push_back(p);
    }
  } else {
    candidates = points;
  }
  // Andrew's monotone chain.
  std::sort(candidates.begin(), candidates.end(),
            [](const Vector2d& a, const Vector2d& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
  candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
  if (candidates.size() < 3) return candidates;
  std::vector<Vector2d> hull(2 * candidates.size());
  size_t k = 0;
  for (const Vector2d& p : candidates) {
    while (k >= 2 && Cross2(hull[k - 2], hull[k - 1], p) <= 0) --k;
    hull[k++] = p;
  }
  for (size_t i = candidates.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && Cross2(hull[k - 2], hull[k - 1], candidates[i]) <= 0) --k;
    hull[k++] = candidates[i];
  }
  hull.resize(k - 1);
  return hull;
}

Rectangle2d MinAreaRectangle(const std::vector<Vector2d>& hull) {
  Rectangle2d best;
  const size_t n = hull.size();
  if (n < 2) return best;
  if (n == 2) {
    best.length = (hull[1] - hull[0]).norm();
    if (best.length > 0) best.length_axis = (hull[1] - hull[0]) / best.length;
    return best;
  }
  // For edge i: the farthest point along the edge (j), from it (k), and back along it (l);
  // all three only move forward as the edge turns counter-clockwise.
  size_t j = 0, k = 0, l = 0;
  double best_area = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < n; ++i) {
    const Vector2d e = (hull[(i + 1) % n] - hull[i]).normalized();
    const Vector2d normal(-e.y(), e.x());  // into the polygon
    const auto along = [&](size_t m) { return (hull[m % n] - hull[i]).dot(e); };
    const auto height = [&](size_t m) { return (hull[m % n] - hull[i]).dot(normal); };
    if (i == 0) {
      for (size_t m = 1; m < n; ++m) {
        if (along(m) > along(j)) j = m;
        if (height(m) > height(k)) k = m;
        if (along(m) < along(l)) l = m;
      }
    } else {
      for (size_t steps = 0; steps < n && along(j + 1) >= along(j); ++steps) j = (j + 1) % n;
      for (size_t steps = 0; steps < n && height(k + 1) >= height(k); ++steps) k = (k + 1) % n;
      for (size_t steps = 0; steps < n && along(l + 1) <= along(l); ++steps) l = (l + 1) % n;
    }
    const double side_along = along(j) - along(l);
    const double side_across = height(k);
    if (side_along * side_across < best_area) {
      best_area = side_along * side_across;
      best.length = std::max(side_along, side_across);
      best.width = std::min(side_along, side_across);
      best.length_axis = side_along >= side_across ? e : normal;
    }
  }
  return best;
}

Extent MeasureExtent(const IsoRegion& region, const ThermalMesh& mesh, const ExtentOptions& options) {
  assert(options.Check().empty());
  Extent extent;
  if (region.pieces.empty()) return extent;

  std::vector<PieceData> pieces(region.pieces.size());
  std::vector<Vector3d> points;
  std::vector<int> piece_of_point;
  std::vector<char> is_vertex;
  std::vector<char> vertex_seen(mesh.points_in_world.size(), 0);
  points.reserve(2 * pieces.size());
  piece_of_point.reserve(2 * pieces.size());
  Eigen::Matrix3d moment = Eigen::Matrix3d::Zero();
  double total_area = 0;
  for (size_t k = 0; k < pieces.size(); ++k) {
    const ClippedPiece& piece = region.pieces[k];
    assert(piece.face >= 0 && piece.face < mesh.NumFaces());
    const Eigen::Vector3i& tri = mesh.faces[piece.face];
    const Vector3d& p0 = mesh.points_in_world[tri[0]];
    const Vector3d face_cross = (mesh.points_in_world[tri[1]] - p0).cross(mesh.points_in_world[tri[2]] - p0);
    PieceData& data = pieces[k];
    data.area = 0.5 * TwiceVectorArea(piece).norm();
    data.centroid = PolygonCentroid(piece);
    if (face_cross.norm() > 0) data.normal = face_cross.normalized();
    for (int i = 0; i < piece.num_points; ++i) {
      // A mesh vertex is in up to ~6 pieces: once is enough for the hull and the fits.
      const Vector3d& p = piece.points_in_world[i];
      int vertex = -1;
      for (int c = 0; c < 3; ++c) {
        if (p == mesh.points_in_world[tri[c]]) vertex = tri[c];
      }
      if (vertex >= 0) {
        if (vertex_seen[vertex]) continue;
        vertex_seen[vertex] = 1;
      }
      points.push_back(p);
      is_vertex.push_back(vertex >= 0 ? 1 : 0);
      piece_of_point.push_back(static_cast<int>(k));
    }
    moment += data.area * data.normal * data.normal.transpose();
    total_area += data.area;
  }
  if (total_area > 0) moment /= total_area;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(moment);  // ascending eigenvalues
  const Vector3d lambda = eigen.eigenvalues();
  const Vector3d least_present = eigen.eigenvectors().col(0);
  const double distortion = (lambda(1) - lambda(0)) / 2;

  Flattening chosen = FlattenOnPlane(points, region.centroid_in_world, region.normal_in_world);
  if (distortion > options.max_plane_distortion) {
    Flattening cylinder = FlattenOnCylinder(points, is_vertex, region.pieces, pieces, least_present, region.centroid_in_world);
    Flattening fold = FlattenOnFold(points, pieces, piece_of_point, least_present, region.centroid_in_world);
    Flattening& curved = fold.rms_m < cylinder.rms_m ? fold : cylinder;
    if (std::isfinite(curved.rms_m) && curved.rms_m * options.min_curved_residual_gain < chosen.rms_m) {
      chosen = std::move(curved);
    }
  }
  extent.unrolling = chosen.name;
  extent.unroll_error_m = chosen.rms_m;
  extent.radius_m = chosen.radius_m;
  extent.fold_angle_rad = chosen.fold_angle_rad;
  extent.full_ring = chosen.full_ring;

  Rectangle2d rectangle;
  if (chosen.full_ring) {
    // No cut: the ring's sides are its circumference and its axial extent.
    double v_min = std::numeric_limits<double>::infinity(), v_max = -v_min;
    for (const Vector2d& uv : chosen.uv) {
      v_min = std::min(v_min, uv.y());
      v_max = std::max(v_max, uv.y());
    }
    const double circumference = kTwoPi * chosen.radius_m;
    const double axial = v_max - v_min;
    rectangle.length = std::max(circumference, axial);
    rectangle.width = std::min(circumference, axial);
    rectangle.length_axis = circumference >= axial ? Vector2d::UnitX() : Vector2d::UnitY();
  } else {
    rectangle = MinAreaRectangle(ConvexHull2d(chosen.uv));
  }
  extent.length_m = rectangle.length;
  extent.width_m = rectangle.width;
  const Vector3d axis =
      rectangle.length_axis.x() * chosen.u_axis_at_centroid + rectangle.length_axis.y() * chosen.v_axis_at_centroid;
  if (axis.norm() > 0) extent.length_axis_in_world = axis.normalized();
  return extent;
}

}  // namespace hw::analyze
