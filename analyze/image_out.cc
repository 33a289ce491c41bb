#include "analyze/image_out.h"

#include <algorithm>
#include <cassert>
#include <cctype>
#include <memory>
#include <string_view>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>

#include "core/atomic_file.h"
#include "core/error.h"

namespace hw::analyze {
namespace {

// OpenImageIO's message for a failed output; the global error is always drained, since
// OpenImageIO prints pending errors at exit.
std::string OiioError(OIIO::ImageOutput* output) {
  std::string message = output ? output->geterror() : std::string();
  const std::string global = OIIO::geterror();
  if (message.empty()) message = global;
  return message.empty() ? "unknown encoder error" : message;
}

// Encodes one image in memory with the OpenImageIO plugin for `format` ("png", "exr",
// "tif") and writes it atomically.
void EncodeAndWrite(const std::filesystem::path& path, const std::string& format,
                    const OIIO::ImageSpec& spec, const void* pixels) {
  std::unique_ptr<OIIO::ImageOutput> output = OIIO::ImageOutput::create(format);
  if (!output) throw core::OutputError(path, "no " + format + " encoder: " + OiioError(nullptr));
  std::vector<unsigned char> bytes;
  OIIO::Filesystem::IOVecOutput memory(bytes);
  // The proxy is given before open(), so the plugin never touches the file system.
  if (!output->set_ioproxy(&memory) || !output->open("image." + format, spec) ||
      !output->write_image(spec.format, pixels) || !output->close()) {
    throw core::OutputError(path, "cannot encode " + format + ": " + OiioError(output.get()));
  }
  OiioError(output.get());
  core::WriteFileAtomically(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace

void WritePng(const std::filesystem::path& path, const ImageRgb8& image) {
  assert(image.width > 0 && image.height > 0 &&
         image.rgb.size() == static_cast<size_t>(image.width) * static_cast<size_t>(image.height) * 3);
  OIIO::ImageSpec spec(image.width, image.height, 3, OIIO::TypeDesc::UINT8);
  spec.attribute("oiio:ColorSpace", "sRGB");
  spec.attribute("png:compressionLevel", 6);
  EncodeAndWrite(path, "png", spec, image.rgb.data());
}

void WriteFloatImage(const std::filesystem::path& path, int width, int height,
                     const std::vector<float>& values, const std::string& units) {
  assert(width > 0 && height > 0 &&
         values.size() == static_cast<size_t>(width) * static_cast<size_t>(height));
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  const bool exr = extension == ".exr";
  assert(exr || extension == ".tif" || extension == ".tiff");
  OIIO::ImageSpec spec(width, height, 1, OIIO::TypeDesc::FLOAT);
  spec.channelnames = {"Y"};
  spec.attribute("ImageDescription",
                 units + "; NaN = no value (unobserved surface or background)");
  spec.attribute("heatwave:units", units);
  spec.attribute("compression", "zip");  // EXR zip; TIFF deflate (OpenImageIO names it zip)
  EncodeAndWrite(path, exr ? "exr" : "tif", spec, values.data());
}

}  // namespace hw::analyze
