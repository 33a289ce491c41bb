#include "core/scan_writer.h"

#include <cassert>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <system_error>

#include <opencv2/core.hpp>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/image_io.h"
#include "core/strings.h"

namespace hw::core {

namespace fs = std::filesystem;

namespace {

// The folder's name for index headers ("scan" for both "a/scan" and "a/scan/").
// One line: a '\n' in a folder name would end the header's comment line.
std::string FolderName(const fs::path& folder) {
  const fs::path name = folder.filename();
  return OneLineMessage(name.empty() ? folder.parent_path().filename().string() : name.string());
}

}  // namespace

ScanWriter::ScanWriter(const fs::path& folder, const Rig& rig) : folder_(folder), rig_(rig) {
  assert(rig_.Check().empty());
  std::error_code ec;
  fs::create_directories(folder_, ec);
  if (ec) throw OutputError(folder_, "cannot create folder: " + ec.message());
  WriteRig(folder_ / "rig.yaml", rig_);
}

std::string ScanWriter::FormatTimestamp(double timestamp_s) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.6f", timestamp_s);
  return buf;
}

std::string ScanWriter::FrameFileName(double timestamp_s, const std::string& extension) {
  return FormatTimestamp(timestamp_s) + extension;
}

std::string ScanWriter::Register(StreamIndex& index, const std::string& stream, double timestamp_s,
                                 const std::string& extension) {
  assert(std::isfinite(timestamp_s));
  const std::string stamp = FormatTimestamp(timestamp_s);
  // The index holds the rounded value; it is what must increase.
  const double rounded_s = std::strtod(stamp.c_str(), nullptr);
  assert(!index.last_rounded_s || rounded_s > *index.last_rounded_s);
  index.last_rounded_s = rounded_s;
  std::string relative = stream + "/" + stamp + extension;
  index.lines.emplace_back(stamp, relative);
  return relative;
}

void ScanWriter::WriteImage(const std::string& relative_path, const cv::Mat& image) const {
  // Encoded in memory and written through the checked writer: cv::imwrite reports success
  // when only its final close fails (a full disk), which would rename a short file into place.
  WriteImageAtomically(folder_ / relative_path, image);
}

int ScanWriter::AddDepth(double timestamp_s, const cv::Mat& depth_m) {
  assert(depth_m.type() == CV_32FC1);
  assert(depth_m.cols == rig_.depth.width && depth_m.rows == rig_.depth.height);
  cv::Mat raw(depth_m.rows, depth_m.cols, CV_16UC1);
  int out_of_range = 0;
  const double scale = rig_.depth_scale;
  for (int y = 0; y < depth_m.rows; ++y) {
    const float* in = depth_m.ptr<float>(y);
    uint16_t* out = raw.ptr<uint16_t>(y);
    for (int x = 0; x < depth_m.cols; ++x) {
      const double d = in[x];
      if (!(std::isfinite(d) && d > 0)) {  // no measurement (NaN fails d > 0 too)
        out[x] = 0;
        continue;
      }
      const double r = std::round(d * scale);
      if (r > 65535.0) {
        out[x] = 0;
        ++out_of_range;
      } else {
        out[x] = static_cast<uint16_t>(r);
      }
    }
  }
  WriteImage(Register(depth_, "depth", timestamp_s, ".png"), raw);
  return out_of_range;
}

void ScanWriter::AddRgb(double timestamp_s, const cv::Mat& rgb) {
  assert(rig_.rgb);
  assert(rgb.type() == CV_8UC3);
  assert(rgb.cols == rig_.rgb->width && rgb.rows == rig_.rgb->height);
  cv::Mat bgr(rgb.rows, rgb.cols, CV_8UC3);
  const int from_to[] = {0, 2, 1, 1, 2, 0};
  cv::mixChannels(&rgb, 1, &bgr, 1, from_to, 3);
  WriteImage(Register(rgb_, "rgb", timestamp_s, ".png"), bgr);
}

int ScanWriter::AddThermal(double timestamp_s, const cv::Mat& apparent_c,
                           ThermalEncoding encoding) {
  assert(rig_.thermal && rig_.thermal_settings);
  assert(apparent_c.type() == CV_32FC1);
  assert(apparent_c.cols == rig_.thermal->width && apparent_c.rows == rig_.thermal->height);
  if (encoding == ThermalEncoding::kFloatTiff) {
    // Continuous so that the TIFF writer sees one plain buffer.
    assert(cv::checkRange(apparent_c));  // readers refuse NaN/inf thermal pixels
    WriteImage(Register(thermal_, "thermal", timestamp_s, ".tiff"), apparent_c.clone());
    return 0;
  }
  const ThermalSettings& settings = *rig_.thermal_settings;
  cv::Mat raw(apparent_c.rows, apparent_c.cols, CV_16UC1);
  int saturated = 0;
  for (int y = 0; y < apparent_c.rows; ++y) {
    const float* in = apparent_c.ptr<float>(y);
    uint16_t* out = raw.ptr<uint16_t>(y);
    for (int x = 0; x < apparent_c.cols; ++x) {
      const double r = std::round(settings.RawFromApparent(static_cast<double>(in[x])));
      if (std::isnan(r)) {
        out[x] = 0;
      } else if (r < 0 || r > 65535.0) {
        out[x] = r < 0 ? 0 : 65535;
        ++saturated;
      } else {
        out[x] = static_cast<uint16_t>(r);
      }
    }
  }
  WriteImage(Register(thermal_, "thermal", timestamp_s, ".png"), raw);
  return saturated;
}

void ScanWriter::AddFfcEvent(double timestamp_s) {
  assert(std::isfinite(timestamp_s));
  assert(ffc_timestamps_s_.empty() ||
         std::strtod(FormatTimestamp(timestamp_s).c_str(), nullptr) >
             std::strtod(FormatTimestamp(ffc_timestamps_s_.back()).c_str(), nullptr));
  ffc_timestamps_s_.push_back(timestamp_s);
}

void ScanWriter::SetGroundTruth(const Trajectory& world_from_depth) {
  groundtruth_ = world_from_depth;
}

int ScanWriter::NumFrames(const std::string& stream) const {
  if (stream == "depth") return static_cast<int>(depth_.lines.size());
  if (stream == "rgb") return static_cast<int>(rgb_.lines.size());
  if (stream == "thermal") return static_cast<int>(thermal_.lines.size());
  assert(false);
  return 0;
}

void ScanWriter::WriteIndex(const std::string& file, const std::string& header,
                            const StreamIndex& index) const {
  // TUM's three header lines, so that TUM tools read the indexes too.
  std::string text = "# " + header + "\n# file: '" + FolderName(folder_) +
                     "' written by heatwave\n# timestamp filename\n";
  for (const auto& [stamp, path] : index.lines) text += stamp + " " + path + "\n";
  WriteFileAtomically(folder_ / file, text);
}

void ScanWriter::Finish() {
  WriteIndex("depth.txt", "depth maps", depth_);
  if (!rgb_.lines.empty()) WriteIndex("rgb.txt", "color images", rgb_);
  if (!thermal_.lines.empty()) {
    WriteIndex("thermal.txt",
               "thermal images (16-bit PNG: raw counts; 32-bit float TIFF: apparent deg C)",
               thermal_);
  }
  if (!ffc_timestamps_s_.empty()) {
    std::string text = "# flat-field correction (shutter) events, thermal clock\n# file: '" +
                       FolderName(folder_) + "' written by heatwave\n# timestamp\n";
    for (const double t : ffc_timestamps_s_) text += FormatTimestamp(t) + "\n";
    WriteFileAtomically(folder_ / "ffc.txt", text);
  }
  if (groundtruth_) WriteTumTrajectory(folder_ / "groundtruth.txt", *groundtruth_);
}

}  // namespace hw::core
