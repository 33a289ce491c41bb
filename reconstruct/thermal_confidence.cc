#include "reconstruct/thermal_confidence.h"

#include <cassert>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

#include "reconstruct/option_check.h"

namespace hw::reconstruct {

using internal::Fail;
using internal::InRange;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// exp(−½ (x / scale)²); NaN → 0.
double Gaussian(double x, double scale) {
  if (std::isnan(x)) return 0;
  const double r = x / scale;
  return std::exp(-0.5 * r * r);
}

// c^p without pow for the common powers (c in [0, 1]; 0^0 = 1).
double Power(double c, double p) {
  if (p == 1) return c;
  if (p == 0) return 1;
  if (p == 2) return c * c;
  return std::pow(c, p);
}

// cos(max_angle_deg), remembered per thread for the last angle asked: the options do not
// change between rays, and the cosine was a quarter of a ray's confidence time.
double CosOfMaxAngle(double max_angle_deg) {
  thread_local double last_deg = kNaN, last_cos = kNaN;
  if (max_angle_deg != last_deg) {
    last_cos = std::cos(max_angle_deg * (M_PI / 180.0));
    last_deg = max_angle_deg;
  }
  return last_cos;
}

}  // namespace

std::string ThermalConfidenceOptions::Check() const {
  const struct {
    const char* name;
    double value;
  } powers[] = {{"motion_power", motion_power},
                {"distortion_power", distortion_power},
                {"angle_power", angle_power},
                {"distance_power", distance_power},
                {"operating_power", operating_power}};
  for (const auto& p : powers) {
    if (!InRange(p.value, 0, 10)) return Fail(p.name, p.value, "in [0, 10]");
  }
  if (!InRange(integration_time_s, 0, 1)) {
    return Fail("integration_time_s", integration_time_s, "in [0, 1] s");
  }
  if (!(motion_blur_px > 0) || !std::isfinite(motion_blur_px)) {
    return Fail("motion_blur_px", motion_blur_px, "> 0 px and finite");
  }
  if (!(distortion_px > 0) || !std::isfinite(distortion_px)) {
    return Fail("distortion_px", distortion_px, "> 0 px and finite");
  }
  if (!(max_angle_deg > 0 && max_angle_deg <= 90)) {
    return Fail("max_angle_deg", max_angle_deg, "in (0, 90] degrees");
  }
  if (!(reference_distance_m > 0) || !std::isfinite(reference_distance_m)) {
    return Fail("reference_distance_m", reference_distance_m, "> 0 m and finite");
  }
  if (!(ffc_settle_s >= 0) || !std::isfinite(ffc_settle_s)) {
    return Fail("ffc_settle_s", ffc_settle_s, ">= 0 s and finite");
  }
  if (!(ffc_ramp_s >= 0) || !std::isfinite(ffc_ramp_s)) {
    return Fail("ffc_ramp_s", ffc_ramp_s, ">= 0 s and finite");
  }
  if (!(drift_onset_s >= 0) || !std::isfinite(drift_onset_s)) {
    return Fail("drift_onset_s", drift_onset_s, ">= 0 s and finite");
  }
  if (!(drift_time_s > 0) || std::isnan(drift_time_s)) {
    return Fail("drift_time_s", drift_time_s, "> 0 s");  // +inf: no drift
  }
  return "";
}

double ImageSpeedPxPerS(const Eigen::Vector3d& point_in_camera,
                        const Eigen::Vector3d& linear_velocity_mps,
                        const Eigen::Vector3d& angular_velocity_radps, double fx, double fy) {
  const double z = point_in_camera.z();
  if (!(z > 0)) return kNaN;
  // u = fx x / z + cx: du/dt = fx (ẋ z − x ż) / z² (likewise v), with Ṗ = −v − ω × P.
  const Eigen::Vector3d velocity =
      -linear_velocity_mps - angular_velocity_radps.cross(point_in_camera);
  const double inv_z2 = 1.0 / (z * z);
  const double du = fx * (velocity.x() * z - point_in_camera.x() * velocity.z()) * inv_z2;
  const double dv = fy * (velocity.y() * z - point_in_camera.y() * velocity.z()) * inv_z2;
  return std::sqrt(du * du + dv * dv);
}

double MotionConfidence(double blur_px, const ThermalConfidenceOptions& o) {
  return Gaussian(blur_px, o.motion_blur_px);
}

double DistortionConfidence(double distortion_px, const ThermalConfidenceOptions& o) {
  return Gaussian(distortion_px, o.distortion_px);
}

double AngleConfidence(double cos_angle, const ThermalConfidenceOptions& o) {
  if (!(cos_angle > 0)) return 0;  // facing away, grazing at 90°, or NaN
  // θ <= max  ⇔  cos θ >= cos(max) on [0°, 90°]; at 90° every front-facing ray passes.
  if (o.max_angle_deg < 90 && cos_angle < CosOfMaxAngle(o.max_angle_deg)) return 0;
  return cos_angle < 1 ? cos_angle : 1;
}

double DistanceConfidence(double distance_m, const ThermalConfidenceOptions& o) {
  if (!(distance_m > 0)) return 0;
  return distance_m <= o.reference_distance_m ? 1 : o.reference_distance_m / distance_m;
}

double OperatingConfidence(double time_since_ffc_s, bool frozen,
                           const ThermalConfidenceOptions& o) {
  if (frozen) return 0;
  const double t = time_since_ffc_s;
  if (std::isnan(t)) return 1;
  assert(t >= 0 && "time since the last FFC event must be >= 0 (NaN: unknown)");
  if (t < o.ffc_settle_s) return 0;
  double c = 1;
  const double ramp_end_s = o.ffc_settle_s + o.ffc_ramp_s;
  if (t < ramp_end_s) c = (t - o.ffc_settle_s) / o.ffc_ramp_s;  // ffc_ramp_s > 0 here
  if (t > o.drift_onset_s) c *= std::exp(-(t - o.drift_onset_s) / o.drift_time_s);
  return c;
}

double RayConfidence(const ConfidenceTerms& c, const ThermalConfidenceOptions& o) {
  assert(c.motion >= 0 && c.motion <= 1);
  assert(c.distortion >= 0 && c.distortion <= 1);
  assert(c.angle >= 0 && c.angle <= 1);
  assert(c.distance >= 0 && c.distance <= 1);
  assert(c.operating >= 0 && c.operating <= 1);
  return Power(c.motion, o.motion_power) * Power(c.distortion, o.distortion_power) *
         Power(c.angle, o.angle_power) * Power(c.distance, o.distance_power) *
         Power(c.operating, o.operating_power);
}

}  // namespace hw::reconstruct
