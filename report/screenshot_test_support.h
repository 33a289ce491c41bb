#pragma once

// Test support for the report's browser tests: how much a screenshot varies (a blank or
// flat-coloured page varies not at all; a rendered model a lot).

#include <png.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <vector>

namespace hw::report::test {

// Variance of the grey level (0–255) over the pixels [x0, x1) × [y0, y1) of an 8-bit PNG
// (clipped to the image); -1 when the file cannot be read or the rectangle is empty.
inline double GreyVariance(const std::filesystem::path& png_path, int x0, int y0, int x1, int y1) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, png_path.c_str())) return -1;
  image.format = PNG_FORMAT_GRAY;
  std::vector<uint8_t> pixels(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, pixels.data(), 0, nullptr)) return -1;
  double sum = 0, sum2 = 0;
  int count = 0;
  for (int y = std::max(y0, 0); y < std::min<int>(y1, static_cast<int>(image.height)); ++y) {
    for (int x = std::max(x0, 0); x < std::min<int>(x1, static_cast<int>(image.width)); ++x) {
      const double g = pixels[static_cast<size_t>(y) * image.width + static_cast<size_t>(x)];
      sum += g;
      sum2 += g * g;
      ++count;
    }
  }
  if (count == 0) return -1;
  const double mean = sum / count;
  return sum2 / count - mean * mean;
}

}  // namespace hw::report::test
