#include "calibrate/target_detect.h"

#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/option_check.h"

namespace hw::calibrate {

namespace {

// A number as "%.3g" prints it.
std::string Short(double value) {
  char buffer[32];
  std::snprintf(buffer, sizeof buffer, "%.3g", value);
  return buffer;
}

// One channel: 3-channel 8-bit is RGB (core::Scan::LoadRgb); any other channel count is
// averaged.
cv::Mat OneChannel(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat grey;
  // cvtColor takes 8-bit, 16-bit and float only: other depths go through float.
  cv::Mat colour = image;
  if (image.depth() != CV_8U && image.depth() != CV_16U && image.depth() != CV_32F) {
    image.convertTo(colour, CV_MAKETYPE(CV_32F, image.channels()));
  }
  if (colour.channels() == 3) {
    cv::cvtColor(colour, grey, cv::COLOR_RGB2GRAY);
  } else if (colour.channels() == 4) {
    cv::cvtColor(colour, grey, cv::COLOR_RGBA2GRAY);
  } else {
    std::vector<cv::Mat> planes;
    cv::split(colour, planes);
    cv::Mat sum = cv::Mat::zeros(image.size(), CV_64F);
    for (const cv::Mat& p : planes) cv::accumulate(p, sum);
    grey = sum / static_cast<double>(planes.size());
  }
  return grey;
}

// 8-bit grey: 8-bit as is, anything else normalised min-max (NaNs to 0).
cv::Mat Grey8(const cv::Mat& image) {
  const cv::Mat one = OneChannel(image);
  if (one.depth() == CV_8U) return one;
  cv::Mat as_float;
  one.convertTo(as_float, CV_32F);
  cv::patchNaNs(as_float, 0);
  cv::Mat out;
  cv::normalize(as_float, out, 0, 255, cv::NORM_MINMAX, CV_8U);
  return out;
}

Detection EmptyDetection(const cv::Mat& image, const std::string& view_name) {
  Detection detection;
  detection.view = view_name;
  detection.width_px = image.cols;
  detection.height_px = image.rows;
  return detection;
}

int MinCorners(const core::Target& target) {
  return std::min<int>(kMinDetectedCorners, static_cast<int>(core::TargetCorners(target).size()));
}

// ---------------------------------------------------------------------------------------
// Chessboard orientation

// The corners OpenCV found, h rows of w, and the image to sample square colours in.
struct Grid {
  int h = 0, w = 0;
  std::vector<cv::Point2f> px;  // row-major
  cv::Point2f At(int r, int c) const { return px[r * w + c]; }
};

double Sample(const cv::Mat& blurred, cv::Point2f p) {
  if (!(p.x >= 0 && p.y >= 0 && p.x <= blurred.cols - 1 && p.y <= blurred.rows - 1)) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  cv::Mat patch;
  cv::getRectSubPix(blurred, cv::Size(1, 1), p, patch, CV_32F);
  return patch.at<float>(0, 0);
}

// Mirrors the columns when the grid is left-handed in the image (the front of a board
// always images right-handed: x right, y down).
void MakeRightHanded(Grid& grid) {
  const cv::Point2f along_row = grid.At(0, grid.w - 1) - grid.At(0, 0);
  const cv::Point2f down = grid.At(grid.h - 1, 0) - grid.At(0, 0);
  if (along_row.x * down.y - along_row.y * down.x >= 0) return;
  for (int r = 0; r < grid.h; ++r) {
    std::reverse(grid.px.begin() + r * grid.w, grid.px.begin() + (r + 1) * grid.w);
  }
}

struct GridColours {
  bool cell00_black = false;  // the cell between corners (0,0) and (1,1) of the grid
  double black = 0, white = 0;  // mean levels of its black and white cells
};

GridColours CellColours(const Grid& grid, const cv::Mat& blurred) {
  double sum[2] = {0, 0};
  int n[2] = {0, 0};
  for (int r = 0; r + 1 < grid.h; ++r) {
    for (int c = 0; c + 1 < grid.w; ++c) {
      const cv::Point2f centre =
          (grid.At(r, c) + grid.At(r, c + 1) + grid.At(r + 1, c) + grid.At(r + 1, c + 1)) * 0.25f;
      const double v = Sample(blurred, centre);
      if (std::isnan(v)) continue;
      sum[(r + c) % 2] += v;
      ++n[(r + c) % 2];
    }
  }
  const double even = n[0] ? sum[0] / n[0] : 0, odd = n[1] ? sum[1] / n[1] : 0;
  GridColours colours;
  colours.cell00_black = even < odd;
  colours.black = std::min(even, odd);
  colours.white = std::max(even, odd);
  return colours;
}

// Whether the board ends beyond side `side` (0 top, 1 right, 2 bottom, 3 left) of the
// grid: 1.4 squares out — past the outer ring of squares, in the white margin — the points
// that would be black squares if the board went on are white.
bool SideIsBoardEdge(const Grid& grid, const cv::Mat& blurred, const GridColours& colours, int side) {
  // Walk along the side: corner k of the side and its inward neighbour.
  const int n = (side % 2 == 0) ? grid.w : grid.h;
  const auto corner = [&](int k, int depth) {
    switch (side) {
      case 0: return grid.At(depth, k);
      case 1: return grid.At(k, grid.w - 1 - depth);
      case 2: return grid.At(grid.h - 1 - depth, k);
      default: return grid.At(k, depth);
    }
  };
  const double mid = 0.5 * (colours.black + colours.white);
  int bright = 0, counted = 0;
  for (int k = 0; k + 1 < n; ++k) {
    // Grid cell (i, j) (between corners (i, j) and (i + 1, j + 1)) two rings beyond the
    // side, next to the side's cell k: 1.4 squares out lies in it.
    int i = 0, j = 0;
    switch (side) {
      case 0: i = -2, j = k; break;
      case 1: i = k, j = grid.w; break;
      case 2: i = grid.h, j = k; break;
      default: i = k, j = -2; break;
    }
    const bool black_if_board = (((i + j) % 2 + 2) % 2 == 0) == colours.cell00_black;
    if (!black_if_board) continue;
    const cv::Point2f a = corner(k, 0), b = corner(k + 1, 0);
    const cv::Point2f outward = 0.5f * ((a - corner(k, 1)) + (b - corner(k + 1, 1)));
    const double v = Sample(blurred, 0.5f * (a + b) + 1.4f * outward);
    if (std::isnan(v)) continue;
    ++counted;
    bright += v > mid;
  }
  return counted > 0 && bright >= 0.75 * counted;
}

// cornerSubPix on findChessboardCornersSB's corners: on the full intrinsics-chessboard
// session (640x480, 24 views) it takes their error from 0.104 px RMS (max 0.95 px) to
// 0.066 (max 0.19 px), on the small one from 0.060 (max 0.14) to 0.066 (max 0.16 px).
// The window's half side is 0.6 of the smallest corner spacing (the window never reaches
// a neighbouring corner), 2 to 7 px (7: 15x15 px, the best of 3, 5, 7 on both sessions); a
// corner the refinement moves by more than 1 px (a fake saddle, e.g. at an occluder's
// edge) keeps OpenCV's position.
void RefineCorners(const cv::Mat& grey8, Grid& grid) {
  double spacing = std::numeric_limits<double>::infinity();
  for (int r = 0; r < grid.h; ++r) {
    for (int c = 0; c < grid.w; ++c) {
      if (c + 1 < grid.w) spacing = std::min(spacing, static_cast<double>(cv::norm(grid.At(r, c + 1) - grid.At(r, c))));
      if (r + 1 < grid.h) spacing = std::min(spacing, static_cast<double>(cv::norm(grid.At(r + 1, c) - grid.At(r, c))));
    }
  }
  const int half = static_cast<int>(std::clamp(std::floor(0.6 * spacing), 2.0, 7.0));
  std::vector<cv::Point2f> refined = grid.px;
  cv::cornerSubPix(grey8, refined, cv::Size(half, half), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 100, 1e-4));
  for (size_t i = 0; i < refined.size(); ++i) {
    if (cv::norm(refined[i] - grid.px[i]) <= 1.0) grid.px[i] = refined[i];
  }
}

// The ids of `grid`'s corners in the board `target`, or nullopt with the reason.
std::optional<std::vector<int>> NumberChessboard(Grid grid, const core::Target& target,
                                                 const cv::Mat& grey8, std::vector<cv::Point2f>& px,
                                                 std::string& reason) {
  MakeRightHanded(grid);
  px = grid.px;
  cv::Mat blurred;
  cv::GaussianBlur(grey8, blurred, cv::Size(5, 5), 1.0);
  blurred.convertTo(blurred, CV_32F);
  const GridColours colours = CellColours(grid, blurred);
  const bool full = grid.h == target.rows && grid.w == target.cols;
  std::array<bool, 4> edge{};
  if (!full) {
    for (int side = 0; side < 4; ++side) edge[side] = SideIsBoardEdge(grid, blurred, colours, side);
  }
  // Board x axis in the image, for the upright rule.
  struct Candidate {
    std::vector<int> ids;
    double upright = 0;  // cosine of the board x axis with the image x axis
  };
  std::vector<Candidate> candidates;
  for (int k = 0; k < 4; ++k) {
    const int h = (k % 2) ? grid.w : grid.h, w = (k % 2) ? grid.h : grid.w;
    if (h > target.rows || w > target.cols) continue;
    // Rotated grid index (r', c') of grid corner (r, c), and the grid sides that become
    // the rotated grid's top and left (sides: 0 top, 1 right, 2 bottom, 3 left).
    const auto rotate = [&](int r, int c) -> std::pair<int, int> {
      switch (k) {
        case 0: return {r, c};
        case 1: return {c, grid.h - 1 - r};
        case 2: return {grid.h - 1 - r, grid.w - 1 - c};
        default: return {grid.w - 1 - c, r};
      }
    };
    const int top = (4 - k) % 4, left = (3 - k + 4) % 4;
    const bool top_edge = edge[top], bottom_edge = edge[(top + 2) % 4];
    const bool left_edge = edge[left], right_edge = edge[(left + 2) % 4];
    int r0 = 0, c0 = 0;
    if (w < target.cols) {
      if (left_edge == right_edge) continue;  // no edge, or both: cannot place it
      c0 = left_edge ? 0 : target.cols - w;
    }
    if (h < target.rows) {
      if (top_edge == bottom_edge) continue;
      r0 = top_edge ? 0 : target.rows - h;
    }
    // Colour: the rotated grid's cell (0, 0) is board cell (r0, c0), i.e. square
    // (r0 + 1, c0 + 1), black when r0 + c0 is even. Which grid cell it is:
    const auto [gr, gc] = [&]() -> std::pair<int, int> {
      switch (k) {
        case 0: return {0, 0};
        case 1: return {grid.h - 2, 0};
        case 2: return {grid.h - 2, grid.w - 2};
        default: return {0, grid.w - 2};
      }
    }();
    const bool black = ((gr + gc) % 2 == 0) == colours.cell00_black;
    if (black != ((r0 + c0) % 2 == 0)) continue;
    Candidate candidate;
    candidate.ids.resize(grid.px.size());
    for (int r = 0; r < grid.h; ++r) {
      for (int c = 0; c < grid.w; ++c) {
        const auto [rr, cc] = rotate(r, c);
        candidate.ids[r * grid.w + c] = (r0 + rr) * target.cols + (c0 + cc);
      }
    }
    // The board's +x axis: from the rotated row's first to last corner, averaged over rows.
    cv::Point2f x_axis(0, 0);
    for (int r = 0; r < grid.h; ++r) {
      for (int c = 0; c < grid.w; ++c) {
        const auto [rr, cc] = rotate(r, c);
        x_axis += (static_cast<float>(cc) - 0.5f * static_cast<float>(w - 1)) * grid.At(r, c);
      }
    }
    const double ax = x_axis.x, ay = x_axis.y;
    candidate.upright = ax / std::max(1e-9, std::hypot(ax, ay));
    candidates.push_back(std::move(candidate));
  }
  if (candidates.empty()) {
    reason = full ? "chessboard found but its square colours match no orientation of the board"
                  : "partial chessboard (" + std::to_string(grid.w) + "x" + std::to_string(grid.h) +
                        " corners) without board edges that place it on the board";
    return std::nullopt;
  }
  const auto best = std::max_element(candidates.begin(), candidates.end(),
                                     [](const Candidate& a, const Candidate& b) { return a.upright < b.upright; });
  return best->ids;
}

// ---------------------------------------------------------------------------------------
// AprilGrid

// 8-bit linear light from `image`: 8-bit is sRGB-decoded, the rest normalised.
cv::Mat LinearGrey8(const cv::Mat& image) {
  const cv::Mat one = OneChannel(image);
  if (one.depth() != CV_8U) return Grey8(image);
  static const cv::Mat lut = [] {
    cv::Mat table(1, 256, CV_8U);
    for (int i = 0; i < 256; ++i) {
      const double s = i / 255.0;
      const double linear = s <= 0.04045 ? s / 12.92 : std::pow((s + 0.055) / 1.055, 2.4);
      table.at<uint8_t>(0, i) = cv::saturate_cast<uint8_t>(255.0 * linear);
    }
    return table;
  }();
  cv::Mat linear;
  cv::LUT(one, lut, linear);
  return linear;
}

}  // namespace

std::string BoardDetectOptions::Check() const {
  if (!(max_homography_rms_px > 0 && max_homography_rms_px <= 50)) {
    return core::OptionFail("max_homography_rms_px", max_homography_rms_px, "in (0, 50]");
  }
  return "";
}

void CheckDetection(const core::Target& target, double max_rms_px, int min_corners,
                    Detection& detection) {
  assert(target.Check().empty());
  detection.homography_rms_px = std::numeric_limits<double>::quiet_NaN();
  detection.accepted = false;
  const auto reject = [&](const std::string& reason) { detection.reason = reason; };
  const std::vector<Eigen::Vector3d> corners = core::TargetCorners(target);
  const size_t n = detection.corner_ids.size();
  if (detection.pixels.size() != n) {
    return reject("corner ids and pixels differ in size (" + std::to_string(n) + " vs " +
                  std::to_string(detection.pixels.size()) + ")");
  }
  const int needed = std::max(min_corners, 4);
  if (static_cast<int>(n) < needed) {
    return reject(std::to_string(n) + " corners found, fewer than the " + std::to_string(needed) +
                  " required");
  }
  std::vector<bool> seen(corners.size(), false);
  std::vector<cv::Point2d> plane, image;
  for (size_t i = 0; i < n; ++i) {
    const int id = detection.corner_ids[i];
    if (id < 0 || id >= static_cast<int>(corners.size())) {
      return reject("corner id " + std::to_string(id) + " outside [0, " +
                    std::to_string(corners.size()) + ")");
    }
    if (seen[id]) return reject("corner id " + std::to_string(id) + " found twice");
    seen[id] = true;
    const Eigen::Vector2d& p = detection.pixels[i];
    if (!p.allFinite()) return reject("corner id " + std::to_string(id) + " has a non-finite pixel");
    plane.emplace_back(corners[id].x(), corners[id].y());
    image.emplace_back(p.x(), p.y());
  }
  const cv::Mat h = cv::findHomography(plane, image, 0);
  if (h.empty()) return reject("no homography fits the corners (degenerate, e.g. collinear)");
  std::vector<cv::Point2d> mapped;
  cv::perspectiveTransform(plane, mapped, h);
  double sum2 = 0;
  for (size_t i = 0; i < n; ++i) {
    const cv::Point2d d = mapped[i] - image[i];
    sum2 += d.dot(d);
  }
  detection.homography_rms_px = std::sqrt(sum2 / static_cast<double>(n));
  if (!(detection.homography_rms_px <= max_rms_px)) {
    return reject("homography RMS " + Short(detection.homography_rms_px) + " px > " + Short(max_rms_px) +
                  " px: the corners are not the target's in their order (wrong ids, a "
                  "misdetection or strong distortion)");
  }
  detection.accepted = true;
  detection.reason.clear();
}

Detection DetectChessboard(const cv::Mat& image, const core::Target& target,
                           const BoardDetectOptions& options, const std::string& view_name) {
  assert(options.Check().empty() && target.Check().empty());
  assert(target.type == core::TargetType::kChessboard);
  Detection detection = EmptyDetection(image, view_name);
  if (image.empty()) {
    detection.reason = "empty image";
    return detection;
  }
  const cv::Mat grey = Grey8(image);
  const int flags = cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_EXHAUSTIVE | cv::CALIB_CB_ACCURACY;
  Grid grid;
  cv::Mat found;
  if (cv::findChessboardCornersSB(grey, cv::Size(target.cols, target.rows), found, flags)) {
    grid.h = target.rows;
    grid.w = target.cols;
  } else if (options.partial) {
    cv::Mat meta;
    const int min_side = std::min({3, target.rows, target.cols});
    if (cv::findChessboardCornersSB(grey, cv::Size(min_side, min_side), found,
                                    flags | cv::CALIB_CB_LARGER, meta) &&
        !meta.empty()) {
      grid.h = meta.rows;
      grid.w = meta.cols;
    }
  }
  if (grid.h == 0 || found.total() != static_cast<size_t>(grid.h * grid.w)) {
    detection.reason = "no chessboard found";
    return detection;
  }
  grid.px.assign(found.ptr<cv::Point2f>(), found.ptr<cv::Point2f>() + found.total());
  RefineCorners(grey, grid);
  std::vector<cv::Point2f> px;
  std::string reason;
  const std::optional<std::vector<int>> ids = NumberChessboard(grid, target, grey, px, reason);
  if (!ids) {
    detection.reason = reason;
    return detection;
  }
  // Row-major by id, as a reader expects.
  std::vector<size_t> order(ids->size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return (*ids)[a] < (*ids)[b]; });
  for (size_t i : order) {
    detection.corner_ids.push_back((*ids)[i]);
    detection.pixels.emplace_back(px[i].x, px[i].y);
  }
  CheckDetection(target, options.max_homography_rms_px, MinCorners(target), detection);
  return detection;
}

Detection DetectAprilGrid(const cv::Mat& image, const core::Target& target,
                          const BoardDetectOptions& options, const std::string& view_name) {
  assert(options.Check().empty() && target.Check().empty());
  assert(target.type == core::TargetType::kAprilGrid && target.family == "tag36h11");
  Detection detection = EmptyDetection(image, view_name);
  if (image.empty()) {
    detection.reason = "empty image";
    return detection;
  }
  cv::Mat linear = LinearGrey8(image);
  if (!linear.isContinuous()) linear = linear.clone();
  apriltag_family_t* family = tag36h11_create();
  apriltag_detector_t* detector = apriltag_detector_create();
  apriltag_detector_add_family(detector, family);
  detector->quad_decimate = 1;  // tags of ~20 px: decimation loses them
  detector->nthreads = 1;
  detector->refine_edges = 1;
  image_u8_t view{linear.cols, linear.rows, static_cast<int32_t>(linear.step), linear.data};
  zarray_t* found = apriltag_detector_detect(detector, &view);
  const int tags = target.rows * target.cols;
  std::map<int, std::array<Eigen::Vector2d, 4>> by_id;
  std::vector<int> count(tags, 0);
  for (int i = 0; i < zarray_size(found); ++i) {
    apriltag_detection_t* det = nullptr;
    zarray_get(found, i, &det);
    if (det->id < 0 || det->id >= tags) continue;
    ++count[det->id];
    std::array<Eigen::Vector2d, 4>& corners = by_id[det->id];
    // libapriltag's pixel centres are at +0.5 (AprilRobotics/apriltag#121).
    for (int k = 0; k < 4; ++k) corners[k] = Eigen::Vector2d(det->p[k][0] - 0.5, det->p[k][1] - 0.5);
  }
  apriltag_detections_destroy(found);
  apriltag_detector_destroy(detector);
  tag36h11_destroy(family);
  for (const auto& [id, corners] : by_id) {
    if (count[id] != 1) continue;
    for (int k = 0; k < 4; ++k) {
      detection.corner_ids.push_back(4 * id + k);
      detection.pixels.push_back(corners[k]);
    }
  }
  if (detection.corner_ids.empty()) {
    detection.reason = "no tag of the grid found";
    return detection;
  }
  CheckDetection(target, options.max_homography_rms_px, MinCorners(target), detection);
  return detection;
}

}  // namespace hw::calibrate
