#include "core/camera.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <charconv>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <system_error>
#include <tuple>
#include <utility>
#include <vector>

#include <Eigen/Dense>

#include "core/camera_mrcal.h"

namespace hw::core {
namespace {

// Shortest text that reads back to the same double ("-525", "0.1", "nan", "inf").
std::string FormatNumber(double value) {
  if (std::isnan(value)) return "nan";
  if (std::isinf(value)) return value > 0 ? "inf" : "-inf";
  std::array<char, 64> buffer{};
  const auto [end, ec] = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  assert(ec == std::errc());
  return std::string(buffer.data(), end);
}

std::string MustBePositive(const std::string& field, double value) {
  return field + ": must be > 0, got " + FormatNumber(value);
}

// The eight OpenCV coefficients k1 k2 p1 p2 k3 k4 k5 k6, zero-filled past the model's count.
struct Coefficients {
  double k1 = 0, k2 = 0, p1 = 0, p2 = 0, k3 = 0, k4 = 0, k5 = 0, k6 = 0;
  bool operator==(const Coefficients&) const = default;
};

Coefficients Unpack(const std::vector<double>& distortion) {
  std::array<double, 8> c{};
  assert(distortion.size() <= c.size());
  for (size_t i = 0; i < distortion.size() && i < c.size(); ++i) c[i] = distortion[i];
  return {c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]};
}

}  // namespace

std::string CameraModelTypeName(CameraModelType type) {
  switch (type) {
    case CameraModelType::kPinhole:
      return "pinhole";
    case CameraModelType::kOpenCV:
      return "opencv";
    case CameraModelType::kSplined:
      return "splined";
  }
  assert(false && "unknown CameraModelType");
  return "unknown";
}

std::optional<CameraModelType> ParseCameraModelType(const std::string& name) {
  if (name == "pinhole") return CameraModelType::kPinhole;
  if (name == "opencv") return CameraModelType::kOpenCV;
  if (name == "splined") return CameraModelType::kSplined;
  return std::nullopt;
}

std::string UndistortOptions::Check() const {
  if (max_iterations <= 0) return MustBePositive("max_iterations", max_iterations);
  // !(x > 0) also rejects NaN.
  if (!(tolerance_px > 0) || !std::isfinite(tolerance_px)) {
    return "tolerance_px: must be > 0 and finite, got " + FormatNumber(tolerance_px);
  }
  return "";
}

std::string SplinedConfig::Check() const {
  if (order != 2 && order != 3) {
    return "splined.order: must be 2 or 3, got " + std::to_string(order);
  }
  // At least 4 knots: a cubic segment needs 4 control points. At most 64: 8192 parameters,
  // far beyond what a calibration constrains (mrcal's examples use 30 x 18 or fewer).
  const std::array<std::pair<const char*, int>, 2> counts{{{"nx", nx}, {"ny", ny}}};
  for (const auto& [name, value] : counts) {
    if (value < 4 || value > 64) {
      return std::string("splined.") + name + ": must be in [4, 64], got " +
             std::to_string(value);
    }
  }
  // The stereographic projection is finite up to 180 degrees off axis; a spline spanning
  // 180 degrees or more across would reach it.
  if (fov_x_deg < 1 || fov_x_deg > 179) {
    return "splined.fov_x_deg: must be in [1, 179] degrees, got " + std::to_string(fov_x_deg);
  }
  return "";
}

CameraModel CameraModel::Pinhole(int width, int height, double fx, double fy) {
  CameraModel model;
  model.width = width;
  model.height = height;
  model.type = CameraModelType::kPinhole;
  model.fx = fx;
  model.fy = fy;
  // Pixel (0, 0) is the centre of the top-left pixel, so the image centre is (w - 1) / 2.
  model.cx = (width - 1) / 2.0;
  model.cy = (height - 1) / 2.0;
  return model;
}

namespace {

// FormatNumber with a plain exponent, "1e6" and "1e300" rather than to_chars' "1e+06".
std::string TidyNumber(double value) {
  std::string text = FormatNumber(value);
  const size_t e = text.find('e');
  if (e == std::string::npos) return text;
  size_t digits = e + 1;
  if (text[digits] == '+') {
    text.erase(digits, 1);
  } else if (text[digits] == '-') {
    ++digits;
  }
  while (digits + 1 < text.size() && text[digits] == '0') text.erase(digits, 1);
  return text;
}

// "" when lo <= value <= hi, else "<field>: must be in [lo, hi] px, got <value>" ("must be
// finite" for NaN and inf).
std::string CheckRangePx(const std::string& field, double value, double lo, double hi) {
  if (!std::isfinite(value)) return field + ": must be finite, got " + FormatNumber(value);
  if (value >= lo && value <= hi) return "";
  return field + ": must be in [" + TidyNumber(lo) + ", " + TidyNumber(hi) + "] px, got " +
         TidyNumber(value);
}

}  // namespace

std::string CameraModel::Check() const {
  // Sizes first: the principal point's range depends on them.
  const std::array<std::pair<const char*, int>, 2> sizes{{{"width", width}, {"height", height}}};
  for (const auto& [name, value] : sizes) {
    if (value < 1 || value > kMaxSidePx) {
      return std::string(name) + ": must be in [1, " + std::to_string(kMaxSidePx) + "] px, got " +
             std::to_string(value);
    }
  }
  const std::array<std::pair<const char*, double>, 2> focals{{{"fx", fx}, {"fy", fy}}};
  for (const auto& [name, value] : focals) {
    if (std::string problem = CheckRangePx(name, value, kMinFocalPx, kMaxFocalPx);
        !problem.empty()) {
      return problem;
    }
  }
  const std::array<std::tuple<const char*, double, int, const char*>, 2> centre{
      {{"cx", cx, width, "width"}, {"cy", cy, height, "height"}}};
  for (const auto& [name, value, size, side] : centre) {
    if (!std::isfinite(value)) {
      return std::string(name) + ": must be finite, got " + TidyNumber(value);
    }
    if (!(value >= -size && value <= 2.0 * size)) {
      return std::string(name) + ": must be in [-" + side + ", 2 " + side + "] = [" +
             TidyNumber(-size) + ", " + TidyNumber(2.0 * size) + "] px, got " + TidyNumber(value);
    }
  }
  const size_t n = distortion.size();
  switch (type) {
    case CameraModelType::kPinhole:
      if (n != 0) {
        return "distortion: pinhole needs 0 coefficients, got " + std::to_string(n);
      }
      break;
    case CameraModelType::kOpenCV:
      if (n != 4 && n != 5 && n != 8) {
        return "distortion: opencv needs 4, 5 or 8 coefficients, got " + std::to_string(n);
      }
      break;
    case CameraModelType::kSplined:
      if (std::string problem = splined.Check(); !problem.empty()) return problem;
      if (n != static_cast<size_t>(splined.NumControls())) {
        return "distortion: splined with nx = " + std::to_string(splined.nx) +
               ", ny = " + std::to_string(splined.ny) + " needs 2 nx ny = " +
               std::to_string(splined.NumControls()) + " control values, got " +
               std::to_string(n);
      }
      break;
  }
  for (size_t i = 0; i < n; ++i) {
    const std::string field = "distortion[" + std::to_string(i) + "]";
    if (!std::isfinite(distortion[i])) {
      return field + ": must be finite, got " + FormatNumber(distortion[i]);
    }
    if (!(std::abs(distortion[i]) <= kMaxAbsDistortion)) {
      return field + ": must be in [-" + TidyNumber(kMaxAbsDistortion) + ", " +
             TidyNumber(kMaxAbsDistortion) + "], got " + TidyNumber(distortion[i]);
    }
  }
  return "";
}

Eigen::VectorXd CameraModel::Params() const {
  Eigen::VectorXd params(NumParams());
  params.head<4>() << fx, fy, cx, cy;
  for (size_t i = 0; i < distortion.size(); ++i) {
    params[4 + static_cast<Eigen::Index>(i)] = distortion[i];
  }
  return params;
}

void CameraModel::SetParams(const Eigen::VectorXd& params) {
  assert(params.size() == NumParams());
  fx = params[0];
  fy = params[1];
  cx = params[2];
  cy = params[3];
  for (size_t i = 0; i < distortion.size(); ++i) {
    distortion[i] = params[4 + static_cast<Eigen::Index>(i)];
  }
}

Eigen::Vector2d CameraModel::Distort(const Eigen::Vector2d& xy_undistorted, Eigen::Matrix2d* J_xy,
                                     Eigen::Matrix<double, 2, Eigen::Dynamic>* J_dist) const {
  if (type == CameraModelType::kSplined) {
    return SplinedDistort(*this, xy_undistorted, J_xy, J_dist);
  }
  const auto num_dist = static_cast<Eigen::Index>(distortion.size());
  if (J_dist != nullptr) J_dist->setZero(2, num_dist);
  if (type == CameraModelType::kPinhole || distortion.empty()) {
    if (J_xy != nullptr) J_xy->setIdentity();
    return xy_undistorted;
  }
  assert(num_dist >= 4 && num_dist <= 8);  // Check() guarantees 4, 5 or 8 for opencv
  const Coefficients c = Unpack(distortion);
  const double x = xy_undistorted.x();
  const double y = xy_undistorted.y();
  const double r2 = x * x + y * y;
  const double r4 = r2 * r2;
  const double r6 = r4 * r2;
  // radial = a / b (OpenCV's rational model; b = 1 with fewer than 8 coefficients).
  const double a = 1 + c.k1 * r2 + c.k2 * r4 + c.k3 * r6;
  const double b = 1 + c.k4 * r2 + c.k5 * r4 + c.k6 * r6;
  const double inv_b = 1 / b;
  const double radial = a * inv_b;
  const double two_xy = 2 * x * y;
  const Eigen::Vector2d xy_distorted(x * radial + c.p1 * two_xy + c.p2 * (r2 + 2 * x * x),
                                     y * radial + c.p1 * (r2 + 2 * y * y) + c.p2 * two_xy);

  if (J_xy != nullptr) {
    // d(radial)/d(r2) by the quotient rule; d(r2)/dx = 2x, d(r2)/dy = 2y.
    const double da = c.k1 + 2 * c.k2 * r2 + 3 * c.k3 * r4;
    const double db = c.k4 + 2 * c.k5 * r2 + 3 * c.k6 * r4;
    const double dradial = (da * b - a * db) * inv_b * inv_b;
    const double cross = two_xy * dradial + 2 * c.p1 * x + 2 * c.p2 * y;
    (*J_xy)(0, 0) = radial + 2 * x * x * dradial + 2 * c.p1 * y + 6 * c.p2 * x;
    (*J_xy)(0, 1) = cross;
    (*J_xy)(1, 0) = cross;
    (*J_xy)(1, 1) = radial + 2 * y * y * dradial + 6 * c.p1 * y + 2 * c.p2 * x;
  }
  if (J_dist != nullptr) {
    // Column order follows `distortion`: k1 k2 p1 p2 k3 k4 k5 k6.
    const std::array<double, 8> dradial_dk{
        r2 * inv_b,           r4 * inv_b,          0, 0, r6 * inv_b, -radial * r2 * inv_b,
        -radial * r4 * inv_b, -radial * r6 * inv_b};
    for (Eigen::Index i = 0; i < num_dist; ++i) {
      (*J_dist)(0, i) = x * dradial_dk[static_cast<size_t>(i)];
      (*J_dist)(1, i) = y * dradial_dk[static_cast<size_t>(i)];
    }
    (*J_dist)(0, 2) = two_xy;
    (*J_dist)(1, 2) = r2 + 2 * y * y;
    (*J_dist)(0, 3) = r2 + 2 * x * x;
    (*J_dist)(1, 3) = two_xy;
  }
  return xy_distorted;
}

namespace {

// A polynomial in one variable of degree N - 1, coefficients from the constant term up.
// Fixed sizes keep the fold test below free of allocations.
template <size_t N>
using Polynomial = std::array<double, N>;

template <size_t N, size_t M>
Polynomial<N + M - 1> Multiply(const Polynomial<N>& p, const Polynomial<M>& q) {
  Polynomial<N + M - 1> product{};
  for (size_t i = 0; i < N; ++i) {
    for (size_t j = 0; j < M; ++j) product[i + j] += p[i] * q[j];
  }
  return product;
}

// p - q, q padded with zeros.
template <size_t N, size_t M>
Polynomial<N> Subtract(const Polynomial<N>& p, const Polynomial<M>& q) {
  static_assert(M <= N);
  Polynomial<N> difference = p;
  for (size_t i = 0; i < M; ++i) difference[i] -= q[i];
  return difference;
}

// C(k, i) / C(n, i) for degree n = N - 1, the monomial-to-Bernstein basis change.
template <size_t N>
constexpr std::array<std::array<double, N>, N> MonomialToBernstein() {
  std::array<std::array<double, N>, N> binomial{};  // Pascal's triangle
  for (size_t k = 0; k < N; ++k) {
    binomial[k][0] = 1;
    for (size_t i = 1; i <= k; ++i) {
      binomial[k][i] = binomial[k - 1][i - 1] + (i < k ? binomial[k - 1][i] : 0);
    }
  }
  std::array<std::array<double, N>, N> ratio{};
  for (size_t k = 0; k < N; ++k) {
    for (size_t i = 0; i <= k; ++i) ratio[k][i] = binomial[k][i] / binomial[N - 1][i];
  }
  return ratio;
}

// True when p(x) > 0 for every x in [0, x_max]. The Bernstein coefficients of p on an
// interval bound it there (p lies in their convex hull): all positive certifies the piece, a
// non-positive end value refutes it, anything else is halved (de Casteljau). A piece still
// undecided after many halvings (a double root, to rounding) counts as not positive, so the
// answer errs on the safe side.
template <size_t N>
bool IsPositiveOn(const Polynomial<N>& p, double x_max) {
  constexpr size_t n = N - 1;  // degree
  // Monomial to Bernstein on [0, x_max]: b_k = sum_{i <= k} C(k, i) / C(n, i) c_i x_max^i.
  static constexpr auto kToBernstein = MonomialToBernstein<N>();
  Polynomial<N> scaled = p;
  double power = 1;
  for (size_t i = 0; i <= n; ++i) {
    scaled[i] *= power;
    power *= x_max;
  }
  constexpr int kMaxDepth = 40;
  constexpr int kMaxPieces = 2000;  // bounds the cost on pathological input
  // Depth-first: at most one pending piece per level besides the current one.
  std::array<Polynomial<N>, kMaxDepth + 2> stack;
  std::array<int, kMaxDepth + 2> depths;
  size_t size = 1;
  depths[0] = 0;
  for (size_t k = 0; k <= n; ++k) {
    double b_k = 0;
    for (size_t i = 0; i <= k; ++i) b_k += kToBernstein[k][i] * scaled[i];
    stack[0][k] = b_k;
  }
  for (int pieces = 0; size > 0; ++pieces) {
    --size;
    const Polynomial<N> piece = stack[size];
    const int depth = depths[size];
    if (*std::min_element(piece.begin(), piece.end()) > 0) continue;
    // Written so that NaN counts as not positive.
    if (!(piece.front() > 0) || !(piece.back() > 0)) return false;
    if (depth == kMaxDepth || pieces == kMaxPieces) return false;
    Polynomial<N>& left = stack[size];
    Polynomial<N>& right = stack[size + 1];
    Polynomial<N> work = piece;
    for (size_t level = 0; level <= n; ++level) {
      left[level] = work[0];
      right[n - level] = work[n - level];
      for (size_t i = 0; i < n - level; ++i) work[i] = (work[i] + work[i + 1]) / 2;
    }
    depths[size] = depths[size + 1] = depth + 1;
    size += 2;
  }
  return true;
}

// A polynomial lens folds over away from the centre: past the fold a distorted point has
// further, unphysical preimages, e.g. beyond a second fold, beyond a pole of the rational
// model, or through the centre on the far side. The physical preimage is the one reached
// from the centre along the segment to it without the map folding (J = I at the centre).
//
// Certified, not sampled: J = A + T, where A is the radial part, with eigenvalues
// radial = a / b (across the ray) and d(r radial)/dr (along it), and T the tangential part,
// linear in the point, so |T|_2 <= |T|_F = tau r along the segment. If b > 0 and both
// eigenvalues of A exceed tau r for every r in [0, R = |xy|], J never becomes singular
// (Weyl), so det J > 0 and the distorted radius grows all the way. With u = r^2,
// r <= (u / R + R) / 2 (equal at r = R), and multiplying by b^2 gives polynomials in u of
// degree <= 7, checked on [0, R^2]:
//   a b - s b^2 > 0,  (a + 2u a') b - 2u a b' - s b^2 > 0,  s = tau (u / R + R) / 2,
// which also keep b > 0 (b = 1 at the centre). IsUnfolded checks them for one R and tau.
// Sufficient, not necessary: it may reject a point near the fold, never accept a wrong one.
bool IsUnfolded(const Coefficients& c, double r_max, double tau) {
  if (r_max == 0) return true;
  const Polynomial<4> a = {1, c.k1, c.k2, c.k3};
  const Polynomial<4> b = {1, c.k4, c.k5, c.k6};
  const Polynomial<4> a_plus_2u_da = {1, 3 * c.k1, 5 * c.k2, 7 * c.k3};
  const Polynomial<4> two_u_db = {0, 2 * c.k4, 4 * c.k5, 6 * c.k6};
  const Polynomial<8> s_b2 =
      Multiply(Polynomial<2>{tau * r_max / 2, tau / (2 * r_max)}, Multiply(b, b));
  Polynomial<8> across{}, along{};
  const Polynomial<7> a_b = Multiply(a, b);
  const Polynomial<7> slope_b2 = Subtract(Multiply(a_plus_2u_da, b), Multiply(a, two_u_db));
  for (size_t i = 0; i < 7; ++i) {
    across[i] = a_b[i];
    along[i] = slope_b2[i];
  }
  // b > 0 needs no test of its own: b changes sign only where a b - s b^2 = b (a - s b) = 0.
  const double u_max = r_max * r_max;
  return IsPositiveOn(Subtract(across, s_b2), u_max) && IsPositiveOn(Subtract(along, s_b2), u_max);
}

// The disc |xy| <= R on which IsUnfolded holds in every direction, with tau replaced by its
// maximum over directions. Shrinking R only relaxes the conditions (s decreases pointwise on
// [0, R'^2] for R' < R), so the certified radii form an interval, found by bisection.
double CertifiedRadius(const Coefficients& c) {
  // |T(w)|_F^2 = w^T Q w over unit directions w; tau_max^2 is the larger eigenvalue of Q.
  const Eigen::Vector2d g0(6 * c.p2, 2 * c.p1), g1(2 * c.p1, 2 * c.p2), g2(2 * c.p2, 6 * c.p1);
  const Eigen::Matrix2d Q = g0 * g0.transpose() + 2 * g1 * g1.transpose() + g2 * g2.transpose();
  const double half_trace = Q.trace() / 2;
  const double tau_max =
      std::sqrt(half_trace + std::sqrt(std::max(0.0, half_trace * half_trace - Q.determinant())));
  constexpr double kLargestRadius = 1e4;  // 1e4 focal lengths out: beyond any use
  double lo = 0, hi = 1;
  while (IsUnfolded(c, hi, tau_max)) {
    lo = hi;
    if (hi >= kLargestRadius) return hi;
    hi *= 2;
  }
  for (int i = 0; i < 30; ++i) {
    const double mid = (lo + hi) / 2;
    (IsUnfolded(c, mid, tau_max) ? lo : hi) = mid;
  }
  return lo;
}

// True when xy_undistorted is certified to be the physical preimage of its distorted point
// (IsUnfolded along its direction); false near or beyond a fold.
bool IsOnPhysicalBranch(const CameraModel& model, const Eigen::Vector2d& xy_undistorted) {
  if (model.type == CameraModelType::kSplined) {
    // No certificate for a spline: accept where the map keeps its orientation (it is the
    // identity-like stereographic projection at the centre), which rules out a preimage
    // past a fold.
    Eigen::Matrix2d J;
    model.Distort(xy_undistorted, &J);
    return J.determinant() > 0;
  }
  const Coefficients c = Unpack(model.distortion);
  // Fast path: the certified disc of a few recent lenses, per thread: 40-odd IsUnfolded
  // calls once per lens instead of one per Unproject. The disc is certified with tau_max >=
  // tau, so it only accepts what the per-direction test below accepts: results never depend
  // on the cache.
  struct Entry {
    Coefficients c;
    double radius2;
  };
  thread_local std::array<Entry, 4> cache;
  thread_local size_t cache_size = 0, cache_next = 0;
  const Entry* entry = nullptr;
  for (size_t i = 0; i < cache_size; ++i) {
    if (cache[i].c == c) entry = &cache[i];
  }
  if (entry == nullptr) {
    const double radius = CertifiedRadius(c);
    cache[cache_next] = {c, radius * radius};
    entry = &cache[cache_next];
    cache_size = std::max(cache_size, cache_next + 1);
    cache_next = (cache_next + 1) % cache.size();
  }
  if (xy_undistorted.squaredNorm() <= entry->radius2) return true;

  const double r_max = xy_undistorted.norm();
  const Eigen::Vector2d w = xy_undistorted / r_max;  // unit direction of the segment
  const double t00 = 2 * c.p1 * w.y() + 6 * c.p2 * w.x();
  const double t01 = 2 * c.p1 * w.x() + 2 * c.p2 * w.y();
  const double t11 = 6 * c.p1 * w.y() + 2 * c.p2 * w.x();
  return IsUnfolded(c, r_max, std::sqrt(t00 * t00 + 2 * t01 * t01 + t11 * t11));
}

// Newton's method (Gauss-Newton on a square 2x2 system) for Distort(xy) = target from the
// guess in `xy`, for at most `max_iterations` steps. On success returns true with `xy` one
// step past the first iterate whose residual is below tolerance_px (through fx, fy): that
// step costs little and, convergence being quadratic, takes the error to rounding level.
// `iterations` accumulates the Distort evaluations spent.
bool SolveDistort(const CameraModel& model, const Eigen::Vector2d& target, double tolerance_px,
                  int max_iterations, Eigen::Vector2d& xy, int& iterations) {
  const Eigen::Vector2d pixels_per_unit(model.fx, model.fy);
  for (int iteration = 0; iteration <= max_iterations; ++iteration) {
    ++iterations;
    Eigen::Matrix2d J;
    const Eigen::Vector2d residual = model.Distort(xy, &J) - target;
    if (!residual.allFinite() || !J.allFinite()) return false;
    // Far out (thousands of image widths) Distort itself is only accurate to a few ulps of
    // the target; below that floor the residual is rounding noise, not lack of convergence.
    const double floor_px =
        64 * std::numeric_limits<double>::epsilon() * target.cwiseProduct(pixels_per_unit).norm();
    const bool converged =
        residual.cwiseProduct(pixels_per_unit).norm() < std::max(tolerance_px, floor_px);
    if (!converged && iteration == max_iterations) return false;
    // Reject a (numerically) singular Jacobian rather than take an enormous step.
    if (!(std::abs(J.determinant()) > 1e-12 * J.squaredNorm())) return false;
    xy -= J.inverse() * residual;
    if (!xy.allFinite()) return false;
    if (converged) return true;
  }
  return false;
}

}  // namespace

std::optional<Eigen::Vector2d> CameraModel::Undistort(const Eigen::Vector2d& xy_distorted,
                                                      const UndistortOptions& options) const {
  assert(options.Check().empty());
  if (!xy_distorted.allFinite()) return std::nullopt;
  if (type == CameraModelType::kPinhole || distortion.empty()) return xy_distorted;

  // Fast path: Newton from the distorted point itself, exact for a weak lens and 3-6
  // iterations for any real lens inside its image.
  int iterations = 0;
  Eigen::Vector2d xy = xy_distorted;
  if (type == CameraModelType::kSplined) {
    // Start from the stereographic preimage, ignoring the spline: |u| = 2 tan(theta / 2),
    // |xy| = tan(theta). Beyond 90 degrees off axis there is no normalised point.
    const double u = xy_distorted.norm();
    const double theta = 2 * std::atan(u / 2);
    if (!(theta < std::numbers::pi / 2)) return std::nullopt;
    if (u > 0) xy = xy_distorted * (std::tan(theta) / u);
  }
  if (SolveDistort(*this, xy_distorted, options.tolerance_px, options.max_iterations, xy,
                   iterations) &&
      IsOnPhysicalBranch(*this, xy)) {
    return xy;
  }
  // Strong lenses far from the centre: Newton may have diverged or landed on an unphysical
  // preimage. Follow the physical branch instead, from the centre (where xy = 0 solves it)
  // to the target in steps, each solved from the last; a step that fails is halved, until
  // the step or the budget of max_iterations runs out.
  constexpr int kIterationsPerStep = 8;  // a short step converges in 2-4
  constexpr double kMinStep = 1.0 / 1024;
  xy.setZero();
  iterations = 0;
  double t = 0, step = 0.25;
  while (t < 1) {
    const double t_next = std::min(1.0, t + step);
    Eigen::Vector2d candidate = xy;
    const int budget = std::min(kIterationsPerStep, options.max_iterations - iterations);
    if (budget <= 0) return std::nullopt;
    // A long step can land Newton on another branch: every accepted step is certified.
    if (SolveDistort(*this, t_next * xy_distorted, options.tolerance_px, budget, candidate,
                     iterations) &&
        IsOnPhysicalBranch(*this, candidate)) {
      t = t_next;
      xy = candidate;
      step *= 2;
    } else {
      step /= 2;
      if (step < kMinStep) return std::nullopt;
    }
  }
  return xy;
}

Eigen::Vector2d CameraModel::Project(const Eigen::Vector3d& point_in_camera,
                                     Eigen::Matrix<double, 2, 3>* J_point,
                                     Eigen::Matrix<double, 2, Eigen::Dynamic>* J_params) const {
  const double inv_z = 1 / point_in_camera.z();
  const Eigen::Vector2d xy(point_in_camera.x() * inv_z, point_in_camera.y() * inv_z);
  Eigen::Matrix2d J_xy;
  Eigen::Matrix<double, 2, Eigen::Dynamic> J_dist;
  const Eigen::Vector2d xy_distorted =
      Distort(xy, J_point != nullptr ? &J_xy : nullptr, J_params != nullptr ? &J_dist : nullptr);
  const Eigen::Vector2d pixel(fx * xy_distorted.x() + cx, fy * xy_distorted.y() + cy);
  const Eigen::DiagonalMatrix<double, 2> focal(fx, fy);
  if (J_point != nullptr) {
    // d(x/z, y/z)/d(point).
    Eigen::Matrix<double, 2, 3> J_normalise;
    J_normalise << inv_z, 0, -xy.x() * inv_z, 0, inv_z, -xy.y() * inv_z;
    *J_point = focal * J_xy * J_normalise;
  }
  if (J_params != nullptr) {
    J_params->setZero(2, NumParams());
    (*J_params)(0, 0) = xy_distorted.x();
    (*J_params)(1, 1) = xy_distorted.y();
    (*J_params)(0, 2) = 1;
    (*J_params)(1, 3) = 1;
    J_params->rightCols(J_dist.cols()) = focal * J_dist;
  }
  return pixel;
}

std::optional<Eigen::Vector3d> CameraModel::Unproject(const Eigen::Vector2d& pixel,
                                                      const UndistortOptions& options) const {
  const Eigen::Vector2d xy_distorted((pixel.x() - cx) / fx, (pixel.y() - cy) / fy);
  const std::optional<Eigen::Vector2d> xy = Undistort(xy_distorted, options);
  if (!xy) return std::nullopt;
  return Eigen::Vector3d(xy->x(), xy->y(), 1);
}

bool CameraModel::IsInImage(const Eigen::Vector2d& pixel) const {
  // Written so that NaN compares false.
  return pixel.x() >= -0.5 && pixel.x() < width - 0.5 && pixel.y() >= -0.5 &&
         pixel.y() < height - 0.5;
}

CameraModel CameraModel::Scaled(double factor) const {
  assert(factor > 0 && std::isfinite(factor));
  CameraModel scaled = *this;
  scaled.width = static_cast<int>(std::lround(width * factor));
  scaled.height = static_cast<int>(std::lround(height * factor));
  scaled.fx = fx * factor;
  scaled.fy = fy * factor;
  // Pixel edges scale, not centres: the left edge of the image is at -0.5 in both images.
  scaled.cx = (cx + 0.5) * factor - 0.5;
  scaled.cy = (cy + 0.5) * factor - 0.5;
  return scaled;
}

Eigen::Matrix3d CameraModel::K() const {
  Eigen::Matrix3d intrinsics;
  intrinsics << fx, 0, cx, 0, fy, cy, 0, 0, 1;
  return intrinsics;
}

bool operator==(const CameraModel& a, const CameraModel& b) {
  return a.width == b.width && a.height == b.height && a.type == b.type && a.fx == b.fx &&
         a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.distortion == b.distortion &&
         (a.type != CameraModelType::kSplined || a.splined == b.splined);
}

}  // namespace hw::core
