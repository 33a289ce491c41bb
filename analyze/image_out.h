#pragma once

// Writing the analyzer's images through OpenImageIO: 8-bit sRGB PNGs for people and float
// images (EXR, TIFF) of the temperature for tools. Both are encoded in memory and written
// with core::WriteFileAtomically: a temporary name in the same folder, renamed into place
// only when every byte is on disk, so a reader never sees a partial image.

#include <filesystem>
#include <string>
#include <vector>

#include "analyze/views.h"

namespace hw::analyze {

// Writes `image` as an 8-bit RGB PNG. Asserts a well-formed image. Throws
// core::OutputError(path, reason) when encoding or writing fails (the reason is
// OpenImageIO's or the file system's); nothing is left at `path` or its temporary then.
void WritePng(const std::filesystem::path& path, const ImageRgb8& image);

// Writes a one-channel 32-bit float image (row-major width · height values; NaN kept:
// unobserved or background) as OpenEXR (".exr", zip-compressed, channel "Y") or TIFF
// (".tif"/".tiff", deflate-compressed, SampleFormat IEEEFP), chosen by the extension
// (any other extension asserts: the caller picks the name). `units` ("°C", "K") goes to the
// metadata: ImageDescription "<units>; NaN = no value (unobserved surface or background)"
// and the attribute "heatwave:units". Throws core::OutputError(path, reason) like WritePng.
void WriteFloatImage(const std::filesystem::path& path, int width, int height,
                     const std::vector<float>& values, const std::string& units);

}  // namespace hw::analyze
