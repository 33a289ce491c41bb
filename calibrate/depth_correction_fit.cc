#include "calibrate/depth_correction_fit.h"

#include <algorithm>
#include <atomic>
#include <cassert>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <limits>
#include <mutex>
#include <numbers>
#include <optional>
#include <random>
#include <stdexcept>
#include <thread>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/median.h"
#include "core/option_check.h"
#include "core/strings.h"

namespace hw::calibrate {

namespace {

using core::Median;
using core::OptionFail;
using core::StringPrintf;

constexpr int kMaxDenseNodes = 2500;  // the reduced system is dense: 2500² doubles = 50 MB
constexpr double kMadToSigma = 1.4826;
constexpr int kCoveredNodeSamples = 50;

using Stencil = core::DepthCorrection::Stencil;

Eigen::Vector2d NodePosition(const core::DepthCorrection& grid, int k) {
  const auto [x, y] = grid.NodePosition(k % grid.nx, k / grid.nx);
  return {x, y};
}

// K × 3 basis of affine fields at the nodes: (1, x_k, y_k).
Eigen::MatrixXd AffineBasis(const core::DepthCorrection& grid) {
  const int num_nodes = grid.nx * grid.ny;
  Eigen::MatrixXd basis(num_nodes, 3);
  for (int k = 0; k < num_nodes; ++k) {
    const Eigen::Vector2d xy = NodePosition(grid, k);
    basis.row(k) << 1, xy.x(), xy.y();
  }
  return basis;
}

// Least-squares plane w = a·x + b·y + c over the selected samples (uniform weights).
std::optional<Eigen::Vector3d> FitPlane(const DepthFrameSamples& s, const std::vector<char>& use,
                                        const std::vector<double>* field = nullptr) {
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  int n = 0;
  for (size_t i = 0; i < s.w.size(); ++i) {
    if (!use[i]) continue;
    const Eigen::Vector3d g(s.x[i], s.y[i], 1);
    h += g * g.transpose();
    b += g * (s.w[i] - (field ? (*field)[i] : 0.0));
    ++n;
  }
  if (n < 3) return std::nullopt;
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(h);
  if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) return std::nullopt;
  return Eigen::Vector3d(ldlt.solve(b));
}

// The largest plane of a frame in (x, y, w) by RANSAC (hypotheses scored on a subsample),
// refitted on its inliers twice. Returns the inlier mask; empty when nothing fits.
std::vector<char> RansacPlane(const DepthFrameSamples& s, const DepthCorrectionOptions& o) {
  const size_t n = s.w.size();
  if (n < 3) return {};
  std::mt19937_64 random(0x9e3779b97f4a7c15ull ^ static_cast<uint64_t>(s.frame));
  std::uniform_int_distribution<size_t> pick(0, n - 1);
  std::vector<size_t> subsample;
  const size_t num_scored = std::min<size_t>(n, 2000);
  for (size_t i = 0; i < num_scored; ++i) subsample.push_back(n <= 2000 ? i : pick(random));
  Eigen::Vector3d best = Eigen::Vector3d::Zero();
  int best_count = -1;
  for (int it = 0; it < o.ransac_iterations; ++it) {
    const size_t i0 = pick(random), i1 = pick(random), i2 = pick(random);
    Eigen::Matrix3d m;
    m << s.x[i0], s.y[i0], 1, s.x[i1], s.y[i1], 1, s.x[i2], s.y[i2], 1;
    const Eigen::FullPivLU<Eigen::Matrix3d> lu(m);
    if (!lu.isInvertible()) continue;
    const Eigen::Vector3d plane = lu.solve(Eigen::Vector3d(s.w[i0], s.w[i1], s.w[i2]));
    int count = 0;
    for (const size_t i : subsample) {
      count += std::abs(s.w[i] - plane.dot(Eigen::Vector3d(s.x[i], s.y[i], 1))) <
               o.ransac_threshold_per_m;
    }
    if (count > best_count) {
      best_count = count;
      best = plane;
    }
  }
  if (best_count < 3) return {};
  // Refit from the hypothesis with Tukey's biweight at a scale from the residuals' MAD: a
  // least-squares refit on the band would lean towards clutter just inside it and, band
  // after band, slide onto it.
  std::vector<double> residual(n), near;
  double scale = o.ransac_threshold_per_m;
  for (int refit = 0; refit < 10; ++refit) {
    near.clear();
    for (size_t i = 0; i < n; ++i) {
      residual[i] = s.w[i] - best.dot(Eigen::Vector3d(s.x[i], s.y[i], 1));
      if (std::abs(residual[i]) < o.ransac_threshold_per_m) near.push_back(std::abs(residual[i]));
    }
    if (near.size() < 3) return {};
    scale = std::min(o.ransac_threshold_per_m, 4.685 * std::max(kMadToSigma * Median(near), 1e-6));
    Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < n; ++i) {
      const double u = residual[i] / scale;
      if (std::abs(u) >= 1) continue;
      const double weight = (1 - u * u) * (1 - u * u);
      const Eigen::Vector3d g(s.x[i], s.y[i], 1);
      h += weight * g * g.transpose();
      b += weight * g * s.w[i];
    }
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(h);
    if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) return {};
    best = ldlt.solve(b);
  }
  std::vector<char> inlier(n, 0);
  for (size_t i = 0; i < n; ++i) {
    inlier[i] = std::abs(s.w[i] - best.dot(Eigen::Vector3d(s.x[i], s.y[i], 1))) < scale;
  }
  return inlier;
}

// One frame's share of the reduced normal equations (its plane eliminated). Its K × K
// matrix is added to a shared total as it is built, not kept: 90 frames of a 50 × 50 grid
// would hold 4.5 GB.
struct FrameSystem {
  Eigen::VectorXd r;  // K
  Eigen::Matrix3d hpp;
  Eigen::Vector3d bp;
  Eigen::MatrixXd hpt;  // 3 × K
};

// Adds frames' matrices to a total in frame order whatever thread builds them, so that a
// calibration is bit-for-bit the same on every run.
class OrderedSum {
 public:
  explicit OrderedSum(Eigen::MatrixXd* total) : total_(total) {}
  void Add(int index, const Eigen::MatrixXd& m) {
    std::unique_lock<std::mutex> lock(mutex_);
    turn_.wait(lock, [&] { return next_ == index; });
    *total_ += m;
    ++next_;
    turn_.notify_all();
  }

 private:
  Eigen::MatrixXd* total_;
  std::mutex mutex_;
  std::condition_variable turn_;
  int next_ = 0;
};

FrameSystem BuildFrameSystem(const core::DepthCorrection& grid, const DepthFrameSamples& s,
                             const std::vector<char>& use, double weight, int index,
                             OrderedSum* s_total) {
  const int num_nodes = grid.nx * grid.ny;
  FrameSystem f;
  Eigen::MatrixXd htt = Eigen::MatrixXd::Zero(num_nodes, num_nodes);
  Eigen::VectorXd bt = Eigen::VectorXd::Zero(num_nodes);
  f.hpp.setZero();
  f.bp.setZero();
  f.hpt = Eigen::MatrixXd::Zero(3, num_nodes);
  for (size_t i = 0; i < s.w.size(); ++i) {
    if (!use[i]) continue;
    const Eigen::Vector3d g(s.x[i], s.y[i], 1);
    const Stencil st = grid.StencilAt(s.x[i], s.y[i]);
    f.hpp += weight * g * g.transpose();
    f.bp += weight * g * s.w[i];
    for (int a = 0; a < 4; ++a) {
      const double wa = weight * st.weight[a];
      bt(st.node[a]) += wa * s.w[i];
      f.hpt.col(st.node[a]) += wa * g;
      for (int b = 0; b < 4; ++b) htt(st.node[a], st.node[b]) += wa * st.weight[b];
    }
  }
  const Eigen::Matrix3d hpp_inv = f.hpp.inverse();
  htt -= f.hpt.transpose() * hpp_inv * f.hpt;
  f.r = bt - f.hpt.transpose() * (hpp_inv * f.bp);
  s_total->Add(index, htt);
  return f;
}

// The frame's reduced matrix times θ, from its samples (the matrix itself is not kept).
Eigen::VectorXd ReducedTimes(const core::DepthCorrection& grid, const DepthFrameSamples& s,
                             const std::vector<char>& use, double weight, const FrameSystem& f,
                             const Eigen::VectorXd& theta) {
  Eigen::VectorXd out = Eigen::VectorXd::Zero(theta.size());
  for (size_t i = 0; i < s.w.size(); ++i) {
    if (!use[i]) continue;
    const Stencil st = grid.StencilAt(s.x[i], s.y[i]);
    double b_theta = 0;
    for (int a = 0; a < 4; ++a) b_theta += st.weight[a] * theta(st.node[a]);
    for (int a = 0; a < 4; ++a) out(st.node[a]) += weight * st.weight[a] * b_theta;
  }
  return out - f.hpt.transpose() * f.hpp.ldlt().solve(f.hpt * theta);
}

// Second differences of the node grid along x and along y (rows of D; D·θ).
Eigen::MatrixXd SecondDifferences(const core::DepthCorrection& grid) {
  const int num_nodes = grid.nx * grid.ny;
  const int rows = (grid.nx >= 3 ? (grid.nx - 2) * grid.ny : 0) +
                   (grid.ny >= 3 ? (grid.ny - 2) * grid.nx : 0);
  Eigen::MatrixXd d = Eigen::MatrixXd::Zero(rows, num_nodes);
  int row = 0;
  for (int iy = 0; iy < grid.ny; ++iy) {
    for (int ix = 1; ix + 1 < grid.nx; ++ix, ++row) {
      const int k = iy * grid.nx + ix;
      d(row, k - 1) = 1;
      d(row, k) = -2;
      d(row, k + 1) = 1;
    }
  }
  for (int iy = 1; iy + 1 < grid.ny; ++iy) {
    for (int ix = 0; ix < grid.nx; ++ix, ++row) {
      const int k = iy * grid.nx + ix;
      d(row, k - grid.nx) = 1;
      d(row, k) = -2;
      d(row, k + grid.nx) = 1;
    }
  }
  return d;
}

template <typename Fn>
void ParallelFor(int count, int num_threads, const Fn& fn) {
  const int threads = std::max(
      1, std::min(count, num_threads > 0 ? num_threads
                                          : static_cast<int>(std::thread::hardware_concurrency())));
  std::atomic<int> next{0};
  std::exception_ptr error;
  std::mutex error_mutex;
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t) {
    pool.emplace_back([&] {
      try {
        for (int i = next++; i < count; i = next++) fn(i);
      } catch (...) {
        // The first failure (e.g. an unreadable frame) is rethrown; the others stop early.
        const std::lock_guard<std::mutex> lock(error_mutex);
        if (!error) error = std::current_exception();
        next = count;
      }
    });
  }
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

// Depth residual (mm) of an inverse-depth residual dw at measured inverse depth w.
double DepthMm(double dw, double w) { return 1e3 * std::abs(dw) / (w * (w - dw)); }

}  // namespace

std::string DepthCorrectionOptions::Check() const {
  if (!(nx >= 2 && nx <= 256)) return OptionFail("nx", nx, "in [2, 256]");
  if (!(ny >= 2 && ny <= 256)) return OptionFail("ny", ny, "in [2, 256]");
  if (nx * ny > kMaxDenseNodes) {
    return OptionFail("nx*ny", nx * ny, "at most " + std::to_string(kMaxDenseNodes) +
                                            " (the reduced system is solved dense)");
  }
  if (!(pixel_step >= 1 && pixel_step <= 64)) return OptionFail("pixel_step", pixel_step, "in [1, 64] px");
  if (!(min_depth_m > 0)) return OptionFail("min_depth_m", min_depth_m, "> 0 m");
  if (!(max_depth_m > min_depth_m)) return OptionFail("max_depth_m", max_depth_m, "> min_depth_m m");
  if (!(ransac_threshold_per_m > 0 && ransac_threshold_per_m <= 1)) {
    return OptionFail("ransac_threshold_per_m", ransac_threshold_per_m, "in (0, 1] 1/m");
  }
  if (!(ransac_iterations >= 10 && ransac_iterations <= 100000)) {
    return OptionFail("ransac_iterations", ransac_iterations, "in [10, 100000]");
  }
  if (!(inlier_sigmas > 0 && std::isfinite(inlier_sigmas))) return OptionFail("inlier_sigmas", inlier_sigmas, "> 0");
  if (!(iterations >= 1 && iterations <= 20)) return OptionFail("iterations", iterations, "in [1, 20]");
  if (!core::InRange(min_plane_fraction, 0, 1)) {
    return OptionFail("min_plane_fraction", min_plane_fraction, "in [0, 1]");
  }
  if (!(min_plane_samples >= 3)) return OptionFail("min_plane_samples", min_plane_samples, ">= 3");
  if (!(smoothness_sigma_per_m > 0 && std::isfinite(smoothness_sigma_per_m))) {
    return OptionFail("smoothness_sigma_per_m", smoothness_sigma_per_m, "> 0 1/m");
  }
  if (!(min_frames >= 2 && min_frames <= 100000)) return OptionFail("min_frames", min_frames, "in [2, 100000]");
  if (!(max_frames >= 0)) return OptionFail("max_frames", max_frames, ">= 0 (0: all)");
  if (!(num_threads >= 0)) return OptionFail("num_threads", num_threads, ">= 0 (0: all cores)");
  return "";
}

std::vector<double> WithoutAffinePart(const core::DepthCorrection& grid,
                                      const std::vector<double>& values) {
  assert(values.size() == static_cast<size_t>(grid.nx) * grid.ny);
  const Eigen::MatrixXd basis = AffineBasis(grid);
  const Eigen::Map<const Eigen::VectorXd> v(values.data(), static_cast<Eigen::Index>(values.size()));
  const Eigen::Vector3d coefficients = (basis.transpose() * basis).ldlt().solve(basis.transpose() * v);
  const Eigen::VectorXd out = v - basis * coefficients;
  return {out.data(), out.data() + out.size()};
}

DepthCorrectionResult FitDepthCorrection(const std::vector<DepthFrameSamples>& frames,
                                         const core::DepthCorrection& grid_in,
                                         const DepthCorrectionOptions& o) {
  assert(o.Check().empty());
  core::DepthCorrection grid = grid_in;
  grid.offset_per_m.assign(static_cast<size_t>(grid.nx) * grid.ny, 0.0);
  assert(grid.Check().empty());
  const int num_nodes = grid.nx * grid.ny;
  const int num_frames = static_cast<int>(frames.size());

  DepthCorrectionResult result;
  result.frames.resize(frames.size());
  std::vector<std::vector<char>> inliers(frames.size());
  std::vector<double> sigma(frames.size(), 0.0);
  std::vector<Eigen::Vector3d> planes(frames.size(), Eigen::Vector3d::Zero());

  // The largest plane of each frame, and whether the frame is usable.
  ParallelFor(num_frames, o.num_threads, [&](int p) {
    const DepthFrameSamples& s = frames[p];
    DepthPlaneFit& fit = result.frames[p];
    fit.frame = s.frame;
    fit.timestamp_s = s.timestamp_s;
    fit.samples = static_cast<int>(s.w.size());
    inliers[p] = RansacPlane(s, o);
    const int count = static_cast<int>(std::count(inliers[p].begin(), inliers[p].end(), 1));
    if (count < o.min_plane_samples) {
      fit.skipped_because = StringPrintf("its largest plane has %d samples (at least %d needed)",
                                         count, o.min_plane_samples);
      return;
    }
    if (count < o.min_plane_fraction * fit.samples) {
      fit.skipped_because =
          StringPrintf("its largest plane holds %.0f %% of its depth (at least %.0f %% needed)",
                       100.0 * count / fit.samples, 100 * o.min_plane_fraction);
      return;
    }
    const std::optional<Eigen::Vector3d> plane = FitPlane(s, inliers[p]);
    if (!plane) {  // the plane's samples on one line: a sliver of wall, no plane to speak of
      fit.skipped_because = "its largest plane's samples are degenerate (on one line)";
      return;
    }
    fit.used = true;
    planes[p] = *plane;
    std::vector<double> residuals;
    for (int i = 0; i < fit.samples; ++i) {
      if (inliers[p][i]) residuals.push_back(std::abs(s.w[i] - planes[p].dot(Eigen::Vector3d(s.x[i], s.y[i], 1))));
    }
    sigma[p] = std::max(kMadToSigma * Median(residuals), 1e-6);
  });
  std::vector<int> used;
  for (int p = 0; p < num_frames; ++p) {
    if (result.frames[p].used) used.push_back(p);
  }
  if (static_cast<int>(used.size()) < o.min_frames) {
    std::string why;
    for (const DepthPlaneFit& fit : result.frames) {
      if (!fit.used) {
        why = StringPrintf("; e.g. frame %d: %s", fit.frame, fit.skipped_because.c_str());
        break;
      }
    }
    throw std::invalid_argument(StringPrintf(
        "%zu of %d depth frames show a usable plane, at least %d are needed%s", used.size(),
        num_frames, o.min_frames, why.c_str()));
  }

  const Eigen::MatrixXd basis = AffineBasis(grid);
  const Eigen::MatrixXd second = SecondDifferences(grid);
  const Eigen::MatrixXd prior =
      second.transpose() * second / (o.smoothness_sigma_per_m * o.smoothness_sigma_per_m);
  Eigen::VectorXd theta = Eigen::VectorXd::Zero(num_nodes);
  std::vector<FrameSystem> systems(used.size());
  Eigen::MatrixXd a, s_total;
  std::vector<double> field;  // per sample of a frame, scratch

  for (int round = 0; round < o.iterations; ++round) {
    s_total = prior;
    OrderedSum s_sum(&s_total);
    // Gate (after the first round, on plane + field) and build each frame's system.
    ParallelFor(static_cast<int>(used.size()), o.num_threads, [&](int u) {
      const int p = used[u];
      const DepthFrameSamples& s = frames[p];
      if (round > 0) {
        std::vector<double> residual(s.w.size());
        std::vector<double> kept;
        for (size_t i = 0; i < s.w.size(); ++i) {
          const Stencil st = grid.StencilAt(s.x[i], s.y[i]);
          double delta = 0;
          for (int k = 0; k < 4; ++k) delta += st.weight[k] * theta(st.node[k]);
          residual[i] = s.w[i] - planes[p].dot(Eigen::Vector3d(s.x[i], s.y[i], 1)) - delta;
          if (inliers[p][i]) kept.push_back(std::abs(residual[i]));
        }
        sigma[p] = std::max(kMadToSigma * Median(kept), 1e-6);
        // Never wider than the RANSAC band: the gate must not open onto the clutter.
        const double gate = std::min(o.inlier_sigmas * sigma[p], o.ransac_threshold_per_m);
        std::vector<char> gated(s.w.size());
        for (size_t i = 0; i < s.w.size(); ++i) gated[i] = std::abs(residual[i]) < gate;
        // A gate that would leave too few samples for a plane keeps the last round's set.
        if (std::count(gated.begin(), gated.end(), 1) >= o.min_plane_samples) inliers[p] = gated;
      }
      systems[u] = BuildFrameSystem(grid, s, inliers[p], 1 / (sigma[p] * sigma[p]), u, &s_sum);
    });
    Eigen::VectorXd r_total = Eigen::VectorXd::Zero(num_nodes);
    for (const FrameSystem& f : systems) r_total += f.r;
    // Affine fields are in the null space of data and prior alike: pin them to zero.
    const double mu = s_total.diagonal().mean();
    a = s_total + mu * basis * basis.transpose();
    theta = a.ldlt().solve(r_total);
    if (!theta.allFinite()) {
      throw std::invalid_argument("the least-squares solve of the field failed (a singular system)");
    }
    for (size_t u = 0; u < used.size(); ++u) {
      const FrameSystem& f = systems[u];
      planes[used[u]] = f.hpp.ldlt().solve(f.bp - f.hpt * theta);
    }
  }

  // Covariance: the frames are the independent units (a frame's pixels share correlated
  // noise, quantisation steps and plane), so a cluster sandwich over frames; never below
  // the independent-pixel one. The affine directions are projected out of both.
  const Eigen::MatrixXd a_inv = a.ldlt().solve(Eigen::MatrixXd::Identity(num_nodes, num_nodes));
  std::vector<Eigen::VectorXd> scores(used.size());
  ParallelFor(static_cast<int>(used.size()), o.num_threads, [&](int u) {
    const int p = used[u];
    scores[u] = systems[u].r - ReducedTimes(grid, frames[p], inliers[p], 1 / (sigma[p] * sigma[p]),
                                            systems[u], theta);
  });
  Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(num_nodes, num_nodes);
  for (const Eigen::VectorXd& score : scores) meat.selfadjointView<Eigen::Lower>().rankUpdate(score);
  meat = meat.selfadjointView<Eigen::Lower>();
  const double n_used = static_cast<double>(used.size());
  meat *= n_used / (n_used - 1);
  const Eigen::MatrixXd projector =
      Eigen::MatrixXd::Identity(num_nodes, num_nodes) -
      basis * (basis.transpose() * basis).ldlt().solve(basis.transpose());
  const Eigen::MatrixXd sandwich = projector * a_inv * meat * a_inv * projector.transpose();
  const Eigen::MatrixXd independent = projector * a_inv * s_total * a_inv * projector.transpose();
  result.covariance = sandwich;
  result.sigma_per_m.resize(num_nodes);
  for (int k = 0; k < num_nodes; ++k) {
    result.sigma_per_m[k] = std::sqrt(std::max({sandwich(k, k), independent(k, k), 0.0}));
  }

  const Eigen::VectorXd theta_projected = projector * theta;
  if (theta_projected.cwiseAbs().maxCoeff() > core::DepthCorrection::kMaxAbsOffsetPerM) {
    // rig.yaml refuses such a field: no sensor reads 1 m as 0.5 m. The "planes" were not flat.
    throw std::invalid_argument(StringPrintf(
        "the fitted field reaches %.3g /m, beyond any depth sensor's (|offset| <= 1 /m): are the "
        "frames of a flat wall?",
        theta_projected.cwiseAbs().maxCoeff()));
  }
  grid.offset_per_m.assign(theta_projected.data(), theta_projected.data() + num_nodes);
  result.correction = grid;

  // Residuals before (a plane alone) and after (plane and field), per frame and overall.
  result.node_samples.assign(num_nodes, 0);
  double sum_before = 0, sum_after = 0;
  result.distance_min_m = std::numeric_limits<double>::infinity();
  result.distance_max_m = 0;
  for (const int p : used) {
    const DepthFrameSamples& s = frames[p];
    DepthPlaneFit& fit = result.frames[p];
    field.assign(s.w.size(), 0.0);
    for (size_t i = 0; i < s.w.size(); ++i) {
      if (!inliers[p][i]) continue;
      field[i] = grid.OffsetAt(s.x[i], s.y[i]);
      const Stencil st = grid.StencilAt(s.x[i], s.y[i]);
      for (int k = 0; k < 4; ++k) result.node_samples[st.node[k]] += st.weight[k] >= 0.25;
    }
    // The joint solve's plane stands in should a refit be degenerate (gating left too few).
    const Eigen::Vector3d plane_alone = FitPlane(s, inliers[p]).value_or(planes[p]);
    const Eigen::Vector3d plane_after = FitPlane(s, inliers[p], &field).value_or(planes[p]);
    double before = 0, after = 0;
    int count = 0;
    for (size_t i = 0; i < s.w.size(); ++i) {
      if (!inliers[p][i]) continue;
      const Eigen::Vector3d g(s.x[i], s.y[i], 1);
      before += std::pow(DepthMm(s.w[i] - plane_alone.dot(g), s.w[i]), 2);
      after += std::pow(DepthMm(s.w[i] - field[i] - plane_after.dot(g), s.w[i]), 2);
      ++count;
    }
    fit.inliers = count;
    fit.sigma_per_m = sigma[p];
    fit.rms_before_mm = std::sqrt(before / std::max(count, 1));
    fit.rms_after_mm = std::sqrt(after / std::max(count, 1));
    fit.distance_m = 1 / plane_after.z();
    fit.tilt_deg = std::acos(std::min(1.0, std::abs(plane_after.z()) / plane_after.norm())) *
                   180 / std::numbers::pi;
    result.distance_min_m = std::min(result.distance_min_m, fit.distance_m);
    result.distance_max_m = std::max(result.distance_max_m, fit.distance_m);
    sum_before += before;
    sum_after += after;
    result.samples_used += count;
  }
  result.frames_used = static_cast<int>(used.size());
  result.rms_before_mm = std::sqrt(sum_before / std::max(result.samples_used, 1));
  result.rms_after_mm = std::sqrt(sum_after / std::max(result.samples_used, 1));

  // Sizes as depth at 3 m: Δz ≈ z²·Δw.
  double sum_field = 0;
  int covered = 0;
  for (int k = 0; k < num_nodes; ++k) {
    sum_field += theta_projected(k) * theta_projected(k);
    if (result.node_samples[k] >= kCoveredNodeSamples) {
      ++covered;
      result.max_sigma_mm_at_3m = std::max(result.max_sigma_mm_at_3m, 9e3 * result.sigma_per_m[k]);
    }
  }
  result.field_rms_mm_at_3m = 9e3 * std::sqrt(sum_field / num_nodes);
  result.coverage = static_cast<double>(covered) / num_nodes;
  if (result.coverage < 1) {
    result.warnings.push_back(StringPrintf(
        "%d of %d grid nodes have fewer than %d samples on a plane: the field there comes from "
        "its neighbours (the smoothness prior); record the wall filling the whole image",
        num_nodes - covered, num_nodes, kCoveredNodeSamples));
  }
  if (result.distance_max_m < 1.5 * result.distance_min_m) {
    result.warnings.push_back(StringPrintf(
        "the planes were seen only from %.2f to %.2f m: the field is assumed the same at every "
        "distance; record from near to far to check it",
        result.distance_min_m, result.distance_max_m));
  }
  return result;
}

DepthFrameSamples SampleDepthFrame(const core::Scan& scan, int index,
                                   const core::CameraModel& camera,
                                   const DepthCorrectionOptions& o) {
  DepthFrameSamples s;
  s.frame = index;
  s.timestamp_s = scan.DepthClockTime(core::Stream::kDepth, index);
  const cv::Mat depth = scan.LoadDepth(index);
  for (int v = o.pixel_step / 2; v < depth.rows; v += o.pixel_step) {
    const float* row = depth.ptr<float>(v);
    for (int u = o.pixel_step / 2; u < depth.cols; u += o.pixel_step) {
      const double z = row[u];
      if (!(z >= o.min_depth_m && z <= o.max_depth_m)) continue;
      const std::optional<Eigen::Vector3d> ray = camera.Unproject({double(u), double(v)});
      if (!ray) continue;
      s.x.push_back(ray->x());
      s.y.push_back(ray->y());
      s.w.push_back(1 / z);
    }
  }
  s.valid = static_cast<int>(s.w.size());
  return s;
}

DepthCorrectionResult CalibrateDepthCorrection(const core::Scan& scan,
                                               const core::CameraModel& camera,
                                               const DepthCorrectionOptions& o,
                                               const std::function<void(int, int)>& progress) {
  assert(o.Check().empty());
  std::vector<int> indices;
  for (int i = 0; i < scan.NumFrames(core::Stream::kDepth); ++i) {
    if (scan.FrameExists(core::Stream::kDepth, i)) indices.push_back(i);
  }
  if (indices.empty()) {
    throw core::InputError(scan.folder(), "has no depth frame to calibrate the depth camera on");
  }
  if (o.max_frames > 0 && static_cast<int>(indices.size()) > o.max_frames) {
    std::vector<int> spread;
    for (int j = 0; j < o.max_frames; ++j) {
      spread.push_back(indices[static_cast<size_t>(j) * indices.size() / o.max_frames]);
    }
    indices = spread;
  }
  std::vector<DepthFrameSamples> frames(indices.size());
  std::atomic<int> done{0};
  std::mutex progress_mutex;
  ParallelFor(static_cast<int>(indices.size()), o.num_threads, [&](int j) {
    frames[j] = SampleDepthFrame(scan, indices[j], camera, o);
    const int d = ++done;
    if (progress) {
      const std::lock_guard<std::mutex> lock(progress_mutex);
      progress(d, static_cast<int>(indices.size()));
    }
  });
  try {
    return FitDepthCorrection(frames, core::DepthCorrection::ZeroOver(camera, o.nx, o.ny), o);
  } catch (const std::invalid_argument& e) {
    throw core::InputError(scan.folder(), e.what());
  }
}

cv::Mat DrawNodeField(const core::DepthCorrection& grid_in, const std::vector<double>& values,
                      const core::CameraModel& camera, bool is_signed, double max_abs,
                      const std::string& title) {
  assert(values.size() == static_cast<size_t>(grid_in.nx) * grid_in.ny);
  core::DepthCorrection grid = grid_in;
  grid.offset_per_m = values;
  const int scale = camera.width < 640 ? 2 : 1;
  const double top = max_abs > 0 ? max_abs : 1;
  cv::Mat level(camera.height * scale, camera.width * scale, CV_8UC1);
  cv::Mat out(level.size(), CV_8UC3);
  for (int v = 0; v < level.rows; ++v) {
    for (int u = 0; u < level.cols; ++u) {
      const std::optional<Eigen::Vector3d> ray =
          camera.Unproject({(u + 0.5) / scale - 0.5, (v + 0.5) / scale - 0.5});
      const double value = ray ? grid.OffsetAt(ray->x(), ray->y()) : 0.0;
      if (is_signed) {
        // Blue (negative) through white to red (positive), BGR.
        const double t = std::clamp(value / top, -1.0, 1.0);
        const auto fade = static_cast<uint8_t>(255 * (1 - std::abs(t)));
        out.at<cv::Vec3b>(v, u) = t < 0 ? cv::Vec3b(255, fade, fade) : cv::Vec3b(fade, fade, 255);
      } else {
        level.at<uint8_t>(v, u) = static_cast<uint8_t>(std::clamp(255 * value / top, 0.0, 255.0));
      }
    }
  }
  if (!is_signed) cv::applyColorMap(level, out, cv::COLORMAP_TURBO);
  const std::string key = is_signed ? StringPrintf("blue -%.2f, white 0, red +%.2f", top, top)
                                    : StringPrintf("colour 0 to %.2f", top);
  for (const auto& [text, y] : {std::pair{title, 18}, std::pair{key, 38}}) {
    cv::putText(out, text, cv::Point(8, y), cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0), 3,
                cv::LINE_AA);
    cv::putText(out, text, cv::Point(8, y), cv::FONT_HERSHEY_SIMPLEX, 0.5,
                cv::Scalar(255, 255, 255), 1, cv::LINE_AA);
  }
  return out;
}

}  // namespace hw::calibrate
