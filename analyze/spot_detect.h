#pragma once

// Finding and measuring hot and cold spots on a mesh with per-vertex temperature.
//
// A spot is a connected region of the surface whose temperature stands out from its
// surroundings (or from ambient, or beyond an absolute limit). Detection runs in two steps:
//  1. Candidates: vertices whose temperature differs from the local background — the
//     area-weighted median within background_radius_m — by at least half of min_delta_k,
//     joined over the mesh (coincident vertices welded: seams do not split a region).
//  2. Each candidate, strongest first, is measured from its peak: the reference is the
//     area-weighted median of the surrounding surface (a ring reached over the mesh, a gap
//     away from the region, so the spot's own heat-spreading tail does not bias it) or
//     ambient; the boundary is the iso-line at boundary_fraction (default half) of the ΔT
//     between the peak and the reference; the region is the connected set beyond that
//     level, grown from the peak. Reference and region are iterated to agreement (the ring
//     moves with the region). For a step edge blurred by optics or fusion smoothing the
//     half level stays on the edge, so the area does not depend on focus or distance.
// The region is then clipped along the iso-line (analyze/iso_region.h) for its area and
// flattened for its length and width. Uncertainties come from the mesh resolution at the
// boundary, the temperature noise there (spread across views / the surroundings' spread,
// inflated where the temperature confidence is low) and the reference's and peak's errors,
// which move the whole boundary at once; see SpotDetection::Measure in the .cc.
//
// The field measured is ThermalMesh::temperature_field (temperature_c: the surface
// temperature after emissivity correction). A low-emissivity patch reads cold in apparent
// temperature but not in surface temperature, so it makes no false cold spot here.

#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "analyze/spot.h"
#include "analyze/thermal_mesh.h"

namespace hw::analyze {

// One row of the severity table: spots with |ΔT| >= min_delta_k (and below the next row's)
// get this name and suggested action.
struct SeverityBand {
  double min_delta_k = 0;  // K, >= 0
  std::string name;
  std::string action;
};

// NETA MTS Table 100.18 (ΔT between similar components under similar load): 1–3 °C possible
// deficiency, warrants investigation; 4–15 °C probable deficiency, repair as time permits;
// above 15 °C major discrepancy, repair immediately. The surrounding surface is our
// "similar component"; the same |ΔT| bands apply to cold spots unless configured.
std::vector<SeverityBand> NetaSeverityTable();

// "" when the table is usable: non-empty, names non-empty, min_delta_k finite, >= 0 and
// strictly increasing.
std::string CheckSeverityTable(const std::vector<SeverityBand>& table);

struct SpotOptions {
  enum class Detect { kDelta, kAbsolute };
  enum class Reference { kSurrounding, kAmbient };

  // kDelta: spots stand min_delta_k beyond the reference. kAbsolute: hot spots are the
  // regions at or above hot_above_c, cold spots at or below cold_below_c (the boundary is
  // that limit; the reference is still measured, for ΔT and severity).
  Detect detect = Detect::kDelta;
  Reference reference = Reference::kSurrounding;
  double ambient_c = std::numeric_limits<double>::quiet_NaN();  // °C; needed for kAmbient
  // Smallest |peak − reference| reported, K, > 0. 2 K: above the ~1 K repeatability of
  // uncooled microbolometer thermography after fusion, and below the 3 K deficit of the
  // mildest building defects (damp patches); NETA's first band starts at 1 K.
  double min_delta_k = 2.0;
  double hot_above_c = std::numeric_limits<double>::quiet_NaN();   // °C, kAbsolute
  double cold_below_c = std::numeric_limits<double>::quiet_NaN();  // °C, kAbsolute
  bool find_hot = true;
  bool find_cold = true;
  // Level of the boundary between reference (0) and peak (1), in (0, 1). 0.5: for a
  // symmetric blur of a step edge the half level stays on the edge.
  double boundary_fraction = 0.5;
  // Smallest area reported, m², >= 0. 1 cm² is ~4 voxels of a 5 mm reconstruction: below
  // that a "spot" is a few noisy vertices.
  double min_area_m2 = 1e-4;
  // Largest region, m², > min_area_m2: a spot is local; a region growing beyond 1 m² is an
  // element at another temperature (a window pane, a door, a warm machine housing), to be
  // assessed as such, and is listed as rejected. Raise it for envelope-scale surveys.
  double max_area_m2 = 1.0;
  // Radius of the local background for candidates, m, > 0. Regions much wider than this
  // raise their own background and are not candidates.
  double background_radius_m = 0.3;
  // The surrounding ring starts max(ring_gap_m, ring_gap_tails·t) beyond the region and is
  // max(ring_width_m, r) wide, r = √(area/π), t the spot's tail length measured on its
  // boundary (|level − reference| / |∇T|: the heat-spreading length of a defect, ~1.25σ of
  // a blur). 4 tails leave e^-4 < 2 % of the tail's excess in the reference.
  double ring_gap_m = 0.02;
  double ring_gap_tails = 4;
  double ring_width_m = 0.05;
  // Smallest observed fraction of the ring's expected area (Steiner: perimeter·w + πw²
  // for a convex region); below it the spot has no surroundings to compare with (a whole
  // part at another temperature, unscanned surface), in [0, 1]. 0.2: a spot filling most of
  // a narrow face (a breaker's front) keeps the strips beside it.
  double min_ring_coverage = 0.2;
  // ... or, enough surroundings for its size: a ring of at least this many times the
  // region's own area, >= 0 (0: coverage alone decides). A small spot on a narrow face (a
  // 24 mm lug on a 60 mm terminal strip) keeps two strips beside it that are a fraction of
  // the annulus yet ten times its area; a whole part keeps none, or a thin spill round its
  // edge far smaller than itself.
  double min_ring_area_ratio = 2;
  // The ring stays on the spot's own smooth surface: it does not cross where the normal
  // turns by more than this from the region's, degrees, in (0, 180]. 45°: box edges and
  // pipe-to-flange corners (90°) stop it; a 5 mm reconstruction's normal noise (a few
  // degrees) and a pipe's curvature over the ring's width (< 40° for r >= 7 cm) do not.
  double ring_max_normal_change_deg = 45;
  // ... where "the region's" normal, at each place the ring starts (a vertex on the
  // region's border), is the area-weighted mean normal of the region within this radius of
  // it, m, [0, 1] (0: that vertex's own). A reconstruction rounds a crease over a few voxels
  // (TSDF normals turn over 2-3 voxels, 10-15 mm at 5 mm): a region spilling into the
  // rounding would start paths already half turned, and they would walk round the crease
  // (a warm cabinet side onto the wall behind it). 2 cm averages over the rounding, and
  // turns a 7 cm pipe's normal by < 10° (the region lies on one side of its border).
  double ring_normal_radius_m = 0.02;
  // A spot must stand out of its surroundings' own variability: |ΔT| >= this many times the
  // ring's robust spread (1.4826·MAD), >= 0. 4: a speckle of fusion noise or texture rarely
  // reaches 4σ; a defect of a few kelvin on a uniform surface does easily.
  double min_contrast_sigmas = 4;
  // Meshes from reconstruct (temperature_views): a spot seen in fewer thermal frames than
  // this, on the area-weighted mean, is unconfirmed and rejected, >= 0. 3: one or two frames
  // can be a reflection, a misregistered edge or a frame at the wrong time; the point of a
  // 3D model is that a defect is seen from several viewpoints.
  double min_views = 3;
  // ... and one whose temperature the views disagree about is not a property of the surface:
  // rejected when the area-weighted mean spread across views (temperature_std_c) reaches
  // this fraction of |ΔT|, >= 0 (0: off). 0.5: the views then differ by as much as the spot
  // stands out. Measured on a reconstructed close-up walk (README, Analysis): found spots
  // 0.04-0.09 (the blurred rim's spread included), a false one of 4 K at 0.75; most
  // reflections do not show (0.1: the walk sees them from one side).
  double max_view_spread_ratio = 0.5;
  // ... and one seen in fewer frames than this fraction of its surroundings' (the ring's
  // area-weighted mean temperature_views), in [0, 1] (0: off). A defect on a surface the scan
  // covered is in at least about as many frames as the surface round it (measured on a
  // reconstructed walk: the three found spots 1.0-1.4); a patch glimpsed past an occluding
  // edge, where thermal and depth edges misregister, is in a few (two cold specks: 0.13 and
  // 0.27, 3-4 frames). 0.5: half as many.
  double min_views_ratio = 0.5;
  // Meshes whose temperature was corrected for emissivity (temperature_emissivity): surface
  // corrected with an emissivity below this is not searched — neither a spot nor anyone's
  // surroundings, as if unobserved — and its area is reported (SpotDetection::
  // unrated_area_m2), [0, 1] (0: off). Below ~0.5 most of the reading is reflection (bare and
  // galvanised metal, glazing): the surface temperature carries the reflected scene's error
  // times (1 − ε)/ε — 2.6× at ε 0.28, 13× at 0.07 — and the thermographer's rule is to tape
  // or paint such a surface and measure there, not to rate the metal. Measured on a
  // reconstructed walk with the true emissivity (README, Analysis): the bare metal held 72 of
  // its 73 false spots. Truth meshes (`emissivity`, a material property) are not masked.
  double min_emissivity = 0.5;
  // The thermal image's resolution (meshes with temperature_footprint_m, the size of a
  // thermal pixel on the surface). Gaussian σ of the thermal optics' blur, pixels, [0, 20]:
  // with the pixel's box (σ 1/√12 px) it blurs the surface's temperature by
  // σ_b = footprint · √(1/12 + psf²). 0.5: a good LWIR lens on a 12-17 µm pitch (the Airy
  // core at f/1 and 10 µm spans about a pixel). A blur never moves a straight step's
  // half-ΔT line, but widens a spot whose profile peaks (a buried cable, a point source):
  // by up to ≈ 1.8 σ_b in all (exponential profile, the heat-spreading shape), so width,
  // length and area get a one-sided term of half that as one sigma.
  double optics_psf_px = 0.5;
  // A spot narrower than this many thermal pixels (width / footprint) is flagged
  // under-resolved in analyze.json and warned about, >= 0 (0: never): its peak and ΔT read
  // low and its size high. 3: the thermographer's measurement-spot rule (a spot must
  // cover at least 3 × 3 pixels of the camera for its temperature to be measured).
  double min_resolved_px = 3;
  // Candidates measured at most, strongest first, >= 1: a bound on the time a very noisy
  // model can take (each weak candidate may flood up to max_area_m2 of surface). The count
  // left unmeasured is reported.
  int max_candidates = 5000;
  // Severity table; empty = NetaSeverityTable().
  std::vector<SeverityBand> severity;

  std::string Check() const;
};

// A candidate that was not reported, and why.
struct RejectedCandidate {
  bool hot = true;
  double peak_c = 0;
  Eigen::Vector3d peak_in_world = Eigen::Vector3d::Zero();
  std::string reason;
};

struct SpotDetection {
  std::vector<Spot> spots;          // hot spots H1.. then cold C1.., each by decreasing |ΔT|
  // Candidates measured and rejected, with the reason. Candidates whose peak does not stand
  // min_delta_k out of their local background are not measured and not listed.
  std::vector<RejectedCandidate> rejected;
  int candidates = 0;  // connected components of candidate vertices
  int unmeasured = 0;  // strong enough but beyond max_candidates
  std::string field;                // the per-vertex field measured
  // Observed surface not searched: corrected with an emissivity below min_emissivity, m².
  double unrated_area_m2 = 0;
};

// Re-measurement of a region at a given level (scoring against a truth whose boundary is
// an iso-temperature of its own, a user's limit for one spot): the region beyond level_c
// (>= for hot, <= for cold) grown from the vertex beyond the level nearest seed_in_world.
struct LevelRequest {
  Eigen::Vector3d seed_in_world = Eigen::Vector3d::Zero();
  bool hot = true;
  double level_c = 0;
};

// Spot detection on one mesh. The mesh's welded graph, vertex areas and faces around each
// vertex are built once (seconds on a 5 M-face model) and shared by detection and any
// re-measurement. `mesh` must outlive the finder and have temperature; options.Check() ==
// "" (both asserted).
class SpotFinder {
 public:
  SpotFinder(const ThermalMesh& mesh, const SpotOptions& options);
  ~SpotFinder();
  SpotFinder(const SpotFinder&) = delete;
  SpotFinder& operator=(const SpotFinder&) = delete;

  // Finds and measures the spots.
  SpotDetection Detect() const;
  // One result per request; nullopt when no vertex is beyond the level or the region is
  // larger than options.max_area_m2 or smaller than min_area_m2.
  std::vector<std::optional<Spot>> MeasureAtLevels(const std::vector<LevelRequest>& requests) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// SpotFinder(mesh, options).Detect().
SpotDetection DetectSpots(const ThermalMesh& mesh, const SpotOptions& options);

// Name and action of the band of |delta_k| in `table` (CheckSeverityTable-valid); "none"
// and "" below the first band.
const SeverityBand* SeverityFor(const std::vector<SeverityBand>& table, double delta_k);

}  // namespace hw::analyze
