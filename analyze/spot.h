#pragma once

// A measured hot or cold spot: what analyze.json lists per spot and the report shows.

#include <limits>
#include <string>
#include <vector>

#include <Eigen/Core>

namespace hw::analyze {

struct Spot {
  static constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();
  std::string id;     // "H1", "H2", … (hot), "C1", … (cold), by decreasing |ΔT|
  bool hot = true;
  // Temperatures, °C, of the field measured (ThermalMesh::temperature_field).
  double peak_c = 0;       // maximum (hot) or minimum (cold) over the region
  double mean_c = 0;       // area-weighted mean over the region
  double reference_c = 0;  // ambient, or the surrounding surface (see reference below)
  std::string reference;   // "surrounding", "ambient" or "absolute"
  double delta_k = 0;      // peak_c − reference_c (negative for a cold spot)
  // One sigma of delta_k, K: the peak vertex's noise (spread across views over √views,
  // inflated by 1/√confidence; else the surroundings' spread), the maximum's bias over the
  // region's robust peak, the reference's standard error, and half of delta_blur_bound_k.
  double delta_sigma_k = 0;
  // How much the thermal image's blur may have lowered |ΔT| at most, K (one-sided: a blur
  // only ever lowers a peak; 0 for a plateau wider than the blur, this much for the most
  // peaked, exponential profile); NaN without temperature_footprint_m.
  double delta_blur_bound_k = kUnknown;
  double level_c = 0;      // the boundary's iso-temperature
  // Extent on the surface, with one-sigma uncertainties.
  double area_m2 = 0;
  double area_sigma_m2 = 0;
  double length_m = 0;     // long side of the minimal bounding rectangle on the surface
  double width_m = 0;      // short side
  double length_sigma_m = 0;
  double width_sigma_m = 0;
  std::string unrolling;   // how the surface was flattened: "plane", "cylinder", "fold"
  Eigen::Vector3d centroid_in_world = Eigen::Vector3d::Zero();  // area-weighted, metres
  Eigen::Vector3d peak_in_world = Eigen::Vector3d::Zero();      // vertex of peak_c
  Eigen::Vector3d normal_in_world = Eigen::Vector3d::UnitZ();   // area-weighted, unit
  double radius_m = 0;     // largest distance from the centroid to the region (framing)
  // From reconstruct's per-vertex fields, area-weighted over the region; NaN when absent.
  double mean_confidence = 0;
  double mean_views = 0;
  double mean_view_spread_c = 0;  // temperature_std_c: the spread across views, K
  double boundary_std_c = 0;  // temperature spread across views at the boundary
  // The thermal image's resolution over the region (temperature_footprint_m); NaN when the
  // mesh does not carry it (then no blur term is in the uncertainties).
  double footprint_m = kUnknown;   // area-weighted mean size of a thermal pixel on the surface
  double blur_sigma_m = kUnknown;  // σ_b = footprint · √(1/12 + optics_psf_px²)
  double width_px = kUnknown;      // width_m / footprint_m: thermal pixels across the spot
  bool resolved = true;       // width_px >= min_resolved_px (true when unknown)
  // The reflection check (analyze/spot_reflection.h); NaN / "" when not checked (no view
  // vectors in the mesh, or the check off).
  double incidence_deg = kUnknown;        // area-weighted angle between the view and the normal
  double reflection_fraction = kUnknown;  // of the checked area, mirror meeting a source
  double reflection_unseen_fraction = kUnknown;  // ... meeting surface without temperature
  std::string reflection_source;          // "operator", "surface" or "" (none)
  Eigen::Vector3d reflection_source_in_world = Eigen::Vector3d::Constant(kUnknown);  // m
  double reflection_source_c = kUnknown;  // the surface source's mean temperature, °C
  bool possible_reflection = false;       // reflection_fraction >= min_fraction
  // Severity from the configured table.
  std::string severity;
  std::string action;
  // Faces wholly or partly inside the region (indices into ThermalMesh::faces).
  std::vector<int> faces;
};

}  // namespace hw::analyze
