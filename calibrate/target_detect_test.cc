#include "calibrate/target_detect.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/output_folder.h"
#include "core/scan.h"
#include "fixtures/calibration_sessions.h"
#include "fixtures/cached_test_data.h"
#include "fixtures/calibration_test_support.h"
#include "fixtures/colour_sensor.h"

namespace hw::calibrate {
namespace {

namespace fs = std::filesystem;
using fixtures::CalibrationSessionKind;
using fixtures::CalibrationSessionOptions;

// The small preset's session of `kind` (320x240 colour, 4 views, one per image corner),
// rendered once per build (fixtures/cached_test_data.h).
fs::path CachedSession(CalibrationSessionKind kind) {
  return fixtures::test::CachedSession("calibrate-" + fixtures::CalibrationSessionName(kind),
                                       CalibrationSessionOptions::Preset(kind, true), "rgb.txt");
}

// Frame i of a session and the truth of its corners: core::TargetCorners projected with
// the TRUE rig's rgb camera at the groundtruth pose of the frame.
struct Frame {
  cv::Mat rgb;
  std::vector<Eigen::Vector2d> truth_px;  // by corner id
};
std::vector<Frame> SessionFrames(const fs::path& dir, core::Target& target) {
  const core::Scan scan = core::Scan::Open(dir);
  const core::Rig truth = core::ReadRig(dir / "truth" / "rig.yaml");
  target = core::ReadTarget(dir / "target.yaml");
  std::vector<Frame> frames;
  for (int i = 0; i < scan.NumFrames(core::Stream::kRgb); ++i) {
    const auto view = fixtures::calibration_test::ViewOfFrame(scan, truth, core::Stream::kRgb, i);
    Frame frame;
    frame.rgb = scan.LoadRgb(i);
    for (const Eigen::Vector3d& corner : core::TargetCorners(target)) {
      frame.truth_px.push_back(view.camera.Project(view.camera_from_world * corner));
    }
    frames.push_back(std::move(frame));
  }
  return frames;
}

struct Errors {
  int views = 0, accepted = 0, corners = 0;
  double rms_px = 0, max_px = 0;
  double outward_px = 0;  // aprilgrid: mean error along the tag's outward diagonal
  double ms_per_image = 0;
};

// Runs `detect` on every frame and compares each corner with the truth of its id (`shift`
// added to the truth: a cropped image's origin).
template <typename Detect>
Errors Measure(const std::vector<Frame>& frames, const Detect& detect) {
  Errors e;
  double sum2 = 0, outward = 0;
  for (const Frame& frame : frames) {
    ++e.views;
    const auto start = std::chrono::steady_clock::now();
    const Detection d = detect(frame.rgb);
    e.ms_per_image += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    EXPECT_EQ(d.width_px, frame.rgb.cols);
    if (!d.accepted) {
      std::printf("  rejected: %s\n", d.reason.c_str());
      continue;
    }
    ++e.accepted;
    EXPECT_LT(d.homography_rms_px, 2.0);
    for (size_t i = 0; i < d.corner_ids.size(); ++i) {
      const int id = d.corner_ids[i];
      const Eigen::Vector2d err = d.pixels[i] - frame.truth_px[id];
      sum2 += err.squaredNorm();
      e.max_px = std::max(e.max_px, err.norm());
      ++e.corners;
      // Tag corners 4t..4t+3: outward = from the tag's centre to the corner.
      const int tag = id / 4;
      const Eigen::Vector2d centre = 0.25 * (frame.truth_px[4 * tag] + frame.truth_px[4 * tag + 1] +
                                             frame.truth_px[4 * tag + 2] + frame.truth_px[4 * tag + 3]);
      outward += err.dot((frame.truth_px[id] - centre).normalized());
    }
  }
  e.rms_px = std::sqrt(sum2 / std::max(e.corners, 1));
  e.outward_px = outward / std::max(e.corners, 1);
  e.ms_per_image /= std::max(e.views, 1);
  return e;
}

// ---------------------------------------------------------------------------------------

TEST(BoardDetectOptions, CheckNamesTheField) {
  EXPECT_EQ(BoardDetectOptions{}.Check(), "");
  for (double bad : {0.0, -1.0, 51.0, std::nan("")}) {
    BoardDetectOptions o;
    o.max_homography_rms_px = bad;
    EXPECT_NE(o.Check().find("max_homography_rms_px"), std::string::npos) << bad;
  }
}

TEST(DetectChessboard, FindsEveryViewOfTheSessionAtTheTrueCorners) {
  core::Target target;
  const auto frames = SessionFrames(CachedSession(CalibrationSessionKind::kColourChessboard), target);
  ASSERT_EQ(target.rows * target.cols, 35);
  const Errors e = Measure(frames, [&](const cv::Mat& image) {
    const Detection d = DetectChessboard(image, target);
    if (d.accepted) {
      EXPECT_EQ(d.corner_ids.size(), 35u);  // the full board in every view
    }
    return d;
  });
  std::printf("chessboard: %d of %d views, %d corners, rms %.3f max %.3f px, %.1f ms per image\n",
              e.accepted, e.views, e.corners, e.rms_px, e.max_px, e.ms_per_image);
  EXPECT_EQ(e.accepted, e.views);
  // Measured: RMS 0.066 px, max 0.16 px (findChessboardCornersSB alone: 0.060, 0.14; the
  // full 640x480 session, 24 views, measured once: 0.066, max 0.19 px, SB alone 0.104, max
  // 0.95 px). The fixtures measured 0.08 px RMS, max 0.21 px, with findChessboardCorners +
  // cornerSubPix on these frames (fixtures/calibration_sessions_test.cc); a wrong id (a
  // square off) is >= 10 px. Bounds: no worse than that classic pipeline, with room.
  EXPECT_LT(e.rms_px, 0.12);
  EXPECT_LT(e.max_px, 0.4);
}

// 8-bit RGB, 8-bit grey, 16-bit, float and double RGB give the same corners (the
// normalisation is affine: the saddle points do not move).
TEST(DetectChessboard, AcceptsGrey16BitAndFloatImages) {
  core::Target target;
  const auto frames = SessionFrames(CachedSession(CalibrationSessionKind::kColourChessboard), target);
  cv::Mat grey, grey16, grey_float, rgb_double;
  cv::cvtColor(frames[0].rgb, grey, cv::COLOR_RGB2GRAY);
  grey.convertTo(grey16, CV_16U, 256.0);
  grey.convertTo(grey_float, CV_32F, 1 / 255.0);
  frames[0].rgb.convertTo(rgb_double, CV_64FC3, 1 / 255.0);
  const Detection reference = DetectChessboard(frames[0].rgb, target);
  ASSERT_TRUE(reference.accepted) << reference.reason;
  for (const cv::Mat& image : {grey, grey16, grey_float, rgb_double}) {
    const Detection d = DetectChessboard(image, target);
    ASSERT_TRUE(d.accepted) << d.reason;
    ASSERT_EQ(d.corner_ids, reference.corner_ids);
    for (size_t i = 0; i < d.pixels.size(); ++i) {
      EXPECT_LT((d.pixels[i] - reference.pixels[i]).norm(), 0.02) << i;
    }
  }
}

// Half the board out of view (the image cropped between its corner columns 3 and 4, the
// left or the right part kept) or hidden (a dark box over its left part): the visible
// corners keep their ids.
TEST(DetectChessboard, PartialBoardsAreNumberedFromTheVisibleEdges) {
  core::Target target;
  const auto frames = SessionFrames(CachedSession(CalibrationSessionKind::kColourChessboard), target);
  int checked = 0;
  for (const Frame& frame : frames) {
    // Halfway between the board's corner columns 3 and 4 (of 0..6), mean x in the image.
    double mid_x = 0;
    for (int r = 0; r < target.rows; ++r) {
      mid_x += 0.5 * (frame.truth_px[r * target.cols + 3].x() + frame.truth_px[r * target.cols + 4].x()) /
               target.rows;
    }
    const int cut = static_cast<int>(std::lround(mid_x));
    const double cut_px = cut;
    struct Case {
      std::string name;
      cv::Mat image;
      double x0;  // the image's origin in the frame
    };
    cv::Mat masked = frame.rgb.clone();
    cv::rectangle(masked, cv::Rect(0, 0, cut, masked.rows), cv::Scalar(40, 40, 40), cv::FILLED);
    const std::vector<Case> cases = {
        {"right half", frame.rgb(cv::Rect(cut, 0, frame.rgb.cols - cut, frame.rgb.rows)).clone(), cut_px},
        {"left half", frame.rgb(cv::Rect(0, 0, cut, frame.rgb.rows)).clone(), 0},
        {"right half behind a dark box", masked, 0}};
    for (const Case& c : cases) {
      const Detection d = DetectChessboard(c.image, target);
      std::printf("partial %s: %s, %zu corners %s\n", c.name.c_str(), d.accepted ? "accepted" : "rejected",
                  d.corner_ids.size(), d.reason.c_str());
      if (!d.accepted) continue;
      ++checked;
      EXPECT_LT(d.corner_ids.size(), 35u);
      for (size_t i = 0; i < d.corner_ids.size(); ++i) {
        const Eigen::Vector2d truth = frame.truth_px[d.corner_ids[i]] - Eigen::Vector2d(c.x0, 0);
        // The numbering is under test: a wrong id is off by a square (>= 15 px here). The
        // corners next to the cut or the box are degraded (their squares are cut; measured
        // up to 2.8 px next to the box), the others are at the full board's accuracy.
        EXPECT_LT((d.pixels[i] - truth).norm(), 5.0) << c.name << " id " << d.corner_ids[i];
      }
    }
  }
  // Each frame gives three cases; most must be found (a cut through a corner column can
  // leave too few for the detector).
  EXPECT_GE(checked, 6) << "of " << 3 * frames.size();
}

// Orientation: the OpenCV sample board (9x6 inner corners, 10x7 squares: not symmetric
// under 180°) turned upside down keeps its ids on the same printed corners — the square
// colours decide; the session's 5x7 board (6x8 squares, symmetric) turned upside down is
// numbered from its new top-left corner — the upright rule decides.
TEST(DetectChessboard, OrientationFollowsTheColoursThenTheUprightRule) {
  const auto turned_pixel = [](const cv::Mat& image, const Eigen::Vector2d& p) {
    return Eigen::Vector2d(image.cols - 1 - p.x(), image.rows - 1 - p.y());
  };
  const fs::path sample = "/usr/share/doc/opencv-doc/examples/data/left01.jpg";
  if (fs::exists(sample)) {
    core::Target board;
    board.type = core::TargetType::kChessboard;
    board.rows = 6;
    board.cols = 9;
    board.square_m = 1.0;
    const cv::Mat image = cv::imread(sample.string(), cv::IMREAD_GRAYSCALE);
    cv::Mat turned;
    cv::rotate(image, turned, cv::ROTATE_180);
    const Detection upright = DetectChessboard(image, board), flipped = DetectChessboard(turned, board);
    ASSERT_TRUE(upright.accepted && flipped.accepted) << upright.reason << flipped.reason;
    ASSERT_EQ(upright.corner_ids, flipped.corner_ids);
    for (size_t i = 0; i < upright.pixels.size(); ++i) {
      EXPECT_LT((turned_pixel(image, flipped.pixels[i]) - upright.pixels[i]).norm(), 0.3) << i;
    }
  }
  core::Target target;
  const auto frames = SessionFrames(CachedSession(CalibrationSessionKind::kColourChessboard), target);
  cv::Mat turned;
  cv::rotate(frames[1].rgb, turned, cv::ROTATE_180);
  const Detection d = DetectChessboard(turned, target);
  ASSERT_TRUE(d.accepted) << d.reason;
  for (size_t i = 0; i < d.pixels.size(); ++i) {
    const Eigen::Vector2d truth = turned_pixel(turned, frames[1].truth_px[34 - d.corner_ids[i]]);
    EXPECT_LT((d.pixels[i] - truth).norm(), 0.5) << d.corner_ids[i];
  }
}

TEST(DetectChessboard, PartialOffRejectsABoardCutInHalf) {
  core::Target target;
  const auto frames = SessionFrames(CachedSession(CalibrationSessionKind::kColourChessboard), target);
  // Cut through the board's middle column of corners.
  double mid_x = 0;
  for (int r = 0; r < target.rows; ++r) mid_x += frames[0].truth_px[r * target.cols + 3].x() / target.rows;
  const cv::Mat half = frames[0].rgb(cv::Rect(0, 0, static_cast<int>(mid_x), frames[0].rgb.rows)).clone();
  BoardDetectOptions options;
  options.partial = false;
  const Detection d = DetectChessboard(half, target, options, "half");
  EXPECT_FALSE(d.accepted);
  EXPECT_EQ(d.view, "half");
  EXPECT_FALSE(d.reason.empty());
}

TEST(DetectAprilGrid, FindsTheTagsInLinearLightWithoutTheSrgbBias) {
  core::Target target;
  const auto frames = SessionFrames(CachedSession(CalibrationSessionKind::kColourAprilGrid), target);
  const Errors linear = Measure(frames, [&](const cv::Mat& image) { return DetectAprilGrid(image, target); });
  // The same detector in sRGB light: encode the frame once more, so that the detector's
  // decoding gives back the stored (sRGB) values.
  cv::Mat encode(1, 256, CV_8U);
  for (int i = 0; i < 256; ++i) {
    encode.at<uint8_t>(0, i) = cv::saturate_cast<uint8_t>(255.0 * fixtures::SrgbFromLinear(i / 255.0));
  }
  const Errors srgb = Measure(frames, [&](const cv::Mat& image) {
    cv::Mat twice;
    cv::LUT(image, encode, twice);
    return DetectAprilGrid(twice, target);
  });
  for (const auto& [name, e] : {std::pair{"linear", linear}, std::pair{"sRGB", srgb}}) {
    std::printf("aprilgrid %s: %d of %d views, %d corners (of %d), rms %.3f max %.3f px, outward bias "
                "%+.3f px, %.1f ms per image\n",
                name, e.accepted, e.views, e.corners, 48 * e.views, e.rms_px, e.max_px, e.outward_px,
                e.ms_per_image);
  }
  EXPECT_EQ(linear.accepted, linear.views);
  EXPECT_GE(linear.corners, 0.75 * 48 * linear.views);
  // Fixtures: 0.36 px RMS on one such frame (tags of ~20 px through the low-cost pipeline).
  EXPECT_LT(linear.rms_px, 0.45);
  EXPECT_LT(linear.max_px, 1.2);
  // Measured along each tag's outward diagonal (4 views, 176 corners): +0.31 px in linear
  // light (the quads grow), -0.14 px in sRGB light (they shrink); the decoding moves the
  // corners outward by 0.45 px. On these 320x240 frames (tags ~20 px) linear light is not
  // the better one; on the full preset (640x480, 24 views, 3456 corners, measured once) it
  // is: linear +0.19 px, RMS 0.23 px; sRGB -0.46 px (the fixtures' 0.38), RMS 0.52 px.
  // Bounds: the linear bias stays within the scatter of real detections, and the tone
  // curve's shift is there (a detector that stopped decoding would fail).
  EXPECT_LT(std::abs(linear.outward_px), 0.45);
  EXPECT_GT(linear.outward_px - srgb.outward_px, 0.25);
}

TEST(CheckDetection, CatchesAWrongOrderDuplicatesAndBadIds) {
  core::Target target;
  const auto frames = SessionFrames(CachedSession(CalibrationSessionKind::kColourChessboard), target);
  const Detection good = DetectChessboard(frames[0].rgb, target);
  ASSERT_TRUE(good.accepted) << good.reason;
  EXPECT_GT(good.homography_rms_px, 0.0);

  Detection shuffled = good;
  std::mt19937 rng(3);
  std::shuffle(shuffled.corner_ids.begin(), shuffled.corner_ids.end(), rng);
  CheckDetection(target, 2.0, 8, shuffled);
  EXPECT_FALSE(shuffled.accepted);
  EXPECT_GT(shuffled.homography_rms_px, 5.0);
  EXPECT_NE(shuffled.reason.find("homography RMS"), std::string::npos) << shuffled.reason;

  // The 180° turn of the symmetric 5x7 board: the same corners, ids reversed, fit a
  // homography just as well — which is why the detector fixes the orientation.
  Detection turned = good;
  for (int& id : turned.corner_ids) id = 34 - id;
  CheckDetection(target, 2.0, 8, turned);
  EXPECT_TRUE(turned.accepted);

  Detection twice = good;
  twice.corner_ids[1] = twice.corner_ids[0];
  CheckDetection(target, 2.0, 8, twice);
  EXPECT_FALSE(twice.accepted);
  EXPECT_NE(twice.reason.find("twice"), std::string::npos) << twice.reason;

  Detection outside = good;
  outside.corner_ids[0] = 35;
  CheckDetection(target, 2.0, 8, outside);
  EXPECT_FALSE(outside.accepted);
  EXPECT_NE(outside.reason.find("outside"), std::string::npos) << outside.reason;

  Detection few = good;
  few.corner_ids.resize(5);
  few.pixels.resize(5);
  CheckDetection(target, 2.0, 8, few);
  EXPECT_FALSE(few.accepted);
  EXPECT_NE(few.reason.find("fewer"), std::string::npos) << few.reason;
}

TEST(Detectors, AnImageWithoutTheTargetIsRejectedWithAReason) {
  core::Target chessboard, aprilgrid;
  SessionFrames(CachedSession(CalibrationSessionKind::kColourChessboard), chessboard);
  const auto april_frames = SessionFrames(CachedSession(CalibrationSessionKind::kColourAprilGrid), aprilgrid);
  cv::Mat noise(240, 320, CV_8UC3);
  cv::randu(noise, 60, 200);
  cv::GaussianBlur(noise, noise, cv::Size(5, 5), 2.0);
  for (const cv::Mat& image : {noise, cv::Mat(240, 320, CV_8UC3, cv::Scalar::all(128))}) {
    const Detection c = DetectChessboard(image, chessboard, {}, "blank");
    EXPECT_FALSE(c.accepted);
    // "no chessboard found", or (noise) a few saddle points the partial search takes for a
    // piece of board that no board edge places.
    EXPECT_FALSE(c.reason.empty());
    const Detection a = DetectAprilGrid(image, aprilgrid, {}, "blank");
    EXPECT_FALSE(a.accepted);
    EXPECT_NE(a.reason.find("no tag"), std::string::npos) << a.reason;
    EXPECT_EQ(a.view, "blank");
    EXPECT_EQ(a.height_px, 240);
  }
  // The aprilgrid is no chessboard.
  EXPECT_FALSE(DetectChessboard(april_frames[0].rgb, chessboard).accepted);
}

// OpenCV's own sample views (package opencv-doc: left01..14.jpg, 9x6 inner corners, 13
// files, left10 missing): every view found, at the corners of findChessboardCorners +
// cornerSubPix. In two halves (first..last), each under 10 s: CALIB_CB_ACCURACY costs
// ~0.6 s per 640x480 image.
void CheckOpenCvSamples(int first, int last) {
  const fs::path dir = "/usr/share/doc/opencv-doc/examples/data";
  if (!fs::exists(dir / "left01.jpg")) GTEST_SKIP() << "opencv-doc is not installed";
  core::Target target;
  target.type = core::TargetType::kChessboard;
  target.rows = 6;
  target.cols = 9;
  target.square_m = 1.0;
  int files = 0, found = 0;
  double max_px = 0, sum2 = 0, ms = 0;
  int corners = 0;
  std::vector<double> errors;
  for (int i = first; i <= last; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "left%02d.jpg", i);
    const cv::Mat grey = cv::imread((dir / name).string(), cv::IMREAD_GRAYSCALE);
    if (grey.empty()) continue;
    ++files;
    const auto start = std::chrono::steady_clock::now();
    const Detection d = DetectChessboard(grey, target, {}, name);
    ms += std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    EXPECT_TRUE(d.accepted) << name << ": " << d.reason;
    if (!d.accepted) continue;
    ++found;
    std::vector<cv::Point2f> reference;
    EXPECT_TRUE(cv::findChessboardCorners(grey, cv::Size(9, 6), reference)) << name;
    cv::cornerSubPix(grey, reference, cv::Size(11, 11), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 0.01));
    // Matched by nearest neighbour: the classic detector's order is its own.
    double image_max = 0;
    for (size_t k = 0; k < d.pixels.size(); ++k) {
      double best = 1e9;
      for (const cv::Point2f& r : reference) {
        best = std::min(best, (d.pixels[k] - Eigen::Vector2d(r.x, r.y)).norm());
      }
      image_max = std::max(image_max, best);
      errors.push_back(best);
      sum2 += best * best;
      ++corners;
    }
    max_px = std::max(max_px, image_max);
    std::printf("  %s: max %.3f px from cornerSubPix, homography rms %.3f px\n", name, image_max,
                d.homography_rms_px);
  }
  std::sort(errors.begin(), errors.end());
  const double median = errors.empty() ? 0 : errors[errors.size() / 2];
  const double p90 = errors.empty() ? 0 : errors[errors.size() * 9 / 10];
  std::printf("opencv samples: %d of %d found, vs findChessboardCorners+cornerSubPix(11x11): median "
              "%.3f p90 %.3f rms %.3f max %.3f px, %.1f ms per image\n",
              found, files, median, p90, std::sqrt(sum2 / std::max(corners, 1)), max_px,
              ms / std::max(files, 1));
  // Measured over all 13: median 0.05 px, p90 0.125 px, max 7.6 px (left02). Not all
  // within 0.1 px: the classic pipeline's 11x11 window (the OpenCV sample's) reaches the
  // next corners of the far, small squares — cornerSubPix disagrees with itself there
  // (11x11 against 5x5 windows: up to 6.4 px on left02). Bounds: every view found, the
  // median within 0.1 px, and no wrong id (a square is ~30 px).
  EXPECT_EQ(found, files);
  EXPECT_LT(median, 0.1);
  EXPECT_LT(max_px, 10.0);
  EXPECT_GE(files, 6);
}
TEST(DetectChessboard, OpenCvSampleImages01To07) { CheckOpenCvSamples(1, 7); }
TEST(DetectChessboard, OpenCvSampleImages08To14) { CheckOpenCvSamples(8, 14); }

}  // namespace
}  // namespace hw::calibrate
