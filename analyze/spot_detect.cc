#include "analyze/spot_detect.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <numeric>
#include <queue>
#include <unordered_map>
#include <utility>

#include "analyze/iso_region.h"
#include "analyze/mesh_fields.h"
#include "analyze/spot_resolution.h"
#include "core/option_check.h"
#include "core/strings.h"
#include "core/yaml_reader.h"

namespace hw::analyze {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kPi = 3.14159265358979323846;

size_t U(int i) { return static_cast<size_t>(i); }

// Everything one measurement needs, shared over candidates.
struct Context {
  const ThermalMesh& mesh;
  const std::vector<double>& temperature_c;  // the mesh's, unrated surface NaN (min_emissivity)
  const VertexGraph& graph;
  const std::vector<double>& field;  // oriented: hot spots are maxima (cold: negated)
  const std::vector<double>& vertex_area;
  const SpotOptions& options;
  const std::vector<std::vector<int>>& vertex_faces;
  // Scratch for the ring's search, one slot per vertex (infinite = unvisited), reset after
  // each search: thousands of candidates on a million-vertex model must not each allocate.
  std::vector<double>* ring_distance;
  std::vector<int>* ring_source;
  std::vector<char>* ring_seen;  // all-zero scratch of BorderNormal
};

// The connected set of vertices with field >= level containing `seed`, stopping (returns
// false) once its area passes max_area_m2.
bool GrowRegion(const Context& c, int seed, double level, std::vector<int>* region,
                std::vector<char>* in_region) {
  region->clear();
  std::vector<int> stack = {seed};
  (*in_region)[U(seed)] = 1;
  double area = 0;
  bool small = true;
  while (!stack.empty()) {
    const int v = stack.back();
    stack.pop_back();
    region->push_back(v);
    area += c.vertex_area[U(v)];
    if (area > c.options.max_area_m2) {
      small = false;
      break;
    }
    for (int i = c.graph.offsets[U(v)]; i < c.graph.offsets[U(v) + 1]; ++i) {
      const int w = c.graph.neighbours[U(i)];
      if ((*in_region)[U(w)] || !(c.field[U(w)] >= level)) continue;
      (*in_region)[U(w)] = 1;
      stack.push_back(w);
    }
  }
  for (int v : stack) region->push_back(v);  // marked but not expanded (only when stopped)
  return small;
}

struct Ring {
  double reference = kNaN;  // area-weighted median of the oriented field
  double spread = kNaN;     // 1.4826·MAD, area-weighted: the surroundings' noise
  double area_m2 = 0;
  double coverage = 0;      // observed area / expected area
  int vertices = 0;
  double mean_views = kNaN;  // area-weighted temperature_views (meshes from reconstruct)
};

// The decay length of the spot's own tail, m: |level − reference| over the median
// temperature gradient along the boundary. For a step blurred by a kernel of scale σ, or a
// defect whose heat spreads exponentially over a length f, this is ≈ 1.25 σ or f: the
// surroundings are measured several of these beyond the boundary, where the tail is gone.
double TailLength(const IsoRegion& iso, double level_minus_reference) {
  std::vector<std::pair<double, double>> gradients;
  for (const IsoSegment& s : iso.boundary) {
    gradients.emplace_back(s.gradient_k_per_m, (s.b_in_world - s.a_in_world).norm());
  }
  const double gradient = WeightedMedian(gradients);
  if (!(gradient > 0)) return 0;
  return std::abs(level_minus_reference) / gradient;
}

// The normal ring paths leaving the region at border vertex `b` are held to: the
// area-weighted mean normal of the region's vertices reached from b over the region's
// graph within ring_normal_radius_m (Euclidean) of it (SpotOptions). `in_region` marks
// the region; `seen` is all-zero scratch, left all-zero.
Eigen::Vector3d BorderNormal(const Context& c, int b, const std::vector<char>& in_region,
                             std::vector<char>* seen) {
  const double radius = c.options.ring_normal_radius_m;
  const Eigen::Vector3d& centre = c.mesh.points_in_world[U(b)];
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  std::vector<int> stack = {b}, visited = {b};
  (*seen)[U(b)] = 1;
  while (!stack.empty()) {
    const int v = stack.back();
    stack.pop_back();
    sum += c.vertex_area[U(v)] * c.mesh.normals[U(v)];
    for (int i = c.graph.offsets[U(v)]; i < c.graph.offsets[U(v) + 1]; ++i) {
      const int w = c.graph.neighbours[U(i)];
      if ((*seen)[U(w)] || !in_region[U(w)]) continue;
      if ((c.mesh.points_in_world[U(w)] - centre).norm() > radius) continue;
      (*seen)[U(w)] = 1;
      visited.push_back(w);
      stack.push_back(w);
    }
  }
  for (int v : visited) (*seen)[U(v)] = 0;
  const double norm = sum.norm();
  return norm > 0 ? Eigen::Vector3d(sum / norm) : c.mesh.normals[U(b)];
}

// The ring of surface between gap and gap + width from the region, over the mesh
// (multi-source Dijkstra on the edge graph from the region's border, which overestimates
// surface distances by a few per cent: the ring sits slightly closer than asked). The ring
// stays on the spot's own smooth surface: a path stops where the normal has turned by more
// than ring_max_normal_change_deg from the region's normal where it left it (BorderNormal),
// so the surroundings of a spot on a breaker face are that face, not the panel behind it,
// and a whole part (a pane in its frame, an end shield on a motor) has no surroundings of
// its own. `in_region` marks the region's vertices.
Ring MeasureRing(const Context& c, const std::vector<int>& region, const std::vector<char>& in_region,
                 double region_area_m2, double perimeter_m, double tail_m) {
  const double r = std::sqrt(region_area_m2 / kPi);
  const double gap = std::max(c.options.ring_gap_m, c.options.ring_gap_tails * tail_m);
  const double width = std::max(c.options.ring_width_m, r);
  const double stop = gap + width;
  const double min_cos = std::cos(c.options.ring_max_normal_change_deg * kPi / 180);
  std::vector<double>& distance = *c.ring_distance;
  std::vector<int>& source = *c.ring_source;
  std::vector<int> touched;
  std::vector<Eigen::Vector3d> border_normals;
  using Item = std::pair<double, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<Item>> queue;
  // Every path leaves through a border vertex (one with a neighbour outside the region):
  // only those start one; the interior is at distance 0 and never entered.
  for (int v : region) {
    distance[U(v)] = 0;
    touched.push_back(v);
  }
  for (int v : region) {
    bool border = false;
    for (int i = c.graph.offsets[U(v)]; i < c.graph.offsets[U(v) + 1] && !border; ++i) {
      border = !in_region[U(c.graph.neighbours[U(i)])];
    }
    if (!border) continue;
    source[U(v)] = static_cast<int>(border_normals.size());
    border_normals.push_back(c.options.ring_normal_radius_m > 0
                                 ? BorderNormal(c, v, in_region, c.ring_seen)
                                 : c.mesh.normals[U(v)]);
    queue.emplace(0.0, v);
  }
  std::vector<std::pair<double, double>> samples;
  double ring_views = 0, ring_views_area = 0;
  Ring ring;
  while (!queue.empty()) {
    const auto [d, v] = queue.top();
    queue.pop();
    if (d > distance[U(v)]) continue;
    if (d >= gap && std::isfinite(c.field[U(v)])) {
      samples.emplace_back(c.field[U(v)], c.vertex_area[U(v)]);
      ring.area_m2 += c.vertex_area[U(v)];
      if (!c.mesh.views.empty() && std::isfinite(c.mesh.views[U(v)])) {
        ring_views += c.vertex_area[U(v)] * c.mesh.views[U(v)];
        ring_views_area += c.vertex_area[U(v)];
      }
    }
    const Eigen::Vector3d& source_normal = border_normals[U(source[U(v)])];
    for (int i = c.graph.offsets[U(v)]; i < c.graph.offsets[U(v) + 1]; ++i) {
      const int w = c.graph.neighbours[U(i)];
      const double dw = d + (c.mesh.points_in_world[U(w)] - c.mesh.points_in_world[U(v)]).norm();
      if (dw > stop || distance[U(w)] <= dw) continue;
      if (c.mesh.normals[U(w)].dot(source_normal) < min_cos) continue;
      if (std::isinf(distance[U(w)])) touched.push_back(w);
      distance[U(w)] = dw;
      source[U(w)] = source[U(v)];
      queue.emplace(dw, w);
    }
  }
  for (int v : touched) distance[U(v)] = std::numeric_limits<double>::infinity();
  ring.vertices = static_cast<int>(samples.size());
  if (ring_views_area > 0) ring.mean_views = ring_views / ring_views_area;
  // A region whose outline runs along mesh borders (a pane meshed on its own) has no
  // iso-line there: its perimeter is at least that of the disc of its area.
  const double outline_m = std::max(perimeter_m, 2 * kPi * r);
  const double expected = outline_m * width + kPi * (stop * stop - gap * gap);
  ring.coverage = expected > 0 ? ring.area_m2 / expected : 0;
  if (samples.empty()) return ring;
  ring.reference = WeightedMedian(samples);
  for (auto& x : samples) x.first = std::abs(x.first - ring.reference);
  ring.spread = 1.4826 * WeightedMedian(samples);
  return ring;
}

// Area-weighted mean of a per-vertex field over the region's vertices where it is finite;
// NaN when the mesh has no such field or no finite value there.
double RegionMean(const Context& c, const std::vector<int>& region, const std::vector<double>& field) {
  if (field.empty()) return kNaN;
  double sum = 0, area = 0;
  for (int v : region) {
    if (!std::isfinite(field[U(v)])) continue;
    sum += c.vertex_area[U(v)] * field[U(v)];
    area += c.vertex_area[U(v)];
  }
  return area > 0 ? sum / area : kNaN;
}

// The peak that sets the level: the region's maximum less twice the noise of one vertex
// (the largest of tens of noisy vertices stands ~2σ above the extreme they sample), but not
// below the area-weighted mean of the hottest 5 % (a noisy plateau's top 5 % also sit ~2σ
// high, so that bound changes nothing there, and it keeps one wild vertex among few from
// setting the level). On an exact mesh (noise 0) the peak is the maximum whatever the
// profile: a small lug's field peaks at its centre, where the hottest 5 % of its area
// (22 mm², the apex vertex and part of the next) averaged 0.06 of the ΔT below the apex and
// put its half-ΔT boundary 2.9 % too wide in area on the truth mesh. One vertex's noise is
// the median standard error of the fused estimate (temperature_std_c / √temperature_views)
// over those hottest 5 % where the mesh has them, else `fallback_noise_c` (the
// surroundings' spread once measured, 0 before), K.
double RobustPeak(const Context& c, const std::vector<int>& region, double fallback_noise_c) {
  std::vector<std::pair<double, int>> values;
  double total = 0;
  for (int v : region) {
    values.emplace_back(c.field[U(v)], v);
    total += c.vertex_area[U(v)];
  }
  std::sort(values.begin(), values.end(), std::greater<>());
  const bool has_errors = !c.mesh.std_c.empty() && !c.mesh.views.empty();
  double sum = 0, weighted = 0;
  std::vector<double> errors;
  for (const auto& [value, v] : values) {
    sum += c.vertex_area[U(v)];
    weighted += value * c.vertex_area[U(v)];
    if (has_errors && std::isfinite(c.mesh.std_c[U(v)]) && c.mesh.views[U(v)] >= 1) {
      errors.push_back(c.mesh.std_c[U(v)] / std::sqrt(c.mesh.views[U(v)]));
    }
    if (sum >= 0.05 * total) break;
  }
  const double top = sum > 0 ? weighted / sum : values.front().first;
  double noise_c = fallback_noise_c;
  if (!errors.empty()) {
    std::nth_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(errors.size() / 2), errors.end());
    noise_c = errors[errors.size() / 2];
  }
  return std::max(top, values.front().first - 2 * noise_c);
}

// Measures one candidate of one kind (the field oriented so that the spot is a maximum).
// Returns false with `reason` when it is not a spot; m->region then holds the region it grew
// (so that the caller does not seed it again), in_region cleared.
struct Measured {
  std::vector<int> region;
  double reference = kNaN;  // oriented
  double level = kNaN;      // oriented
  double peak = kNaN;       // oriented, robust
  Ring ring;
  IsoRegion iso;
};

bool MeasureCandidate(const Context& c, int seed, double start_reference, double ambient,
                      double absolute_level, std::vector<char>* in_region, Measured* m,
                      std::string* reason) {
  const SpotOptions& o = c.options;
  const bool absolute = o.detect == SpotOptions::Detect::kAbsolute;
  const bool surrounding = o.reference == SpotOptions::Reference::kSurrounding;
  double reference = surrounding ? start_reference : ambient;
  std::vector<int> faces;
  constexpr int kMaxIterations = 8;
  for (int iteration = 0; iteration < kMaxIterations; ++iteration) {
    for (int v : m->region) (*in_region)[U(v)] = 0;
    // The level: half way (boundary_fraction) from the reference to the peak; the peak is
    // the robust one of the region at the previous level (the seed alone at first).
    const double ring_noise = std::isfinite(m->ring.spread) ? m->ring.spread : 0.0;
    const double peak = m->region.empty() ? c.field[U(seed)] : RobustPeak(c, m->region, ring_noise);
    const double level = absolute ? absolute_level : reference + o.boundary_fraction * (peak - reference);
    // Against ambient the ΔT is known at once; the local background of a candidate (the
    // median within background_radius_m) is only a start: inside a spot wider than that
    // radius it sits near the peak, so the surroundings' ring decides, below.
    if (!absolute && !surrounding && !(peak - reference >= o.min_delta_k)) {
      *reason = "ΔT to the reference below min_delta_k";
      for (int v : m->region) (*in_region)[U(v)] = 0;
      return false;
    }
    const bool small = GrowRegion(c, seed, level, &m->region, in_region);
    if (!small) {
      *reason = "region larger than max_area_m2: a surface at another temperature, not a spot";
      for (int v : m->region) (*in_region)[U(v)] = 0;
      return false;
    }
    faces.clear();
    for (int v : m->region) faces.insert(faces.end(), c.vertex_faces[U(v)].begin(), c.vertex_faces[U(v)].end());
    std::sort(faces.begin(), faces.end());
    faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
    m->iso = ClipToLevel(c.mesh, c.field, faces, level, true);
    m->level = level;
    m->peak = RobustPeak(c, m->region, ring_noise);
    if (!surrounding) {
      m->reference = reference;
      if (!absolute) {
        // The level moves with the robust peak of the grown region; iterate on it too.
        const double next_level = reference + o.boundary_fraction * (m->peak - reference);
        if (std::abs(next_level - level) < 1e-3) break;
      } else {
        break;
      }
      continue;
    }
    m->ring = MeasureRing(c, m->region, *in_region, m->iso.area_m2, m->iso.perimeter_m, TailLength(m->iso, level - reference));
    const bool surrounded =
        std::isfinite(m->ring.reference) &&
        (m->ring.coverage >= o.min_ring_coverage ||
         (o.min_ring_area_ratio > 0 && m->ring.area_m2 >= o.min_ring_area_ratio * m->iso.area_m2));
    if (absolute && !surrounded) {
      // A limit needs no surroundings; ΔT is then taken over the limit itself.
      m->reference = level;
      m->ring = Ring();
      break;
    }
    if (!surrounded) {
      *reason = "no surrounding surface to compare with (ring coverage " +
                core::RoundedNumber(m->ring.coverage) + " < min_ring_coverage, ring area " +
                core::RoundedNumber(m->iso.area_m2 > 0 ? m->ring.area_m2 / m->iso.area_m2 : 0) +
                "x the region's < min_ring_area_ratio)";
      for (int v : m->region) (*in_region)[U(v)] = 0;
      return false;
    }
    m->reference = m->ring.reference;
    const double next_level = absolute ? level : m->reference + o.boundary_fraction * (m->peak - m->reference);
    if (std::abs(m->ring.reference - reference) < 1e-3 && std::abs(next_level - level) < 1e-3) break;
    reference = m->ring.reference;
  }
  const double views = RegionMean(c, m->region, c.mesh.views);
  const double view_spread = RegionMean(c, m->region, c.mesh.std_c);
  const double delta = std::abs(m->peak - m->reference);
  const double spread = std::isfinite(m->ring.spread) ? m->ring.spread : 0.0;
  if (!absolute && !(delta >= o.min_delta_k)) {
    *reason = "ΔT to the reference below min_delta_k";
  } else if (!absolute && !(delta >= o.min_contrast_sigmas * spread)) {
    *reason = "ΔT below min_contrast_sigmas × the surroundings' spread (" + core::RoundedNumber(spread) + " K)";
  } else if (m->iso.area_m2 < o.min_area_m2) {
    *reason = "area below min_area_m2";
  } else if (views < o.min_views) {  // false for NaN (no views field)
    *reason = "seen in fewer than min_views thermal frames (" + core::RoundedNumber(views) + ")";
  } else if (views < o.min_views_ratio * m->ring.mean_views) {
    *reason = core::StringPrintf("seen in %.1f thermal frames, its surroundings in %.1f (min_views_ratio)",
                                 views, m->ring.mean_views);
  } else if (!absolute && o.max_view_spread_ratio > 0 && view_spread >= o.max_view_spread_ratio * delta) {
    *reason = core::StringPrintf("the views disagree: spread %.2f K across views for a ΔT of %.2f K "
                                 "(max_view_spread_ratio)", view_spread, delta);
  } else {
    return true;
  }
  for (int v : m->region) (*in_region)[U(v)] = 0;
  return false;
}

// Uncertainties of area, length and width (one sigma), and the reconstruct fields.
void FillSpot(const Context& c, const Measured& m, double sign, Spot* spot) {
  const ThermalMesh& mesh = c.mesh;
  const std::vector<double>& t = c.temperature_c;
  spot->reference_c = sign * m.reference;
  spot->level_c = sign * m.level;
  spot->area_m2 = m.iso.area_m2;
  spot->centroid_in_world = m.iso.centroid_in_world;
  spot->normal_in_world = m.iso.normal_in_world;
  spot->faces = m.iso.faces;
  // Peak: the extreme vertex of the region.
  int peak_vertex = m.region.front();
  for (int v : m.region) {
    if (c.field[U(v)] > c.field[U(peak_vertex)]) peak_vertex = v;
  }
  spot->peak_c = t[U(peak_vertex)];
  spot->peak_in_world = mesh.points_in_world[U(peak_vertex)];
  spot->delta_k = spot->peak_c - spot->reference_c;
  // Area-weighted means over the region's vertices.
  double area = 0, mean = 0, confidence = 0, views = 0;
  for (int v : m.region) {
    const double a = c.vertex_area[U(v)];
    area += a;
    mean += a * t[U(v)];
    if (!mesh.confidence.empty()) confidence += a * mesh.confidence[U(v)];
    if (!mesh.views.empty()) views += a * mesh.views[U(v)];
  }
  spot->mean_view_spread_c = RegionMean(c, m.region, mesh.std_c);
  spot->mean_c = area > 0 ? mean / area : spot->peak_c;
  spot->mean_confidence = mesh.confidence.empty() || area <= 0 ? kNaN : confidence / area;
  spot->mean_views = mesh.views.empty() || area <= 0 ? kNaN : views / area;
  spot->radius_m = 0;
  for (const ClippedPiece& piece : m.iso.pieces) {
    for (int k = 0; k < piece.num_points; ++k) {
      spot->radius_m = std::max(spot->radius_m, (piece.points_in_world[U(k)] - spot->centroid_in_world).norm());
    }
  }

  // Boundary noise per iso-segment: σ_T of one vertex (spread across views over √views where
  // reconstruct gave them, else the surroundings' spread), inflated by 1/√C for a mean
  // confidence C < 1 (the online rule's confidence is a weight of evidence); the segment's
  // position error is σ_T / |∇T| plus the mesh resolution term h/√12 (the iso-line can sit
  // anywhere in a triangle of side h when the field is sharper than the mesh). These are
  // independent between segments. The reference's error (median of the ring: 1.2533 σ/√n)
  // and the robust peak's move the level, hence the whole boundary at once.
  const double ring_sigma = std::isfinite(m.ring.spread) ? m.ring.spread : 0.0;
  double coherent_area = 0, incoherent_area2 = 0, coherent_d = 0, incoherent_d2 = 0, length_sum = 0;
  double boundary_std = 0;
  int boundary_vertices = 0;
  double sigma_reference = m.ring.vertices > 0 ? 1.2533 * ring_sigma / std::sqrt(m.ring.vertices) : 0.0;
  const double f = c.options.boundary_fraction;
  // The peak that sets the level (RobustPeak) may stand below the maximum (noise on a
  // plateau, or a profile that never flattens under noise): their difference is the peak's
  // uncertainty, added to the vertex noise.
  double region_max = -std::numeric_limits<double>::infinity();
  for (int v : m.region) region_max = std::max(region_max, c.field[U(v)]);
  const double sigma_peak_shape = std::isfinite(region_max) ? region_max - m.peak : 0.0;
  for (const IsoSegment& s : m.iso.boundary) {
    const Eigen::Vector3i& face = mesh.faces[U(s.face)];
    double sigma_t = ring_sigma, conf = 1, h = 0;
    if (!mesh.std_c.empty() && !mesh.views.empty()) {
      double sum = 0;
      int n = 0;
      for (int k = 0; k < 3; ++k) {
        const double sd = mesh.std_c[U(face[k])], nv = mesh.views[U(face[k])];
        if (std::isfinite(sd) && nv >= 1) {
          sum += sd / std::sqrt(nv);
          ++n;
        }
      }
      if (n > 0) sigma_t = std::max(sigma_t, sum / n);
    }
    if (!mesh.confidence.empty()) {
      double sum = 0;
      for (int k = 0; k < 3; ++k) sum += std::isfinite(mesh.confidence[U(face[k])]) ? mesh.confidence[U(face[k])] : 0;
      conf = std::clamp(sum / 3, 0.05, 1.0);
    }
    for (int k = 0; k < 3; ++k) {
      h = std::max(h, (mesh.points_in_world[U(face[(k + 1) % 3])] - mesh.points_in_world[U(face[k])]).norm());
    }
    const double length = (s.b_in_world - s.a_in_world).norm();
    const double gradient = std::max(s.gradient_k_per_m, 1e-9);
    const double sigma_d2 = std::pow(sigma_t / std::sqrt(conf) / gradient, 2) + h * h / 12;
    const double sigma_peak = std::hypot(sigma_t / std::sqrt(conf), sigma_peak_shape);
    const double sigma_level = c.options.detect == SpotOptions::Detect::kAbsolute
                                   ? 0.0
                                   : std::hypot((1 - f) * sigma_reference, f * sigma_peak);
    incoherent_area2 += std::pow(length, 2) * sigma_d2;
    coherent_area += length * sigma_level / gradient;
    incoherent_d2 += length * sigma_d2;
    coherent_d += length * sigma_level / gradient;
    length_sum += length;
    boundary_std += sigma_t;
    ++boundary_vertices;
  }
  spot->area_sigma_m2 = std::sqrt(incoherent_area2 + coherent_area * coherent_area);
  const double mean_d2 = length_sum > 0 ? incoherent_d2 / length_sum : 0;
  const double mean_coherent = length_sum > 0 ? coherent_d / length_sum : 0;
  // A side's length is set by its two ends: independent errors add in quadrature; a level
  // shift moves both ends outwards together.
  spot->length_sigma_m = std::sqrt(2 * mean_d2 + 4 * mean_coherent * mean_coherent);
  spot->width_sigma_m = spot->length_sigma_m;
  spot->boundary_std_c = boundary_vertices > 0 ? boundary_std / boundary_vertices : kNaN;
  // ΔT's one sigma: the peak vertex's own noise; the maximum's bias, the largest of n
  // independent noisy samples standing ~σ·√(2 ln n) above what they sample (n: the region's
  // vertices, or its thermal pixels where the mesh gives their footprint, whichever is
  // fewer: neighbouring vertices interpolate the same pixels), or the maximum's excess over
  // the robust peak if larger; and the ring median's standard error (none against a given
  // ambient).
  double sigma_vertex = ring_sigma;
  if (!mesh.std_c.empty() && !mesh.views.empty() && std::isfinite(mesh.std_c[U(peak_vertex)]) &&
      mesh.views[U(peak_vertex)] >= 1) {
    sigma_vertex = mesh.std_c[U(peak_vertex)] / std::sqrt(mesh.views[U(peak_vertex)]);
  }
  if (!mesh.confidence.empty() && std::isfinite(mesh.confidence[U(peak_vertex)])) {
    sigma_vertex /= std::sqrt(std::clamp(mesh.confidence[U(peak_vertex)], 0.05, 1.0));
  }
  double samples = static_cast<double>(m.region.size());
  const double footprint_m = RegionMean(c, m.region, mesh.footprint_m);
  if (footprint_m > 0) samples = std::min(samples, area / (footprint_m * footprint_m));
  const double max_bias = std::max(sigma_vertex * std::sqrt(2 * std::log(std::max(samples, 1.0))), sigma_peak_shape);
  const double sigma_reference_delta = spot->reference == "ambient" ? 0.0 : sigma_reference;
  spot->delta_sigma_k = std::sqrt(sigma_vertex * sigma_vertex + max_bias * max_bias +
                                  sigma_reference_delta * sigma_reference_delta);
}


// The Spot of a measured region: figures, extent, severity.
Spot MakeSpot(const Context& c, const Measured& m, bool hot, const std::vector<SeverityBand>& table) {
  const SpotOptions& options = c.options;
  Spot spot;
  spot.hot = hot;
  spot.reference = options.detect == SpotOptions::Detect::kAbsolute
                       ? "absolute"
                       : (options.reference == SpotOptions::Reference::kAmbient ? "ambient" : "surrounding");
  if (options.detect == SpotOptions::Detect::kAbsolute && m.ring.vertices > 0) spot.reference = "surrounding";
  FillSpot(c, m, hot ? 1.0 : -1.0, &spot);
  const Extent extent = MeasureExtent(m.iso, c.mesh, ExtentOptions());
  spot.length_m = extent.length_m;
  spot.width_m = extent.width_m;
  spot.unrolling = extent.unrolling;
  ApplyResolution(RegionMean(c, m.region, c.mesh.footprint_m), m.iso.perimeter_m, options, &spot);
  if (const SeverityBand* band = SeverityFor(table, spot.delta_k)) {
    spot.severity = band->name;
    spot.action = band->action;
  } else {
    spot.severity = "none";
  }
  return spot;
}

// What every measurement shares: the welded graph, vertex areas, faces around vertices.
struct Prepared {
  VertexGraph graph;
  std::vector<double> vertex_area;
  std::vector<std::vector<int>> vertex_faces;
  std::vector<SeverityBand> table;

  Prepared(const ThermalMesh& mesh, const SpotOptions& options)
      : graph(BuildVertexGraph(mesh)), vertex_area(VertexAreas(mesh)), vertex_faces(U(mesh.NumVertices())),
        table(options.severity.empty() ? NetaSeverityTable() : options.severity) {
    for (int f = 0; f < mesh.NumFaces(); ++f) {
      for (int k = 0; k < 3; ++k) vertex_faces[U(mesh.faces[U(f)][k])].push_back(f);
    }
  }
};

}  // namespace

struct SpotFinder::Impl {
  const ThermalMesh& mesh;
  SpotOptions options;
  Prepared prepared;
  // temperature_c with the surface below min_emissivity unobserved (NaN), and that surface's
  // area; empty when nothing is masked.
  std::vector<double> rated_c;
  double unrated_area_m2 = 0;
  const std::vector<double>& Temperature() const { return rated_c.empty() ? mesh.temperature_c : rated_c; }
};

SpotFinder::SpotFinder(const ThermalMesh& mesh, const SpotOptions& options)
    : impl_(std::make_unique<Impl>(Impl{mesh, options, Prepared(mesh, options), {}, 0})) {
  assert(mesh.HasTemperature());
  assert(options.Check().empty());
  // A reading corrected with a low emissivity is mostly reflection (SpotOptions::min_emissivity):
  // not a temperature to search, neither as a spot nor as anyone's surroundings.
  if (mesh.emissivity.empty() || options.min_emissivity <= 0) return;
  Impl& m = *impl_;
  for (size_t v = 0; v < mesh.emissivity.size(); ++v) {
    if (!(mesh.emissivity[v] < options.min_emissivity) || !std::isfinite(mesh.temperature_c[v])) continue;
    if (m.rated_c.empty()) m.rated_c = mesh.temperature_c;
    m.rated_c[v] = kNaN;
    m.unrated_area_m2 += m.prepared.vertex_area[v];
  }
}

SpotFinder::~SpotFinder() = default;

SpotDetection DetectSpots(const ThermalMesh& mesh, const SpotOptions& options) {
  return SpotFinder(mesh, options).Detect();
}

SpotDetection SpotFinder::Detect() const {
  const ThermalMesh& mesh = impl_->mesh;
  const SpotOptions& options = impl_->options;
  const Prepared& prepared = impl_->prepared;
  SpotDetection result;
  result.field = mesh.temperature_field;
  result.unrated_area_m2 = impl_->unrated_area_m2;
  const std::vector<double>& temperature = impl_->Temperature();
  const VertexGraph& graph = prepared.graph;
  const std::vector<double>& vertex_area = prepared.vertex_area;
  const std::vector<SeverityBand>& table = prepared.table;
  const std::vector<double> background =
      options.reference == SpotOptions::Reference::kSurrounding || options.detect == SpotOptions::Detect::kDelta
          ? LocalBackground(mesh, temperature, vertex_area, options.background_radius_m)
          : std::vector<double>(U(mesh.NumVertices()), kNaN);

  for (const bool hot : {true, false}) {
    if ((hot && !options.find_hot) || (!hot && !options.find_cold)) continue;
    const double sign = hot ? 1.0 : -1.0;
    std::vector<double> field(temperature.size());
    for (size_t v = 0; v < field.size(); ++v) field[v] = sign * temperature[v];
    std::vector<double> oriented_background(background.size());
    for (size_t v = 0; v < background.size(); ++v) oriented_background[v] = sign * background[v];
    const double ambient = sign * options.ambient_c;
    const double absolute_level = sign * (hot ? options.hot_above_c : options.cold_below_c);
    std::vector<double> ring_distance(field.size(), std::numeric_limits<double>::infinity());
    std::vector<int> ring_source(field.size(), -1);
    std::vector<char> ring_seen(field.size(), 0);
    Context c{mesh, temperature, graph, field, vertex_area, options, prepared.vertex_faces, &ring_distance, &ring_source,
              &ring_seen};

    // Candidate vertices and their components.
    std::vector<char> candidate(field.size(), 0);
    for (size_t v = 0; v < field.size(); ++v) {
      if (!std::isfinite(field[v])) continue;
      if (options.detect == SpotOptions::Detect::kAbsolute) {
        candidate[v] = field[v] >= absolute_level;
      } else {
        const double reference = options.reference == SpotOptions::Reference::kAmbient ? ambient : oriented_background[v];
        candidate[v] = field[v] - reference >= 0.5 * options.min_delta_k;
      }
    }
    // One seed per component: its peak, its strength against the most background-like local
    // background over the component (inside a spot wider than background_radius_m the
    // background at the peak is the spot's own temperature; at the component's rim it is
    // not), and as the first reference the background at the peak (the nearest guess; the
    // surrounding ring then moves it).
    struct Seed {
      double strength;  // peak − reference, oriented
      int peak;
      double reference;
    };
    std::vector<Seed> seeds;
    // Further peaks of a component (two hot joints on one warm busbar are one component):
    // its vertices that are the highest of their neighbours and stand min_delta_k out of
    // their own local background, measured after every component's first seed (kDelta).
    std::vector<Seed> more_seeds;
    std::vector<char> seen(field.size(), 0);
    std::vector<int> members;
    for (size_t start = 0; start < field.size(); ++start) {
      if (!candidate[start] || seen[start]) continue;
      int peak = static_cast<int>(start);
      double reference = std::numeric_limits<double>::infinity();
      std::vector<int> stack = {peak};
      seen[start] = 1;
      members.clear();
      while (!stack.empty()) {
        const int v = stack.back();
        stack.pop_back();
        members.push_back(v);
        if (field[U(v)] > field[U(peak)]) peak = v;
        if (std::isfinite(oriented_background[U(v)])) reference = std::min(reference, oriented_background[U(v)]);
        for (int i = graph.offsets[U(v)]; i < graph.offsets[U(v) + 1]; ++i) {
          const int w = graph.neighbours[U(i)];
          if (candidate[U(w)] && !seen[U(w)]) {
            seen[U(w)] = 1;
            stack.push_back(w);
          }
        }
      }
      if (options.reference == SpotOptions::Reference::kAmbient) reference = ambient;
      if (!std::isfinite(reference)) reference = field[U(peak)] - options.min_delta_k;
      const double first_reference = options.reference == SpotOptions::Reference::kAmbient ? ambient
                           : std::isfinite(oriented_background[U(peak)]) ? oriented_background[U(peak)]
                                                                          : reference;
      seeds.push_back({field[U(peak)] - reference, peak, first_reference});
      // Own local background, also against ambient: a surface that is all above ambient
      // (every vertex of a uniform wall the highest of its neighbours) seeds nothing more.
      if (options.detect != SpotOptions::Detect::kDelta) continue;
      for (int v : members) {
        const double own = oriented_background[U(v)];
        if (v == peak || !std::isfinite(own) || !(field[U(v)] - own >= options.min_delta_k)) continue;
        bool highest = true;
        for (int i = graph.offsets[U(v)]; i < graph.offsets[U(v) + 1] && highest; ++i) {
          highest = !(field[U(graph.neighbours[U(i)])] > field[U(v)]);
        }
        const double first = options.reference == SpotOptions::Reference::kAmbient ? ambient : own;
        if (highest) more_seeds.push_back({field[U(v)] - own, v, first});
      }
    }
    std::sort(more_seeds.begin(), more_seeds.end(), [](const Seed& a, const Seed& b) { return a.strength > b.strength; });
    std::sort(seeds.begin(), seeds.end(), [](const Seed& a, const Seed& b) { return a.strength > b.strength; });
    result.candidates += static_cast<int>(seeds.size());

    // claimed: in an accepted spot; visited: in a region measured (a rejected one's too) and
    // no higher than its seed, so that a further peak inside it is not measured again.
    std::vector<char> claimed(field.size(), 0), visited(field.size(), 0), in_region(field.size(), 0);
    std::vector<Spot> spots;
    int measured = 0;
    const size_t first_seeds = seeds.size();
    seeds.insert(seeds.end(), more_seeds.begin(), more_seeds.end());
    for (size_t k = 0; k < seeds.size(); ++k) {
      const Seed& seed = seeds[k];
      // A candidate that does not stand min_delta_k out of even its most favourable local
      // background is noise or texture: not measured (thousands of them on a noisy model
      // would each flood the surface around them), counted in `candidates` only.
      if (options.detect == SpotOptions::Detect::kDelta && seed.strength < options.min_delta_k) continue;
      if (claimed[U(seed.peak)] || (k >= first_seeds && visited[U(seed.peak)])) continue;
      if (measured == options.max_candidates) {
        ++result.unmeasured;
        continue;
      }
      ++measured;
      Measured m;
      std::string reason;
      const bool accepted = MeasureCandidate(c, seed.peak, seed.reference, ambient, absolute_level, &in_region, &m, &reason);
      // Only what stands no higher than the seed: a flood from a weak seed at a low level can
      // sweep over a stronger peak of another component, which keeps its own measurement.
      for (int v : m.region) visited[U(v)] |= field[U(v)] <= field[U(seed.peak)];
      if (!accepted) {
        result.rejected.push_back({hot, temperature[U(seed.peak)], mesh.points_in_world[U(seed.peak)], reason});
        continue;
      }
      // Regions do not overlap: one reaching an accepted spot's is that spot again (found
      // from another seed that its level left outside it).
      bool overlaps = false;
      for (int v : m.region) overlaps |= claimed[U(v)] != 0;
      for (int v : m.region) {
        claimed[U(v)] = 1;
        in_region[U(v)] = 0;
      }
      if (overlaps) continue;
      Spot spot = MakeSpot(c, m, hot, table);
      spots.push_back(std::move(spot));
    }
    std::sort(spots.begin(), spots.end(),
              [](const Spot& a, const Spot& b) { return std::abs(a.delta_k) > std::abs(b.delta_k); });
    for (size_t i = 0; i < spots.size(); ++i) {
      spots[i].id = (hot ? "H" : "C") + std::to_string(i + 1);
      result.spots.push_back(std::move(spots[i]));
    }
  }
  return result;
}

std::vector<std::optional<Spot>> SpotFinder::MeasureAtLevels(const std::vector<LevelRequest>& requests) const {
  const ThermalMesh& mesh = impl_->mesh;
  const SpotOptions& options = impl_->options;
  const Prepared& prepared = impl_->prepared;
  std::vector<std::optional<Spot>> out;
  for (const LevelRequest& request : requests) {
    const double sign = request.hot ? 1.0 : -1.0;
    SpotOptions o = options;
    o.detect = SpotOptions::Detect::kAbsolute;
    o.hot_above_c = request.hot ? request.level_c : request.level_c + 1;
    o.cold_below_c = request.hot ? request.level_c - 1 : request.level_c;
    const std::vector<double>& temperature = impl_->Temperature();
    std::vector<double> field(temperature.size());
    for (size_t v = 0; v < field.size(); ++v) field[v] = sign * temperature[v];
    // The seed: the vertex nearest the given point among those beyond the level.
    int seed = -1;
    double best = 0;
    for (int v = 0; v < mesh.NumVertices(); ++v) {
      if (!(field[U(v)] >= sign * request.level_c)) continue;
      const double d = (mesh.points_in_world[U(v)] - request.seed_in_world).squaredNorm();
      if (seed < 0 || d < best) {
        seed = v;
        best = d;
      }
    }
    if (seed < 0) {
      out.emplace_back();
      continue;
    }
    std::vector<double> ring_distance(field.size(), std::numeric_limits<double>::infinity());
    std::vector<int> ring_source(field.size(), -1);
    std::vector<char> ring_seen(field.size(), 0);
    Context c{mesh, impl_->Temperature(), prepared.graph, field, prepared.vertex_area, o, prepared.vertex_faces, &ring_distance, &ring_source,
              &ring_seen};
    std::vector<char> in_region(field.size(), 0);
    Measured m;
    std::string reason;
    if (!MeasureCandidate(c, seed, field[U(seed)], kNaN, sign * request.level_c, &in_region, &m, &reason)) {
      out.emplace_back();
      continue;
    }
    out.emplace_back(MakeSpot(c, m, request.hot, prepared.table));
  }
  return out;
}

}  // namespace hw::analyze
