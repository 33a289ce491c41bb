#pragma once

// sRGB transfer functions (IEC 61966-2-1). Colours are blended, shaded and anti-aliased in
// linear light and encoded to sRGB only when written to an 8-bit image, so that averaging
// pixels does not darken edges.

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace hw::analyze {

// sRGB-encoded value in [0, 1] → linear light in [0, 1].
inline float SrgbToLinear(float encoded) {
  const float c = std::clamp(encoded, 0.0f, 1.0f);
  return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

// Linear light in [0, 1] (clamped) → sRGB-encoded value in [0, 1].
inline float LinearToSrgb(float linear) {
  const float c = std::clamp(linear, 0.0f, 1.0f);
  return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

// Linear light → 8-bit sRGB, rounded.
inline std::uint8_t LinearToSrgb8(float linear) {
  return static_cast<std::uint8_t>(std::lround(255.0f * LinearToSrgb(linear)));
}

}  // namespace hw::analyze
