#pragma once

// The images a camera is calibrated from: a folder of image files, or one stream of a scan
// folder (a calibration session, scan-format.md).

#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/scan.h"

namespace hw::calibrate {

struct CalibrationImage {
  std::string name;  // file name, or "<stream>/<frame file>" for a scan
  // One channel, as the camera gave it: CV_8U (colour converted to luma), CV_16U (raw
  // thermal counts or IR), CV_32F (°C: a scan's thermal stream).
  cv::Mat image;
};

// The images of `path`:
// - a scan folder (it holds rig.yaml and stream indexes): the frames of `stream` (thermal →
//   CV_32F °C, rgb → CV_8U luma); the depth stream holds no image of a target and is an
//   error saying to give a folder of the depth camera's IR images instead;
// - any other folder: its .png .jpg .jpeg .bmp .tif .tiff files (case-insensitive), sorted
//   by name; 8-bit colour converted to luma (Rec. 601, as OpenCV's cvtColor), 16-bit kept.
// Throws core::InputError naming the file for an unreadable or undecodable image, images of
// different sizes ("left03.jpg is 320x240, left01.jpg 640x480"), a folder with no image.
std::vector<CalibrationImage> LoadCalibrationImages(const std::filesystem::path& path, core::Stream stream);

}  // namespace hw::calibrate
