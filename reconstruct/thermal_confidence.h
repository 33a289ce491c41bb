#pragma once

// The per-ray confidence of a thermal observation (HeatWave, Moghadam & Vidas, §2.2):
// C_R = Π c_i^p_i over five metrics, each c_i in [0, 1]: c1 motion blur, c2 lens
// distortion, c3 angle between the ray and the surface normal, c4 distance, c5 the camera's
// operating condition (time since its last flat-field correction). Pure functions, called
// once per ray: no allocation, no pow when a power is 0 or 1.

#include <string>

#include <Eigen/Core>

namespace hw::reconstruct {

struct ThermalConfidenceOptions {
  // Powers p_i, each in [0, 10]; 0 turns a metric off (0^0 = 1), larger makes it stricter.
  // All 1 as in the paper, which weighs the metrics equally.
  double motion_power = 1, distortion_power = 1, angle_power = 1, distance_power = 1,
         operating_power = 1;

  // c1 motion: blur_px = image speed of the surface point (px/s) × integration_time_s;
  // c1 = exp(−½ (blur_px / motion_blur_px)²).
  // A microbolometer pixel does not integrate over an exposure: it follows the scene with a
  // first-order lag whose thermal time constant τ is 7–12 ms depending on the detector
  // (detector makers' figures); the edge of a moving point smears over about speed × τ
  // pixels. 10 ms is the middle of that range.
  double integration_time_s = 0.010;  // τ, s, [0, 1]
  // Blur where c1 = e^−½ ≈ 0.61: one pixel, where the pixel's value starts mixing the
  // temperature of its neighbours (at 2 px c1 = 0.14, at 3 px 0.011).
  double motion_blur_px = 1.0;  // px, > 0

  // c2 lens distortion: d = how far the lens model moves the pixel (px);
  // c2 = exp(−½ (d / distortion_px)²). The distortion terms are least constrained by a
  // calibration where they are largest (the corners of a wide-angle thermal lens, where
  // targets are seen least), so a ray's direction errs in proportion to how much it was
  // moved. 20 px (c2 = 0.61 there) is 1/8 of a 160 px wide image: the displacement of the
  // outer part of a wide-angle lens; pixels moved by < 9 px keep c2 > 0.9.
  double distortion_px = 20;  // px, > 0

  // c3 angle θ between the ray and the surface normal: c3 = cos θ up to max_angle_deg, 0
  // beyond. cos θ is the paper's term (the pixel's footprint on the surface grows as
  // 1/cos θ); beyond 80° the footprint is > 5.8× the frontal one and the directional
  // emissivity of dielectrics (paints, plaster, skin) has fallen well below its normal value
  // (Fresnel), so the apparent temperature is mostly reflection.
  double max_angle_deg = 80;  // degrees, (0, 90]

  // c4 distance d (m): c4 = min(1, reference_distance_m / d) (a pixel's footprint grows as d).
  // 1 m: a Lepton-class pixel (57° / 160 px ≈ 6 mrad) covers ~6 mm there, about one 5 mm
  // TSDF voxel; farther, one pixel averages over several voxels.
  double reference_distance_m = 1.0;  // m, > 0

  // c5 operating condition from the time since the last flat-field (shutter) event Δ (s):
  // 0 for Δ < ffc_settle_s (the shutter closure: the camera repeats a stale frame), rising
  // linearly to 1 at ffc_settle_s + ffc_ramp_s, then 1 until drift_onset_s, then
  // exp(−(Δ − drift_onset_s) / drift_time_s) (offset and fixed-pattern noise re-grow).
  // (When drift_onset_s < ffc_settle_s + ffc_ramp_s the ramp and the decay multiply.)
  // A frozen (repeated) frame: 0. Unknown Δ (no ffc.txt): 1.
  // Closure: nominally ~0.4 s, up to ~0.5 s for a long FFC, on FLIR Tau 2 / A-series
  // cores. A Lepton's default FFC lasts 23 frames at 26 Hz (≈ 0.9 s): set 0.9 there.
  double ffc_settle_s = 0.5;  // s, >= 0
  // After the shutter reopens: actuating it heats the core (a Lepton draws ~800 mW for ~1 s
  // during a shutter event, 160 mW otherwise), so the first frames carry a transient offset.
  // 0.5 s is ~4 frames at the 9 Hz export-free rate.
  double ffc_ramp_s = 0.5;  // s, >= 0
  // Drift: the offset re-grows with the body temperature change since the FFC. Lepton's
  // automatic FFC repeats every 3 min (or after 1.5 K of body change): the maker's budget
  // for acceptable drift. So the first minute is trusted fully, a frame at 3 min gets
  // exp(−120/300) = 0.67, one 10 min after an FFC (manual FFC mode) 0.17.
  double drift_onset_s = 60;  // s, >= 0
  double drift_time_s = 300;  // s, > 0

  // "" or the first bad field: name, value and constraint.
  std::string Check() const;
};

// Image speed (px/s) of a static point seen by a moving camera: point_in_camera (m, z > 0),
// camera linear velocity (m/s) and angular velocity (rad/s), both in the camera frame (the
// point's velocity in that frame is −v − ω × P), fx fy in px; the norm of (du/dt, dv/dt) of
// the pinhole projection. NaN for z <= 0 (or a NaN input).
double ImageSpeedPxPerS(const Eigen::Vector3d& point_in_camera,
                        const Eigen::Vector3d& linear_velocity_mps,
                        const Eigen::Vector3d& angular_velocity_radps, double fx, double fy);

// The five metrics, each in [0, 1]. An input that is NaN (no valid measure: a point behind
// the camera, a pixel the lens model could not map) gives 0, except for c5 (below).
// c1 from the blur (px, >= 0): exp(−½ (blur_px / motion_blur_px)²).
double MotionConfidence(double blur_px, const ThermalConfidenceOptions& o);
// c2 from the lens model's displacement of the pixel (px, >= 0).
double DistortionConfidence(double distortion_px, const ThermalConfidenceOptions& o);
// c3 from cos θ, θ between the ray towards the camera and the surface normal, in [−1, 1]:
// cos θ when θ <= max_angle_deg, 0 beyond and for a surface facing away (cos θ <= 0).
double AngleConfidence(double cos_angle, const ThermalConfidenceOptions& o);
// c4 from the camera-to-surface distance (m): min(1, reference_distance_m / d); 0 for d <= 0.
double DistanceConfidence(double distance_m, const ThermalConfidenceOptions& o);
// c5 from the time since the last flat-field event (s, >= 0; NaN = unknown → 1 unless
// frozen); frozen: the frame repeats the previous image (0).
double OperatingConfidence(double time_since_ffc_s, bool frozen, const ThermalConfidenceOptions& o);

struct ConfidenceTerms {
  double motion = 1, distortion = 1, angle = 1, distance = 1, operating = 1;
};
// Π c_i^p_i, in [0, 1]. Terms in [0, 1] (asserted).
double RayConfidence(const ConfidenceTerms& c, const ThermalConfidenceOptions& o);

}  // namespace hw::reconstruct
