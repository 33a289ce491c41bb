#include "analyze/align.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <unordered_map>
#include <stdexcept>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

#include "analyze/point_index.h"
#include "core/option_check.h"

namespace hw::analyze {
namespace {

using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Vector6d = Eigen::Matrix<double, 6, 1>;

constexpr double kPi = 3.14159265358979323846;
constexpr int kChunk = 1024;  // samples per parallel chunk
// Cell edge of the covariance's clusters, in mean mesh edges (see Covariance).
constexpr double kClusterEdges = 4;

struct Sample {
  Eigen::Vector3d point;   // on BEFORE's surface, BEFORE's frame
  Eigen::Vector3d normal;  // the face's, unit
};

// `count` points uniformly distributed by area over the mesh's faces.
std::vector<Sample> SampleSurface(const ThermalMesh& mesh, int count, unsigned seed) {
  std::vector<double> cumulative(static_cast<size_t>(mesh.NumFaces()));
  double total = 0;
  for (int f = 0; f < mesh.NumFaces(); ++f) cumulative[static_cast<size_t>(f)] = total += mesh.FaceArea(f);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::vector<Sample> samples;
  samples.reserve(static_cast<size_t>(count));
  for (int i = 0; i < count; ++i) {
    const double pick = uniform(rng) * total;
    const size_t f = std::min(static_cast<size_t>(std::upper_bound(cumulative.begin(), cumulative.end(), pick) -
                                                  cumulative.begin()),
                              cumulative.size() - 1);
    const Eigen::Vector3i& t = mesh.faces[f];
    const Eigen::Vector3d& a = mesh.points_in_world[static_cast<size_t>(t[0])];
    const Eigen::Vector3d& b = mesh.points_in_world[static_cast<size_t>(t[1])];
    const Eigen::Vector3d& c = mesh.points_in_world[static_cast<size_t>(t[2])];
    // Uniform on the triangle: sqrt of one uniform for the distance from a.
    const double r1 = std::sqrt(uniform(rng));
    const double r2 = uniform(rng);
    samples.push_back({(1 - r1) * a + r1 * (1 - r2) * b + r1 * r2 * c, (b - a).cross(c - a).normalized()});
  }
  return samples;
}

// Area-weighted centroid and covariance of the surface (exact per triangle:
// ∫ x xᵀ dA = A/12 (a aᵀ + b bᵀ + c cᵀ + s sᵀ), s = a + b + c).
void SurfaceMoments(const ThermalMesh& mesh, Eigen::Vector3d* centroid, Eigen::Matrix3d* covariance) {
  double area = 0;
  Eigen::Vector3d first = Eigen::Vector3d::Zero();
  Eigen::Matrix3d second = Eigen::Matrix3d::Zero();
  // About the first vertex, so far-away coordinates do not cancel catastrophically.
  const Eigen::Vector3d origin = mesh.points_in_world[static_cast<size_t>(mesh.faces[0][0])];
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const Eigen::Vector3i& t = mesh.faces[static_cast<size_t>(f)];
    const Eigen::Vector3d a = mesh.points_in_world[static_cast<size_t>(t[0])] - origin;
    const Eigen::Vector3d b = mesh.points_in_world[static_cast<size_t>(t[1])] - origin;
    const Eigen::Vector3d c = mesh.points_in_world[static_cast<size_t>(t[2])] - origin;
    const double A = mesh.FaceArea(f);
    const Eigen::Vector3d s = a + b + c;
    area += A;
    first += A * s / 3;
    second += A / 12 * (a * a.transpose() + b * b.transpose() + c * c.transpose() + s * s.transpose());
  }
  const Eigen::Vector3d mean = first / area;
  *centroid = origin + mean;
  *covariance = second / area - mean * mean.transpose();
}

// AFTER's vertices that lie on an open boundary (an edge of one face, after joining
// coincident vertices): a sample matched there most likely has no counterpart in AFTER.
std::vector<char> BoundaryVertices(const ThermalMesh& mesh) {
  const std::vector<int> weld = WeldMap(mesh.points_in_world);
  std::vector<uint64_t> edges;  // (low, high) welded vertex pairs, one per face side
  edges.reserve(3 * mesh.faces.size());
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int e = 0; e < 3; ++e) {
      const auto u = static_cast<uint32_t>(weld[static_cast<size_t>(f[e])]);
      const auto v = static_cast<uint32_t>(weld[static_cast<size_t>(f[(e + 1) % 3])]);
      if (u != v) edges.push_back(static_cast<uint64_t>(std::min(u, v)) << 32 | std::max(u, v));
    }
  }
  std::sort(edges.begin(), edges.end());
  std::vector<char> group_on_boundary(weld.size(), 0);
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    if (j - i == 1) {
      group_on_boundary[static_cast<size_t>(edges[i] >> 32)] = 1;
      group_on_boundary[static_cast<size_t>(edges[i] & 0xffffffffu)] = 1;
    }
    i = j;
  }
  std::vector<char> on_boundary(weld.size(), 0);
  for (size_t v = 0; v < weld.size(); ++v) on_boundary[v] = group_on_boundary[static_cast<size_t>(weld[v])];
  return on_boundary;
}

struct Target {
  const ThermalMesh& mesh;
  const PointIndex& index;
  const std::vector<char>& on_boundary;
  Eigen::Vector3d pivot;  // the linearisation point, AFTER's frame (its centroid)
};

struct Gate {
  double distance_m;
  double tukey_m;
  double cos_normal;
};

// The normal equations of one ICP step: the correction x = (ω, δ) about the pivot.
struct System {
  Matrix6d H = Matrix6d::Zero();
  Vector6d g = Vector6d::Zero();
  double sum_w = 0;
  double sum_w_r2 = 0;
  double sum_r2 = 0;
  int inliers = 0;
  void Add(const System& o) {
    H += o.H;
    g += o.g;
    sum_w += o.sum_w;
    sum_w_r2 += o.sum_w_r2;
    sum_r2 += o.sum_r2;
    inliers += o.inliers;
  }
};

// A sample's contribution w·r·J to the gradient, with where it lies (AFTER's frame).
struct Term {
  Eigen::Vector3d point;
  Vector6d gradient;
};

// The normal equations at a pose; with `terms`, also every inlier's gradient term.
System Accumulate(const std::vector<Sample>& samples, const Eigen::Isometry3d& after_from_before,
                  const Target& target, const Gate& gate, int threads, std::vector<Term>* terms = nullptr) {
  const int chunks = static_cast<int>((samples.size() + kChunk - 1) / kChunk);
  std::vector<System> parts(static_cast<size_t>(chunks));
  std::vector<std::vector<Term>> part_terms(terms != nullptr ? static_cast<size_t>(chunks) : 0);
  const double gate2 = gate.distance_m * gate.distance_m;
  ParallelChunks(chunks, threads, [&](int chunk) {
    System& s = parts[static_cast<size_t>(chunk)];
    const size_t end = std::min(samples.size(), static_cast<size_t>(chunk + 1) * kChunk);
    for (size_t i = static_cast<size_t>(chunk) * kChunk; i < end; ++i) {
      const Eigen::Vector3d q = after_from_before * samples[i].point;
      double d2 = 0;
      const int v = target.index.Nearest(q, &d2);
      if (v < 0 || d2 > gate2 || target.on_boundary[static_cast<size_t>(v)]) continue;
      const Eigen::Vector3d& n = target.mesh.normals[static_cast<size_t>(v)];
      if (n.dot(after_from_before.linear() * samples[i].normal) < gate.cos_normal) continue;
      const double r = n.dot(q - target.mesh.points_in_world[static_cast<size_t>(v)]);
      const double u = r / gate.tukey_m;
      if (std::abs(u) >= 1) continue;
      const double w = (1 - u * u) * (1 - u * u);
      Vector6d J;
      J << (q - target.pivot).cross(n), n;
      s.H.selfadjointView<Eigen::Lower>().rankUpdate(J, w);
      s.g += w * r * J;
      if (terms != nullptr) part_terms[static_cast<size_t>(chunk)].push_back({q, w * r * J});
      s.sum_w += w;
      s.sum_w_r2 += w * r * r;
      s.sum_r2 += r * r;
      ++s.inliers;
    }
  });
  System total;
  for (const System& p : parts) total.Add(p);
  if (terms != nullptr) {
    terms->clear();
    for (const std::vector<Term>& t : part_terms) terms->insert(terms->end(), t.begin(), t.end());
  }
  total.H = total.H.selfadjointView<Eigen::Lower>();
  return total;
}

// Solves H x = −g in the directions the geometry constrains (relative eigenvalue above
// 1e-10); zero along the others.
Vector6d Solve(const System& s) {
  Eigen::SelfAdjointEigenSolver<Matrix6d> eig(s.H);
  const double top = eig.eigenvalues().maxCoeff();
  Vector6d x = Vector6d::Zero();
  if (!(top > 0)) return x;
  for (int k = 0; k < 6; ++k) {
    const double lambda = eig.eigenvalues()[k];
    if (lambda > 1e-10 * top) x -= eig.eigenvectors().col(k) * (eig.eigenvectors().col(k).dot(s.g) / lambda);
  }
  return x;
}

// [exp(ω) | δ] about the pivot, applied on the left.
Eigen::Isometry3d Correction(const Vector6d& x, const Eigen::Vector3d& pivot) {
  const Eigen::Vector3d omega = x.head<3>();
  const double angle = omega.norm();
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  if (angle > 0) R = Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = pivot - R * pivot + x.tail<3>();
  return T;
}

struct IcpResult {
  Eigen::Isometry3d after_from_before;
  int iterations = 0;
  bool converged = false;
};

// ICP iterations; the gate for iteration k comes from gate_at(k).
template <class GateAt>
IcpResult Icp(const std::vector<Sample>& samples, Eigen::Isometry3d start, const Target& target, int iterations,
              const GateAt& gate_at, const AlignOptions& options) {
  IcpResult result{start, 0, false};
  for (int k = 0; k < iterations; ++k) {
    const System s = Accumulate(samples, result.after_from_before, target, gate_at(k), options.threads);
    result.iterations = k + 1;
    if (s.inliers < 6) break;
    const Vector6d x = Solve(s);
    result.after_from_before = Correction(x, target.pivot) * result.after_from_before;
    if (x.head<3>().norm() < options.rotation_tolerance_rad && x.tail<3>().norm() < options.translation_tolerance_m) {
      result.converged = true;
      break;
    }
  }
  return result;
}

double MeanEdge(const ThermalMesh& mesh) {
  double sum = 0;
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int e = 0; e < 3; ++e) {
      sum += (mesh.points_in_world[static_cast<size_t>(f[e])] - mesh.points_in_world[static_cast<size_t>(f[(e + 1) % 3])])
                 .norm();
    }
  }
  return sum / (3.0 * static_cast<double>(mesh.faces.size()));
}

// The covariance of the pose from the final normal equations, as a cluster-robust
// ("sandwich") estimate H⁻¹ B H⁻¹, B = Σ_cells g_c g_cᵀ · C/(C − 1), g_c the summed gradient
// terms of the samples in a cubic cell of edge cell_m. Samples closer than the meshes' vertex
// spacing share vertex noise (the same BEFORE triangle, the same nearest AFTER vertex), so
// σ² H⁻¹, which takes every sample as independent, is too small (by ≈ 1.8× in σ on the
// test scene); summing within cells a few edges wide keeps those correlations.
// Then moved from the pivot to AFTER's origin: δ_origin = δ_pivot + pivot × ω.
// +Inf on the diagonal when H leaves a direction unconstrained.
Matrix6d Covariance(const System& s, const std::vector<Term>& terms, const Eigen::Vector3d& pivot, double cell_m) {
  Matrix6d covariance = Matrix6d::Zero();
  Eigen::SelfAdjointEigenSolver<Matrix6d> eig(s.H);
  const double top = eig.eigenvalues().maxCoeff();
  if (!(s.inliers > 6 && top > 0 && eig.eigenvalues().minCoeff() > 1e-10 * top)) {
    covariance.diagonal().setConstant(std::numeric_limits<double>::infinity());
    return covariance;
  }
  std::unordered_map<uint64_t, Vector6d> cells;
  for (const Term& t : terms) {
    const Eigen::Vector3d c = ((t.point - pivot) / cell_m).array().floor();
    // 21 bits per axis: cells are unique within ±10⁶ cells of the pivot, far beyond a scan.
    uint64_t key = 0;
    for (int k = 0; k < 3; ++k) key = key << 21 | (static_cast<uint64_t>(static_cast<int64_t>(c[k]) + (1 << 20)) & 0x1fffff);
    auto [it, fresh] = cells.try_emplace(key, Vector6d::Zero());
    it->second += t.gradient;
  }
  Matrix6d B = Matrix6d::Zero();
  for (const auto& [key, g] : cells) B += g * g.transpose();
  const double n = static_cast<double>(cells.size());
  if (n > 1) B *= n / (n - 1);
  const Matrix6d H_inverse = eig.eigenvectors() * eig.eigenvalues().cwiseInverse().asDiagonal() * eig.eigenvectors().transpose();
  const Matrix6d about_pivot = H_inverse * B * H_inverse;
  Matrix6d to_origin = Matrix6d::Identity();
  to_origin.block<3, 3>(3, 0) << 0, -pivot.z(), pivot.y(), pivot.z(), 0, -pivot.x(), -pivot.y(), pivot.x(), 0;
  covariance = to_origin * about_pivot * to_origin.transpose();
  return covariance;
}

}  // namespace

std::string AlignOptions::Check() const {
  using core::InRange;
  using core::OptionFail;
  if (!InRange(samples, 100, 1e7)) return OptionFail("samples", samples, "in [100, 1e7]");
  if (!InRange(coarse_samples, 100, samples)) return OptionFail("coarse_samples", coarse_samples, "in [100, samples]");
  if (!InRange(coarse_iterations, 1, 1000)) return OptionFail("coarse_iterations", coarse_iterations, "in [1, 1000]");
  if (!InRange(max_iterations, 1, 10000)) return OptionFail("max_iterations", max_iterations, "in [1, 10000]");
  if (!(max_correspondence_distance_m > 0 && max_correspondence_distance_m <= 100)) {
    return OptionFail("max_correspondence_distance_m", max_correspondence_distance_m, "in (0, 100]");
  }
  if (!InRange(coarse_correspondence_distance_m, max_correspondence_distance_m, 1000)) {
    return OptionFail("coarse_correspondence_distance_m", coarse_correspondence_distance_m,
                      "in [max_correspondence_distance_m, 1000]");
  }
  if (!(robust_loss_scale_m > 0 && robust_loss_scale_m <= 100)) {
    return OptionFail("robust_loss_scale_m", robust_loss_scale_m, "in (0, 100]");
  }
  if (!InRange(max_normal_angle_deg, 1, 180)) return OptionFail("max_normal_angle_deg", max_normal_angle_deg, "in [1, 180]");
  if (!(rotation_tolerance_rad > 0 && rotation_tolerance_rad <= 1)) {
    return OptionFail("rotation_tolerance_rad", rotation_tolerance_rad, "in (0, 1]");
  }
  if (!(translation_tolerance_m > 0 && translation_tolerance_m <= 1)) {
    return OptionFail("translation_tolerance_m", translation_tolerance_m, "in (0, 1]");
  }
  if (!InRange(threads, 0, 256)) return OptionFail("threads", threads, "in [0, 256]");
  return "";
}

Alignment AlignMeshes(const ThermalMesh& before, const ThermalMesh& after, const AlignOptions& options) {
  if (const std::string bad = options.Check(); !bad.empty()) throw std::invalid_argument(bad);
  assert(before.NumFaces() > 0 && after.NumFaces() > 0);  // MakeThermalMesh guarantees it

  std::vector<int> used;  // AFTER vertices some face uses (a normal)
  for (int v = 0; v < after.NumVertices(); ++v) {
    if (after.normals[static_cast<size_t>(v)].squaredNorm() > 0) used.push_back(v);
  }
  const PointIndex index(after.points_in_world, used);
  const std::vector<char> on_boundary = BoundaryVertices(after);
  Eigen::Vector3d centroid_before, centroid_after;
  Eigen::Matrix3d cov_before, cov_after;
  SurfaceMoments(before, &centroid_before, &cov_before);
  SurfaceMoments(after, &centroid_after, &cov_after);
  const Target target{after, index, on_boundary, centroid_after};

  const double cos_normal = std::cos(options.max_normal_angle_deg * kPi / 180);
  const Gate fine{options.max_correspondence_distance_m, options.robust_loss_scale_m, cos_normal};
  const double shrink = options.coarse_iterations > 1
                            ? std::pow(options.max_correspondence_distance_m / options.coarse_correspondence_distance_m,
                                       1.0 / (options.coarse_iterations - 1))
                            : 1.0;
  auto coarse_gate = [&](int k) {
    const double d = std::max(options.max_correspondence_distance_m,
                              options.coarse_correspondence_distance_m * std::pow(shrink, k));
    // The Tukey scale follows the gate while far off, then settles at the fine one.
    return Gate{d, std::max(options.robust_loss_scale_m, d), cos_normal};
  };

  // Candidates: identity, and the 4 proper rotations taking BEFORE's principal axes onto
  // AFTER's (sign flips of the eigenvectors), centroid onto centroid.
  std::vector<std::pair<std::string, Eigen::Isometry3d>> candidates{{"identity", Eigen::Isometry3d::Identity()}};
  const Eigen::Matrix3d axes_before = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov_before).eigenvectors();
  const Eigen::Matrix3d axes_after = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov_after).eigenvectors();
  int flip = 0;
  for (int signs = 0; signs < 8; ++signs) {
    const Eigen::Vector3d s(signs & 1 ? -1 : 1, signs & 2 ? -1 : 1, signs & 4 ? -1 : 1);
    const Eigen::Matrix3d R = axes_after * s.asDiagonal() * axes_before.transpose();
    if (R.determinant() < 0) continue;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    T.translation() = centroid_after - R * centroid_before;
    candidates.emplace_back("principal axes (flip " + std::to_string(++flip) + " of 4)", T);
  }

  const std::vector<Sample> coarse_samples = SampleSurface(before, options.coarse_samples, options.seed);
  double best_fraction = -1, best_rms = std::numeric_limits<double>::infinity();
  Alignment alignment;
  for (const auto& [name, start] : candidates) {
    const IcpResult r = Icp(coarse_samples, start, target, options.coarse_iterations, coarse_gate, options);
    const System s = Accumulate(coarse_samples, r.after_from_before, target, fine, options.threads);
    const double fraction = static_cast<double>(s.inliers) / static_cast<double>(coarse_samples.size());
    const double rms = s.inliers > 0 ? std::sqrt(s.sum_r2 / s.inliers) : std::numeric_limits<double>::infinity();
    // More of BEFORE explained wins; the residual only breaks ties (a wrong pose can fit
    // a small part tightly).
    if (fraction > best_fraction || (fraction == best_fraction && rms < best_rms)) {
      best_fraction = fraction;
      best_rms = rms;
      alignment.after_from_before = r.after_from_before;
      alignment.coarse = name;
    }
  }

  const std::vector<Sample> samples = SampleSurface(before, options.samples, options.seed + 1);
  const IcpResult r = Icp(samples, alignment.after_from_before, target, options.max_iterations,
                          [&](int) { return fine; }, options);
  alignment.after_from_before = r.after_from_before;
  alignment.iterations = r.iterations;
  alignment.converged = r.converged;

  std::vector<Term> terms;
  const System s = Accumulate(samples, alignment.after_from_before, target, fine, options.threads, &terms);
  alignment.inlier_fraction = static_cast<double>(s.inliers) / static_cast<double>(samples.size());
  alignment.rms_residual_m = s.inliers > 0 ? std::sqrt(s.sum_r2 / s.inliers) : 0;
  alignment.covariance = Covariance(s, terms, target.pivot, kClusterEdges * std::max(MeanEdge(before), MeanEdge(after)));
  return alignment;
}

}  // namespace hw::analyze
