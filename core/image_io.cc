#include "core/image_io.h"

#include <png.h>

#include <bit>
#include <csetjmp>
#include <cstring>
#include <memory>
#include <vector>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "core/atomic_file.h"
#include "core/error.h"

namespace hw::core {

namespace fs = std::filesystem;

namespace {

// Largest decoded image DecodeImage produces when the caller's check lets anything through
// (bytes): a guard against a header claiming gigapixels, far above any camera frame.
constexpr double kMaxDecodedBytes = 1024.0 * 1024.0 * 1024.0;

bool StartsWith(std::string_view bytes, std::string_view prefix) {
  return bytes.substr(0, prefix.size()) == prefix;
}

void CheckDecodedSize(const ImageHeader& header, const fs::path& path) {
  if (header.width <= 0 || header.height <= 0 || header.channels <= 0) {
    throw InputError(path, "image header has no pixels (" + std::to_string(header.width) + "x" +
                               std::to_string(header.height) + ")");
  }
  const double bytes = static_cast<double>(header.width) * header.height * header.channels *
                       static_cast<double>(CV_ELEM_SIZE1(header.depth));
  if (bytes > kMaxDecodedBytes) {
    throw InputError(path, header.format + " header claims " + std::to_string(header.width) +
                               "x" + std::to_string(header.height) +
                               " pixels, more than 1 GiB decoded; not decoded");
  }
}

// --- PNG through libpng, with our handlers -------------------------------------------------

// libpng reports errors by calling the error handler, which must not return: it longjmps
// back to the setjmp of the phase that is running. Each phase function below holds only
// trivially destructible locals, so the jump skips no destructor.
struct PngContext {
  std::string_view bytes;
  size_t position = 0;
  std::string error;  // the decoder's reason
  std::jmp_buf jump;
};

void PngErrorHandler(png_structp png, png_const_charp message) {
  auto* context = static_cast<PngContext*>(png_get_error_ptr(png));
  context->error = message ? message : "unknown libpng error";
  std::longjmp(context->jump, 1);
}

// Warnings (e.g. "iCCP: known incorrect sRGB profile") do not affect the pixels: dropped,
// rather than printed on stderr as libpng's default handler does.
void PngWarningHandler(png_structp, png_const_charp) {}

void PngReadFromMemory(png_structp png, png_bytep out, size_t count) {
  auto* context = static_cast<PngContext*>(png_get_io_ptr(png));
  if (count > context->bytes.size() - context->position) {
    png_error(png, "file is truncated");
  }
  std::memcpy(out, context->bytes.data() + context->position, count);
  context->position += count;
}

struct PngStructs {
  png_structp png = nullptr;
  png_infop info = nullptr;
  ~PngStructs() {
    if (png) png_destroy_read_struct(&png, info ? &info : nullptr, nullptr);
  }
};

// Phase 1: signature, header, transforms. Returns false on error (context.error set).
bool PngReadHeader(PngStructs& s, PngContext& context, ImageHeader& header) {
  if (setjmp(context.jump)) return false;
  png_set_read_fn(s.png, &context, PngReadFromMemory);
  png_read_info(s.png, s.info);
  const int color_type = png_get_color_type(s.png, s.info);
  const int bit_depth = png_get_bit_depth(s.png, s.info);
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(s.png);
  if (color_type == PNG_COLOR_TYPE_GRAY && bit_depth < 8) png_set_expand_gray_1_2_4_to_8(s.png);
  if (png_get_valid(s.png, s.info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(s.png);
  // PNG stores 16-bit samples big-endian.
  if (bit_depth == 16 && std::endian::native == std::endian::little) png_set_swap(s.png);
  png_set_interlace_handling(s.png);
  png_read_update_info(s.png, s.info);
  header.format = "PNG";
  header.width = static_cast<int>(png_get_image_width(s.png, s.info));
  header.height = static_cast<int>(png_get_image_height(s.png, s.info));
  header.channels = png_get_channels(s.png, s.info);
  header.depth = png_get_bit_depth(s.png, s.info) == 16 ? CV_16U : CV_8U;
  return true;
}

// Phase 2: the pixels, then the chunks after them up to IEND (a cut file fails here).
bool PngReadPixels(PngStructs& s, PngContext& context, png_bytepp rows) {
  if (setjmp(context.jump)) return false;
  png_read_image(s.png, rows);
  png_read_end(s.png, nullptr);
  return true;
}

cv::Mat DecodePng(std::string_view bytes, const fs::path& path, const ImageHeaderCheck& check,
                  ImageHeader* header_only) {
  PngContext context;
  context.bytes = bytes;
  PngStructs s;
  s.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &context, PngErrorHandler,
                                 PngWarningHandler);
  if (!s.png) throw std::bad_alloc();
  s.info = png_create_info_struct(s.png);
  if (!s.info) throw std::bad_alloc();
  ImageHeader header;
  if (!PngReadHeader(s, context, header)) {
    throw InputError(path, "cannot decode PNG header: " + context.error);
  }
  if (header_only) {
    *header_only = header;
    return {};
  }
  if (check) check(header);
  CheckDecodedSize(header, path);
  cv::Mat image(header.height, header.width, header.type());
  std::vector<png_bytep> rows(static_cast<size_t>(header.height));
  for (int y = 0; y < header.height; ++y) rows[static_cast<size_t>(y)] = image.ptr(y);
  if (!PngReadPixels(s, context, rows.data())) {
    throw InputError(path, "cannot decode PNG: " + context.error);
  }
  return image;
}

// --- JPEG and TIFF through OpenImageIO -------------------------------------------------------

std::string OiioError(OIIO::ImageInput* input) {
  std::string message = input ? input->geterror() : std::string();
  const std::string global = OIIO::geterror();  // always drained: OIIO prints pending errors at exit
  if (message.empty()) message = global;
  return message.empty() ? "unknown decoder error" : message;
}

cv::Mat DecodeWithOiio(std::string_view bytes, const std::string& format, const fs::path& path,
                       const ImageHeaderCheck& check, ImageHeader* header_only) {
  const std::string extension = format == "TIFF" ? "tiff" : "jpg";
  OIIO::Filesystem::IOMemReader memory(bytes.data(), bytes.size());
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);  // pixels as stored, not premultiplied
  std::unique_ptr<OIIO::ImageInput> input = OIIO::ImageInput::create(extension, false, &config);
  if (!input) throw InputError(path, "no " + format + " decoder: " + OiioError(nullptr));
  if (!input->set_ioproxy(&memory)) {
    throw InputError(path, "cannot decode " + format + ": " + OiioError(input.get()));
  }
  OIIO::ImageSpec spec;
  if (!input->open("frame." + extension, spec, config)) {
    throw InputError(path, "cannot decode " + format + " header: " + OiioError(input.get()));
  }
  ImageHeader header;
  header.format = format;
  header.width = spec.width;
  header.height = spec.height;
  header.channels = spec.nchannels;
  OIIO::TypeDesc read_type;
  switch (spec.format.basetype) {
    case OIIO::TypeDesc::UINT8:
      header.depth = CV_8U;
      read_type = OIIO::TypeDesc::UINT8;
      break;
    case OIIO::TypeDesc::UINT16:
      header.depth = CV_16U;
      read_type = OIIO::TypeDesc::UINT16;
      break;
    case OIIO::TypeDesc::HALF:
    case OIIO::TypeDesc::FLOAT:
    case OIIO::TypeDesc::DOUBLE:
      header.depth = CV_32F;
      read_type = OIIO::TypeDesc::FLOAT;
      break;
    default:
      input->close();
      throw InputError(path, format + " samples of type " + std::string(spec.format.c_str()) +
                                 " are not supported (8/16-bit unsigned or float)");
  }
  if (header_only) {
    *header_only = header;
    input->close();
    OiioError(input.get());
    return {};
  }
  if (header.channels < 1 || header.channels > 4) {
    input->close();
    throw InputError(path, format + " image has " + std::to_string(header.channels) +
                               " channels, expected 1 to 4");
  }
  if (check) check(header);
  CheckDecodedSize(header, path);
  cv::Mat image(header.height, header.width, header.type());
  if (!input->read_image(0, 0, 0, header.channels, read_type, image.data)) {
    throw InputError(path, "cannot decode " + format + ": " + OiioError(input.get()));
  }
  input->close();
  OiioError(input.get());
  return image;
}

// The format by content, not by file name.
std::string SniffFormat(std::string_view bytes) {
  if (StartsWith(bytes, "\x89PNG\r\n\x1a\n")) return "PNG";
  if (StartsWith(bytes, "\xFF\xD8\xFF")) return "JPEG";
  if (StartsWith(bytes, std::string_view("II*\0", 4)) ||
      StartsWith(bytes, std::string_view("MM\0*", 4)) ||
      StartsWith(bytes, std::string_view("II+\0", 4)) ||
      StartsWith(bytes, std::string_view("MM\0+", 4))) {
    return "TIFF";
  }
  return "";
}

cv::Mat Decode(std::string_view bytes, const fs::path& path, const ImageHeaderCheck& check,
               ImageHeader* header_only) {
  if (bytes.empty()) throw InputError(path, "empty file, expected an image");
  const std::string format = SniffFormat(bytes);
  if (format.empty()) throw InputError(path, "not a PNG, JPEG or TIFF image");
  if (format == "PNG") return DecodePng(bytes, path, check, header_only);
  return DecodeWithOiio(bytes, format, path, check, header_only);
}

}  // namespace

int ImageHeader::type() const { return CV_MAKETYPE(depth, channels); }

std::string ImageTypeName(int cv_type) {
  static const char* const kDepthNames[] = {"8-bit unsigned", "8-bit signed",   "16-bit unsigned",
                                            "16-bit signed",  "32-bit integer", "32-bit float",
                                            "64-bit float",   "16-bit float"};
  return std::string(kDepthNames[CV_MAT_DEPTH(cv_type) & 7]) + " " +
         std::to_string(CV_MAT_CN(cv_type)) + "-channel";
}

ImageHeader DecodeImageHeader(std::string_view bytes, const fs::path& path_for_errors) {
  ImageHeader header;
  Decode(bytes, path_for_errors, nullptr, &header);
  return header;
}

cv::Mat DecodeImage(std::string_view bytes, const fs::path& path_for_errors,
                    const ImageHeaderCheck& check) {
  return Decode(bytes, path_for_errors, check, nullptr);
}

cv::Mat ReadImage(const fs::path& path, const ImageHeaderCheck& check) {
  return DecodeImage(ReadFile(path, kMaxFrameFileBytes), path, check);
}

std::string EncodeImage(const cv::Mat& image, const std::string& extension,
                        const fs::path& path_for_errors) {
  std::vector<uchar> buffer;
  try {
    if (!cv::imencode(extension, image, buffer)) {
      throw OutputError(path_for_errors, "cannot encode a " + ImageTypeName(image.type()) +
                                             " image as " + extension);
    }
  } catch (const cv::Exception& e) {
    throw OutputError(path_for_errors, "cannot encode image: " + e.msg);
  }
  return std::string(buffer.begin(), buffer.end());
}

void WriteImageAtomically(const fs::path& path, const cv::Mat& image) {
  WriteFileAtomically(path, EncodeImage(image, path.extension().string(), path));
}

}  // namespace hw::core
