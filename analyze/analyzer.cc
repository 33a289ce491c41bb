#include "analyze/analyzer.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <sstream>

#include "analyze/annotate.h"
#include "analyze/output_support.h"
#include "analyze/image_out.h"
#include "analyze/view_select.h"
#include "analyze/views.h"
#include "core/atomic_file.h"
#include "core/json.h"
#include "core/strings.h"

namespace hw::analyze {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

size_t U(int i) { return static_cast<size_t>(i); }

// Area-weighted quantile of the per-vertex field over faces (each face's area split over
// its observed vertices).
struct FieldStats {
  double min_c = NAN, median_c = NAN, max_c = NAN, p01_c = NAN, p99_c = NAN, observed_area_m2 = 0;
};

FieldStats Stats(const ThermalMesh& mesh) {
  FieldStats s;
  std::vector<std::pair<double, double>> values;
  for (int f = 0; f < mesh.NumFaces(); ++f) {
    const Eigen::Vector3i& face = mesh.faces[U(f)];
    const double a = mesh.FaceArea(f);
    bool all = true;
    for (int k = 0; k < 3; ++k) {
      const double t = mesh.temperature_c[U(face[k])];
      if (std::isfinite(t)) {
        values.emplace_back(t, a / 3);
      } else {
        all = false;
      }
    }
    if (all) s.observed_area_m2 += a;
  }
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  double total = 0;
  for (const auto& v : values) total += v.second;
  auto quantile = [&](double q) {
    double sum = 0;
    for (const auto& v : values) {
      sum += v.second;
      if (sum >= q * total) return v.first;
    }
    return values.back().first;
  };
  s.min_c = values.front().first;
  s.max_c = values.back().first;
  s.median_c = quantile(0.5);
  s.p01_c = quantile(0.01);
  s.p99_c = quantile(0.99);
  return s;
}

std::string SpotLabelText(const Spot& spot) {
  return spot.id + " " + FixedText(spot.peak_c, 1) + " °C";
}

struct ModeSpec {
  ViewMode mode;
  const char* suffix;
  const char* title;
};

constexpr ModeSpec kModes[] = {
    {ViewMode::kThermal, "thermal", "Surface temperature"},
    {ViewMode::kColour, "colour", "Visible colour"},
    {ViewMode::kIhMapping, "ih", "IH mapping: hue = temperature, intensity = visible texture"},
    {ViewMode::kHighlight, "highlight", "Thermal highlighting: palette outside the normal band"},
};

}  // namespace

AnalyzeResult Analyze(const ThermalMesh& mesh, const AnalyzeInputs& inputs, const fs::path& out_folder,
                      const std::function<void(int, int)>& progress) {
  const AnalyzeConfig& config = inputs.config;
  assert(config.Check().empty());
  const auto start = Clock::now();
  AnalyzeResult result;
  result.out_folder = out_folder;
  result.vertices = mesh.NumVertices();
  result.faces = mesh.NumFaces();
  result.area_m2 = mesh.TotalArea();
  result.warnings = mesh.report.warnings;
  const bool has_temperature = mesh.HasTemperature();

  FieldStats stats;
  if (has_temperature) {
    stats = Stats(mesh);
    result.observed_area_m2 = stats.observed_area_m2;
    result.temperature_min_c = stats.min_c;
    result.temperature_median_c = stats.median_c;
    result.temperature_max_c = stats.max_c;
    if (!std::isfinite(stats.median_c)) result.warnings.push_back("no vertex has a temperature: nothing to measure");
  }
  const bool measurable = has_temperature && std::isfinite(stats.median_c);
  // One BVH for the reflection check and the images.
  std::unique_ptr<MeshRenderer> bvh;
  const bool check_reflections = measurable && config.reflections.check && !mesh.view_m.empty();
  result.checked_reflections = check_reflections;
  if (inputs.write_images || check_reflections) {
    bvh = std::make_unique<MeshRenderer>(mesh);
    result.timings.bvh_s = bvh->build_seconds();
  }
  if (measurable) {
    const auto t = Clock::now();
    const SpotFinder finder(mesh, config.spots);
    result.detection = finder.Detect();
    result.timings.detect_s = Seconds(t);
    if (result.detection->unrated_area_m2 > 0) {
      char text[320];
      std::snprintf(text, sizeof(text),
                    "%.0f cm² of the observed surface has an emissivity below %g (bare metal, glazing): its reading is "
                    "mostly reflection, so no spot is rated there; tape or paint it and re-measure (spots.min_emissivity)",
                    1e4 * result.detection->unrated_area_m2, config.spots.min_emissivity);
      result.warnings.push_back(text);
    }
    if (check_reflections) {
      const auto tr = Clock::now();
      CheckReflections(mesh, *bvh, config.reflections, &result.detection->spots);
      result.timings.reflections_s = Seconds(tr);
      for (const Spot& s : result.detection->spots) {
        if (s.possible_reflection) result.warnings.push_back(ReflectionWarning(s));
      }
    }
    for (const Spot& s : result.detection->spots) {
      if (s.resolved) continue;
      char text[320];
      std::snprintf(text, sizeof(text),
                    "%s is %.2f thermal pixels across (one covers %.1f mm of its surface): under-resolved, its "
                    "peak and ΔT read low and its size high; measure it from closer (spots.min_resolved_px %g)",
                    s.id.c_str(), s.width_px, 1000 * s.footprint_m, config.spots.min_resolved_px);
      result.warnings.push_back(text);
    }
    if (inputs.truth) {
      result.truth = ScoreAgainstTruth(result.detection->spots, *inputs.truth, inputs.truth_observed_only);
      AddThresholdErrors(finder, result.detection->spots, *inputs.truth, inputs.truth_observed_only, &*result.truth);
    }
  }
  const std::vector<Spot> no_spots;
  const std::vector<Spot>& spots = result.detection ? result.detection->spots : no_spots;

  // One span for every overview (images comparable), wide enough for every spot's peak.
  if (measurable) {
    double lo = stats.p01_c, hi = stats.p99_c;
    for (const Spot& s : spots) {
      lo = std::min(lo, s.peak_c);
      hi = std::max(hi, s.peak_c);
    }
    result.span = std::isfinite(config.span_min_c) ? Span{config.span_min_c, config.span_max_c} : RoundOut(lo, hi);
    // The normal band: between the levels of the mildest hot and cold spots, so exactly the
    // spots (and anything as abnormal) take the palette.
    // Without spots of a kind that side is open: the band reaches the field's extreme (so
    // nothing is beyond it, and the bar's label reads a real temperature).
    double band_low = std::min(result.span.min_c, stats.min_c), band_high = std::max(result.span.max_c, stats.max_c);
    for (const Spot& s : spots) {
      if (s.hot) band_high = std::min(band_high, s.level_c);
      if (!s.hot) band_low = std::max(band_low, s.level_c);
    }
    if (!(band_low < band_high)) {
      band_low = stats.median_c - config.spots.min_delta_k;
      band_high = stats.median_c + config.spots.min_delta_k;
    }
    result.highlight_band = std::isfinite(config.highlight_low_c) ? Span{config.highlight_low_c, config.highlight_high_c}
                                                                   : Span{band_low, band_high};
  }

  if (inputs.write_images) {
    const MeshRenderer& renderer = *bvh;
    const ViewSelectOptions select = SelectOptions(config);
    std::vector<NamedView> views = ConfiguredViews(mesh, config);
    struct CloseUp {
      const Spot* spot;
      NamedView view;
      double visible;
    };
    std::vector<CloseUp> closeups;
    if (config.closeups) {
      std::vector<const Spot*> order;
      for (const Spot& s : spots) order.push_back(&s);
      std::stable_sort(order.begin(), order.end(),
                       [](const Spot* a, const Spot* b) { return std::abs(a->delta_k) > std::abs(b->delta_k); });
      if (order.size() > U(config.max_closeups)) order.resize(U(config.max_closeups));
      for (const Spot* s : order) {
        std::vector<Eigen::Vector3d> points;
        for (int f : s->faces) {
          const Eigen::Vector3i& face = mesh.faces[U(f)];
          points.push_back((mesh.points_in_world[U(face[0])] + mesh.points_in_world[U(face[1])] +
                            mesh.points_in_world[U(face[2])]) / 3);
        }
        // At most ~200 points scored: enough for a visible fraction to a few per cent.
        if (points.size() > 200) {
          std::vector<Eigen::Vector3d> thinned;
          const size_t stride = points.size() / 200 + 1;
          for (size_t i = 0; i < points.size(); i += stride) thinned.push_back(points[i]);
          points.swap(thinned);
        }
        double visible = 0;
        NamedView v = CloseUpView(renderer, s->centroid_in_world, s->normal_in_world, s->radius_m, points, select, &visible);
        v.name = s->id;
        closeups.push_back({s, v, visible});
      }
    }
    const int total = static_cast<int>(views.size() + closeups.size());
    int done = 0;
    if (progress) progress(0, total);  // the bar starts its clock before the first render
    const RenderOptions render_options = ImageRenderOptions(config, inputs.num_threads);
    const std::optional<PaletteChoice> palette = ParsePalette(config.palette);
    const fs::path image_folder = out_folder / "images";
    fs::create_directories(image_folder);

    auto render_view = [&](const NamedView& view, const Spot* framed, double visible) {
      auto tr = Clock::now();
      const SampleBuffer samples = renderer.Render(view.camera, render_options);
      result.timings.render_s += Seconds(tr);
      ++result.timings.renders;
      // Labels: every spot whose peak is in the frame and seen from the camera.
      std::vector<SpotLabel> labels;
      std::vector<std::string> labelled;
      if (measurable) {
        const Eigen::Vector3d eye = view.camera.world_from_camera.translation();
        for (const Spot& s : spots) {
          double depth = 0;
          const Eigen::Vector2d px = view.camera.Project(s.peak_in_world, &depth);
          if (!(depth > 0) || px.x() < 0 || px.y() < 0 || px.x() > view.camera.width || px.y() > view.camera.height) {
            continue;
          }
          // An orthographic eye is the point on the camera plane above the peak.
          const Eigen::Vector3d from =
              view.camera.orthographic
                  ? Eigen::Vector3d(s.peak_in_world - depth * view.camera.world_from_camera.linear().col(2))
                  : eye;
          const bool seen = renderer.Unoccluded(from, s.peak_in_world, 2e-3);
          labels.push_back({px, SpotLabelText(s), seen});
          if (seen) labelled.push_back(s.id);
        }
      }
      // The close-up's span: its own pixels, so the spot's structure shows.
      Span span = result.span;
      std::vector<float> temperature;
      if (measurable) {
        auto tc = Clock::now();
        temperature = TemperatureImage(mesh, samples, mesh.temperature_c);
        result.timings.compose_s += Seconds(tc);
        if (framed != nullptr && !std::isfinite(config.span_min_c)) {
          const Span own = AutoSpan(temperature, 1, 100);
          span = RoundOut(std::min(own.min_c, framed->peak_c), std::max(own.max_c, framed->peak_c));
        }
      }
      const std::string base = view.name;
      bool first = true;
      for (const ModeSpec& m : kModes) {
        if (!measurable && m.mode != ViewMode::kColour) continue;
        auto tc = Clock::now();
        ViewStyle style;
        style.mode = m.mode;
        style.palette = palette->palette;
        style.inverted = palette->inverted;
        style.span = span;
        style.band_low_c = result.highlight_band.min_c;
        style.band_high_c = result.highlight_band.max_c;
        const ImageRgb8 image = ComposeView(mesh, samples, measurable ? mesh.temperature_c : std::vector<double>(U(mesh.NumVertices()), NAN), style);
        Annotation a;
        if (config.legends) {
          a.title = (framed != nullptr ? "Spot " + framed->id + " — " : "View " + view.name + " — ") + m.title;
        }
        if (config.legends && m.mode != ViewMode::kColour) {
          ColourBar bar;
          bar.palette = style.palette;
          bar.inverted = style.inverted;
          bar.ih_hue = m.mode == ViewMode::kIhMapping;
          bar.span = span;
          bar.title = mesh.temperature_field == "temperature_c" ? "Surface temperature" : mesh.temperature_field;
          if (m.mode == ViewMode::kHighlight) bar.band = result.highlight_band;
          a.colour_bar = bar;
        }
        a.spots = labels;
        const ImageRgb8 annotated = Annotate(image, a);
        result.timings.compose_s += Seconds(tc);
        auto tw = Clock::now();
        AnalyzeImage out;
        out.file = "images/" + base + "-" + m.suffix + ".png";
        WritePng(out_folder / out.file, annotated);
        if (first && measurable) {
          out.float_file = "images/" + base + "-" + mesh.temperature_field + (config.float_format == "exr" ? ".exr" : ".tif");
          WriteFloatImage(out_folder / out.float_file, samples.width, samples.height, temperature, "degC");
        }
        first = false;
        result.timings.write_s += Seconds(tw);
        out.view = view.name;
        out.mode = ViewModeName(m.mode);
        out.spot_id = framed != nullptr ? framed->id : "";
        out.visible_fraction = framed != nullptr ? visible : -1;
        out.camera = view.camera;
        out.span = span;
        out.labelled_spots = labelled;
        result.images.push_back(out);
      }
      ++done;
      if (progress) progress(done, total);
    };
    for (const NamedView& v : views) render_view(v, nullptr, -1);
    for (const CloseUp& c : closeups) render_view(c.view, c.spot, c.visible);
  }

  result.timings.total_s = Seconds(start);
  core::WriteFileAtomically(out_folder / "analyze.json", AnalyzeJson(mesh, inputs, result));
  return result;
}

namespace {

}  // namespace

std::string AnalyzeJson(const ThermalMesh& mesh, const AnalyzeInputs& inputs, const AnalyzeResult& r) {
  const AnalyzeConfig& c = inputs.config;
  core::JsonObject root;
  root.Int("version", 1).String("model", inputs.model_path.string()).String("config", inputs.config_path.string());
  root.String("field", mesh.HasTemperature() ? mesh.temperature_field : "");
  core::JsonObject m;
  m.Int("vertices", r.vertices)
      .Int("faces", r.faces)
      .Number("area_m2", r.area_m2)
      .Number("observed_area_m2", r.observed_area_m2)
      .Bool("has_temperature", mesh.HasTemperature())
      .Bool("has_colour", mesh.HasColour())
      .Bool("has_confidence", !mesh.confidence.empty())
      .Int("vertices_dropped_non_finite", mesh.report.vertices_non_finite)
      .Int("faces_dropped_degenerate", mesh.report.faces_degenerate)
      .Int("temperatures_unobserved", mesh.report.temperatures_unobserved)
      .Number("temperature_min_c", r.temperature_min_c)
      .Number("temperature_median_c", r.temperature_median_c)
      .Number("temperature_max_c", r.temperature_max_c);
  root.Add("mesh", m.str());
  core::JsonObject d;
  const SpotOptions& so = c.spots;
  d.String("detect", so.detect == SpotOptions::Detect::kDelta ? "delta" : "absolute")
      .String("reference", so.reference == SpotOptions::Reference::kSurrounding ? "surrounding" : "ambient")
      .Number("ambient_c", so.ambient_c)
      .Number("min_delta_k", so.min_delta_k)
      .Number("hot_above_c", so.hot_above_c)
      .Number("cold_below_c", so.cold_below_c)
      .Bool("hot", so.find_hot)
      .Bool("cold", so.find_cold)
      .Number("boundary_fraction", so.boundary_fraction)
      .Number("min_area_m2", so.min_area_m2)
      .Number("max_area_m2", so.max_area_m2)
      .Number("background_radius_m", so.background_radius_m)
      .Add("reflections", ReflectionOptionsJson(c.reflections))
      .Bool("checked_reflections", r.checked_reflections);
  root.Add("detection", d.str());
  std::vector<std::string> bands;
  for (const SeverityBand& b : so.severity.empty() ? NetaSeverityTable() : so.severity) {
    bands.push_back(core::JsonObject().String("name", b.name).Number("min_delta_k", b.min_delta_k).String("action", b.action).str());
  }
  root.Add("severity_table", core::JsonArray(bands, "  "));
  std::vector<std::string> spots, rejected;
  if (r.detection) {
    for (const Spot& s : r.detection->spots) {
      std::vector<std::string> files;
      for (const AnalyzeImage& image : r.images) {
        if (image.spot_id == s.id) files.push_back(image.file);
      }
      spots.push_back(SpotJson(s, files));
    }
    for (const RejectedCandidate& x : r.detection->rejected) {
      rejected.push_back(core::JsonObject()
                             .String("kind", x.hot ? "hot" : "cold")
                             .Number("peak_c", x.peak_c)
                             .Add("peak_m", Vector3Json(x.peak_in_world))
                             .String("reason", x.reason)
                             .str());
    }
    root.Int("candidates", r.detection->candidates);
    root.Int("candidates_unmeasured", r.detection->unmeasured);
    root.Number("unrated_area_m2", r.detection->unrated_area_m2);
  }
  root.Add("spots", core::JsonArray(spots, "  "));
  root.Add("rejected", core::JsonArray(rejected, "  "));
  root.String("palette", c.palette).Bool("legends", c.legends);
  root.Add("span_c", "[" + core::JsonNumber(r.span.min_c) + ", " + core::JsonNumber(r.span.max_c) + "]");
  root.Add("highlight_band_c",
           "[" + core::JsonNumber(r.highlight_band.min_c) + ", " + core::JsonNumber(r.highlight_band.max_c) + "]");
  std::vector<std::string> images;
  for (const AnalyzeImage& i : r.images) {
    core::JsonObject o;
    o.String("file", i.file).String("float_file", i.float_file).String("view", i.view).String("mode", i.mode);
    o.String("spot", i.spot_id).Number("visible_fraction", i.visible_fraction);
    o.Add("span_c", "[" + core::JsonNumber(i.span.min_c) + ", " + core::JsonNumber(i.span.max_c) + "]");
    std::vector<std::string> labelled;
    for (const std::string& id : i.labelled_spots) labelled.push_back(core::JsonString(id));
    o.Add("labelled_spots", "[" + [&] {
      std::string s;
      for (size_t k = 0; k < labelled.size(); ++k) s += (k ? ", " : "") + labelled[k];
      return s;
    }() + "]");
    o.Add("camera", CameraJson(i.camera));
    images.push_back(o.str());
  }
  root.Add("images", core::JsonArray(images, "  "));
  if (r.truth) {
    core::JsonObject t;
    t.String("file", inputs.truth_path.string())
        .Bool("observed_only", inputs.truth_observed_only)
        .Int("found", r.truth->found)
        .Int("missed", r.truth->missed)
        .Int("false_spots", static_cast<int64_t>(r.truth->false_spots.size()))
        .Number("max_abs_area_error", r.truth->max_abs_area_error)
        .Number("max_abs_length_error", r.truth->max_abs_length_error)
        .Number("max_abs_width_error", r.truth->max_abs_width_error)
        .Number("max_abs_delta_error_k", r.truth->max_abs_delta_error_k)
        .Number("max_abs_area_error_at_threshold", r.truth->max_abs_area_error_at_threshold)
        .Number("max_abs_length_error_at_threshold", r.truth->max_abs_length_error_at_threshold)
        .Number("max_abs_width_error_at_threshold", r.truth->max_abs_width_error_at_threshold);
    std::vector<std::string> matches;
    for (const TruthMatch& x : r.truth->matches) {
      matches.push_back(core::JsonObject()
                            .String("truth", x.truth_id)
                            .String("spot", x.spot_id)
                            .Number("distance_m", x.distance_m)
                            .Number("area_error", x.area_error)
                            .Number("length_error", x.length_error)
                            .Number("width_error", x.width_error)
                            .Bool("area_covered", x.area_covered)
                            .Bool("length_covered", x.length_covered)
                            .Bool("width_covered", x.width_covered)
                            .Number("delta_error_k", x.delta_error_k)
                            .Bool("delta_covered", x.delta_covered)
                            .Number("area_error_at_threshold", x.area_error_at_threshold)
                            .Number("length_error_at_threshold", x.length_error_at_threshold)
                            .Number("width_error_at_threshold", x.width_error_at_threshold)
                            .str());
    }
    t.Add("matches", core::JsonArray(matches, "    "));
    const auto ids = [](const std::vector<std::string>& list) {
      std::vector<std::string> quoted;
      for (const std::string& id : list) quoted.push_back(core::JsonString(id));
      return core::JsonArray(quoted, "    ");
    };
    t.Add("false_spot_ids", ids(r.truth->false_spots));
    t.Add("false_flagged_as_reflections", ids(r.truth->false_flagged_as_reflections));
    t.Add("found_flagged_as_reflections", ids(r.truth->found_flagged_as_reflections));
    std::vector<std::string> partly;
    for (const auto& [truth_id, spot_id] : r.truth->partly_observed) {
      partly.push_back(core::JsonObject().String("truth", truth_id).String("spot", spot_id).str());
    }
    t.Add("partly_observed_matches", core::JsonArray(partly, "    "));
    root.Add("truth", t.str());
  }
  core::JsonObject timings;
  timings.Number("detect_s", r.timings.detect_s)
      .Number("reflections_s", r.timings.reflections_s)
      .Number("bvh_build_s", r.timings.bvh_s)
      .Number("render_s", r.timings.render_s)
      .Int("renders", r.timings.renders)
      .Number("compose_s", r.timings.compose_s)
      .Number("write_s", r.timings.write_s)
      .Number("total_s", r.timings.total_s);
  root.Add("timings", timings.str());
  std::vector<std::string> warnings;
  for (const std::string& w : r.warnings) warnings.push_back(core::JsonString(w));
  root.Add("warnings", core::JsonArray(warnings, "  "));
  return root.str() + "\n";
}

std::string FormatAnalyzeSummary(const AnalyzeResult& r) {
  std::ostringstream s;
  s << "analyze: " << r.vertices << " vertices, " << r.faces << " faces, " << FixedText(r.area_m2, 2) << " m²";
  if (r.detection) {
    s << ", " << FixedText(100 * r.observed_area_m2 / std::max(r.area_m2, 1e-12), 1) << " % with temperature ("
      << FixedText(r.temperature_min_c, 1) << " … " << FixedText(r.temperature_max_c, 1) << " °C, median "
      << FixedText(r.temperature_median_c, 1) << ")\n";
    s << "  spots: " << r.detection->spots.size() << " (" << r.detection->candidates << " candidates, "
      << r.detection->rejected.size() << " measured and rejected) on " << r.detection->field << "\n";
    if (r.detection->unmeasured > 0) {
      s << "  warning: " << r.detection->unmeasured << " weaker candidates not measured (spots.max_candidates)\n";
    }
    s << "  id    peak °C  ref °C   ΔT K         area cm²        length cm      width cm    px  severity\n";
    int shown = 0;
    for (const Spot& x : r.detection->spots) {
      if (++shown > 12) {
        s << "  … " << r.detection->spots.size() - 12 << " more in analyze.json\n";
        break;
      }
      // Thermal pixels across (width / footprint), "-" when the mesh does not say.
      char px[16] = "    -";
      if (std::isfinite(x.width_px)) std::snprintf(px, sizeof px, "%5.1f", x.width_px);
      char line[256];
      std::snprintf(line, sizeof line, "  %-4s %8.1f %7.1f %6.1f ±%-4.1f %8.1f ±%-6.1f %6.1f ±%-5.1f %6.1f ±%-5.1f %s%s %s\n",
                    x.id.c_str(), x.peak_c, x.reference_c, x.delta_k, x.delta_sigma_k, 1e4 * x.area_m2, 1e4 * x.area_sigma_m2,
                    100 * x.length_m, 100 * x.length_sigma_m, 100 * x.width_m, 100 * x.width_sigma_m, px,
                    x.resolved ? " " : "!", (x.severity + (x.possible_reflection ? " (reflection?)" : "")).c_str());
      s << line;
    }
  } else {
    s << ", no temperature\n";
  }
  if (r.truth) {
    s << "  truth: " << r.truth->found << " found, " << r.truth->missed << " missed, " << r.truth->false_spots.size()
      << " false";
    if (!r.truth->false_flagged_as_reflections.empty() || !r.truth->found_flagged_as_reflections.empty()) {
      s << " (flagged as possible reflections: " << r.truth->false_flagged_as_reflections.size() << " false, "
        << r.truth->found_flagged_as_reflections.size() << " found)";
    }
    for (const auto& [truth_id, spot_id] : r.truth->partly_observed) s << ", " << spot_id << " on " << truth_id << " (seen in part)";
    s << "; max |error| area " << FixedText(100 * r.truth->max_abs_area_error, 2) << " %, length "
      << FixedText(100 * r.truth->max_abs_length_error, 2) << " %, width " << FixedText(100 * r.truth->max_abs_width_error, 2)
      << " %, ΔT " << FixedText(r.truth->max_abs_delta_error_k, 2) << " K\n         at the truth's own thresholds: area " << FixedText(100 * r.truth->max_abs_area_error_at_threshold, 2)
      << " %, length " << FixedText(100 * r.truth->max_abs_length_error_at_threshold, 2) << " %, width "
      << FixedText(100 * r.truth->max_abs_width_error_at_threshold, 2) << " %\n";
  }
  s << "  images: " << r.images.size() << " in " << (r.out_folder / "images").string() << " (" << r.timings.renders
    << " renders, " << FixedText(1e3 * r.timings.render_s / std::max(1, r.timings.renders), 0) << " ms each, BVH "
    << FixedText(1e3 * r.timings.bvh_s, 0) << " ms)\n";
  for (const std::string& w : r.warnings) s << "  warning: " << w << "\n";
  s << "  total " << FixedText(r.timings.total_s, 1) << " s; wrote " << (r.out_folder / "analyze.json").string() << "\n";
  return s.str();
}

}  // namespace hw::analyze
