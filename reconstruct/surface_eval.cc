#include "reconstruct/surface_eval.h"

#include <algorithm>
#include <cassert>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "reconstruct/option_check.h"
#include "reconstruct/row_bands.h"

namespace hw::reconstruct {

std::vector<std::optional<double>> PointToMeshDistances(
    const std::vector<Eigen::Vector3d>& points, const std::vector<Eigen::Vector3d>& vertices,
    const std::vector<Eigen::Vector3i>& faces, double max_distance_m) {
  assert(max_distance_m > 0);
  return PointToMeshDistances(points, TriangleGrid(vertices, faces, max_distance_m), max_distance_m);
}

std::vector<std::optional<double>> PointToMeshDistances(const std::vector<Eigen::Vector3d>& points,
                                                        const TriangleGrid& grid, double max_distance_m) {
  std::vector<std::optional<double>> out(points.size());
  // Independent queries, each writing its own element: the same result on any thread count.
  ForEachBand(static_cast<int>(points.size()), 0, [&](int begin, int end) {
    for (int i = begin; i < end; ++i) {
      if (const auto closest = grid.FindClosest(points[i], max_distance_m)) out[i] = closest->distance_m;
    }
  });
  return out;
}

SurfaceDistanceStats SummarizeDistances(const std::vector<std::optional<double>>& distances) {
  SurfaceDistanceStats s;
  s.points = static_cast<int>(distances.size());
  std::vector<double> d;
  d.reserve(distances.size());
  for (const auto& x : distances) {
    if (x) {
      d.push_back(*x);
    } else {
      ++s.beyond_search;
    }
  }
  if (d.empty()) return s;
  std::sort(d.begin(), d.end());
  const auto quantile = [&](double q) { return d[std::min(d.size() - 1, static_cast<size_t>(q * (d.size() - 1) + 0.5))]; };
  s.median_m = d.size() % 2 ? d[d.size() / 2] : 0.5 * (d[d.size() / 2 - 1] + d[d.size() / 2]);
  s.p90_m = quantile(0.9);
  s.max_m = d.back();
  double sum = 0, sum2 = 0;
  for (const double x : d) {
    sum += x;
    sum2 += x * x;
  }
  s.mean_m = sum / d.size();
  s.rms_m = std::sqrt(sum2 / d.size());
  return s;
}

std::string MeshRegistrationOptions::Check() const {
  using internal::Fail;
  if (max_points < 6) return Fail("max_points", max_points, ">= 6");
  if (max_iterations < 1) return Fail("max_iterations", max_iterations, ">= 1");
  if (!(max_distance_m > 0) || !std::isfinite(max_distance_m)) {
    return Fail("max_distance_m", max_distance_m, "> 0 m and finite");
  }
  if (!(outlier_median_ratio >= 1) || !std::isfinite(outlier_median_ratio)) {
    return Fail("outlier_median_ratio", outlier_median_ratio, ">= 1 and finite");
  }
  if (!(min_eigenvalue_ratio > 0 && min_eigenvalue_ratio < 1)) {
    return Fail("min_eigenvalue_ratio", min_eigenvalue_ratio, "in (0, 1)");
  }
  if (!(converged_m > 0) || !std::isfinite(converged_m)) return Fail("converged_m", converged_m, "> 0 m and finite");
  return "";
}

MeshRegistration RegisterToMesh(const std::vector<Eigen::Vector3d>& points, const TriangleGrid& grid,
                                const MeshRegistrationOptions& options) {
  assert(options.Check().empty());
  MeshRegistration out;
  // An evenly strided subset: model vertices come block by block, so a stride samples the
  // whole surface.
  std::vector<Eigen::Vector3d> sample;
  const size_t stride = std::max<size_t>(1, (points.size() + options.max_points - 1) / options.max_points);
  for (size_t i = 0; i < points.size(); i += stride) sample.push_back(points[i]);

  const auto& vertices = grid.vertices();
  const auto& faces = grid.faces();
  core::Rigid3d transform;
  std::vector<Eigen::Vector3d> moved(sample.size()), target(sample.size()), direction(sample.size());
  std::vector<double> distance(sample.size());
  std::vector<char> found(sample.size());
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    // Correspondences, each point on its own (in parallel; the sums below run in order).
    ForEachBand(static_cast<int>(sample.size()), 0, [&](int begin, int end) {
      for (int i = begin; i < end; ++i) {
        moved[i] = transform * sample[i];
        const auto closest = grid.FindClosest(moved[i], options.max_distance_m);
        found[i] = closest.has_value();
        if (!closest) continue;
        target[i] = closest->on_face.point;
        distance[i] = closest->distance_m;
        // The distance's gradient: towards the point from its closest mesh point; on the mesh
        // itself, the face normal (the sign does not matter to a squared residual).
        const Eigen::Vector3i& f = faces[closest->face];
        direction[i] = distance[i] > 1e-12
                           ? Eigen::Vector3d((moved[i] - target[i]) / distance[i])
                           : (vertices[f[1]] - vertices[f[0]]).cross(vertices[f[2]] - vertices[f[0]]).normalized();
      }
    });
    std::vector<double> found_distances;
    for (size_t i = 0; i < sample.size(); ++i) {
      if (found[i]) found_distances.push_back(distance[i]);
    }
    if (found_distances.size() < 6) break;
    std::nth_element(found_distances.begin(), found_distances.begin() + found_distances.size() / 2,
                     found_distances.end());
    const double gate_m = options.outlier_median_ratio * found_distances[found_distances.size() / 2];

    // Normal equations of r_i = n_i · (p_i + ω × p_i + v − q_i) in ξ = (ω, v), about the
    // centroid of the points used (a well-scaled system: rotation and translation decouple).
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    int used = 0;
    for (size_t i = 0; i < sample.size(); ++i) {
      if (found[i] && distance[i] <= gate_m) {
        centroid += moved[i];
        ++used;
      }
    }
    if (used < 6) break;
    centroid /= used;
    Eigen::Matrix<double, 6, 6> jtj = Eigen::Matrix<double, 6, 6>::Zero();
    Eigen::Matrix<double, 6, 1> jtr = Eigen::Matrix<double, 6, 1>::Zero();
    for (size_t i = 0; i < sample.size(); ++i) {
      if (!found[i] || distance[i] > gate_m) continue;
      const Eigen::Vector3d& n = direction[i];
      Eigen::Matrix<double, 6, 1> j;
      j << (moved[i] - centroid).cross(n), n;
      const double r = n.dot(moved[i] - target[i]);
      jtj += j * j.transpose();
      jtr += j * r;
    }
    // Solve in the directions the surface constrains; the others stay where they are.
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>> eigen(jtj);
    const double largest = eigen.eigenvalues().maxCoeff();
    Eigen::Matrix<double, 6, 1> xi = Eigen::Matrix<double, 6, 1>::Zero();
    int constrained = 0;
    for (int k = 0; k < 6; ++k) {
      const double lambda = eigen.eigenvalues()(k);
      if (!(lambda > options.min_eigenvalue_ratio * largest)) continue;
      ++constrained;
      const Eigen::Matrix<double, 6, 1> u = eigen.eigenvectors().col(k);
      xi -= u * (u.dot(jtr) / lambda);
    }
    const Eigen::Vector3d omega = xi.head<3>(), v = xi.tail<3>();
    const double angle = omega.norm();
    const Eigen::Quaterniond q =
        angle > 0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, omega / angle)) : Eigen::Quaterniond::Identity();
    // Rotation about the centroid, then the translation: p -> q (p − c) + c + v.
    const core::Rigid3d step(q, centroid - q * centroid + v);
    transform = step * transform;
    out.iterations = iteration + 1;
    out.correspondences = used;
    out.constrained_directions = constrained;
    // How far the step moved the points used (RMS, m): the rotation's part from their spread.
    double moved2 = 0;
    for (size_t i = 0; i < sample.size(); ++i) {
      if (found[i] && distance[i] <= gate_m) moved2 += (step * moved[i] - moved[i]).squaredNorm();
    }
    if (std::sqrt(moved2 / used) < options.converged_m) {
      out.converged = true;
      break;
    }
  }
  out.reference_from_points = transform;
  out.rotation_deg = transform.RotationAngle() * 180.0 / M_PI;
  out.translation_m = transform.TranslationNorm();
  return out;
}

}  // namespace hw::reconstruct
