#include "calibrate/line_alignment.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include <ceres/ceres.h>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "core/median.h"
#include "core/option_check.h"

namespace hw::calibrate {
namespace {

using core::Median;

constexpr double kDegToRad = M_PI / 180.0;
constexpr double kNearZ = 0.05;

// A residual: a 3D point of the depth frame (at the thermal frame's time) and the 2D line
// n·x + c = 0 (|n| = 1, pixels) it must project onto.
struct PointOnLine {
  Eigen::Vector3d point_in_depth;
  Eigen::Vector3d line;  // (n_x, n_y, c)
  int match = 0;
  Eigen::Vector3d shift_per_px = Eigen::Vector3d::Zero();  // occlusion edges: m per px of edge offset
};

struct PointToLineCost {
  PointToLineCost(const PointOnLine& r, const core::CameraModel& k)
      : point_(r.point_in_depth), line_(r.line), shift_(r.shift_per_px), fx_(k.fx), fy_(k.fy), cx_(k.cx), cy_(k.cy) {}
  template <typename T>
  bool operator()(const T* q_xyzw, const T* t, const T* edge_offset_px, T* residual) const {
    const Eigen::Map<const Eigen::Quaternion<T>> q(q_xyzw);  // depth_from_thermal rotation
    const Eigen::Matrix<T, 3, 1> d =
        point_.cast<T>() + edge_offset_px[0] * shift_.cast<T>() - Eigen::Map<const Eigen::Matrix<T, 3, 1>>(t);
    const Eigen::Matrix<T, 3, 1> p = q.conjugate() * d;
    // Points behind the camera cannot happen for accepted matches (clipped); guard anyway.
    const T z = p.z() > T(kNearZ) ? p.z() : T(kNearZ);
    const T u = T(fx_) * p.x() / z + T(cx_);
    const T v = T(fy_) * p.y() / z + T(cy_);
    residual[0] = T(line_.x()) * u + T(line_.y()) * v + T(line_.z());
    return true;
  }
  Eigen::Vector3d point_, line_, shift_;
  double fx_, fy_, cx_, cy_;
};

double Residual(const PointOnLine& r, const core::Rigid3d& depth_from_thermal, double edge_offset_px,
                const core::CameraModel& k) {
  const Eigen::Vector3d p = depth_from_thermal.rotation.conjugate() *
                            (r.point_in_depth + edge_offset_px * r.shift_per_px - depth_from_thermal.translation);
  const double z = std::max(p.z(), kNearZ);
  return r.line.x() * (k.fx * p.x() / z + k.cx) + r.line.y() * (k.fy * p.y() / z + k.cy) + r.line.z();
}

// [ω; δt] applied to a pose as in extrinsics.h.
core::Rigid3d Perturb(const core::Rigid3d& pose, const Vector6d& x) {
  const Eigen::Vector3d w = x.head<3>();
  const double angle = w.norm();
  const Eigen::Quaterniond dq =
      angle > 0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, w / angle)) : Eigen::Quaterniond::Identity();
  return core::Rigid3d(dq * pose.rotation, pose.translation + x.tail<3>());
}

// Associates every frame's 2D segments with the projected 3D segments; fills the residuals.
void Associate(const std::vector<LineFrame>& frames, const core::CameraModel& k, const core::Rigid3d& pose,
               double edge_offset_px, double gate_px, const LineAlignmentOptions& options, std::vector<LineMatch>* matches,
               std::vector<PointOnLine>* residuals) {
  matches->clear();
  residuals->clear();
  const double cos_gate = std::cos(options.gate_deg * kDegToRad);
  const core::Rigid3d thermal_from_depth = pose.Inverse();
  for (size_t f = 0; f < frames.size(); ++f) {
    const LineFrame& frame = frames[f];
    // Projections of the 3D segments.
    struct Projected {
      bool ok = false;
      Eigen::Vector2d a, b;
    };
    // The 3D segments with the current edge offset applied (occlusion lines move).
    std::vector<Segment3d> lines = frame.lines_3d;
    for (Segment3d& line : lines) {
      const double z_mid = 0.5 * (line.a.z() + line.b.z());
      line.a += edge_offset_px * line.edge_shift_per_px * (line.a.z() / z_mid);
      line.b += edge_offset_px * line.edge_shift_per_px * (line.b.z() / z_mid);
    }
    std::vector<Projected> projected(lines.size());
    for (size_t i = 0; i < lines.size(); ++i) {
      projected[i].ok = ProjectSegment(lines[i], pose, k, &projected[i].a, &projected[i].b);
    }
    for (size_t j = 0; j < frame.lines_2d.size(); ++j) {
      const Segment2d& s = frame.lines_2d[j];
      const Eigen::Vector2d dir = (s.b - s.a).normalized();
      const Eigen::Vector2d n(-dir.y(), dir.x());
      const double c = -n.dot(s.a);
      const double len = s.Length();
      int best = -1;
      double best_cost = std::numeric_limits<double>::infinity();
      Eigen::Vector3d best_pa, best_pb, best_sa, best_sb, pa_shift, pb_shift;
      for (size_t i = 0; i < frame.lines_3d.size(); ++i) {
        const Projected& p = projected[i];
        if (!p.ok) continue;
        const Eigen::Vector2d pd = p.b - p.a;
        if (pd.norm() < 1e-6 || std::abs(pd.normalized().dot(dir)) < cos_gate) continue;
        // Overlap along the 2D segment: its parameter range [0, len] against the projection's.
        const double s0 = dir.dot(p.a - s.a), s1 = dir.dot(p.b - s.a);
        const double lo = std::max(0.0, std::min(s0, s1)), hi = std::min(len, std::max(s0, s1));
        if (hi - lo < options.min_overlap * len) continue;
        // The 3D points projecting at the ends of the overlap: intersect the 2D points' rays
        // with the plane through the 3D segment and the camera centre... simpler and exact
        // for a line: solve for the segment parameter μ whose projection has parameter s.
        const Segment3d& line = lines[i];
        const Eigen::Vector3d A = thermal_from_depth * line.a, B = thermal_from_depth * line.b;
        auto point_at = [&](double s_target, Eigen::Vector3d* out) {
          // Projection of A + μ (B − A) has 2D parameter s(μ); it is monotone: bisect.
          auto param = [&](double mu) {
            Eigen::Vector3d X = A + mu * (B - A);
            if (X.z() < kNearZ) X.z() = kNearZ;
            const Eigen::Vector2d px(k.fx * X.x() / X.z() + k.cx, k.fy * X.y() / X.z() + k.cy);
            return dir.dot(px - s.a);
          };
          double m0 = 0, m1 = 1, p0 = param(0), p1 = param(1);
          const double tol = 1e-6 * (1 + std::abs(p1 - p0));
          if (s_target < std::min(p0, p1) - tol || s_target > std::max(p0, p1) + tol) return false;
          for (int it = 0; it < 40; ++it) {
            const double mm = 0.5 * (m0 + m1), pm = param(mm);
            if ((s_target - p0) * (s_target - pm) <= 0) {
              m1 = mm, p1 = pm;
            } else {
              m0 = mm, p0 = pm;
            }
          }
          *out = line.a + 0.5 * (m0 + m1) * (line.b - line.a);
          return true;
        };
        Eigen::Vector3d pa, pb;
        if (!point_at(lo, &pa) || !point_at(hi, &pb)) continue;
        pa_shift = line.edge_shift_per_px * (pa.z() / (0.5 * (line.a.z() + line.b.z())));
        pb_shift = line.edge_shift_per_px * (pb.z() / (0.5 * (line.a.z() + line.b.z())));
        // Distance gate at both ends of the overlap.
        const double da = std::abs(n.dot(k.Project(thermal_from_depth * pa)) + c);
        const double db = std::abs(n.dot(k.Project(thermal_from_depth * pb)) + c);
        if (da > gate_px || db > gate_px) continue;
        const double cost = da + db;
        if (cost < best_cost) {
          best_cost = cost, best = static_cast<int>(i);
          // Stored without the offset: the solve applies its own.
          best_pa = pa - edge_offset_px * pa_shift, best_pb = pb - edge_offset_px * pb_shift;
          best_sa = pa_shift, best_sb = pb_shift;
        }
      }
      if (best < 0) continue;
      LineMatch m;
      m.frame = static_cast<int>(f);
      m.line_3d = best;
      m.line_2d = static_cast<int>(j);
      const Eigen::Vector3d line(n.x(), n.y(), c);
      residuals->push_back({best_pa, line, static_cast<int>(matches->size()), best_sa});
      residuals->push_back({best_pb, line, static_cast<int>(matches->size()), best_sb});
      matches->push_back(m);
    }
  }
}

// An axis (sign chosen so that its largest component is positive), 2 decimals.
std::string DirectionName(Eigen::Vector3d v) {
  Eigen::Index largest = 0;
  v.cwiseAbs().maxCoeff(&largest);
  if (v[largest] < 0) v = -v;
  for (int i = 0; i < 3; ++i) {
    if (std::abs(v[i]) < 0.005) v[i] = 0;  // no "-0.00"
  }
  std::ostringstream s;
  s.precision(2);
  s << std::fixed << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return s.str();
}

}  // namespace

std::string LineAlignmentOptions::Check() const {
  using core::InRange;
  using core::OptionFail;
  if (!InRange(max_iterations, 1, 100)) return OptionFail("max_iterations", max_iterations, "in [1, 100]");
  if (!(initial_gate_mrad > 0)) return OptionFail("initial_gate_mrad", initial_gate_mrad, "> 0 mrad");
  if (!(final_gate_mrad > 0 && final_gate_mrad <= initial_gate_mrad)) {
    return OptionFail("final_gate_mrad", final_gate_mrad, "in (0, initial_gate_mrad] mrad");
  }
  if (!(gate_deg > 0 && gate_deg <= 45)) return OptionFail("gate_deg", gate_deg, "in (0, 45] deg");
  if (!(min_overlap > 0 && min_overlap <= 1)) return OptionFail("min_overlap", min_overlap, "in (0, 1]");
  if (!(loss_sigmas > 0)) return OptionFail("loss_sigmas", loss_sigmas, "> 0");
  if (cluster_frames < 1) return OptionFail("cluster_frames", cluster_frames, ">= 1");
  if (!(sigma_inflation >= 1)) return OptionFail("sigma_inflation", sigma_inflation, ">= 1");
  if (min_matches < 6) return OptionFail("min_matches", min_matches, ">= 6");
  if (!(max_sigma_deg > 0)) return OptionFail("max_sigma_deg", max_sigma_deg, "> 0 deg");
  if (!(max_sigma_mm > 0)) return OptionFail("max_sigma_mm", max_sigma_mm, "> 0 mm");
  return "";
}

bool ProjectSegment(const Segment3d& line, const core::Rigid3d& depth_from_thermal, const core::CameraModel& camera,
                    Eigen::Vector2d* a_px, Eigen::Vector2d* b_px) {
  const core::Rigid3d thermal_from_depth = depth_from_thermal.Inverse();
  Eigen::Vector3d a = thermal_from_depth * line.a, b = thermal_from_depth * line.b;
  if (a.z() < kNearZ && b.z() < kNearZ) return false;
  if (a.z() < kNearZ) a = a + (kNearZ - a.z()) / (b.z() - a.z()) * (b - a);
  if (b.z() < kNearZ) b = b + (kNearZ - b.z()) / (a.z() - b.z()) * (a - b);
  *a_px = camera.Project(a);
  *b_px = camera.Project(b);
  return true;
}

LineAlignmentResult AlignLines(const std::vector<LineFrame>& frames, const core::CameraModel& k,
                               const core::Rigid3d& initial, const LineAlignmentOptions& options) {
  assert(options.Check().empty());
  assert(k.type == core::CameraModelType::kPinhole);
  LineAlignmentResult result;
  result.estimate.camera = "thermal";
  result.estimate.residual_unit = "px";
  core::Rigid3d pose = initial;
  const double f_px = 0.5 * (k.fx + k.fy);
  std::vector<PointOnLine> residuals;
  double sigma_px = options.final_gate_mrad * 1e-3 * f_px / 3;  // before any residual: a third of the final gate
  double edge_px = 0;       // occlusion edge offset, depth px
  bool solve_edge = false;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    const double gate_mrad = std::max(options.final_gate_mrad, options.initial_gate_mrad * std::pow(0.5, iteration));
    // Once the residuals are known the gate also follows them (never wider than the schedule).
    const double gate_px = iteration == 0 ? gate_mrad * 1e-3 * f_px
                                          : std::min(gate_mrad * 1e-3 * f_px, std::max(options.final_gate_mrad * 1e-3 * f_px, 4 * sigma_px));
    Associate(frames, k, pose, edge_px, gate_px, options, &result.matches, &residuals);
    result.matches_per_iteration.push_back(static_cast<int>(result.matches.size()));
    if (static_cast<int>(result.matches.size()) < options.min_matches) {
      std::ostringstream s;
      s << "too few line matches: " << result.matches.size() << " 2D–3D matches over " << frames.size()
        << " frames (at least " << options.min_matches << " needed)";
      result.failure = s.str();
      result.estimate.depth_from_camera = pose;
      return result;
    }
    int occlusion_residuals = 0;
    for (const PointOnLine& r : residuals) occlusion_residuals += r.shift_per_px.norm() > 0;
    solve_edge = options.estimate_edge_offset && occlusion_residuals >= 2 * options.min_matches;
    const double loss_scale = options.loss_sigmas * sigma_px;
    double q[4] = {pose.rotation.x(), pose.rotation.y(), pose.rotation.z(), pose.rotation.w()};
    double t[3] = {pose.translation.x(), pose.translation.y(), pose.translation.z()};
    double e[1] = {edge_px};
    ceres::Problem::Options problem_options;
    problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    ceres::Problem problem(problem_options);
    ceres::HuberLoss loss(loss_scale);
    for (const PointOnLine& r : residuals) {
      problem.AddResidualBlock(
          new ceres::AutoDiffCostFunction<PointToLineCost, 1, 4, 3, 1>(new PointToLineCost(r, k)), &loss, q, t, e);
    }
    problem.SetManifold(q, new ceres::EigenQuaternionManifold);
    if (!solve_edge) problem.SetParameterBlockConstant(e);
    ceres::Solver::Options solver_options;
    solver_options.linear_solver_type = ceres::DENSE_QR;
    solver_options.max_num_iterations = 50;
    solver_options.num_threads = 1;
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
    const core::Rigid3d next(Eigen::Quaterniond(q[3], q[0], q[1], q[2]), Eigen::Vector3d(t[0], t[1], t[2]));
    result.cost_per_iteration.push_back(summary.final_cost);
    const core::PoseError step = core::ComparePoses(pose, next);
    pose = next;
    edge_px = e[0];
    // Robust σ of the residuals (MAD) for the next gate and loss.
    std::vector<double> abs_r;
    for (const PointOnLine& r : residuals) abs_r.push_back(std::abs(Residual(r, pose, edge_px, k)));
    sigma_px = std::max(1.4826 * Median(abs_r), 1e-3);
    const bool converged = step.rotation_rad < 1e-3 * kDegToRad && step.translation_m < 1e-6;
    if (converged && gate_mrad <= options.final_gate_mrad) break;
  }
  result.estimate.depth_from_camera = pose;
  result.robust_sigma_px = sigma_px;
  result.edge_offset_px = edge_px;

  // Covariance: Jacobians in [ω; δt (; edge offset)] by central differences, Huber weights.
  const int dim = solve_edge ? 7 : 6;
  const double loss_scale = options.loss_sigmas * sigma_px;
  Eigen::MatrixXd H7 = Eigen::MatrixXd::Zero(dim, dim);
  std::map<int, Eigen::VectorXd> cluster_gradients;
  double weighted_ss = 0, sum_w = 0, ss = 0;
  int inliers = 0;
  std::vector<double> match_weight(result.matches.size(), 1.0);
  for (const PointOnLine& r : residuals) {
    const double value = Residual(r, pose, edge_px, k);
    Eigen::RowVectorXd J(dim);
    for (int c = 0; c < 6; ++c) {
      Vector6d h = Vector6d::Zero();
      h[c] = 1e-6;
      J[c] = (Residual(r, Perturb(pose, h), edge_px, k) - Residual(r, Perturb(pose, -h), edge_px, k)) / 2e-6;
    }
    if (dim == 7) J[6] = (Residual(r, pose, edge_px + 1e-3, k) - Residual(r, pose, edge_px - 1e-3, k)) / 2e-3;
    const double w = std::abs(value) <= loss_scale ? 1.0 : loss_scale / std::abs(value);
    inliers += std::abs(value) <= loss_scale;
    match_weight[r.match] = std::min(match_weight[r.match], w);
    H7 += w * J.transpose() * J;
    const int cluster = result.matches[r.match].frame / options.cluster_frames;
    auto [it, inserted] = cluster_gradients.try_emplace(cluster, Eigen::VectorXd::Zero(dim));
    it->second += w * value * J.transpose();
    weighted_ss += w * value * value;
    sum_w += w;
    ss += value * value;
  }
  for (size_t i = 0; i < result.matches.size(); ++i) result.matches[i].weight = match_weight[i];
  const int n = static_cast<int>(residuals.size());
  result.estimate.observations = n;
  result.estimate.rms_residual = n > 0 ? std::sqrt(ss / n) : 0;
  result.inlier_fraction = n > 0 ? static_cast<double>(inliers) / n : 0;
  // The pose's information with the edge offset marginalised (Schur complement).
  Matrix6d H = H7.topLeftCorner<6, 6>();
  if (dim == 7 && H7(6, 6) > 0) H -= H7.topRightCorner<6, 1>() * H7.bottomLeftCorner<1, 6>() / H7(6, 6);
  result.information = H;

  // Degeneracy: an information matrix singular to rounding (exactly parallel lines); nearly
  // singular ones are caught by the σ bounds below, in units.
  Eigen::SelfAdjointEigenSolver<Matrix6d> eig(H);
  const double largest = eig.eigenvalues().maxCoeff();
  Matrix6d H_inv = Matrix6d::Zero();
  if (largest <= 0 || eig.eigenvalues().minCoeff() <= largest * 1e-14) {
    const Vector6d v = eig.eigenvectors().col(0);
    const bool rotation = v.head<3>().norm() > v.tail<3>().norm();
    result.failure = "the line matches leave the " + std::string(rotation ? "rotation about" : "translation along") +
                     " the depth frame's direction " +
                     DirectionName(rotation ? v.head<3>().normalized() : v.tail<3>().normalized()) +
                     " unobservable (information matrix singular: all lines parallel, or too few)";
    return result;
  }
  const Eigen::MatrixXd H7_inv = H7.inverse();
  H_inv = 0.5 * (H7_inv + H7_inv.transpose()).topLeftCorner<6, 6>();
  const double s2 = weighted_ss / std::max(1.0, sum_w - dim);
  const Matrix6d classic = 2.0 * s2 * H_inv;
  Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(dim, dim);
  for (const auto& [cluster, g] : cluster_gradients) meat += g * g.transpose();
  const int clusters = static_cast<int>(cluster_gradients.size());
  // Small-sample correction of the cluster sandwich: G / (G − 1).
  const double correction = clusters > 1 ? static_cast<double>(clusters) / (clusters - 1) : 1.0;
  const Matrix6d sandwich = (correction * H7_inv * meat * H7_inv).topLeftCorner<6, 6>();
  if (dim == 7) {
    result.edge_offset_sigma_px = std::sqrt(std::max(2.0 * s2 * H7_inv(6, 6), (correction * H7_inv * meat * H7_inv)(6, 6)));
  }
  // The larger of the two, direction by direction: Σ = classic + positive part of (sandwich − classic).
  Eigen::SelfAdjointEigenSolver<Matrix6d> diff(0.5 * (sandwich + sandwich.transpose()) - classic);
  Matrix6d extra = Matrix6d::Zero();
  for (int i = 0; i < 6; ++i) {
    const double l = diff.eigenvalues()[i];
    if (l > 0) extra += l * diff.eigenvectors().col(i) * diff.eigenvectors().col(i).transpose();
  }
  result.estimate.covariance = classic + extra;  // inflated below, after the observability check

  // Unobservable direction: σ too large.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> rot(result.estimate.covariance.topLeftCorner<3, 3>());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> tra(result.estimate.covariance.bottomRightCorner<3, 3>());
  const double rot_sigma_deg = std::sqrt(std::max(0.0, rot.eigenvalues()[2])) / kDegToRad;
  const double tra_sigma_mm = std::sqrt(std::max(0.0, tra.eigenvalues()[2])) * 1e3;
  if (rot_sigma_deg > options.max_sigma_deg || tra_sigma_mm > options.max_sigma_mm) {
    std::ostringstream s;
    s.precision(3);
    if (tra_sigma_mm > options.max_sigma_mm) {
      s << "the translation along the depth frame's direction " << DirectionName(tra.eigenvectors().col(2))
        << " is unobservable from these lines (σ " << tra_sigma_mm << " mm > max_sigma_mm " << options.max_sigma_mm
        << ": lines nearly parallel, or too few)";
    } else {
      s << "the rotation about the depth frame's direction " << DirectionName(rot.eigenvectors().col(2))
        << " is unobservable from these lines (σ " << rot_sigma_deg << "° > max_sigma_deg " << options.max_sigma_deg
        << ": lines nearly parallel, or too few)";
    }
    result.failure = s.str();
    result.estimate.covariance.setZero();
  }
  result.estimate.covariance *= options.sigma_inflation * options.sigma_inflation;
  return result;
}

}  // namespace hw::calibrate
