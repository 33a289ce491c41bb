#include "calibrate/mrcal_problem.h"

#include <Eigen/Cholesky>
#include <cassert>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include <Eigen/Geometry>

#include "core/cameramodel_io.h"

// After mrcal: mrcal.h declares cholmod_sparse_struct itself, without the header.
#include <cholmod.h>

namespace hw::calibrate {

Eigen::Vector2d MrcalProject(const mrcal_lensmodel_t& lensmodel,
                             const std::vector<double>& intrinsics, const Eigen::Vector3d& p_cam,
                             Eigen::Matrix<double, 2, 3>* dq_dp, Eigen::MatrixXd* dq_dintrinsics) {
  const int n = static_cast<int>(intrinsics.size());
  const mrcal_point3_t p{{p_cam.x(), p_cam.y(), p_cam.z()}};
  mrcal_point2_t q{};
  std::array<mrcal_point3_t, 2> dq_dp_mrcal{};
  std::vector<double> dq_di(dq_dintrinsics != nullptr ? static_cast<size_t>(2 * n) : 0);
  mrcal_project(&q, dq_dp != nullptr ? dq_dp_mrcal.data() : nullptr,
                dq_dintrinsics != nullptr ? dq_di.data() : nullptr, &p, 1, &lensmodel,
                intrinsics.data());
  if (dq_dp != nullptr) {
    for (int r = 0; r < 2; ++r) {
      for (int c = 0; c < 3; ++c) (*dq_dp)(r, c) = dq_dp_mrcal[static_cast<size_t>(r)].xyz[c];
    }
  }
  if (dq_dintrinsics != nullptr) {
    dq_dintrinsics->resize(2, n);
    for (int r = 0; r < 2; ++r) {
      for (int c = 0; c < n; ++c) (*dq_dintrinsics)(r, c) = dq_di[static_cast<size_t>(r * n + c)];
    }
  }
  return {q.x, q.y};
}

Eigen::Vector3d MrcalTransform(const mrcal_pose_t& rt, const Eigen::Vector3d& p_target,
                               Eigen::Matrix<double, 3, 6>* dp_drt) {
  const std::array<double, 6> rt_array{rt.r.x, rt.r.y, rt.r.z, rt.t.x, rt.t.y, rt.t.z};
  const std::array<double, 3> x_in{p_target.x(), p_target.y(), p_target.z()};
  std::array<double, 3> x_out{};
  std::array<double, 18> J{};  // (3, 6) row-major
  mrcal_transform_point_rt(x_out.data(), dp_drt != nullptr ? J.data() : nullptr, nullptr,
                           rt_array.data(), x_in.data());
  if (dp_drt != nullptr) {
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 6; ++c) (*dp_drt)(r, c) = J[static_cast<size_t>(6 * r + c)];
    }
  }
  return {x_out[0], x_out[1], x_out[2]};
}

MrcalProblem::MrcalProblem(const mrcal_lensmodel_t& lensmodel, int width_px, int height_px,
                           const std::vector<Eigen::Vector3d>& corners_target,
                           const std::vector<ViewObservation>& views, TargetShapeModel shape)
    : lensmodel_(lensmodel), imagersize_{width_px, height_px}, shape_(std::move(shape)), corners_(corners_target) {
  const int num_corners = static_cast<int>(corners_.size());
  for (size_t v = 0; v < views.size(); ++v) {
    view_begin_.push_back(static_cast<int>(observations_.size()));
    for (size_t k = 0; k < views[v].corner_ids.size(); ++k) {
      mrcal_observation_point_t observation{};
      observation.icam.intrinsics = 0;
      observation.icam.extrinsics = static_cast<int>(v);
      observation.i_point = static_cast<int>(v) * num_corners + views[v].corner_ids[k];
      observation.px = {{views[v].pixels[k].x(), views[v].pixels[k].y(), 1.0}};
      observations_.push_back(observation);
    }
  }
  view_begin_.push_back(static_cast<int>(observations_.size()));
  poses.resize(views.size());
  shape_params = Eigen::VectorXd::Zero(NumShape());
  UpdatePoints();
}

Eigen::VectorXd TargetShapeModel::Basis(double u) const {
  const int n = static_cast<int>(knots_u.size());
  Eigen::VectorXd w = Eigen::VectorXd::Zero(n);
  if (n == 1 || u <= knots_u.front()) {
    w[0] = 1;
  } else if (u >= knots_u.back()) {
    w[n - 1] = 1;
  } else {
    const int j = static_cast<int>(std::upper_bound(knots_u.begin(), knots_u.end(), u) - knots_u.begin()) - 1;
    const double t = (u - knots_u[static_cast<size_t>(j)]) / (knots_u[static_cast<size_t>(j + 1)] - knots_u[static_cast<size_t>(j)]);
    w[j] = 1 - t;
    w[j + 1] = t;
  }
  return w;
}

void MrcalProblem::UpdatePoints() {
  const size_t num_corners = corners_.size();
  const size_t num_views = view_begin_.size() - 1;
  const int num_shape = NumShape();
  points_.resize(num_views * num_corners);
  shape_basis_.assign(num_shape > 0 ? points_.size() : 0, Eigen::MatrixXd::Zero(3, num_shape));
  for (size_t v = 0; v < num_views; ++v) {
    const Eigen::Matrix3d R =
        core::QuaternionFromRodrigues({poses[v].r.x, poses[v].r.y, poses[v].r.z}).toRotationMatrix();
    // The camera centre in the target frame: p_cam = R p + t = 0.
    const Eigen::Vector3d c = -R.transpose() * Eigen::Vector3d(poses[v].t.x, poses[v].t.y, poses[v].t.z);
    // A pose not yet known (the camera in the target plane or behind it) gives u = 0.
    const double distance = c.z() < 0 ? -c.z() : std::numeric_limits<double>::infinity();
    for (size_t k = 0; k < num_corners; ++k) {
      Eigen::Vector3d p = corners_[k];
      if (num_shape > 0) {
        const size_t first = k / 4 * 4;  // core::TargetCorners: 4 consecutive ids per square
        const Eigen::Vector3d centre =
            0.25 * (corners_[first] + corners_[first + 1] + corners_[first + 2] + corners_[first + 3]);
        // The corner's edges have outward normals (sx, 0) and (0, sy).
        const double sx = corners_[k].x() > centre.x() ? 1 : -1, sy = corners_[k].y() > centre.y() ? 1 : -1;
        const double ux = -sx * (c.x() - corners_[k].x()) / distance;
        const double uy = -sy * (c.y() - corners_[k].y()) / distance;
        Eigen::MatrixXd& basis = shape_basis_[v * num_corners + k];
        const int first_knot = shape_.pixel_offset ? 1 : 0;
        if (shape_.pixel_offset && !intrinsics.empty() && std::isfinite(distance)) {
          // Metres on the target per pixel of the edge's shift along its image normal: the
          // image of a step n along the outward normal, its part across the edge's image t.
          Eigen::Matrix<double, 2, 3> dq_dp_cam;
          MrcalProject(lensmodel_, intrinsics, R * corners_[k] + Eigen::Vector3d(poses[v].t.x, poses[v].t.y, poses[v].t.z),
                       &dq_dp_cam, nullptr);
          const Eigen::Matrix<double, 2, 3> dq_dp = dq_dp_cam * R;
          const auto metres_per_px = [&](const Eigen::Vector2d& across, const Eigen::Vector2d& along) {
            const double cross = std::abs(across.x() * along.y() - across.y() * along.x());
            return cross > 0 ? along.norm() / cross : 0.0;
          };
          basis(0, 0) = sx * metres_per_px(dq_dp.col(0), dq_dp.col(1));
          basis(1, 0) = sy * metres_per_px(dq_dp.col(1), dq_dp.col(0));
        }
        if (!shape_.knots_u.empty()) {
          const int n = static_cast<int>(shape_.knots_u.size());
          basis.block(0, first_knot, 1, n) = sx * shape_.Basis(ux).transpose();
          basis.block(1, first_knot, 1, n) = sy * shape_.Basis(uy).transpose();
        }
        p += basis * shape_params;
      }
      points_[v * num_corners + k] = {{p.x(), p.y(), p.z()}};
    }
  }
}

Eigen::RowVectorXd MrcalProblem::ShapePrior() const {
  const int n = static_cast<int>(shape_.knots_u.size());
  if (n < 2) return {};
  const Eigen::VectorXd u = Eigen::Map<const Eigen::VectorXd>(shape_.knots_u.data(), n);
  Eigen::RowVectorXd row = Eigen::RowVectorXd::Zero(NumShape());
  row.tail(n) = (u.array() - u.mean()).matrix().transpose();
  return row / row.norm();
}

double MrcalProblem::EstimateShapeStep() {
  const int num_shape = NumShape();
  if (num_shape == 0) return 0;
  UpdatePoints();  // u and the metres per pixel at the current poses and intrinsics
  Eigen::MatrixXd J;
  const std::vector<Eigen::Vector2d> residuals = Residuals(&J);
  Eigen::VectorXd r(2 * NumObservations());
  for (int o = 0; o < NumObservations(); ++o) {
    if (observations_[static_cast<size_t>(o)].px.z < 0) {
      J.middleRows(2 * o, 2).setZero();
      r.segment<2>(2 * o).setZero();
    } else {
      r.segment<2>(2 * o) = residuals[static_cast<size_t>(o)];
    }
  }
  // r(state + dx, shape + ds) = r - J [dx; ds]: least squares over both, the shape's part
  // kept; the gauge prior holds F's slope at zero.
  Eigen::MatrixXd JtJ = J.transpose() * J;
  Eigen::VectorXd Jtr = J.transpose() * r;
  if (const Eigen::RowVectorXd prior = ShapePrior(); prior.size() > 0) {
    const double weight = 1e6 * JtJ.diagonal().tail(num_shape).mean();
    JtJ.bottomRightCorner(num_shape, num_shape) += weight * prior.transpose() * prior;
    Jtr.tail(num_shape) -= weight * prior.transpose() * (prior * shape_params);
  }
  const Eigen::VectorXd ds = JtJ.ldlt().solve(Jtr).tail(num_shape);
  if (!ds.allFinite()) throw std::runtime_error("intrinsics: the target shape parameters are not observable");
  shape_params += ds;
  UpdatePoints();
  // In metres: a pixel offset's step converted at a typical ~1 mm per pixel.
  double largest = 0;
  for (int j = 0; j < num_shape; ++j) {
    largest = std::max(largest, (j == 0 && shape_.pixel_offset ? 1e-3 : 1.0) * std::abs(ds[j]));
  }
  return largest;
}

Eigen::MatrixXd MrcalProblem::PointShapeJacobian(int o) const {
  return shape_basis_[static_cast<size_t>(observations_[static_cast<size_t>(o)].i_point)];
}

int MrcalProblem::NumIntrinsics() const { return mrcal_lensmodel_num_params(&lensmodel_); }

int MrcalProblem::NumState() const {
  return NumIntrinsics() + 6 * (static_cast<int>(view_begin_.size()) - 1);
}

namespace {

mrcal_problem_selections_t Selections(bool optimize_core, bool optimize_distortion) {
  mrcal_problem_selections_t selections{};
  selections.do_optimize_intrinsics_core = optimize_core;
  selections.do_optimize_intrinsics_distortions = optimize_distortion;
  selections.do_optimize_extrinsics = true;
  selections.do_optimize_frames = false;
  selections.do_optimize_calobject_warp = false;
  // mrcal's light regularisation (distortion towards 0, principal point towards the
  // centre), as its calibration tool applies: LENSMODEL_OPENCV8 needs it, its rational
  // numerator and denominator otherwise grow together without bound (|k| > 1e4 on opencv5
  // data). On the tests' opencv5 data its effect is negligible (the chi-square of the
  // intrinsics' error against the truth goes from 17.40 to 17.42).
  selections.do_apply_regularization = true;
  selections.do_apply_outlier_rejection = false;  // points: not implemented in mrcal 2.2
  return selections;
}

// Range penalties of discrete points: far outside any calibration distance, never active.
constexpr mrcal_problem_constants_t kConstants{1e-6, 1e6};

}  // namespace

void MrcalProblem::Optimize(bool optimize_core, bool optimize_distortion) {
  const mrcal_problem_selections_t selections = Selections(optimize_core, optimize_distortion);
  const mrcal_problem_constants_t constants = kConstants;
  const int num_points = static_cast<int>(points_.size());
  const mrcal_stats_t stats = mrcal_optimize(
      nullptr, 0, nullptr, 0, intrinsics.data(), poses.data(), nullptr, points_.data(), nullptr,
      /*Ncameras_intrinsics=*/1, /*Ncameras_extrinsics=*/static_cast<int>(poses.size()),
      /*Nframes=*/0, num_points, /*Npoints_fixed=*/num_points, nullptr, observations_.data(), 0,
      NumObservations(), nullptr, &lensmodel_, imagersize_.data(), selections, &constants, 0.0, 0,
      0, /*verbose=*/false, /*check_gradient=*/false);
  if (!(stats.rms_reproj_error__pixels >= 0) || !std::isfinite(stats.rms_reproj_error__pixels)) {
    throw std::runtime_error("intrinsics: mrcal_optimize failed (rms reprojection error " +
                             std::to_string(stats.rms_reproj_error__pixels) + ")");
  }
}

Eigen::MatrixXd MrcalProblem::RegularizationJacobian() const {
  const mrcal_problem_selections_t selections = Selections(true, true);
  const mrcal_problem_constants_t constants = kConstants;
  const int num_views = static_cast<int>(poses.size());
  const int num_points = static_cast<int>(points_.size());
  const int num_measurements = mrcal_num_measurements(
      0, NumObservations(), 0, 0, 1, num_views, 0, num_points, num_points, selections, &lensmodel_);
  const int num_states =
      mrcal_num_states(1, num_views, 0, num_points, num_points, 0, selections, &lensmodel_);
  const int begin = mrcal_measurement_index_regularization(0, NumObservations(), 0, 0);
  const int count = mrcal_num_measurements_regularization(1, num_views, 0, num_points, num_points,
                                                          0, selections, &lensmodel_);
  // mrcal's own sparse Jacobian, one callback: exact, and a splined model's hundreds of
  // intrinsics would cost two callbacks each by finite differences.
  const int num_nonzero =
      _mrcal_num_j_nonzero(0, NumObservations(), 0, 0, 1, num_views, 0, num_points, num_points,
                           nullptr, observations_.data(), selections, &lensmodel_);
  cholmod_common common;
  cholmod_start(&common);
  cholmod_sparse* Jt = cholmod_allocate_sparse(static_cast<size_t>(num_states),
                                               static_cast<size_t>(num_measurements),
                                               static_cast<size_t>(num_nonzero), 1, 1, 0,
                                               CHOLMOD_REAL, &common);
  std::vector<double> b_packed(static_cast<size_t>(num_states)),
      x(static_cast<size_t>(num_measurements));
  // Buffer sizes in bytes.
  const bool ok =
      Jt != nullptr &&
      mrcal_optimizer_callback(b_packed.data(), static_cast<int>(sizeof(double)) * num_states,
                               x.data(), static_cast<int>(sizeof(double)) * num_measurements,
                               reinterpret_cast<struct cholmod_sparse_struct*>(Jt),
                               intrinsics.data(), poses.data(), nullptr, points_.data(), nullptr,
                               1, num_views, 0, num_points, num_points, nullptr,
                               observations_.data(), 0, NumObservations(), nullptr, &lensmodel_,
                               imagersize_.data(), selections, &constants, 0.0, 0, 0, false);
  const int n = NumIntrinsics();
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(count, n);
  if (ok) {
    // Jt is the Jacobian of the packed (unitless) state b_packed = b / scale: column by
    // column (one per measurement) d x / d b = d x / d b_packed / scale. The intrinsics lead
    // the state; the regularisation depends on nothing else.
    std::vector<double> scale(static_cast<size_t>(num_states), 1.0);
    mrcal_unpack_solver_state_vector(scale.data(), 1, num_views, 0, num_points, num_points,
                                     selections, &lensmodel_);
    const auto* column_begin = static_cast<const int*>(Jt->p);
    const auto* rows = static_cast<const int*>(Jt->i);
    const auto* values = static_cast<const double*>(Jt->x);
    for (int m = 0; m < count; ++m) {
      for (int k = column_begin[begin + m]; k < column_begin[begin + m + 1]; ++k) {
        assert(rows[k] < n);
        if (rows[k] < n) J(m, rows[k]) = values[k] / scale[static_cast<size_t>(rows[k])];
      }
    }
  }
  cholmod_free_sparse(&Jt, &common);
  cholmod_finish(&common);
  if (!ok) throw std::runtime_error("intrinsics: mrcal_optimizer_callback failed");
  return J;
}

std::vector<Eigen::Vector2d> MrcalProblem::Residuals(Eigen::MatrixXd* J) const {
  const int n_intrinsics = NumIntrinsics();
  const int num_shape = NumShape();
  if (J != nullptr) *J = Eigen::MatrixXd::Zero(2 * NumObservations(), NumState() + num_shape);
  std::vector<Eigen::Vector2d> residuals;
  residuals.reserve(observations_.size());
  Eigen::Matrix<double, 3, 6> dp_drt;
  Eigen::Matrix<double, 2, 3> dq_dp;
  Eigen::MatrixXd dq_di;
  for (size_t v = 0; v + 1 < view_begin_.size(); ++v) {
    // dp_cam/dp_target is the pose's rotation; u's and the metres per pixel's dependence on
    // the pose is left out (the shape times the change of a ratio of distances: second order).
    const Eigen::Matrix3d R =
        num_shape > 0 && J != nullptr
            ? core::QuaternionFromRodrigues({poses[v].r.x, poses[v].r.y, poses[v].r.z}).toRotationMatrix()
            : Eigen::Matrix3d::Identity();
    for (int o = view_begin_[v]; o < view_begin_[v + 1]; ++o) {
      const mrcal_observation_point_t& observation = observations_[static_cast<size_t>(o)];
      const mrcal_point3_t& point = points_[static_cast<size_t>(observation.i_point)];
      const Eigen::Vector3d p_cam =
          MrcalTransform(poses[v], {point.x, point.y, point.z}, J != nullptr ? &dp_drt : nullptr);
      const Eigen::Vector2d q =
          MrcalProject(lensmodel_, intrinsics, p_cam, J != nullptr ? &dq_dp : nullptr,
                       J != nullptr ? &dq_di : nullptr);
      residuals.emplace_back(observation.px.x - q.x(), observation.px.y - q.y());
      if (J != nullptr) {
        J->block(2 * o, 0, 2, n_intrinsics) = dq_di;
        J->block(2 * o, n_intrinsics + 6 * static_cast<int>(v), 2, 6) = dq_dp * dp_drt;
        if (num_shape > 0) {
          J->block(2 * o, NumState(), 2, num_shape) = dq_dp * R * PointShapeJacobian(o);
        }
      }
    }
  }
  return residuals;
}

int MrcalProblem::MarkOutliers(double sigmas) {
  const std::vector<Eigen::Vector2d> residuals = Residuals(nullptr);
  double sum_squared = 0;
  int inliers = 0;
  for (size_t o = 0; o < residuals.size(); ++o) {
    if (observations_[o].px.z < 0) continue;
    sum_squared += residuals[o].squaredNorm();
    ++inliers;
  }
  if (inliers == 0) return 0;
  const double threshold_squared = sigmas * sigmas * sum_squared / inliers;
  int marked = 0;
  for (size_t o = 0; o < residuals.size(); ++o) {
    if (observations_[o].px.z >= 0 && residuals[o].squaredNorm() > threshold_squared) {
      observations_[o].px.z = -1;
      ++marked;
    }
  }
  return marked;
}

IntrinsicsResult MrcalProblem::Result(bool core_free) const {
  IntrinsicsResult result;
  const int n_intrinsics = NumIntrinsics();
  result.camera.width = imagersize_[0];
  result.camera.height = imagersize_[1];
  if (lensmodel_.type == MRCAL_LENSMODEL_SPLINED_STEREOGRAPHIC) {
    const auto& config = lensmodel_.LENSMODEL_SPLINED_STEREOGRAPHIC__config;
    result.camera.type = core::CameraModelType::kSplined;
    result.camera.splined = {config.order, config.Nx, config.Ny, config.fov_x_deg};
  } else {
    result.camera.type = core::CameraModelType::kOpenCV;
  }
  result.camera.fx = intrinsics[0];
  result.camera.fy = intrinsics[1];
  result.camera.cx = intrinsics[2];
  result.camera.cy = intrinsics[3];
  result.camera.distortion.assign(intrinsics.begin() + 4, intrinsics.end());
  if (const std::string problem = result.camera.Check(); !problem.empty()) {
    throw std::runtime_error("intrinsics: mrcal converged to an invalid camera: " + problem);
  }
  std::array<char, 128> name{};
  mrcal_lensmodel_name(name.data(), static_cast<int>(name.size()), &lensmodel_);
  result.mrcal_lensmodel = name.data();
  result.mrcal_intrinsics = intrinsics;
  for (const mrcal_pose_t& pose : poses) {
    result.camera_from_target.emplace_back(
        core::QuaternionFromRodrigues({pose.r.x, pose.r.y, pose.r.z}),
        Eigen::Vector3d(pose.t.x, pose.t.y, pose.t.z));
  }

  Eigen::MatrixXd J;
  const std::vector<Eigen::Vector2d> residuals = Residuals(&J);
  double sum_squared = 0;
  int inliers = 0;
  for (size_t v = 0; v + 1 < view_begin_.size(); ++v) {
    std::vector<Eigen::Vector2d> view_residuals;
    std::vector<bool> view_outlier;
    double view_sum = 0;
    int view_inliers = 0;
    for (int o = view_begin_[v]; o < view_begin_[v + 1]; ++o) {
      const Eigen::Vector2d& r = residuals[static_cast<size_t>(o)];
      const bool is_outlier = observations_[static_cast<size_t>(o)].px.z < 0;
      view_residuals.push_back(r);
      view_outlier.push_back(is_outlier);
      if (is_outlier) {
        ++result.outliers;
        J.middleRows(2 * o, 2).setZero();  // an outlier carries no information
        continue;
      }
      view_sum += r.squaredNorm();
      ++view_inliers;
      result.worst_px = std::max(result.worst_px, r.norm());
    }
    sum_squared += view_sum;
    inliers += view_inliers;
    result.view_rms_px.push_back(view_inliers > 0 ? std::sqrt(view_sum / view_inliers)
                                                  : std::numeric_limits<double>::quiet_NaN());
    result.residuals_px.push_back(std::move(view_residuals));
    result.outlier.push_back(std::move(view_outlier));
  }
  // A fixed core (splined models) is no unknown: it has no variance and no column.
  const int fixed = core_free ? 0 : 4;
  const int num_shape = NumShape();
  const int num_free = NumState() - fixed + num_shape;
  const int dof = 2 * inliers - num_free;
  if (inliers == 0 || dof <= 0) {
    throw std::runtime_error("intrinsics: " + std::to_string(2 * inliers) +
                             " inlier measurements for " + std::to_string(num_free) +
                             " unknowns: the problem is not overdetermined");
  }
  result.rms_px = std::sqrt(sum_squared / inliers);
  result.observation_sigma_px = std::sqrt(sum_squared / dof);

  Eigen::MatrixXd JtJ = Eigen::MatrixXd::Zero(num_free, num_free);
  JtJ.selfadjointView<Eigen::Lower>().rankUpdate(J.rightCols(num_free).transpose());
  const Eigen::MatrixXd J_regularization = RegularizationJacobian().rightCols(n_intrinsics - fixed);
  JtJ.topLeftCorner(n_intrinsics - fixed, n_intrinsics - fixed).selfadjointView<Eigen::Lower>()
      .rankUpdate(J_regularization.transpose());
  if (const Eigen::RowVectorXd prior = ShapePrior(); prior.size() > 0) {
    // The gauge direction (module comment): pinned, it adds no uncertainty to the rest.
    const double weight = 1e6 * JtJ.diagonal().tail(num_shape).mean();
    JtJ.bottomRightCorner(num_shape, num_shape).selfadjointView<Eigen::Lower>().rankUpdate(
        prior.transpose(), weight);
  }
  const Eigen::LLT<Eigen::MatrixXd, Eigen::Lower> llt(JtJ);
  if (llt.info() != Eigen::Success) {
    throw std::runtime_error(
        "intrinsics: J^T J is singular at the optimum: the views do not "
        "constrain every intrinsic parameter and pose");
  }
  // The shape parameters are marginalised: the state's block of the full inverse.
  const Eigen::MatrixXd covariance = result.observation_sigma_px * result.observation_sigma_px *
                                     llt.solve(Eigen::MatrixXd::Identity(num_free, num_free));
  const int num_state_free = NumState() - fixed;
  result.state_covariance = Eigen::MatrixXd::Zero(NumState(), NumState());
  result.state_covariance.bottomRightCorner(num_state_free, num_state_free) =
      covariance.topLeftCorner(num_state_free, num_state_free);
  result.edge_shift_knots_u = shape_.knots_u;
  for (int j = 0; j < num_shape; ++j) {
    const double sigma = std::sqrt(covariance(num_state_free + j, num_state_free + j));
    if (j == 0 && shape_.pixel_offset) {
      result.edge_shift_px = shape_params[j];
      result.edge_shift_sigma_px = sigma;
    } else {
      result.edge_shift_m.push_back(shape_params[j]);
      result.edge_shift_sigma_m.push_back(sigma);
    }
  }
  result.intrinsics_covariance = result.state_covariance.topLeftCorner(n_intrinsics, n_intrinsics);
  return result;
}

}  // namespace hw::calibrate
