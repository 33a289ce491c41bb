#include "analyze/views.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <sstream>

#include "analyze/srgb.h"
#include "core/option_check.h"

namespace hw::analyze {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Linear grey standing in for the visible colour of a mesh without colour (sRGB ≈ 188).
constexpr float kNoColourGreyLinear = 0.5f;


Eigen::Vector3f ColourAtSample(const ThermalMesh& mesh, const SampleBuffer& samples, size_t i) {
  if (!mesh.HasColour()) return Eigen::Vector3f::Constant(kNoColourGreyLinear);
  const Eigen::Vector3i& tri = mesh.faces[static_cast<size_t>(samples.face[i])];
  const float u = samples.bary_u[i];
  const float v = samples.bary_v[i];
  return (1 - u - v) * mesh.colour_linear[static_cast<size_t>(tri[0])] +
         u * mesh.colour_linear[static_cast<size_t>(tri[1])] +
         v * mesh.colour_linear[static_cast<size_t>(tri[2])];
}

float Luminance(const Eigen::Vector3f& linear) {
  return 0.2126f * linear[0] + 0.7152f * linear[1] + 0.0722f * linear[2];
}

Eigen::Vector3f DecodeSrgb(const Eigen::Vector3f& encoded) {
  return {SrgbToLinear(encoded[0]), SrgbToLinear(encoded[1]), SrgbToLinear(encoded[2])};
}

// The palette tabulated once per image (PaletteColour costs three pow() a call): 1024
// intervals, linear interpolation in linear light; differs from PaletteColour by < 1e-3
// (under half an 8-bit level after encoding, except where rounding falls on a boundary).
class PaletteTable {
 public:
  PaletteTable(Palette palette, bool inverted) {
    for (int i = 0; i <= kIntervals; ++i) {
      table_[static_cast<size_t>(i)] = PaletteColour(palette, inverted, static_cast<double>(i) / kIntervals);
    }
  }
  Eigen::Vector3f operator()(double t01) const {
    const double position = std::clamp(t01, 0.0, 1.0) * kIntervals;
    const int i = std::min(static_cast<int>(position), kIntervals - 1);
    const auto w = static_cast<float>(position - i);
    return (1 - w) * table_[static_cast<size_t>(i)] + w * table_[static_cast<size_t>(i) + 1];
  }

 private:
  static constexpr int kIntervals = 1024;
  std::array<Eigen::Vector3f, kIntervals + 1> table_;
};

bool ShowsTemperature(ViewMode mode) { return mode != ViewMode::kColour; }

void CheckBuffer(const ThermalMesh& mesh, const SampleBuffer& samples) {
  const size_t n = static_cast<size_t>(samples.width) * static_cast<size_t>(samples.height) *
                   static_cast<size_t>(samples.samples_per_pixel);
  assert(samples.width > 0 && samples.height > 0 && samples.samples_per_pixel > 0);
  assert(samples.face.size() == n && samples.bary_u.size() == n && samples.bary_v.size() == n &&
         samples.cos_incidence.size() == n);
  for ([[maybe_unused]] int f : samples.face) assert(f < mesh.NumFaces());
  (void)mesh;
  (void)n;
}

}  // namespace

std::optional<ViewMode> ParseViewMode(std::string_view name) {
  if (name == "thermal") return ViewMode::kThermal;
  if (name == "colour" || name == "color") return ViewMode::kColour;
  if (name == "ih" || name == "ih-mapping") return ViewMode::kIhMapping;
  if (name == "highlight") return ViewMode::kHighlight;
  return std::nullopt;
}

std::string ViewModeName(ViewMode mode) {
  switch (mode) {
    case ViewMode::kThermal: return "thermal";
    case ViewMode::kColour: return "colour";
    case ViewMode::kIhMapping: return "ih";
    case ViewMode::kHighlight: return "highlight";
  }
  return "";
}

std::string ViewStyle::Check() const {
  using core::InRange;
  using core::OptionFail;
  if (!std::isfinite(span.min_c)) return OptionFail("span.min_c", span.min_c, "finite");
  if (!std::isfinite(span.max_c)) return OptionFail("span.max_c", span.max_c, "finite");
  if (!(span.max_c > span.min_c)) {
    std::ostringstream constraint;
    constraint.precision(17);
    constraint << "> span.min_c (" << span.min_c << ")";
    return OptionFail("span.max_c", span.max_c, constraint.str());
  }
  if (mode == ViewMode::kHighlight) {
    if (!std::isfinite(band_low_c)) return OptionFail("band_low_c", band_low_c, "finite");
    if (!std::isfinite(band_high_c)) return OptionFail("band_high_c", band_high_c, "finite");
    if (!(band_high_c > band_low_c)) {
      std::ostringstream constraint;
      constraint.precision(17);
      constraint << "> band_low_c (" << band_low_c << ")";
      return OptionFail("band_high_c", band_high_c, constraint.str());
    }
  }
  if (!InRange(ambient, 0, 1)) return OptionFail("ambient", ambient, "in [0, 1]");
  if (!InRange(diffuse, 0, 1)) return OptionFail("diffuse", diffuse, "in [0, 1]");
  if (!(ambient + diffuse > 0) || ambient + diffuse > 1) {
    return OptionFail("ambient + diffuse", ambient + diffuse, "in (0, 1]");
  }
  if (!InRange(hatch_period_px, 3, 64)) {
    return OptionFail("hatch_period_px", hatch_period_px, "in [3, 64]");
  }
  return "";
}

float UnobservedHatchGrey(int x, int y, int period_px) {
  // Lines along x + y = k · period through pixel centres; the distance from a pixel centre
  // to the nearest line, perpendicular to it, sets a box-filtered coverage of a 1.5 px line.
  const double period = period_px;
  const double along = std::fmod(static_cast<double>(x) + y + 1, period);
  const double distance_px = std::min(along, period - along) / std::sqrt(2.0);
  const double coverage = std::clamp(0.75 + 0.5 - distance_px, 0.0, 1.0);
  const double base = SrgbToLinear(0.62f);
  const double line = SrgbToLinear(0.40f);
  return static_cast<float>((1 - coverage) * base + coverage * line);
}

ImageRgb8 ComposeView(const ThermalMesh& mesh, const SampleBuffer& samples,
                      const std::vector<double>& field_c, const ViewStyle& style) {
  assert(style.Check().empty());
  CheckBuffer(mesh, samples);
  const bool shows_temperature = ShowsTemperature(style.mode);
  assert(!shows_temperature || field_c.size() == static_cast<size_t>(mesh.NumVertices()));
  const Eigen::Vector3f background =
      DecodeSrgb(Eigen::Vector3f(style.background_srgb8[0], style.background_srgb8[1],
                                 style.background_srgb8[2]) /
                 255.0f);
  const PaletteTable palette(style.palette, style.inverted);
  const auto ambient = static_cast<float>(style.ambient);
  const auto diffuse = static_cast<float>(style.diffuse);

  ImageRgb8 image;
  image.width = samples.width;
  image.height = samples.height;
  image.rgb.resize(static_cast<size_t>(image.width) * static_cast<size_t>(image.height) * 3);
  const int spp = samples.samples_per_pixel;
  for (int y = 0; y < samples.height; ++y) {
    for (int x = 0; x < samples.width; ++x) {
      Eigen::Vector3f sum = Eigen::Vector3f::Zero();
      for (int s = 0; s < spp; ++s) {
        const size_t i = samples.Index(x, y, s);
        if (samples.face[i] < 0) {
          sum += background;
          continue;
        }
        const float shading = ambient + diffuse * std::clamp(samples.cos_incidence[i], 0.0f, 1.0f);
        const double t_c = shows_temperature ? static_cast<double>(InterpolateAtSample(mesh, field_c, samples, i)) : kNaN;
        if (shows_temperature && std::isnan(t_c)) {
          sum += Eigen::Vector3f::Constant(UnobservedHatchGrey(x, y, style.hatch_period_px) * shading);
          continue;
        }
        Eigen::Vector3f colour = Eigen::Vector3f::Zero();
        switch (style.mode) {
          case ViewMode::kThermal:
            colour = palette(style.span.Normalize(t_c));
            break;
          case ViewMode::kColour:
            colour = ColourAtSample(mesh, samples, i);
            break;
          case ViewMode::kIhMapping: {
            const auto t01 = static_cast<float>(style.span.Normalize(t_c));
            const float intensity = Luminance(ColourAtSample(mesh, samples, i)) * shading;
            colour = IhColour(t01, intensity);
            sum += colour;  // intensity already carries the shading
            continue;
          }
          case ViewMode::kHighlight:
            colour = (t_c < style.band_low_c || t_c > style.band_high_c)
                         ? palette(style.span.Normalize(t_c))
                         : ColourAtSample(mesh, samples, i);
            break;
        }
        sum += colour * shading;
      }
      const Eigen::Vector3f mean = sum / static_cast<float>(spp);
      std::uint8_t* out = image.rgb.data() + (static_cast<size_t>(y) * static_cast<size_t>(image.width) + static_cast<size_t>(x)) * 3;
      for (int c = 0; c < 3; ++c) out[c] = LinearToSrgb8(mean[c]);
    }
  }
  return image;
}

std::vector<float> TemperatureImage(const ThermalMesh& mesh, const SampleBuffer& samples,
                                    const std::vector<double>& field_c) {
  CheckBuffer(mesh, samples);
  assert(field_c.size() == static_cast<size_t>(mesh.NumVertices()));
  std::vector<float> image(static_cast<size_t>(samples.width) * static_cast<size_t>(samples.height),
                           std::numeric_limits<float>::quiet_NaN());
  for (int y = 0; y < samples.height; ++y) {
    for (int x = 0; x < samples.width; ++x) {
      double sum = 0;
      int count = 0;
      for (int s = 0; s < samples.samples_per_pixel; ++s) {
        const double value = InterpolateAtSample(mesh, field_c, samples, samples.Index(x, y, s));
        if (std::isnan(value)) continue;
        sum += value;
        ++count;
      }
      if (count > 0) {
        image[static_cast<size_t>(y) * static_cast<size_t>(samples.width) + static_cast<size_t>(x)] =
            static_cast<float>(sum / count);
      }
    }
  }
  return image;
}

}  // namespace hw::analyze
