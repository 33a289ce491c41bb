#include "analyze/comparison.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <sstream>

#include "analyze/annotate.h"
#include "analyze/image_out.h"
#include "analyze/output_support.h"
#include "analyze/render.h"
#include "analyze/spot_reflection.h"
#include "analyze/view_select.h"
#include "analyze/views.h"
#include "core/atomic_file.h"
#include "core/error.h"
#include "core/json.h"

namespace hw::analyze {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

size_t U(int i) { return static_cast<size_t>(i); }

// "+8.0", "−3.2" (U+2212, as the colour bar's ticks).
std::string Signed(double value, int digits) {
  const std::string s = FixedText(std::abs(value), digits);
  if (s == FixedText(0, digits)) return s;
  return (value < 0 ? "−" : "+") + s;
}

// `text` padded with spaces to `width` characters (UTF-8 code points, so "—" and "°" count
// once), on the left when `right` (numbers).
std::string Pad(const std::string& text, size_t width, bool right = false) {
  size_t n = 0;
  for (const char ch : text) n += (static_cast<unsigned char>(ch) & 0xC0) != 0x80;
  const std::string fill(n < width ? width - n : 1, ' ');
  return right ? fill + text : text + fill;
}

bool HasAnyTemperature(const ThermalMesh& mesh) {
  return std::any_of(mesh.temperature_c.begin(), mesh.temperature_c.end(), [](double t) { return std::isfinite(t); });
}

double MeanEdgeLength(const ThermalMesh& mesh) {
  double sum = 0;
  for (const Eigen::Vector3i& f : mesh.faces) {
    for (int k = 0; k < 3; ++k) {
      sum += (mesh.points_in_world[U(f[k])] - mesh.points_in_world[U(f[(k + 1) % 3])]).norm();
    }
  }
  return mesh.faces.empty() ? 0 : sum / (3.0 * static_cast<double>(mesh.faces.size()));
}

// ±m rounded up to the ticks' step.
Span SymmetricRoundOut(double m) {
  const double step = NiceStep(2 * m, 6);
  const double r = std::ceil(m / step - 1e-9) * step;
  return Span{-r, r};
}

// The temperature change a spot change stands for, K: the peak's change for a pair, the
// spot's own ΔT for one that appeared (+) or vanished (−: its excess is gone).
double ChangeMagnitudeK(const SpotChange& c) {
  if (!c.after_id.empty() && !c.before_id.empty()) return c.peak_after_c - c.peak_before_c;
  if (!c.after_id.empty()) return c.delta_after_k;
  return -c.delta_before_k;
}

bool Has(const SpotChange& c, const char* kind) {
  return std::find(c.kinds.begin(), c.kinds.end(), kind) != c.kinds.end();
}

std::string ChangeLabelText(const SpotChange& c) {
  std::string text = ChangeName(c);
  if (c.kinds.empty()) return text + " " + FixedText(c.peak_after_c, 1) + " °C";
  for (size_t k = 0; k < c.kinds.size(); ++k) text += (k ? ", " : " ") + c.kinds[k];
  if (Has(c, "heated") || Has(c, "cooled")) text += " " + Signed(c.peak_after_c - c.peak_before_c, 1) + " K";
  if (Has(c, "grew") || Has(c, "shrank")) {
    text += " " + Signed(100 * (c.area_after_m2 - c.area_before_m2) / c.area_before_m2, 0) + " %";
  }
  if (Has(c, "appeared")) text += " ΔT " + Signed(c.delta_after_k, 1) + " K";
  if (Has(c, "vanished")) text += ", was ΔT " + Signed(c.delta_before_k, 1) + " K";
  if (NeedsSecondView(c)) text += " (reflection?)";
  return text;
}

const Spot* FindSpot(const std::vector<Spot>& spots, const std::string& id) {
  for (const Spot& s : spots) {
    if (s.id == id) return &s;
  }
  return nullptr;
}

// Where a change is drawn on the AFTER model: AFTER's spot, or BEFORE's carried into
// AFTER's frame.
struct ChangePlace {
  Eigen::Vector3d peak_in_after = Eigen::Vector3d::Zero();
  Eigen::Vector3d centroid_in_after = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal_in_after = Eigen::Vector3d::UnitZ();
  double radius_m = 0;
  std::vector<Eigen::Vector3d> region_points_in_after;  // face centroids, at most ~200
};

ChangePlace PlaceOf(const SpotChange& c, const ThermalMesh& before, const ThermalMesh& after, const CompareResult& r) {
  const bool in_after = !c.after_id.empty();
  const Spot* s = in_after ? FindSpot(r.after_spots.spots, c.after_id) : FindSpot(r.before_spots.spots, c.before_id);
  assert(s != nullptr);
  const ThermalMesh& mesh = in_after ? after : before;
  const Eigen::Isometry3d to_after = in_after ? Eigen::Isometry3d::Identity() : r.alignment.after_from_before;
  ChangePlace p;
  p.peak_in_after = to_after * s->peak_in_world;
  p.centroid_in_after = to_after * s->centroid_in_world;
  p.normal_in_after = to_after.linear() * s->normal_in_world;
  p.radius_m = s->radius_m;
  // At most ~200 points scored: enough for a visible fraction to a few per cent.
  const size_t stride = s->faces.size() / 200 + 1;
  for (size_t i = 0; i < s->faces.size(); i += stride) {
    const Eigen::Vector3i& f = mesh.faces[U(s->faces[i])];
    p.region_points_in_after.push_back(
        to_after * ((mesh.points_in_world[U(f[0])] + mesh.points_in_world[U(f[1])] + mesh.points_in_world[U(f[2])]) / 3));
  }
  return p;
}

struct ImageSpec {
  const char* suffix;
  ViewMode mode;
  bool difference;  // the difference field (K) rather than AFTER's temperature (°C)
  const char* title;
};

constexpr ImageSpec kImages[] = {
    {"difference", ViewMode::kThermal, true, "Temperature change after − before"},
    {"difference-highlight", ViewMode::kHighlight, true, "Temperature change beyond the detection threshold"},
    {"thermal", ViewMode::kThermal, false, "Surface temperature after"},
};

}  // namespace

std::string ChangeName(const SpotChange& change) {
  return change.after_id.empty() ? "before-" + change.before_id : change.after_id;
}

CompareResult CompareModels(const ThermalMesh& before, const ThermalMesh& after, const CompareInputs& inputs,
                            const fs::path& out_folder, const std::function<void(int, int)>& progress) {
  const AnalyzeConfig& config = inputs.config;
  assert(config.Check().empty());
  const auto start = Clock::now();
  for (const auto& [mesh, path] : {std::pair{&before, inputs.before_path}, std::pair{&after, inputs.after_path}}) {
    if (!mesh->HasTemperature() || !HasAnyTemperature(*mesh)) {
      throw core::InputError(path, "no " + config.field + ": nothing to compare");
    }
  }
  CompareResult result;
  result.out_folder = out_folder;
  for (const std::string& w : before.report.warnings) result.warnings.push_back("BEFORE: " + w);
  for (const std::string& w : after.report.warnings) result.warnings.push_back("AFTER: " + w);

  AlignOptions align = inputs.align;
  align.threads = inputs.num_threads;
  CompareOptions compare = inputs.compare;
  compare.threads = inputs.num_threads;
  auto t = Clock::now();
  result.alignment = AlignMeshes(before, after, align);
  result.timings.align_s = Seconds(t);
  const Alignment& a = result.alignment;
  result.rotation_deg = Eigen::AngleAxisd(a.after_from_before.linear()).angle() * 180 / M_PI;
  result.translation_m = a.after_from_before.translation().norm();
  result.after_mean_edge_m = MeanEdgeLength(after);
  // Half the samples: two scans of one asset overlap more than that; less means another
  // asset or a wrong local minimum. A residual above the edge length: the surfaces do not
  // lie on each other (a scan's noise is well below its mesh resolution).
  if (a.inlier_fraction < 0.5) {
    result.warnings.push_back("alignment: only " + FixedText(100 * a.inlier_fraction, 0) +
                              " % of BEFORE's samples lie on AFTER's surface (< 50 %): the models overlap "
                              "little or the alignment failed; check the difference images");
  }
  if (a.rms_residual_m > result.after_mean_edge_m) {
    result.warnings.push_back("alignment: RMS residual " + FixedText(1e3 * a.rms_residual_m, 1) +
                              " mm exceeds AFTER's mean edge length " + FixedText(1e3 * result.after_mean_edge_m, 1) +
                              " mm: the shapes differ or the alignment failed");
  }
  if (!a.converged) {
    result.warnings.push_back("alignment: ICP did not converge in " + std::to_string(a.iterations) + " iterations");
  }

  t = Clock::now();
  result.difference = MapDifference(before, after, a, compare);
  result.timings.difference_s = Seconds(t);
  const TemperatureDifference& d = result.difference;
  if (d.compared_area_m2 < 0.5 * d.after_area_m2) {
    result.warnings.push_back("only " + FixedText(100 * d.compared_area_m2 / std::max(d.after_area_m2, 1e-12), 0) +
                              " % of AFTER's surface has a BEFORE temperature to compare with");
  }

  t = Clock::now();
  result.before_spots = DetectSpots(before, config.spots);
  result.after_spots = DetectSpots(after, config.spots);
  result.timings.detect_s = Seconds(t);

  // The reflection check, as analyze runs it, on each model's spots with that model's own
  // views: a spot that appeared or vanished only because one scan looked at a shiny surface
  // head-on (or at a hot pipe's mirror image) is the classic false change. AFTER's BVH is
  // the images' one.
  const auto checkable = [&](const ThermalMesh& mesh, const SpotDetection& detection) {
    return config.reflections.check && !mesh.view_m.empty() && !detection.spots.empty();
  };
  result.before_checked_reflections = checkable(before, result.before_spots);
  result.after_checked_reflections = checkable(after, result.after_spots);
  std::unique_ptr<MeshRenderer> after_bvh;
  if (inputs.write_images || result.after_checked_reflections) {
    after_bvh = std::make_unique<MeshRenderer>(after);
    result.timings.bvh_s += after_bvh->build_seconds();
  }
  if (result.before_checked_reflections) {
    const MeshRenderer before_bvh(before);
    result.timings.bvh_s += before_bvh.build_seconds();
    t = Clock::now();
    CheckReflections(before, before_bvh, config.reflections, &result.before_spots.spots);
    result.timings.reflections_s += Seconds(t);
  }
  if (result.after_checked_reflections) {
    t = Clock::now();
    CheckReflections(after, *after_bvh, config.reflections, &result.after_spots.spots);
    result.timings.reflections_s += Seconds(t);
  }
  for (const Spot& s : result.before_spots.spots) {
    if (s.possible_reflection) result.warnings.push_back("BEFORE: " + ReflectionWarning(s));
  }
  for (const Spot& s : result.after_spots.spots) {
    if (s.possible_reflection) result.warnings.push_back("AFTER: " + ReflectionWarning(s));
  }
  result.changes = MatchSpots(result.before_spots.spots, result.after_spots.spots, a, compare);

  // Spans: the difference symmetric about 0 (white = no change), wide enough for every
  // change and for the highlighting band inside it; AFTER's temperature as analyze draws it.
  const double band_k = config.spots.min_delta_k;
  result.highlight_band_k = Span{-band_k, band_k};
  {
    std::vector<float> values;
    for (double v : d.difference_k) {
      if (std::isfinite(v)) values.push_back(static_cast<float>(v));
    }
    double m = values.empty() ? 0 : SymmetricAutoSpan(values, 1, 99).max_c;
    for (const SpotChange& c : result.changes) {
      if (std::isfinite(ChangeMagnitudeK(c))) m = std::max(m, std::abs(ChangeMagnitudeK(c)));
    }
    result.span_k = SymmetricRoundOut(std::max(m, 1.5 * band_k));
  }
  if (std::isfinite(config.span_min_c)) {
    result.after_span_c = Span{config.span_min_c, config.span_max_c};
  } else {
    std::vector<float> values;
    for (double v : after.temperature_c) {
      if (std::isfinite(v)) values.push_back(static_cast<float>(v));
    }
    const Span s = AutoSpan(values, 1, 99);
    double lo = s.min_c, hi = s.max_c;
    for (const Spot& x : result.after_spots.spots) {
      lo = std::min(lo, x.peak_c);
      hi = std::max(hi, x.peak_c);
    }
    result.after_span_c = RoundOut(lo, hi);
  }

  if (inputs.write_images) {
    const MeshRenderer& renderer = *after_bvh;
    const ViewSelectOptions select = SelectOptions(config);
    std::vector<NamedView> views = ConfiguredViews(after, config);
    std::vector<ChangePlace> places;
    for (const SpotChange& c : result.changes) places.push_back(PlaceOf(c, before, after, result));
    struct CloseUp {
      size_t change;
      NamedView view;
      double visible;
    };
    std::vector<CloseUp> closeups;
    if (config.closeups) {
      std::vector<size_t> order;
      for (size_t i = 0; i < result.changes.size(); ++i) {
        if (!result.changes[i].kinds.empty()) order.push_back(i);
      }
      std::stable_sort(order.begin(), order.end(), [&](size_t x, size_t y) {
        return std::abs(ChangeMagnitudeK(result.changes[x])) > std::abs(ChangeMagnitudeK(result.changes[y]));
      });
      if (order.size() > U(config.max_closeups)) order.resize(U(config.max_closeups));
      for (size_t i : order) {
        const ChangePlace& p = places[i];
        double visible = 0;
        NamedView v = CloseUpView(renderer, p.centroid_in_after, p.normal_in_after, p.radius_m,
                                  p.region_points_in_after, select, &visible);
        v.name = ChangeName(result.changes[i]);
        closeups.push_back({i, v, visible});
      }
    }
    const int total = static_cast<int>(views.size() + closeups.size());
    int done = 0;
    if (progress) progress(0, total);  // the bar starts its clock before the first render
    const RenderOptions render_options = ImageRenderOptions(config, inputs.num_threads);
    const std::optional<PaletteChoice> palette = ParsePalette(config.palette);
    const fs::path image_folder = out_folder / "images";
    fs::create_directories(image_folder);

    auto render_view = [&](const NamedView& view, const SpotChange* framed, double visible) {
      auto tr = Clock::now();
      const SampleBuffer samples = renderer.Render(view.camera, render_options);
      result.timings.render_s += Seconds(tr);
      ++result.timings.renders;
      // Labels: every change (and unchanged AFTER spot) in the frame, dimmed when hidden.
      std::vector<SpotLabel> labels;
      std::vector<std::string> labelled;
      const Eigen::Vector3d eye = view.camera.world_from_camera.translation();
      for (size_t i = 0; i < result.changes.size(); ++i) {
        const Eigen::Vector3d& peak = places[i].peak_in_after;
        double depth = 0;
        const Eigen::Vector2d px = view.camera.Project(peak, &depth);
        if (!(depth > 0) || px.x() < 0 || px.y() < 0 || px.x() > view.camera.width || px.y() > view.camera.height) {
          continue;
        }
        const Eigen::Vector3d from =
            view.camera.orthographic ? Eigen::Vector3d(peak - depth * view.camera.world_from_camera.linear().col(2))
                                     : eye;
        const bool seen = renderer.Unoccluded(from, peak, 2e-3);
        labels.push_back({px, ChangeLabelText(result.changes[i]), seen});
        if (seen) labelled.push_back(ChangeName(result.changes[i]));
      }
      auto tc = Clock::now();
      const std::vector<float> difference = TemperatureImage(after, samples, d.difference_k);
      // A close-up's difference span: its own pixels and the change it frames, so a change
      // smaller than the overviews' largest still shows.
      Span span_k = result.span_k;
      if (framed != nullptr) {
        const double own = SymmetricAutoSpan(difference, 1, 100).max_c;
        double m = std::max(own, 1.5 * band_k);
        if (std::isfinite(ChangeMagnitudeK(*framed))) m = std::max(m, std::abs(ChangeMagnitudeK(*framed)));
        span_k = SymmetricRoundOut(m);
      }
      result.timings.compose_s += Seconds(tc);
      bool first = true;
      for (const ImageSpec& spec : kImages) {
        tc = Clock::now();
        ViewStyle style;
        style.mode = spec.mode;
        if (spec.difference) {
          style.palette = Palette::kDiverging;
          style.span = span_k;
          style.band_low_c = result.highlight_band_k.min_c;
          style.band_high_c = result.highlight_band_k.max_c;
        } else {
          style.palette = palette->palette;
          style.inverted = palette->inverted;
          style.span = result.after_span_c;
        }
        const ImageRgb8 image = ComposeView(after, samples, spec.difference ? d.difference_k : after.temperature_c, style);
        Annotation ann;
        ann.title = (framed != nullptr ? "Change " + ChangeName(*framed) + " — " : "View " + view.name + " — ") +
                    spec.title;
        ColourBar bar;
        bar.palette = style.palette;
        bar.inverted = style.inverted;
        bar.span = style.span;
        if (spec.difference) {
          bar.units = "K";
          bar.title = "after − before";
          if (spec.mode == ViewMode::kHighlight) bar.band = result.highlight_band_k;
        } else {
          bar.title = after.temperature_field;
        }
        ann.colour_bar = bar;
        ann.spots = labels;
        const ImageRgb8 annotated = Annotate(image, ann);
        result.timings.compose_s += Seconds(tc);
        auto tw = Clock::now();
        AnalyzeImage out;
        out.file = "images/" + view.name + "-" + spec.suffix + ".png";
        WritePng(out_folder / out.file, annotated);
        if (first) {
          out.float_file = "images/" + view.name + "-difference_k" + (config.float_format == "exr" ? ".exr" : ".tif");
          WriteFloatImage(out_folder / out.float_file, samples.width, samples.height, difference, "K");
        }
        first = false;
        result.timings.write_s += Seconds(tw);
        out.view = view.name;
        out.mode = ViewModeName(spec.mode);
        out.spot_id = framed != nullptr ? ChangeName(*framed) : "";
        out.visible_fraction = framed != nullptr ? visible : -1;
        out.camera = view.camera;
        out.span = style.span;
        out.labelled_spots = labelled;
        result.images.push_back(out);
      }
      ++done;
      if (progress) progress(done, total);
    };
    for (const NamedView& v : views) render_view(v, nullptr, -1);
    for (const CloseUp& c : closeups) render_view(c.view, &result.changes[c.change], c.visible);
  }

  result.timings.total_s = Seconds(start);
  core::WriteFileAtomically(out_folder / "compare.json", CompareJson(before, after, inputs, result));
  return result;
}

namespace {

std::string MeshJson(const ThermalMesh& mesh, const fs::path& path) {
  return core::JsonObject()
      .String("file", path.string())
      .Int("vertices", mesh.NumVertices())
      .Int("faces", mesh.NumFaces())
      .Number("area_m2", mesh.TotalArea())
      .Bool("has_colour", mesh.HasColour())
      .Int("vertices_dropped_non_finite", mesh.report.vertices_non_finite)
      .Int("faces_dropped_degenerate", mesh.report.faces_degenerate)
      .Int("temperatures_unobserved", mesh.report.temperatures_unobserved)
      .str();
}

// The field an image shows: the difference images carry the suffixes of kImages.
std::string ImageField(const AnalyzeImage& i, const std::string& temperature_field) {
  const auto ends = [&](const std::string& tail) {
    return i.file.size() >= tail.size() && i.file.compare(i.file.size() - tail.size(), tail.size(), tail) == 0;
  };
  return ends("-difference.png") || ends("-difference-highlight.png") ? "difference_k" : temperature_field;
}

}  // namespace

std::string CompareJson(const ThermalMesh& before, const ThermalMesh& after, const CompareInputs& inputs,
                        const CompareResult& r) {
  const AnalyzeConfig& c = inputs.config;
  core::JsonObject root;
  root.Int("version", 1)
      .String("before", inputs.before_path.string())
      .String("after", inputs.after_path.string())
      .String("config", inputs.config_path.string())
      .String("field", after.temperature_field);
  root.Add("before_mesh", MeshJson(before, inputs.before_path)).Add("after_mesh", MeshJson(after, inputs.after_path));

  const Alignment& a = r.alignment;
  const Eigen::Quaterniond q(a.after_from_before.linear());
  std::vector<std::string> rows;
  const Eigen::Matrix4d m = a.after_from_before.matrix();
  for (int i = 0; i < 4; ++i) {
    rows.push_back("[" + core::JsonNumber(m(i, 0)) + ", " + core::JsonNumber(m(i, 1)) + ", " +
                   core::JsonNumber(m(i, 2)) + ", " + core::JsonNumber(m(i, 3)) + "]");
  }
  const double var_rot = a.covariance(0, 0) + a.covariance(1, 1) + a.covariance(2, 2);
  const double var_trans = a.covariance(3, 3) + a.covariance(4, 4) + a.covariance(5, 5);
  core::JsonObject al;
  al.Add("after_from_before", core::JsonArray(rows, "    "))
      .Add("q_xyzw", "[" + core::JsonNumber(q.x()) + ", " + core::JsonNumber(q.y()) + ", " + core::JsonNumber(q.z()) +
                         ", " + core::JsonNumber(q.w()) + "]")
      .Add("translation_m", Vector3Json(a.after_from_before.translation()))
      .Number("rotation_deg", r.rotation_deg)
      .Number("translation_length_m", r.translation_m)
      .Number("sigma_rotation_deg", std::sqrt(var_rot) * 180 / M_PI)
      .Number("sigma_translation_m", std::sqrt(var_trans))
      .Number("rms_residual_m", a.rms_residual_m)
      .Number("after_mean_edge_m", r.after_mean_edge_m)
      .Number("inlier_fraction", a.inlier_fraction)
      .Int("iterations", a.iterations)
      .Bool("converged", a.converged)
      .String("coarse", a.coarse)
      .Number("max_correspondence_distance_m", inputs.align.max_correspondence_distance_m)
      .Number("robust_loss_scale_m", inputs.align.robust_loss_scale_m);
  root.Add("alignment", al.str());

  const TemperatureDifference& d = r.difference;
  root.Add("difference", core::JsonObject()
                             .Int("compared_vertices", d.compared_vertices)
                             .Number("compared_area_m2", d.compared_area_m2)
                             .Number("after_area_m2", d.after_area_m2)
                             .Number("mean_k", d.mean_k)
                             .Number("median_k", d.median_k)
                             .Number("p95_abs_k", d.p95_abs_k)
                             .Number("max_distance_m", inputs.compare.max_distance_m)
                             .Number("region_radius_m", inputs.compare.region_radius_m)
                             .Add("span_k", SpanJson(r.span_k))
                             .Add("highlight_band_k", SpanJson(r.highlight_band_k))
                             .str());
  root.Add("detection", core::JsonObject()
                            .String("detect", c.spots.detect == SpotOptions::Detect::kDelta ? "delta" : "absolute")
                            .String("reference",
                                    c.spots.reference == SpotOptions::Reference::kSurrounding ? "surrounding" : "ambient")
                            .Number("min_delta_k", c.spots.min_delta_k)
                            .Number("min_area_m2", c.spots.min_area_m2)
                            .Number("max_area_m2", c.spots.max_area_m2)
                            .Number("spot_match_distance_m", inputs.compare.spot_match_distance_m)
                            .Number("spot_match_radius_factor", inputs.compare.spot_match_radius_factor)
                            .Number("area_change_relative", inputs.compare.area_change_relative)
                            .Number("area_change_sigmas", inputs.compare.area_change_sigmas)
                            .Number("peak_change_k", inputs.compare.peak_change_k)
                            .Add("reflections", ReflectionOptionsJson(c.reflections))
                            .Bool("before_checked_reflections", r.before_checked_reflections)
                            .Bool("after_checked_reflections", r.after_checked_reflections)
                            .str());
  std::vector<std::string> before_spots, after_spots, changes;
  for (const Spot& s : r.before_spots.spots) before_spots.push_back(SpotJson(s, {}));
  for (const Spot& s : r.after_spots.spots) after_spots.push_back(SpotJson(s, {}));
  root.Add("before_spots", core::JsonArray(before_spots, "  "));
  root.Add("after_spots", core::JsonArray(after_spots, "  "));
  for (const SpotChange& x : r.changes) {
    std::vector<std::string> images;
    for (const AnalyzeImage& i : r.images) {
      if (!i.spot_id.empty() && i.spot_id == ChangeName(x)) images.push_back(i.file);
    }
    changes.push_back(core::JsonObject()
                          .String("name", ChangeName(x))
                          .Add("kinds", StringsJson(x.kinds))
                          .String("before", x.before_id)
                          .String("after", x.after_id)
                          .Number("distance_m", x.distance_m)
                          .Number("area_before_m2", x.area_before_m2)
                          .Number("area_after_m2", x.area_after_m2)
                          .Number("area_change_relative", (x.area_after_m2 - x.area_before_m2) / x.area_before_m2)
                          .Number("peak_before_c", x.peak_before_c)
                          .Number("peak_after_c", x.peak_after_c)
                          .Number("peak_change_k", x.peak_after_c - x.peak_before_c)
                          .Number("delta_before_k", x.delta_before_k)
                          .Number("delta_after_k", x.delta_after_k)
                          .Bool("before_possible_reflection", x.before_possible_reflection)
                          .Bool("after_possible_reflection", x.after_possible_reflection)
                          .Bool("needs_second_view", NeedsSecondView(x))
                          .Add("images", StringsJson(images))
                          .str());
  }
  root.Add("changes", core::JsonArray(changes, "  "));
  std::vector<std::string> images;
  for (const AnalyzeImage& i : r.images) {
    core::JsonObject o;
    o.String("file", i.file)
        .String("float_file", i.float_file)
        .String("view", i.view)
        .String("mode", i.mode)
        .String("field", ImageField(i, after.temperature_field))
        .String("change", i.spot_id)
        .Number("visible_fraction", i.visible_fraction)
        .Add("span", SpanJson(i.span))
        .Add("labelled", StringsJson(i.labelled_spots))
        .Add("camera", CameraJson(i.camera));
    images.push_back(o.str());
  }
  root.Add("images", core::JsonArray(images, "  "));
  root.Add("timings", core::JsonObject()
                          .Number("align_s", r.timings.align_s)
                          .Number("difference_s", r.timings.difference_s)
                          .Number("detect_s", r.timings.detect_s)
                          .Number("reflections_s", r.timings.reflections_s)
                          .Number("bvh_build_s", r.timings.bvh_s)
                          .Number("render_s", r.timings.render_s)
                          .Int("renders", r.timings.renders)
                          .Number("compose_s", r.timings.compose_s)
                          .Number("write_s", r.timings.write_s)
                          .Number("total_s", r.timings.total_s)
                          .str());
  std::vector<std::string> warnings;
  for (const std::string& w : r.warnings) warnings.push_back(core::JsonString(w));
  root.Add("warnings", core::JsonArray(warnings, "  "));
  return root.str() + "\n";
}

std::string FormatCompareSummary(const CompareResult& r) {
  std::ostringstream s;
  const Alignment& a = r.alignment;
  s << "compare: aligned by " << FixedText(r.rotation_deg, 2) << "° and " << FixedText(100 * r.translation_m, 1)
    << " cm (start " << a.coarse << "), RMS residual " << FixedText(1e3 * a.rms_residual_m, 2) << " mm, "
    << FixedText(100 * a.inlier_fraction, 0) << " % inliers, " << a.iterations << " iterations"
    << (a.converged ? "" : " (not converged)") << "\n";
  const TemperatureDifference& d = r.difference;
  s << "  difference after − before on " << FixedText(100 * d.compared_area_m2 / std::max(d.after_area_m2, 1e-12), 1)
    << " % of AFTER's surface: mean " << Signed(d.mean_k, 2) << " K, median " << Signed(d.median_k, 2)
    << " K, 95 % of |ΔT| below " << FixedText(d.p95_abs_k, 2) << " K\n";
  s << "  spots: " << r.before_spots.spots.size() << " before, " << r.after_spots.spots.size() << " after\n";
  s << "  change    before after kinds             peak °C before → after  area cm² before → after\n";
  int shown = 0;
  for (const SpotChange& x : r.changes) {
    if (x.kinds.empty()) continue;
    if (++shown > 12) {
      s << "  … more in compare.json\n";
      break;
    }
    std::string kinds;
    for (size_t k = 0; k < x.kinds.size(); ++k) kinds += (k ? "," : "") + x.kinds[k];
    if (NeedsSecondView(x)) kinds += " (refl.?)";
    const auto num = [](double v, double scale) { return std::isfinite(v) ? FixedText(scale * v, 1) : std::string("—"); };
    s << "  " << Pad(ChangeName(x), 10) << Pad(x.before_id.empty() ? "—" : x.before_id, 7)
      << Pad(x.after_id.empty() ? "—" : x.after_id, 6) << Pad(kinds, 18) << Pad(num(x.peak_before_c, 1), 6, true)
      << " → " << Pad(num(x.peak_after_c, 1), 8) << Pad(num(x.area_before_m2, 1e4), 7, true) << " → "
      << num(x.area_after_m2, 1e4) << "\n";
  }
  const size_t unchanged = static_cast<size_t>(
      std::count_if(r.changes.begin(), r.changes.end(), [](const SpotChange& x) { return x.kinds.empty(); }));
  s << "  " << unchanged << " spot" << (unchanged == 1 ? "" : "s") << " unchanged\n";
  std::string verify;
  int to_verify = 0;
  for (const SpotChange& x : r.changes) {
    if (!NeedsSecondView(x)) continue;
    const char* scans = x.before_possible_reflection && x.after_possible_reflection ? "both scans"
                        : x.after_possible_reflection                              ? "AFTER"
                                                                                   : "BEFORE";
    verify += (to_verify++ ? ", " : "") + ChangeName(x) + " (" + scans + ")";
  }
  if (to_verify > 0) {
    s << "  verify: " << verify << (to_verify == 1 ? " may be a reflection" : " may be reflections")
      << " in that scan: re-image from another angle before calling it a change\n";
  }
  if (!r.images.empty()) {
    s << "  images: " << r.images.size() << " in " << (r.out_folder / "images").string() << " ("
      << r.timings.renders << " renders)\n";
  }
  for (const std::string& w : r.warnings) s << "  warning: " << w << "\n";
  s << "  total " << FixedText(r.timings.total_s, 1) << " s (align " << FixedText(r.timings.align_s, 1) << " s); wrote "
    << (r.out_folder / "compare.json").string() << "\n";
  return s.str();
}

}  // namespace hw::analyze
