#include "report/report_model.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <tuple>
#include <map>

#include <Eigen/Geometry>

#include "core/error.h"
#include "core/strings.h"
#include "report/report_inputs.h"

namespace hw::report {
namespace {

namespace fs = std::filesystem;
using core::StringPrintf;

constexpr const char* kDash = "—";

std::string Join(const std::vector<std::string>& parts, const std::string& sep) {
  std::string out;
  for (const std::string& p : parts) {
    if (p.empty()) continue;
    out += (out.empty() ? "" : sep) + p;
  }
  return out;
}

std::string Or(const std::string& s, const std::string& fallback = kDash) { return s.empty() ? fallback : s; }

std::string Capitalised(std::string s) {
  if (!s.empty() && s[0] >= 'a' && s[0] <= 'z') s[0] = static_cast<char>(s[0] - 'a' + 'A');
  return s;
}

std::string Anchor(const std::string& prefix, const std::string& id) {
  std::string out = prefix;
  for (char c : id) {
    if ((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9')) {
      out += c;
    } else if (c >= 'A' && c <= 'Z') {
      out += static_cast<char>(c - 'A' + 'a');
    } else {
      out += '-';
    }
  }
  return out;
}

// Severity bands ranked by threshold: rank 0 the most severe. Tints go red → amber →
// yellow → grey-blue, the order thermography reports use for priorities.
struct SeverityRanks {
  std::vector<SeverityRecord> bands;  // most severe first
  int Rank(const std::string& name) const {
    for (size_t i = 0; i < bands.size(); ++i) {
      if (bands[i].name == name) return static_cast<int>(i);
    }
    return static_cast<int>(bands.size());
  }
  std::array<std::uint8_t, 3> Tint(const std::string& name) const {
    static constexpr std::array<std::array<std::uint8_t, 3>, 4> kTints = {
        {{200, 40, 40}, {230, 130, 30}, {235, 200, 50}, {120, 150, 180}}};
    return kTints[static_cast<size_t>(std::min(Rank(name), 3))];
  }
};

SeverityRanks Ranks(const AnalysisRecord& a) {
  SeverityRanks r{a.severity};
  std::stable_sort(r.bands.begin(), r.bands.end(),
                   [](const SeverityRecord& x, const SeverityRecord& y) { return x.min_delta_k > y.min_delta_k; });
  return r;
}

const ReportImageRecord* FindImage(const AnalysisRecord& a, const std::string& file) {
  for (const ReportImageRecord& im : a.images) {
    if (im.file == file) return &im;
  }
  return nullptr;
}

std::string ModeTitle(const std::string& mode) {
  if (mode == "thermal") return "Thermal";
  if (mode == "colour") return "Visible colour";
  if (mode == "ih") return "IH mapping";
  if (mode == "highlight") return "Thermal highlighting";
  return mode;
}

// Width and height from a PNG's IHDR chunk (the analyzer's legends make an image larger
// than its render). Throws core::InputError for a missing file or one that is not a PNG.
std::pair<int, int> PngSize(const fs::path& png) {
  if (!fs::is_regular_file(png)) throw core::InputError(png, "missing: analyze.json lists this image");
  std::ifstream in(png, std::ios::binary);
  unsigned char header[24] = {};
  in.read(reinterpret_cast<char*>(header), sizeof header);
  static constexpr unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (in.gcount() != sizeof header || !std::equal(kSignature, kSignature + 8, header) ||
      std::string(reinterpret_cast<const char*>(header + 12), 4) != "IHDR") {
    throw core::InputError(png, "not a PNG file");
  }
  auto be32 = [&](int at) {
    return static_cast<int>(uint32_t{header[at]} << 24 | uint32_t{header[at + 1]} << 16 |
                            uint32_t{header[at + 2]} << 8 | header[at + 3]);
  };
  const int w = be32(16), h = be32(20);
  if (w <= 0 || h <= 0 || w > 1 << 16 || h > 1 << 16) throw core::InputError(png, "PNG of invalid size");
  return {w, h};
}

Figure MakeFigure(const AnalysisRecord& a, const ReportImageRecord& im) {
  Figure f;
  f.png = a.folder / im.file;
  std::tie(f.width_px, f.height_px) = PngSize(f.png);
  const std::optional<analyze::PaletteChoice> palette = analyze::ParsePalette(a.palette);
  const std::optional<analyze::ViewMode> mode = analyze::ParseViewMode(im.mode);
  if (!palette || !mode) {
    throw core::InputError(a.folder / "analyze.json",
                           "image " + im.file + ": unknown palette '" + a.palette + "' or mode '" + im.mode + "'");
  }
  std::string caption = ModeTitle(im.mode);
  if (*mode != analyze::ViewMode::kColour && !a.legends) {
    ColourKey key;
    key.mode = *mode;
    key.palette = palette->palette;
    key.inverted = palette->inverted;
    key.span = im.span;
    key.band_low_c = a.band.min_c;
    key.band_high_c = a.band.max_c;
    f.key = key;
  }
  if (*mode != analyze::ViewMode::kColour) {
    caption += StringPrintf(", %.1f–%.1f °C", im.span.min_c, im.span.max_c);
    if (*mode == analyze::ViewMode::kHighlight) {
      caption += StringPrintf(" outside %.1f–%.1f °C", a.band.min_c, a.band.max_c);
    }
  }
  f.caption = caption;
  return f;
}

// The four modes of one view (overview or spot close-up), in the analyzer's order.
FigureGrid ViewGrid(const AnalysisRecord& a, const std::vector<const ReportImageRecord*>& images,
                    const std::string& caption) {
  FigureGrid grid;
  grid.columns = 2;
  grid.caption = caption;
  for (const ReportImageRecord* im : images) grid.figures.push_back(MakeFigure(a, *im));
  return grid;
}

// " 3 of them (H5, H7, H8) may be reflections: …" or "" when none is flagged.
std::string ReflectionSummary(const AnalysisRecord& a) {
  std::string ids;
  int n = 0;
  for (const ReportSpot& s : a.spots) {
    if (s.possible_reflection) ids += (n++ ? ", " : "") + s.id;
  }
  if (n == 0) return "";
  return StringPrintf(" %d of them (%s) may be %s: seen nearly head-on on a shiny surface, which reflects the "
                      "thermographer, or mirroring a warmer surface; verify %s from another angle before acting.",
                      n, ids.c_str(), n == 1 ? "a reflection" : "reflections", n == 1 ? "it" : "them");
}

// "38.8 ± 2.1 K" (one decimal, as the severity bands are read); "38.8 K" without σ.
std::string FormatDelta(double delta_k, double sigma_k) {
  return std::isfinite(sigma_k) ? StringPrintf("%.1f ± %.1f K", delta_k, sigma_k) : StringPrintf("%.1f K", delta_k);
}

double Decimals(double sigma) {
  if (!(sigma > 0) || !std::isfinite(sigma)) return 1;
  return std::clamp(1.0 - std::floor(std::log10(sigma)), 0.0, 4.0);
}

Table SpotTable(const AnalysisRecord& a, const SeverityRanks& ranks) {
  Table t;
  t.header = {"Spot", "Kind", "Severity", "Peak", "ΔT", "Area", "Length", "Suggested action"};
  t.numeric = {false, false, false, true, true, true, true, false};
  for (const ReportSpot& s : a.spots) {
    t.rows.push_back({s.id, s.kind, s.severity, FormatCelsius(s.peak_c), FormatDelta(s.delta_k, s.delta_sigma_k),
                      FormatArea(s.area_m2, s.area_sigma_m2), FormatLength(s.length_m, s.length_sigma_m), s.action});
    t.tint_srgb8.push_back(ranks.Tint(s.severity));
    t.row_links.push_back(Anchor("spot-", s.id));
  }
  t.caption = "ΔT: peak against the " + a.reference +
              " reference. Area and length measured on the 3D model along the boundary isotherm, "
              "with one standard deviation.";
  return t;
}

Table SummaryTable(const AnalysisRecord& a, const SeverityRanks& ranks) {
  Table t;
  t.header = {"Severity", "From ΔT", "Hot", "Cold", "Action"};
  t.numeric = {false, true, true, true, false};
  int total_hot = 0, total_cold = 0;
  for (const SeverityRecord& b : ranks.bands) {
    int hot = 0, cold = 0;
    for (const ReportSpot& s : a.spots) {
      if (s.severity != b.name) continue;
      (s.kind == "hot" ? hot : cold)++;
    }
    total_hot += hot;
    total_cold += cold;
    t.rows.push_back({Capitalised(b.name), StringPrintf("%g K", b.min_delta_k), std::to_string(hot),
                      std::to_string(cold), b.action});
    t.tint_srgb8.push_back(ranks.Tint(b.name));
  }
  t.rows.push_back({"Total", "", std::to_string(total_hot), std::to_string(total_cold), ""});
  t.tint_srgb8.push_back(std::nullopt);
  return t;
}

Section InspectionSection(const Job& job, const core::Rig* rig) {
  Section s{1, "inspection", "Inspection", {}, false};
  KeyValues who;
  who.rows = {{"Client", Join({job.client.name, job.client.address}, "\n")},
              {"Client contact", Or(job.client.contact)},
              {"Site", Join({job.site.name, job.site.address}, "\n")},
              {"Site contact", Or(job.site.contact)},
              {"Inspection date", job.inspection_date},
              {"Inspector", Join({job.inspector.name, job.inspector.qualification}, ", ")},
              {"Inspector certificate", Or(job.inspector.certificate)},
              {"Company", Or(job.inspector.company)},
              {"Standards followed", Or(Join(job.standards, "; "))}};
  s.blocks.push_back(who);
  if (!job.assets.empty()) {
    Table assets;
    assets.header = {"Asset", "Name", "Location", "Description"};
    assets.numeric = {false, false, false, false};
    for (const JobAsset& x : job.assets) assets.rows.push_back({x.id, Or(x.name), Or(x.location), Or(x.description)});
    assets.caption = "Assets inspected.";
    s.blocks.push_back(assets);
  }
  const JobConditions& c = job.conditions;
  auto num = [](double v, const std::string& formatted) { return std::isnan(v) ? std::string(kDash) : formatted; };
  const double emissivity = !std::isnan(c.emissivity) ? c.emissivity
                            : (rig && rig->thermal_settings) ? rig->thermal_settings->emissivity
                                                             : std::nan("");
  const double reflected = !std::isnan(c.reflected_c) ? c.reflected_c
                           : (rig && rig->thermal_settings) ? rig->thermal_settings->reflected_c
                                                            : std::nan("");
  KeyValues conditions;
  conditions.rows = {
      {"Ambient air temperature", num(c.ambient_c, StringPrintf("%.1f °C", c.ambient_c))},
      {"Reflected apparent temperature",
       num(reflected, StringPrintf("%.1f °C", reflected)) + (std::isnan(c.reflected_c) && !std::isnan(reflected) ? " (rig default)" : "")},
      {"Emissivity", num(emissivity, StringPrintf("%.2f", emissivity)) + (std::isnan(c.emissivity) && !std::isnan(emissivity) ? " (rig default)" : "")},
      {"Load", Or(Join({std::isnan(c.load_percent) ? "" : StringPrintf("%.0f %% of rated", c.load_percent), c.load},
                       ", "))},
      {"Weather", Or(c.weather)},
      {"Wind", num(c.wind_m_s, StringPrintf("%.1f m/s", c.wind_m_s))},
      {"Relative humidity", num(c.humidity_percent, StringPrintf("%.0f %%", c.humidity_percent))}};
  s.blocks.push_back(Paragraph{"Conditions during the inspection:", Paragraph::Style::kBody});
  s.blocks.push_back(conditions);
  if (!job.notes.empty()) {
    s.blocks.push_back(Paragraph{"Notes from the inspector:", Paragraph::Style::kBody});
    s.blocks.push_back(Paragraph{job.notes, Paragraph::Style::kBody});
  }
  return s;
}

std::string CameraText(const core::CameraModel& c) {
  const std::string model =
      c.type == core::CameraModelType::kPinhole ? "pinhole"
      : c.type == core::CameraModelType::kOpenCV
          ? "OpenCV distortion"
          : StringPrintf("mrcal splined stereographic (order %d, %d × %d knots, %d° across)", c.splined.order,
                         c.splined.nx, c.splined.ny, c.splined.fov_x_deg);
  std::string s = StringPrintf("%d × %d px, %s, fx %.1f, fy %.1f, cx %.1f, cy %.1f px", c.width, c.height, model.c_str(),
                               c.fx, c.fy, c.cx, c.cy);
  if (c.type == core::CameraModelType::kSplined) {
    s += StringPrintf("\n%zu spline control values", c.distortion.size());  // hundreds: not listed
  } else if (!c.distortion.empty()) {
    std::vector<std::string> k;
    for (double d : c.distortion) k.push_back(StringPrintf("%.4g", d));
    s += "\ndistortion " + Join(k, ", ");
  }
  return s;
}

Section EquipmentSection(const Job& job, const core::Rig* rig, const fs::path& rig_path) {
  Section s{1, "equipment", "Equipment and calibration", {}, false};
  KeyValues kv;
  kv.rows = {{"Instrument", Or(job.instrument.model)},
             {"Serial number", Or(job.instrument.serial)},
             {"Last calibration", Or(job.instrument.calibration_date)}};
  if (rig) {
    kv.rows.push_back({"Rig calibration file", rig_path.filename().string()});
    kv.rows.push_back({"Depth camera", CameraText(rig->depth)});
    if (rig->rgb) kv.rows.push_back({"Colour camera", CameraText(*rig->rgb)});
    if (rig->thermal) {
      kv.rows.push_back({"Thermal camera", CameraText(*rig->thermal)});
      const Eigen::Vector3d t_mm = rig->depth_from_thermal.translation * 1000;
      const double angle_deg = Eigen::AngleAxisd(rig->depth_from_thermal.rotation).angle() * 180 / M_PI;
      kv.rows.push_back({"Thermal to depth", StringPrintf("translation (%.1f, %.1f, %.1f) mm, rotation %.2f°", t_mm.x(),
                                                          t_mm.y(), t_mm.z(), angle_deg)});
      kv.rows.push_back({"Thermal stream offset", StringPrintf("%.1f ms to the depth clock", rig->thermal_time_offset_s * 1000)});
    }
    if (rig->thermal_settings) {
      const core::ThermalSettings& t = *rig->thermal_settings;
      kv.rows.push_back({"Spectral band", StringPrintf("%.1f–%.1f µm", t.spectral_band_um[0], t.spectral_band_um[1])});
      kv.rows.push_back({"NETD", StringPrintf("%.0f mK per frame", t.netd_k * 1000)});
    }
  }
  s.blocks.push_back(kv);
  s.blocks.push_back(Paragraph{
      "Calibration residuals and QA verdicts: no calibration certificate was given for this rig; the figures above "
      "are the rig file's. A certificate from the heatwave calibration bench adds intrinsic RMS, extrinsic "
      "residual and stream latency with pass/fail verdicts.",
      Paragraph::Style::kNote});
  return s;
}

Section ScanSection(const AnalysisRecord& a, const std::optional<ReconstructionRecord>& rec) {
  Section s{1, "scan", "Scan and model", {}, false};
  KeyValues kv;
  if (rec) {
    kv.rows.push_back({"Depth frames", StringPrintf("%d; %d fused, %d tracked, %d recovered, %d lost, %d without depth, "
                                                    "%d missing",
                                                    rec->depth_frames, rec->fused, rec->tracked, rec->recovered,
                                                    rec->lost, rec->no_depth, rec->missing)});
    if (rec->has_thermal) {
      std::string thermal = StringPrintf("%d; %d fused", rec->thermal_frames, rec->thermal_fused);
      if (rec->thermal_skipped > 0) {
        thermal += StringPrintf(" (the sharpest of each %g s), %d skipped", rec->thermal_frame_interval_s,
                                rec->thermal_skipped);
      }
      kv.rows.push_back({"Thermal frames", thermal});
      kv.rows.push_back({"Temperature estimate", rec->thermal_method + "; emissivity " + rec->emissivity});
    }
    kv.rows.push_back({"Model resolution", StringPrintf("%.1f mm voxels", rec->voxel_size_m * 1000)});
    if (rec->ate_rmse_m) {
      kv.rows.push_back({"Tracking error (synthetic truth)", StringPrintf("%.1f mm RMS", *rec->ate_rmse_m * 1000)});
    }
    kv.rows.push_back({"Reconstruction time", StringPrintf("%.1f s (%.1f frames/s)", rec->total_s, rec->frames_per_s)});
  }
  kv.rows.push_back({"Model", StringPrintf("%d vertices, %d triangles, %.2f m²", a.vertices, a.faces, a.area_m2)});
  kv.rows.push_back({"Surface with temperature", StringPrintf("%.2f m² (%.0f %%)", a.observed_area_m2,
                                                              a.area_m2 > 0 ? 100 * a.observed_area_m2 / a.area_m2 : 0)});
  kv.rows.push_back({"Temperature range", FormatCelsius(a.min_c) + " to " + FormatCelsius(a.max_c) + ", median " +
                                              FormatCelsius(a.median_c)});
  s.blocks.push_back(kv);
  std::vector<std::string> warnings = a.warnings;
  if (rec) warnings.insert(warnings.begin(), rec->warnings.begin(), rec->warnings.end());
  for (const std::string& w : warnings) s.blocks.push_back(Paragraph{w, Paragraph::Style::kWarning});
  return s;
}

Section OverviewSection(const AnalysisRecord& a) {
  Section s{1, "overview", "Overview", {}, true};
  s.blocks.push_back(Paragraph{
      "The model in the four views: thermal (temperature on the palette), visible colour, IH mapping (hue from "
      "temperature, brightness from the visible texture) and thermal highlighting (visible colour, the palette only "
      "where the temperature is outside the normal band). Hatched grey: surface the thermal camera did not see.",
      Paragraph::Style::kBody});
  std::vector<std::string> views;
  for (const ReportImageRecord& im : a.images) {
    if (im.spot.empty() && std::find(views.begin(), views.end(), im.view) == views.end()) views.push_back(im.view);
  }
  for (const std::string& view : views) {
    std::vector<const ReportImageRecord*> images;
    for (const ReportImageRecord& im : a.images) {
      if (im.spot.empty() && im.view == view) images.push_back(&im);
    }
    s.blocks.push_back(ViewGrid(a, images, "View " + view + "."));
  }
  if (views.empty()) s.blocks.push_back(Paragraph{"The analysis was run without images.", Paragraph::Style::kNote});
  return s;
}

std::vector<Section> SpotSections(const AnalysisRecord& a, const SeverityRanks& ranks) {
  std::vector<Section> out;
  Section head{1, "spots", "Hot and cold spots", {}, true};
  if (a.spots.empty()) {
    head.blocks.push_back(Paragraph{"No hot or cold spot met the detection criteria (section Method).",
                                    Paragraph::Style::kBody});
  } else {
    head.blocks.push_back(SpotTable(a, ranks));
  }
  out.push_back(head);
  for (const ReportSpot& s : a.spots) {
    Section sec{2, Anchor("spot-", s.id), s.id + " — " + s.kind + " spot, " + s.severity, {}, false};
    KeyValues kv;
    kv.rows = {{"Severity", Capitalised(s.severity)},
               {"Suggested action", s.action},
               {"Peak temperature", FormatCelsius(s.peak_c)},
               {"Mean temperature", FormatCelsius(s.mean_c)},
               {"Reference (" + s.reference + ")", FormatCelsius(s.reference_c)},
               {"ΔT", FormatDelta(s.delta_k, s.delta_sigma_k) +
                          (s.delta_blur_bound_k >= 0.05
                               ? StringPrintf(" (the thermal image's blur may read it up to %.1f K low)", s.delta_blur_bound_k)
                               : "")},
               {"Boundary isotherm", FormatCelsius(s.level_c)},
               {"Area", FormatArea(s.area_m2, s.area_sigma_m2)},
               {"Length", FormatLength(s.length_m, s.length_sigma_m)},
               {"Width", FormatLength(s.width_m, s.width_sigma_m)},
               {"Location (model frame)",
                StringPrintf("x %.2f, y %.2f, z %.2f m", s.centroid_m.x(), s.centroid_m.y(), s.centroid_m.z())},
               {"Thermal views", StringPrintf("%.1f on average, confidence %.2f", s.mean_views, s.mean_confidence) +
                                     (std::isnan(s.spread_c) ? "" : StringPrintf(", spread across views %.2f K", s.spread_c))}};
    if (std::isfinite(s.width_px) && std::isfinite(s.footprint_m)) {
      kv.rows.push_back({"Thermal resolution",
                         StringPrintf("%.1f thermal pixels across (one pixel covers %.1f mm of the surface)", s.width_px,
                                      1000 * s.footprint_m) +
                             (s.resolved ? "" : "; under-resolved: the peak and ΔT read low and the size high")});
    }
    if (std::isfinite(s.reflection_fraction)) {
      std::string check = StringPrintf("seen %.0f° from head-on; ", s.incidence_deg);
      if (s.reflection_source == "operator") {
        check += StringPrintf("over %.0f %% of the spot the mirror direction returns to the thermographer",
                              100 * s.reflection_fraction);
      } else if (s.reflection_source == "surface") {
        check += StringPrintf("over %.0f %% of the spot the mirror direction meets a %s surface",
                              100 * s.reflection_fraction, FormatCelsius(s.reflection_source_c).c_str());
      } else {
        check += "the mirror direction meets nothing as warm as the spot";
      }
      check += s.possible_reflection ? ": possibly a reflection — re-image from another angle before acting"
                                     : ": not flagged as a reflection";
      kv.rows.push_back({"Reflection check", check});
    }
    sec.blocks.push_back(kv);
    std::vector<const ReportImageRecord*> images;
    for (const std::string& file : s.images) {
      const ReportImageRecord* im = FindImage(a, file);
      if (!im) throw core::InputError(a.folder / "analyze.json", "spot " + s.id + ": image " + file + " is not in images");
      images.push_back(im);
    }
    if (!images.empty()) sec.blocks.push_back(ViewGrid(a, images, "Close-up of " + s.id + "."));
    out.push_back(sec);
  }
  return out;
}

Section MethodSection(const AnalysisRecord& a, const SeverityRanks& ranks) {
  Section s{1, "method", "Method", {}, true};
  s.blocks.push_back(Paragraph{
      "The rig (depth, colour and thermal-infrared cameras, rigidly mounted) was moved around the assets. Its path was "
      "tracked by ICP on the depth stream and the depth fused into a 3D model (KinectFusion-style TSDF). Every thermal "
      "frame was converted to surface temperature with the emissivity and reflected temperature given, and laid onto the "
      "model weighted by the confidence of each ray (camera motion, lens distortion, viewing angle, distance, camera "
      "condition), so that each surface region keeps its best observations.",
      Paragraph::Style::kBody});
  std::string detect =
      a.detect == "delta"
          ? StringPrintf("A spot is a connected region at least %g K warmer (hot) or colder (cold) than its %s reference",
                         a.min_delta_k, a.reference.c_str())
          : StringPrintf("A spot is a connected region above %.1f °C (hot) or below %.1f °C (cold)", a.hot_above_c,
                         a.cold_below_c);
  detect += StringPrintf(
      ", between %g and %g m², bounded by the isotherm at %.0f %% of the way from the reference to the peak. Its area "
      "and length are measured on the model's surface; their uncertainties propagate the temperature noise at the "
      "boundary. %d candidates were examined; %zu were rejected.",
      a.min_area_m2, a.max_area_m2, a.boundary_fraction * 100, a.candidates, a.rejected.size());
  if (std::any_of(a.spots.begin(), a.spots.end(), [](const ReportSpot& x) { return std::isfinite(x.reflection_fraction); })) {
    detect += " Each spot was checked for reflections: the direction it was viewed from, mirrored about the surface, "
              "was traced through the model; a spot whose mirror directions mostly return to the thermographer (and "
              "that is no warmer than a person) or meet a surface at least as warm is marked as a possible reflection.";
  }
  s.blocks.push_back(Paragraph{detect, Paragraph::Style::kBody});
  Table sev;
  sev.header = {"Severity", "From ΔT", "Action"};
  sev.numeric = {false, true, false};
  for (const SeverityRecord& b : ranks.bands) {
    sev.rows.push_back({Capitalised(b.name), StringPrintf("%g K", b.min_delta_k), b.action});
    sev.tint_srgb8.push_back(ranks.Tint(b.name));
  }
  sev.caption = "Severity table used.";
  s.blocks.push_back(sev);
  if (!a.rejected.empty()) {
    Table rej;
    rej.header = {"Candidate", "Why it is not reported"};
    rej.numeric = {false, false};
    for (const auto& [what, reason] : a.rejected) rej.rows.push_back({what, reason});
    rej.caption = "Candidates not reported.";
    s.blocks.push_back(rej);
  }
  return s;
}

Section DisclaimerSection() {
  Section s{1, "disclaimer", "Limitations and disclaimer", {}, false};
  s.blocks.push_back(Paragraph{
      "Infrared thermography measures surface temperature only, under the conditions of the inspection: load, ambient "
      "and reflected temperatures, emissivity and weather change the readings. Shiny metal (low emissivity) reflects "
      "its surroundings and reads wrong unless its emissivity was given. Surfaces the thermal camera did not see are "
      "not assessed. Severity follows the table in section Method; the suggested actions are guidance and do not "
      "replace the judgement of a qualified person on site.",
      Paragraph::Style::kBody});
  return s;
}

}  // namespace

std::string FormatWithSigma(double value, double sigma, double scale, const std::string& unit) {
  const int decimals = static_cast<int>(Decimals(sigma * scale));
  if (!std::isfinite(sigma)) return StringPrintf("%.*f %s", decimals, value * scale, unit.c_str());
  return StringPrintf("%.*f ± %.*f %s", decimals, value * scale, decimals, sigma * scale, unit.c_str());
}

std::string FormatCelsius(double value_c) { return std::isnan(value_c) ? kDash : StringPrintf("%.1f °C", value_c); }

std::string FormatArea(double area_m2, double sigma_m2) {
  return area_m2 < 0.1 ? FormatWithSigma(area_m2, sigma_m2, 1e4, "cm²") : FormatWithSigma(area_m2, sigma_m2, 1, "m²");
}

std::string FormatLength(double length_m, double sigma_m) {
  return length_m < 1 ? FormatWithSigma(length_m, sigma_m, 100, "cm") : FormatWithSigma(length_m, sigma_m, 1, "m");
}

Document BuildDocument(const ReportInputs& in) {
  const AnalysisRecord a = ReadAnalysisRecord(in.analyze_json);
  std::optional<ReconstructionRecord> rec;
  if (!in.reconstruct_json.empty()) rec = ReadReconstructionRecord(in.reconstruct_json);
  // The rig: the one given, else the one the reconstruction used when it is still there.
  fs::path rig_path = in.rig_yaml;
  if (rig_path.empty() && rec && !rec->rig.empty() && fs::is_regular_file(rec->rig)) rig_path = rec->rig;
  std::optional<core::Rig> rig;
  if (!rig_path.empty()) rig = core::ReadRig(rig_path);
  const Job& job = in.job;
  const SeverityRanks ranks = Ranks(a);

  Document doc;
  doc.cover.title = job.title;
  doc.cover.subtitle = job.site.name + " — " + job.client.name;
  std::vector<std::string> asset_ids;
  for (const JobAsset& x : job.assets) asset_ids.push_back(x.id);
  doc.cover.facts.rows = {{"Client", job.client.name},
                          {"Site", job.site.name},
                          {"Assets", Or(Join(asset_ids, ", "))},
                          {"Inspection date", job.inspection_date},
                          {"Report reference", Or(job.reference)},
                          {"Inspector", Join({job.inspector.name, job.inspector.qualification}, ", ")},
                          {"Standards", Or(Join(job.standards, "; "))},
                          {"Issued", job.issued_utc.substr(0, 10) + " " + job.issued_utc.substr(11, 5) + " UTC"}};
  for (const ReportImageRecord& im : a.images) {
    if (im.spot.empty() && im.mode == "thermal") {
      doc.cover.hero = MakeFigure(a, im);
      break;
    }
  }
  doc.cover.summary = SummaryTable(a, ranks);
  doc.cover.summary.caption = StringPrintf("%zu spot%s found on %.2f m² of surface with temperature.", a.spots.size(),
                                           a.spots.size() == 1 ? "" : "s", a.observed_area_m2);

  Section summary{1, "summary", "Summary", {}, false};
  int hot = 0;
  for (const ReportSpot& s : a.spots) hot += s.kind == "hot";
  summary.blocks.push_back(Paragraph{
      StringPrintf("%d hot and %d cold spot%s found on %.2f m² of surface with temperature (%.2f m² scanned), ",
                   hot, static_cast<int>(a.spots.size()) - hot, a.spots.size() - static_cast<size_t>(hot) == 1 ? "" : "s",
                   a.observed_area_m2, a.area_m2) +
          StringPrintf("surface temperatures %.1f to %.1f °C.", a.min_c, a.max_c) + ReflectionSummary(a),
      Paragraph::Style::kBody});
  if (!a.spots.empty()) summary.blocks.push_back(SpotTable(a, ranks));
  doc.sections.push_back(summary);
  doc.sections.push_back(InspectionSection(job, rig ? &*rig : nullptr));
  doc.sections.push_back(EquipmentSection(job, rig ? &*rig : nullptr, rig_path));
  doc.sections.push_back(ScanSection(a, rec));
  doc.sections.push_back(OverviewSection(a));
  for (Section& s : SpotSections(a, ranks)) doc.sections.push_back(std::move(s));
  doc.sections.push_back(MethodSection(a, ranks));
  doc.sections.push_back(DisclaimerSection());

  doc.author = job.inspector.name;
  doc.subject = job.client.name + " — " + job.site.name;
  doc.keywords = Join({"thermography", Join(job.standards, ", ")}, ", ");
  doc.creator = in.creator;
  doc.created_utc = job.issued_utc;
  doc.footer = Join({job.reference.empty() ? "" : "Report " + job.reference, job.client.name, job.site.name}, " · ");

  if (!in.model_ply.empty()) {
    ModelView view;
    view.model_ply = in.model_ply;
    const std::optional<analyze::PaletteChoice> palette = analyze::ParsePalette(a.palette);
    view.palette = palette ? palette->palette : analyze::Palette::kIron;
    view.inverted = palette && palette->inverted;
    view.span = a.span;
    view.band_low_c = a.band.min_c;
    view.band_high_c = a.band.max_c;
    for (const ReportSpot& s : a.spots) {
      view.markers.push_back({s.id, Anchor("spot-", s.id), s.kind == "hot", s.peak_m,
                              s.normal.norm() > 0 ? s.normal.normalized() : Eigen::Vector3d::UnitZ()});
    }
    doc.model_view = view;
  }
  return doc;
}

}  // namespace hw::report
