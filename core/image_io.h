#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <string_view>

#include <opencv2/core/mat.hpp>

namespace hw::core {

// Reading and writing the image files of scans (PNG, JPEG, TIFF) through one checked path.
//
// Reading: the file is read by ReadFile (regular files only, size cap), its header is
// decoded first and shown to the caller's check, and only an image the caller accepts is
// decompressed — a small file that claims 30000x30000 pixels costs a header read, not
// gigabytes. Decoder messages never reach stderr: PNG is decoded with libpng directly with
// our own error/warning handlers (OpenCV and OpenImageIO let libpng print its own lines),
// JPEG and TIFF with OpenImageIO, which returns its messages as strings. Every failure is an
// InputError naming the file and the decoder's reason.
//
// Writing: EncodeImage encodes in memory (cv::imencode) and WriteImageAtomically writes the
// bytes through WriteFileAtomically, so a full disk is detected byte-exactly and no short
// image is ever renamed into place.

// What an encoded image holds, from its header.
struct ImageHeader {
  std::string format;  // "PNG" | "JPEG" | "TIFF"
  int width = 0;       // pixels
  int height = 0;      // pixels
  int channels = 0;    // after expanding palettes and sub-byte grey to 8-bit
  int depth = 0;       // OpenCV depth of the decoded samples: CV_8U, CV_16U or CV_32F
  int type() const;    // CV_MAKETYPE(depth, channels)
};

// "16-bit unsigned 1-channel", "8-bit unsigned 3-channel", ... for messages.
std::string ImageTypeName(int cv_type);

// Throws InputError (with the path) when the header describes an image the caller cannot
// use; called before any pixel is decompressed.
using ImageHeaderCheck = std::function<void(const ImageHeader&)>;

// The header of an encoded image in memory. Throws InputError(path_for_errors, reason) when
// the bytes are not a PNG, JPEG or TIFF image or the header is malformed.
ImageHeader DecodeImageHeader(std::string_view bytes, const std::filesystem::path& path_for_errors);

// Decodes an image in memory. `check` (if set) sees the header first. Channels are in file
// order: grey, grey+alpha, RGB or RGBA — not OpenCV's BGR. 16-bit samples are in host
// byte order. Throws InputError naming path_for_errors and the decoder's reason on corrupt
// or truncated data.
cv::Mat DecodeImage(std::string_view bytes, const std::filesystem::path& path_for_errors,
                    const ImageHeaderCheck& check = nullptr);

// ReadFile(path, kMaxFrameFileBytes) + DecodeImage.
cv::Mat ReadImage(const std::filesystem::path& path, const ImageHeaderCheck& check = nullptr);

// Encodes `image` (OpenCV channel order: BGR for colour) in the format of `extension`
// (".png", ".tiff", ".jpg") in memory. Throws OutputError(path_for_errors) if the encoder
// fails.
std::string EncodeImage(const cv::Mat& image, const std::string& extension,
                        const std::filesystem::path& path_for_errors);

// EncodeImage (format from path's extension) + WriteFileAtomically. Throws OutputError.
void WriteImageAtomically(const std::filesystem::path& path, const cv::Mat& image);

}  // namespace hw::core
