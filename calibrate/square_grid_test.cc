#include "calibrate/square_grid.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include "calibrate/synthetic_views.h"
#include "core/output_folder.h"
#include "core/scan.h"
#include "fixtures/calibration_sessions.h"
#include "fixtures/cached_test_data.h"
#include "fixtures/calibration_test_support.h"

namespace hw::calibrate {
namespace {

namespace fs = std::filesystem;
using fixtures::CalibrationSessionKind;
using fixtures::CalibrationSessionOptions;

// A session's thermal frames with the true pixels of every corner.
struct View {
  cv::Mat thermal_c;                   // CV_32F apparent °C
  std::vector<Eigen::Vector2d> truth;  // by corner id
};
struct Session {
  core::Target target;
  std::vector<View> views;
};

Session LoadSession(const std::string& name, bool small, int num_views) {
  auto preset =
      CalibrationSessionOptions::Preset(CalibrationSessionKind::kThermalSquareGrid, small);
  preset.thermal_square_grid.views.num_views = num_views;
  const fs::path dir = fixtures::test::CachedSession(name, preset, "thermal.txt");
  const core::Scan scan = core::Scan::Open(dir);
  const core::Rig truth = core::ReadRig(dir / "truth" / "rig.yaml");
  Session session;
  session.target = core::ReadTarget(dir / "target.yaml");
  for (int i = 0; i < scan.NumFrames(core::Stream::kThermal); ++i) {
    const auto frame =
        fixtures::calibration_test::ViewOfFrame(scan, truth, core::Stream::kThermal, i);
    session.views.push_back(
        {scan.LoadThermal(i), fixtures::calibration_test::ProjectCorners(
                                  frame.camera, frame.camera_from_world, session.target)});
  }
  return session;
}

struct Score {
  int accepted = 0, views = 0, corners = 0, corners_total = 0;
  double rms_px = 0, max_px = 0, ms_per_image = 0;
};

// Detection rate and corner errors against truth over a session's views.
Score Evaluate(const Session& session, const SquareGridOptions& options) {
  Score score;
  double sum2 = 0, ms = 0;
  for (const View& view : session.views) {
    const auto start = std::chrono::steady_clock::now();
    const Detection d = DetectSquareGrid(view.thermal_c, session.target, options, "view");
    ms +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    ++score.views;
    score.corners_total += static_cast<int>(view.truth.size());
    EXPECT_EQ(d.corner_ids.size(), d.pixels.size());
    if (!d.accepted) {
      std::printf("  rejected: %s\n", d.reason.c_str());
      continue;
    }
    ++score.accepted;
    for (size_t k = 0; k < d.corner_ids.size(); ++k) {
      const double e = (d.pixels[k] - view.truth[static_cast<size_t>(d.corner_ids[k])]).norm();
      sum2 += e * e;
      score.max_px = std::max(score.max_px, e);
      ++score.corners;
    }
  }
  score.rms_px = std::sqrt(sum2 / std::max(score.corners, 1));
  score.ms_per_image = ms / std::max(score.views, 1);
  return score;
}

void Print(const char* label, const Score& s) {
  std::printf("%s: %d/%d views, %d/%d corners, RMS %.3f px, max %.3f px, %.2f ms/image\n", label,
              s.accepted, s.views, s.corners, s.corners_total, s.rms_px, s.max_px, s.ms_per_image);
}

TEST(SquareGridOptions, CheckNamesTheField) {
  EXPECT_EQ(SquareGridOptions{}.Check(), "");
  SquareGridOptions o;
  o.max_homography_rms_px = 0;
  EXPECT_NE(o.Check().find("max_homography_rms_px"), std::string::npos);
  o = {};
  o.min_hole_area_px = 0.5;
  EXPECT_NE(o.Check().find("min_hole_area_px"), std::string::npos);
  o = {};
  o.edge_sigma_px = 0.1;
  EXPECT_NE(o.Check().find("edge_sigma_px"), std::string::npos);
}

// A mask drawn exactly: plate 1, background 0 plus `pedestal` x the plate's coverage blurred
// by 3 px and shifted 2 px right (the background heated by the plate and seen through the
// holes by parallax), integrated over each pixel (8 x 8 samples) and blurred by the optics'
// 0.8 px; 4 x 5 holes of 12 px at a pitch of 24 px, turned 7 degrees. Returns the mean
// outward shift of the found edges (px: the corners' displacement along the hole's diagonal
// over sqrt 2) and the corners' RMS error.
struct EdgeScore {
  double outward_px = 0, rms_px = 0;
};
EdgeScore DetectDrawnMask(double pedestal) {
  const core::Target target = test::SquareGridTarget(4, 5, 0.02, 0.04);
  constexpr int kSub = 8, kW = 200, kH = 160;
  constexpr double kPxPerM = 600, kAngle = 7 * M_PI / 180;
  const Eigen::Vector2d origin(45, 40);  // pixel of the target frame's origin (the first hole's TL)
  const Eigen::Matrix2d R = Eigen::Rotation2Dd(kAngle).toRotationMatrix();
  const auto to_pixel = [&](const Eigen::Vector2d& m) -> Eigen::Vector2d { return origin + kPxPerM * (R * m); };
  const auto to_target = [&](const Eigen::Vector2d& px) -> Eigen::Vector2d {
    return R.transpose() * (px - origin) / kPxPerM;
  };
  const double margin = 0.03;
  cv::Mat plate(kH * kSub, kW * kSub, CV_32F);
  for (int b = 0; b < plate.rows; ++b) {
    for (int a = 0; a < plate.cols; ++a) {
      const Eigen::Vector2d t = to_target({(a + 0.5) / kSub - 0.5, (b + 0.5) / kSub - 0.5});
      const double span_x = (target.cols - 1) * target.pitch_m + target.square_m;
      const double span_y = (target.rows - 1) * target.pitch_m + target.square_m;
      bool on_plate = t.x() > -margin && t.y() > -margin && t.x() < span_x + margin && t.y() < span_y + margin;
      const double fx = t.x() / target.pitch_m, fy = t.y() / target.pitch_m;
      const double cx = std::floor(fx), cy = std::floor(fy);
      if (cx >= 0 && cy >= 0 && cx < target.cols && cy < target.rows &&
          (fx - cx) * target.pitch_m < target.square_m && (fy - cy) * target.pitch_m < target.square_m)
        on_plate = false;
      plate.at<float>(b, a) = on_plate ? 1.0f : 0.0f;
    }
  }
  cv::Mat heated;
  cv::GaussianBlur(plate, heated, cv::Size(0, 0), 3.0 * kSub);
  const cv::Mat shift = (cv::Mat_<double>(2, 3) << 1, 0, 2.0 * kSub, 0, 1, 0);
  cv::warpAffine(heated, heated, shift, heated.size(), cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  cv::Mat scene = plate + (1.0f - plate).mul(heated * pedestal);
  cv::GaussianBlur(scene, scene, cv::Size(0, 0), 0.8 * kSub);
  cv::Mat image;
  cv::resize(scene, image, cv::Size(kW, kH), 0, 0, cv::INTER_AREA);

  const Detection d = DetectSquareGrid(image, target);
  EXPECT_TRUE(d.accepted) << d.reason;
  EXPECT_EQ(d.corner_ids.size(), static_cast<size_t>(4 * target.rows * target.cols));
  const std::vector<Eigen::Vector3d> corners = core::TargetCorners(target);
  EdgeScore score;
  double sum2 = 0;
  for (size_t k = 0; k < d.corner_ids.size(); ++k) {
    const int id = d.corner_ids[k];
    const Eigen::Vector2d truth = to_pixel(corners[static_cast<size_t>(id)].head<2>());
    Eigen::Vector2d centre = Eigen::Vector2d::Zero();
    for (int j = 0; j < 4; ++j) centre += 0.25 * corners[static_cast<size_t>(id / 4 * 4 + j)].head<2>();
    const Eigen::Vector2d outward = (truth - to_pixel(centre)).normalized();
    const Eigen::Vector2d error = d.pixels[k] - truth;
    score.outward_px += error.dot(outward) / std::sqrt(2.0) / static_cast<double>(d.corner_ids.size());
    sum2 += error.squaredNorm();
  }
  score.rms_px = std::sqrt(sum2 / std::max<size_t>(d.corner_ids.size(), 1));
  std::printf("drawn mask, pedestal %.2f: edges moved outwards by %+.4f px on average, corner RMS %.4f px\n",
              pedestal, score.outward_px, score.rms_px);
  return score;
}

// The edge locator finds the step, not the level between the plate and whatever the
// profile's ends see. Measured: a clean mask 0.0001 px outwards, corner RMS 0.013 px;
// background heated up to 30 % of the contrast and seen shifted through the holes −0.051 px
// (into the holes), RMS 0.077 px. The mid-level crossing used before: 0.0004 / 0.049 px and
// −0.088 / 0.142 px. Bounds between the two, so the old locator's bias fails them.
TEST(SquareGridEdges, HeatedBackgroundBesideTheHolesMovesTheEdgesLittle) {
  const EdgeScore clean = DetectDrawnMask(0.0), heated = DetectDrawnMask(0.3);
  EXPECT_LT(std::abs(clean.outward_px), 0.01);
  EXPECT_LT(clean.rms_px, 0.03);
  EXPECT_LT(std::abs(heated.outward_px), 0.07);
  EXPECT_LT(heated.rms_px, 0.11);
}

// The small session (160x120 thermal, 3x4 holes), more views than the preset's 4 so that
// every cell of TargetViewPoses (corners, edges, centre) is covered.
TEST(SquareGridSession, SmallSessionDetectedAndRefinementHelps) {
  const Session session = LoadSession("square-grid-small", true, 9);
  SquareGridOptions refined, raw;
  raw.refine = false;
  const Score with = Evaluate(session, refined), without = Evaluate(session, raw);
  Print("small, refined", with);
  Print("small, not refined", without);
  EXPECT_EQ(with.accepted, with.views);
  EXPECT_EQ(with.corners, with.corners_total);
  // Measured (9 views, holes of 5-20 px): refined RMS 0.27 px, max 0.55 px (the mid-level
  // crossing used before: 0.28 / 0.65 px, the gradient peak at 1.0 / 1.5 px: 0.29 / 0.42); not refined
  // (lines through the thresholded contour) RMS 0.76 px, max 1.88 px. Bounds: real
  // detections on blurred 160x120 frames scatter by a few tenths of a pixel.
  EXPECT_LT(with.rms_px, 0.4);
  EXPECT_LT(with.max_px, 1.0);
  EXPECT_LT(with.rms_px, without.rms_px);
}

// The full-size session (320x240 thermal, 5x7 holes, the preset's 24 views). Its first run
// renders the session (~65 s on 2 cores), later runs reuse it (< 1 s): too slow for the
// suite, run on demand (README): build/calibrate/calibrate_square_grid_test
// --gtest_also_run_disabled_tests --gtest_filter='*FullSession*'.
TEST(SquareGridSession, DISABLED_FullSessionDetectedAndRefinementHelps) {
  const auto preset =
      CalibrationSessionOptions::Preset(CalibrationSessionKind::kThermalSquareGrid, false);
  const Session session =
      LoadSession("square-grid-full", false, preset.thermal_square_grid.views.num_views);
  SquareGridOptions refined, raw;
  raw.refine = false;
  const Score with = Evaluate(session, refined), without = Evaluate(session, raw);
  Print("full, refined", with);
  Print("full, not refined", without);
  // Measured: refined RMS 0.21 px, max 0.46 px (the mid-level crossing used before: 0.31 /
  // 0.64 px); not refined RMS 0.65 px, max 3.0 px.
  EXPECT_EQ(with.accepted, with.views);
  EXPECT_EQ(with.corners, with.corners_total);
  EXPECT_LT(with.rms_px, 0.4);
  EXPECT_LT(with.max_px, 1.0);
  EXPECT_LT(with.rms_px, without.rms_px);
}

// Every corner of an accepted detection within `tolerance_px` of its id's true pixel: less
// than half a hole's side, so a hole given another hole's id fails.
void ExpectOrdered(const Detection& d, const View& view, double tolerance_px,
                   const std::string& what) {
  ASSERT_TRUE(d.accepted) << what << ": " << d.reason;
  double worst = 0;
  for (size_t k = 0; k < d.corner_ids.size(); ++k) {
    worst =
        std::max(worst, (d.pixels[k] - view.truth[static_cast<size_t>(d.corner_ids[k])]).norm());
  }
  std::printf("%s: %zu corners, worst %.2f px, homography RMS %.2f px\n", what.c_str(),
              d.corner_ids.size(), worst, d.homography_rms_px);
  EXPECT_LT(worst, tolerance_px) << what;
}

// One session frame (the centre view: holes of ~10 px) altered as real frames are.
TEST(SquareGridRobustness, PolarityDepthContrastAndOcclusion) {
  const Session session = LoadSession("square-grid-small", true, 9);
  const View& view = session.views[4];
  const int holes = session.target.rows * session.target.cols;
  const auto hole_size_px = [&](const Detection& d) {
    return (d.pixels[2] - d.pixels[0]).norm() / std::sqrt(2.0);
  };
  const Detection plain = DetectSquareGrid(view.thermal_c, session.target);
  ExpectOrdered(plain, view, 1.5, "as rendered");
  ASSERT_EQ(static_cast<int>(plain.corner_ids.size()), 4 * holes);
  const double tolerance = 0.5 * hole_size_px(plain);

  // The homography check: lens distortion and corner scatter leave 0.24 px here.
  SquareGridOptions strict;
  strict.max_homography_rms_px = 0.05;
  const Detection too_strict = DetectSquareGrid(view.thermal_c, session.target, strict);
  EXPECT_FALSE(too_strict.accepted);
  EXPECT_NE(too_strict.reason.find("max_homography_rms_px"), std::string::npos)
      << too_strict.reason;
  EXPECT_EQ(too_strict.pixels, plain.pixels);  // the corners are still returned
  EXPECT_NEAR(too_strict.homography_rms_px, plain.homography_rms_px, 1e-12);

  // Inverted polarity (holes warmer than the plate).
  ExpectOrdered(DetectSquareGrid(-view.thermal_c, session.target), view, 1.5, "negated");

  // 16-bit raw counts with their own offset and gain.
  cv::Mat raw;
  view.thermal_c.convertTo(raw, CV_16U, 40.0, 12000.0);
  ExpectOrdered(DetectSquareGrid(raw, session.target), view, 1.5, "16-bit counts");

  // 4 % of the contrast (1 K), vignetting (+3 K towards the corners), noise of 0.05 K.
  cv::Mat low(view.thermal_c.size(), CV_32F);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  const double cx = 0.5 * (low.cols - 1), cy = 0.5 * (low.rows - 1);
  for (int y = 0; y < low.rows; ++y) {
    for (int x = 0; x < low.cols; ++x) {
      const double r2 = ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (cx * cx + cy * cy);
      low.at<float>(y, x) =
          static_cast<float>(0.04 * static_cast<double>(view.thermal_c.at<float>(y, x)) +
                             3.0 * r2) +
          noise(rng);
    }
  }
  ExpectOrdered(DetectSquareGrid(low, session.target), view, tolerance,
                "low contrast, vignetting, noise");

  // A hand (34 °C) over the top-left hole: the other 11 are placed in the grid.
  cv::Mat hand = view.thermal_c.clone();
  const Eigen::Vector2d tl_centre = 0.5 * (view.truth[0] + view.truth[2]);
  cv::circle(hand, cv::Point(static_cast<int>(tl_centre.x()), static_cast<int>(tl_centre.y())),
             static_cast<int>(hole_size_px(plain)), cv::Scalar(34.0), cv::FILLED);
  const Detection occluded = DetectSquareGrid(hand, session.target);
  ExpectOrdered(occluded, view, tolerance, "top-left hole hidden");
  EXPECT_EQ(static_cast<int>(occluded.corner_ids.size()), 4 * (holes - 1));
  EXPECT_EQ(std::count(occluded.corner_ids.begin(), occluded.corner_ids.end(), 0), 0);

  // The whole left column hidden: the 3 columns left fit two places of the grid, but only
  // one leaves no hole on the plate's right margin.
  cv::Mat column = view.thermal_c.clone();
  std::vector<cv::Point> left;
  const int last_row = session.target.rows - 1;
  for (const Eigen::Vector2d& p :
       {view.truth[0], view.truth[3 + 4 * session.target.cols * last_row],
        view.truth[2 + 4 * session.target.cols * last_row], view.truth[1]}) {
    left.emplace_back(static_cast<int>(p.x()), static_cast<int>(p.y()));
  }
  cv::Mat mask = cv::Mat::zeros(column.size(), CV_8U);
  cv::fillConvexPoly(mask, left, cv::Scalar(255));
  cv::dilate(mask, mask, cv::Mat(), cv::Point(-1, -1), 3);
  column.setTo(cv::Scalar(34.0), mask);
  const Detection no_column = DetectSquareGrid(column, session.target);
  std::printf("left column hidden: accepted %d, %zu corners, reason '%s'\n", no_column.accepted,
              no_column.corner_ids.size(), no_column.reason.c_str());
  ExpectOrdered(no_column, view, tolerance, "left column hidden");
  EXPECT_EQ(static_cast<int>(no_column.corner_ids.size()), 4 * (holes - session.target.rows));

  // ... and the right margin hidden too: nothing tells the two places apart, so no guess.
  const int cols = session.target.cols;
  const Eigen::Vector2d top_right = view.truth[4 * (cols - 1) + 1];
  const Eigen::Vector2d bottom_right = view.truth[4 * (cols * last_row + cols - 1) + 2];
  const std::vector<cv::Point> right = {
      cv::Point(static_cast<int>(top_right.x()) + 3, 0), cv::Point(column.cols - 1, 0),
      cv::Point(column.cols - 1, column.rows - 1),
      cv::Point(static_cast<int>(bottom_right.x()) + 3, column.rows - 1)};
  cv::fillConvexPoly(column, right, cv::Scalar(34.0));
  const Detection ambiguous = DetectSquareGrid(column, session.target);
  EXPECT_FALSE(ambiguous.accepted);
  EXPECT_NE(ambiguous.reason.find("several places"), std::string::npos) << ambiguous.reason;
}

// No target: smooth clutter and a few lone squares of several sizes.
TEST(SquareGridRobustness, NoTargetIsRejectedWithAReason) {
  const core::Target target = test::SquareGridTarget(3, 4, 0.04, 0.065);
  cv::Mat clutter(120, 160, CV_32F);
  cv::randu(clutter, 15.0, 30.0);
  cv::GaussianBlur(clutter, clutter, cv::Size(0, 0), 6.0);
  cv::rectangle(clutter, cv::Rect(20, 20, 12, 12), cv::Scalar(40.0), cv::FILLED);
  cv::rectangle(clutter, cv::Rect(90, 30, 25, 25), cv::Scalar(10.0), cv::FILLED);
  cv::rectangle(clutter, cv::Rect(60, 80, 8, 8), cv::Scalar(40.0), cv::FILLED);
  const Detection d = DetectSquareGrid(clutter, target, {}, "clutter");
  std::printf("clutter: accepted %d, reason '%s'\n", d.accepted, d.reason.c_str());
  EXPECT_FALSE(d.accepted);
  EXPECT_FALSE(d.reason.empty());
  EXPECT_EQ(d.view, "clutter");
  EXPECT_EQ(d.width_px, 160);

  cv::Mat flat(120, 160, CV_16U, cv::Scalar(30000));
  const Detection f = DetectSquareGrid(flat, target);
  EXPECT_FALSE(f.accepted);
  EXPECT_FALSE(f.reason.empty());

  core::Target board = target;
  board.type = core::TargetType::kChessboard;
  board.pitch_m = 0;
  EXPECT_THROW(DetectSquareGrid(clutter, board), std::invalid_argument);
  EXPECT_THROW(DetectSquareGrid(cv::Mat(10, 10, CV_8UC3), target), std::invalid_argument);
}

}  // namespace
}  // namespace hw::calibrate
