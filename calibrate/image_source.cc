#include "calibrate/image_source.h"

#include <algorithm>
#include <cctype>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/image_io.h"

namespace hw::calibrate {
namespace {

namespace fs = std::filesystem;

std::string Lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// One channel: colour to luma (file channel order is RGB for core::ReadImage), alpha dropped.
cv::Mat ToOneChannel(const cv::Mat& image, bool rgb_order) {
  if (image.channels() == 1) return image;
  cv::Mat grey;
  if (image.channels() == 2) {
    cv::extractChannel(image, grey, 0);
  } else if (image.channels() == 3) {
    cv::cvtColor(image, grey, rgb_order ? cv::COLOR_RGB2GRAY : cv::COLOR_BGR2GRAY);
  } else {
    cv::cvtColor(image, grey, rgb_order ? cv::COLOR_RGBA2GRAY : cv::COLOR_BGRA2GRAY);
  }
  return grey;
}

cv::Mat ReadOne(const fs::path& path) {
  if (Lower(path.extension().string()) == ".bmp") {
    // core::ReadImage covers PNG, JPEG and TIFF; BMP (uncompressed, no decompression bomb)
    // through OpenCV, in BGR order.
    const std::string bytes = core::ReadFile(path, core::kMaxFrameFileBytes);
    const cv::Mat image = cv::imdecode(cv::Mat(1, static_cast<int>(bytes.size()), CV_8U, const_cast<char*>(bytes.data())),
                                       cv::IMREAD_UNCHANGED);
    if (image.empty()) throw core::InputError(path, "cannot be decoded as a BMP image");
    return ToOneChannel(image, false);
  }
  return ToOneChannel(core::ReadImage(path), true);
}

}  // namespace

std::vector<CalibrationImage> LoadCalibrationImages(const fs::path& path, core::Stream stream) {
  std::vector<CalibrationImage> out;
  if (!fs::is_directory(path)) throw core::InputError(path, "not a folder of images or a scan folder");
  if (fs::exists(path / "rig.yaml")) {
    if (stream == core::Stream::kDepth) {
      throw core::InputError(path, "a scan's depth stream holds no image of the target: give --images a folder of the "
                                   "depth camera's IR images");
    }
    const core::Scan scan = core::Scan::Open(path);
    const int n = scan.NumFrames(stream);
    if (n == 0) throw core::InputError(path, "the scan has no " + core::StreamName(stream) + " frames");
    for (int i = 0; i < n; ++i) {
      const cv::Mat frame = scan.Load(stream, i);
      out.push_back({core::StreamName(stream) + "/" + std::to_string(i),
                     stream == core::Stream::kRgb ? ToOneChannel(frame, true) : frame});
    }
    return out;
  }
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(path)) {
    const std::string ext = Lower(entry.path().extension().string());
    if (entry.is_regular_file() &&
        (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp" || ext == ".tif" || ext == ".tiff")) {
      files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) throw core::InputError(path, "holds no image (.png .jpg .jpeg .bmp .tif .tiff)");
  for (const fs::path& file : files) {
    CalibrationImage image{file.filename().string(), ReadOne(file)};
    if (!out.empty() && image.image.size() != out.front().image.size()) {
      throw core::InputError(file, "is " + std::to_string(image.image.cols) + "x" + std::to_string(image.image.rows) +
                                       ", " + out.front().name + " " + std::to_string(out.front().image.cols) + "x" +
                                       std::to_string(out.front().image.rows) + ": images of one camera have one size");
    }
    out.push_back(std::move(image));
  }
  return out;
}

}  // namespace hw::calibrate
