#include "calibrate/square_grid.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <queue>
#include <stdexcept>
#include <utility>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/option_check.h"

namespace hw::calibrate {
namespace {

using Quad = std::array<cv::Point2d, 4>;

// A square blob: its corners (TL TR BR BL once oriented), centre, grid axes.
struct Hole {
  Quad corners;
  cv::Point2d centre;
  cv::Point2d u, v;  // one hole side along the target's x and y, pixels
  double area = 0;
  std::vector<cv::Point> contour;
};

double Cross(const cv::Point2d& a, const cv::Point2d& b) { return a.x * b.y - a.y * b.x; }

// The image as float in [0, 1] between its 1st and 99th percentiles (robust to the raw
// range of 16-bit counts and to a few hot or dead pixels).
cv::Mat Normalised(const cv::Mat& image) {
  cv::Mat f;
  image.convertTo(f, CV_32F);
  std::vector<float> values;
  values.reserve(f.total() / 4 + 1);
  for (int y = 0; y < f.rows; y += 2) {
    for (int x = 0; x < f.cols; x += 2) values.push_back(f.at<float>(y, x));
  }
  const auto percentile = [&](double q) {
    auto it = values.begin() + static_cast<long>(q * static_cast<double>(values.size() - 1));
    std::nth_element(values.begin(), it, values.end());
    return static_cast<double>(*it);
  };
  const double lo = percentile(0.01), hi = percentile(0.99);
  const double scale = hi > lo ? 1.0 / (hi - lo) : 1.0;
  f.convertTo(f, CV_32F, scale, -lo * scale);
  return f;
}

// Orders a quad's corners as TL TR BR BL in the orientation rule of the header and sets
// the hole's axes.
void Orient(Hole& h) {
  const Quad& q = h.corners;
  const cv::Point2d a = 0.5 * ((q[1] - q[0]) + (q[2] - q[3]));
  const cv::Point2d b = 0.5 * ((q[2] - q[1]) + (q[3] - q[0]));
  const std::array<cv::Point2d, 4> candidates = {a, -a, b, -b};
  int best = 0;
  for (int k = 1; k < 4; ++k) {
    const auto rightness = [&](int i) {
      return candidates[i].x / std::max(1e-9, cv::norm(candidates[i]));
    };
    if (rightness(k) > rightness(best)) best = k;
  }
  h.u = candidates[best];
  h.v = best < 2 ? b : a;
  if (h.v.y < 0) h.v = -h.v;
  // TL minimises the coordinate along u + v etc., in the dual basis of (u, v).
  const double det = Cross(h.u, h.v);
  Quad ordered;
  const std::array<std::pair<int, int>, 4> signs = {{{-1, -1}, {1, -1}, {1, 1}, {-1, 1}}};
  for (int k = 0; k < 4; ++k) {
    double best_score = -1e18;
    for (const cv::Point2d& p : q) {
      const cv::Point2d d = p - h.centre;
      const double s = Cross(d, h.v) / det, t = Cross(h.u, d) / det;
      const double score = signs[k].first * s + signs[k].second * t;
      if (score > best_score) {
        best_score = score;
        ordered[k] = p;
      }
    }
  }
  h.corners = ordered;
}

// Lines through the contour pixels of each side (pixels within 15 % of the side's length
// of a corner left out), shifted half a pixel outwards (the contour runs through the
// boundary pixels inside the blob), intersected. Keeps the polygon's corners on failure.
void FitContourLines(Hole& h) {
  std::array<std::vector<cv::Point2f>, 4> side_points;
  for (const cv::Point& p : h.contour) {
    const cv::Point2d pd(p.x, p.y);
    int best = -1;
    double best_d = 1e18;
    for (int k = 0; k < 4; ++k) {
      const cv::Point2d a = h.corners[k], b = h.corners[(k + 1) % 4];
      const cv::Point2d ab = b - a;
      const double len2 = ab.dot(ab);
      const double t = (pd - a).dot(ab) / len2;
      if (t < 0.15 || t > 0.85) continue;
      const double d = std::abs(Cross(ab, pd - a)) / std::sqrt(len2);
      if (d < best_d) {
        best_d = d;
        best = k;
      }
    }
    if (best >= 0 && best_d < 2.0)
      side_points[best].push_back(cv::Point2f(static_cast<float>(p.x), static_cast<float>(p.y)));
  }
  std::array<cv::Point2d, 4> point, dir;
  for (int k = 0; k < 4; ++k) {
    if (side_points[k].size() < 2) return;
    cv::Vec4f line;
    cv::fitLine(side_points[k], line, cv::DIST_L2, 0, 0.01, 0.01);
    dir[k] = cv::Point2d(line[0], line[1]);
    point[k] = cv::Point2d(line[2], line[3]);
    cv::Point2d normal(dir[k].y, -dir[k].x);
    if (normal.dot(point[k] - h.centre) < 0) normal = -normal;
    point[k] += 0.5 * normal;
  }
  Quad out;
  for (int k = 0; k < 4; ++k) {
    // Corner k is where side k-1 (ending at it) meets side k (starting at it).
    if (!IntersectLines(point[(k + 3) % 4], dir[(k + 3) % 4], point[k], dir[k], &out[k])) return;
    if (cv::norm(out[k] - h.corners[k]) > 3.0) return;
  }
  h.corners = out;
}

// The hole's corners refined on its sides' profiles (edge_profiles.h); false when that failed.
bool RefineWithProfiles(const cv::Mat& f, const SquareGridOptions& options, Hole& h) {
  EdgeProfileOptions edges;
  edges.edge = options.edge;
  edges.edge_sigma_px = options.edge_sigma_px;
  return RefineSquareCorners(f, edges, h.centre, h.corners);
}

// Square blobs of one polarity (holes brighter than their surroundings when `bright`)
// thresholded against the local mean over windows of a few sizes; duplicates (same centre
// within a third of the side) kept once.
std::vector<Hole> FindHoles(const cv::Mat& f, bool bright, const SquareGridOptions& options) {
  std::vector<Hole> holes;
  const int min_side = std::min(f.cols, f.rows);
  for (const int divisor : {3, 6, 12}) {
    const int window = std::max(7, min_side / divisor) | 1;
    cv::Mat mean;
    cv::blur(f, mean, cv::Size(window, window), cv::Point(-1, -1), cv::BORDER_REPLICATE);
    cv::Mat binary = bright ? (f > mean + 0.02) : (f < mean - 0.02);
    std::vector<std::vector<cv::Point>> contours;
    std::vector<cv::Vec4i> hierarchy;
    // Outer boundaries only (no parent in the two-level hierarchy): a hole's inner boundary
    // traced on the plate's pixels would sit a pixel outside the hole.
    cv::findContours(binary, contours, hierarchy, cv::RETR_CCOMP, cv::CHAIN_APPROX_NONE);
    for (size_t ci = 0; ci < contours.size(); ++ci) {
      if (hierarchy[ci][3] >= 0) continue;
      std::vector<cv::Point>& contour = contours[ci];
      const double area = cv::contourArea(contour);
      if (area < options.min_hole_area_px || area > 0.25 * static_cast<double>(f.total())) continue;
      const cv::Rect box = cv::boundingRect(contour);
      if (box.x <= 1 || box.y <= 1 || box.br().x >= f.cols - 1 || box.br().y >= f.rows - 1)
        continue;
      std::vector<cv::Point> hull;
      cv::convexHull(contour, hull);
      if (area < 0.8 * cv::contourArea(hull)) continue;
      const double perimeter = cv::arcLength(hull, true);
      std::vector<cv::Point> poly;
      for (double eps = 0.03; eps <= 0.12 && poly.size() != 4; eps += 0.015) {
        cv::approxPolyDP(hull, poly, eps * perimeter, true);
      }
      if (poly.size() != 4 || !cv::isContourConvex(poly)) continue;
      // A quadrilateral, not a disc or a blob that four of its points happen to outline.
      // Most of the outline lies on the polygon's sides (a disc's arcs bulge away from its
      // chords; a blurred square only rounds its corners).
      int on_sides = 0;
      for (const cv::Point& q : contour)
        on_sides +=
            std::abs(cv::pointPolygonTest(
                poly, cv::Point2f(static_cast<float>(q.x), static_cast<float>(q.y)), true)) <= 1.0;
      if (on_sides < 0.6 * static_cast<double>(contour.size())) continue;
      Hole h;
      for (int k = 0; k < 4; ++k) h.corners[k] = cv::Point2d(poly[k].x, poly[k].y);
      // Squares seen in perspective: opposite sides of comparable length.
      const auto side = [&](int k) { return cv::norm(h.corners[(k + 1) % 4] - h.corners[k]); };
      if (std::min(side(0), side(2)) < 0.4 * std::max(side(0), side(2)) ||
          std::min(side(1), side(3)) < 0.4 * std::max(side(1), side(3))) {
        continue;
      }
      h.area = area;
      h.centre = 0.25 * (h.corners[0] + h.corners[1] + h.corners[2] + h.corners[3]);
      h.contour = std::move(contour);
      Orient(h);
      FitContourLines(h);
      h.centre = 0.25 * (h.corners[0] + h.corners[1] + h.corners[2] + h.corners[3]);
      Orient(h);
      bool duplicate = false;
      for (const Hole& other : holes) {
        duplicate |= cv::norm(other.centre - h.centre) < 0.33 * std::sqrt(other.area);
      }
      if (!duplicate) holes.push_back(std::move(h));
    }
  }
  return holes;
}

// Grid coordinates (column, row) of the holes connected to holes[seed] through
// neighbours one pitch apart along their own axes (perspective varies slowly).
std::map<int, std::pair<int, int>> GrowGrid(const std::vector<Hole>& holes, int seed,
                                            double pitch_over_side) {
  std::map<int, std::pair<int, int>> cell{{seed, {0, 0}}};
  std::map<std::pair<int, int>, int> taken{{{0, 0}, seed}};
  std::queue<int> todo;
  todo.push(seed);
  while (!todo.empty()) {
    const int i = todo.front();
    todo.pop();
    for (int j = 0; j < static_cast<int>(holes.size()); ++j) {
      if (cell.count(j)) continue;
      const double ratio = holes[i].area / holes[j].area;
      if (ratio < 0.4 || ratio > 2.5) continue;
      const cv::Point2d U = 0.5 * (holes[i].u + holes[j].u) * pitch_over_side;
      const cv::Point2d V = 0.5 * (holes[i].v + holes[j].v) * pitch_over_side;
      const cv::Point2d d = holes[j].centre - holes[i].centre;
      const double det = Cross(U, V);
      if (std::abs(det) < 1e-9) continue;
      const double a = Cross(d, V) / det, b = Cross(U, d) / det;
      const double ra = std::round(a), rb = std::round(b);
      if (std::abs(a - ra) > 0.3 || std::abs(b - rb) > 0.3) continue;
      if (std::abs(ra) > 1 || std::abs(rb) > 1 || (ra == 0 && rb == 0)) continue;
      const std::pair<int, int> c = {cell[i].first + static_cast<int>(ra),
                                     cell[i].second + static_cast<int>(rb)};
      if (taken.count(c)) continue;
      cell[j] = c;
      taken[c] = j;
      todo.push(j);
    }
  }
  return cell;
}

}  // namespace

std::string SquareGridOptions::Check() const {
  if (!(max_homography_rms_px > 0 && max_homography_rms_px <= 50)) {
    return core::OptionFail("max_homography_rms_px", max_homography_rms_px, "in (0, 50]");
  }
  if (!core::InRange(min_hole_area_px, 1, 1e6)) {
    return core::OptionFail("min_hole_area_px", min_hole_area_px, "in [1, 1e6]");
  }
  if (!core::InRange(edge_sigma_px, 0.3, 3)) {
    return core::OptionFail("edge_sigma_px", edge_sigma_px, "in [0.3, 3]");
  }
  return "";
}

Detection DetectSquareGrid(const cv::Mat& image, const core::Target& target,
                           const SquareGridOptions& options, const std::string& view_name) {
  if (target.type != core::TargetType::kSquareGrid || !target.Check().empty()) {
    throw std::invalid_argument("DetectSquareGrid: the target is not a valid square_grid");
  }
  if (image.empty() || image.channels() != 1) {
    throw std::invalid_argument("DetectSquareGrid: the image must be non-empty and single-channel");
  }
  if (const std::string message = options.Check(); !message.empty()) {
    throw std::invalid_argument("DetectSquareGrid: " + message);
  }
  Detection detection;
  detection.view = view_name;
  detection.width_px = image.cols;
  detection.height_px = image.rows;
  const cv::Mat f = Normalised(image);
  const double p = target.pitch_m, s = target.square_m;
  const int holes_total = target.rows * target.cols;

  // Per polarity: the largest lattice of holes; the polarity with more holes wins.
  struct Candidate {
    std::vector<Hole> holes;
    std::map<int, std::pair<int, int>> cell;
  };
  Candidate best;
  for (const bool bright : {true, false}) {
    Candidate c;
    c.holes = FindHoles(f, bright, options);
    for (int seed = 0; seed < static_cast<int>(c.holes.size()); ++seed) {
      auto cell = GrowGrid(c.holes, seed, p / s);
      if (cell.size() > c.cell.size()) c.cell = std::move(cell);
      if (static_cast<int>(c.cell.size()) >= holes_total) break;
    }
    if (c.cell.size() > best.cell.size()) best = std::move(c);
  }
  if (best.cell.empty()) {
    detection.reason = "no square holes found";
    return detection;
  }
  // A blob beside the target can join the lattice: keep the target-sized window of
  // lattice cells that holds the most holes.
  {
    int lo_c = 1 << 30, lo_r = 1 << 30, hi_c = -(1 << 30), hi_r = -(1 << 30);
    for (const auto& [i, c] : best.cell) {
      lo_c = std::min(lo_c, c.first);
      hi_c = std::max(hi_c, c.first);
      lo_r = std::min(lo_r, c.second);
      hi_r = std::max(hi_r, c.second);
    }
    int best_count = -1, best_c = lo_c, best_r = lo_r;
    for (int c0 = lo_c; c0 <= std::max(lo_c, hi_c - target.cols + 1); ++c0) {
      for (int r0 = lo_r; r0 <= std::max(lo_r, hi_r - target.rows + 1); ++r0) {
        int count = 0;
        for (const auto& [i, c] : best.cell) {
          count += c.first >= c0 && c.first < c0 + target.cols && c.second >= r0 &&
                   c.second < r0 + target.rows;
        }
        if (count > best_count) {
          best_count = count;
          best_c = c0;
          best_r = r0;
        }
      }
    }
    std::erase_if(best.cell, [&](const auto& entry) {
      const auto& c = entry.second;
      return c.first < best_c || c.first >= best_c + target.cols || c.second < best_r ||
             c.second >= best_r + target.rows;
    });
  }
  int min_c = 1 << 30, max_c = -(1 << 30), min_r = 1 << 30, max_r = -(1 << 30);
  for (const auto& [i, c] : best.cell) {
    min_c = std::min(min_c, c.first);
    max_c = std::max(max_c, c.first);
    min_r = std::min(min_r, c.second);
    max_r = std::max(max_r, c.second);
  }
  const int span_c = max_c - min_c + 1, span_r = max_r - min_r + 1;
  if (span_c > target.cols || span_r > target.rows) {
    detection.reason = "the holes found span " + std::to_string(span_r) + " rows x " +
                       std::to_string(span_c) + " columns, more than the target's " +
                       std::to_string(target.rows) + " x " + std::to_string(target.cols) +
                       " (rolled by more than 45 degrees, or not this target)";
    return detection;
  }

  // Homography from the lattice's corners (target plane, offset 0) to the image.
  const auto corner_in_target = [&](int col, int row, int k) {
    const double x = col * p + ((k == 1 || k == 2) ? s : 0.0);
    const double y = row * p + ((k == 2 || k == 3) ? s : 0.0);
    return cv::Point2d(x, y);
  };
  std::vector<cv::Point2d> plane, pixels;
  for (const auto& [i, c] : best.cell) {
    for (int k = 0; k < 4; ++k) {
      plane.push_back(corner_in_target(c.first - min_c, c.second - min_r, k));
      pixels.push_back(best.holes[i].corners[k]);
    }
  }
  const cv::Mat H = cv::findHomography(plane, pixels, 0);
  if (H.empty()) {
    detection.reason = "no homography through the holes found";
    return detection;
  }
  const auto project = [&](const cv::Point2d& xy) {
    std::vector<cv::Point2d> in{xy}, out;
    cv::perspectiveTransform(in, out, H);
    return out[0];
  };
  // Levels of the holes and the plate (bar between two holes), for telling plate apart.
  std::vector<double> hole_levels, plate_levels;
  for (const auto& [i, c] : best.cell) {
    const cv::Point2d centre =
        project(corner_in_target(c.first - min_c, c.second - min_r, 0) + cv::Point2d(s / 2, s / 2));
    hole_levels.push_back(SampleBilinear(f, centre.x, centre.y));
    const cv::Point2d bar = project(corner_in_target(c.first - min_c, c.second - min_r, 0) +
                                    cv::Point2d(s + (p - s) / 2, s / 2));
    plate_levels.push_back(SampleBilinear(f, bar.x, bar.y));
  }
  const auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  const double hole_level = median(hole_levels), plate_level = median(plate_levels);
  // A blob that joined the lattice but is no hole (a warm hand over one, a reflection):
  // its middle is not at the holes' level, or its corners are off the lattice.
  std::erase_if(best.cell, [&](const auto& entry) {
    const Hole& h = best.holes[entry.first];
    const double rel =
        (SampleBilinear(f, h.centre.x, h.centre.y) - hole_level) / (plate_level - hole_level);
    const int col = entry.second.first - min_c, row = entry.second.second - min_r;
    const double pitch_px = cv::norm(project(corner_in_target(col + 1, row, 0)) -
                                     project(corner_in_target(col, row, 0)));
    double worst = 0;
    for (int k = 0; k < 4; ++k)
      worst = std::max(worst, cv::norm(h.corners[k] - project(corner_in_target(col, row, k))));
    return rel > 0.35 || worst > 0.15 * pitch_px;
  });
  if (best.cell.empty()) {
    detection.reason = "no square holes found";
    return detection;
  }

  // Place the lattice in the grid. A predicted hole is seen as a hole when its middle is
  // at the holes' level and the bars around it at the plate's, as plate when both are at
  // the plate's or a fifth of it is at the plate's (then the placement is wrong), else as
  // hidden. A placement scores one per
  // hole seen beyond the lattice (then taken from the candidates, or located from its
  // predicted corners by the profile refinement) and loses two per plate seen.
  const double contrast = plate_level - hole_level;
  const auto mean_level = [&](const std::vector<cv::Point2d>& plane_points) {
    std::vector<cv::Point2d> image_points;
    cv::perspectiveTransform(plane_points, image_points, H);
    double sum = 0;
    int n = 0;
    for (const cv::Point2d& q : image_points) {
      if (q.x < 0 || q.y < 0 || q.x > f.cols - 1 || q.y > f.rows - 1) return std::nan("");
      sum += SampleBilinear(f, q.x, q.y);
      ++n;
    }
    return (sum / n - hole_level) / contrast;  // 0: hole level, 1: plate level
  };
  struct Placement {
    int off_c = 0, off_r = 0, score = 0;
    std::map<int, Hole> recovered;  // hole id -> hole
  };
  std::vector<Placement> placements;
  const double bar = 0.5 * (p - s);
  for (int oc = 0; oc + span_c <= target.cols; ++oc) {
    for (int orow = 0; orow + span_r <= target.rows; ++orow) {
      Placement pl{oc, orow, 0, {}};
      for (int r = 0; r < target.rows; ++r) {
        for (int c = 0; c < target.cols; ++c) {
          const int lc = c - oc + min_c, lr = r - orow + min_r;  // lattice coordinates
          bool found = false;
          for (const auto& [i, cc] : best.cell) found |= cc.first == lc && cc.second == lr;
          if (found) continue;
          const cv::Point2d o = corner_in_target(lc - min_c, lr - min_r, 0);
          std::vector<cv::Point2d> inner, ring;
          for (int a = 0; a < 3; ++a) {
            for (int b = 0; b < 3; ++b)
              inner.push_back(o + cv::Point2d((0.3 + 0.2 * a) * s, (0.3 + 0.2 * b) * s));
            const double t = (0.3 + 0.2 * a) * s;
            ring.push_back(o + cv::Point2d(-bar, t));
            ring.push_back(o + cv::Point2d(s + bar, t));
            ring.push_back(o + cv::Point2d(t, -bar));
            ring.push_back(o + cv::Point2d(t, s + bar));
          }
          // Plate over a fifth of the predicted hole (a row or column of the samples): the
          // grid's edge (its plate margin, wider than a bar) where the placement puts a hole.
          std::vector<cv::Point2d> spread, spread_px;
          for (int a = 0; a < 5; ++a) {
            for (int b = 0; b < 5; ++b) {
              spread.push_back(o + cv::Point2d((0.2 + 0.15 * a) * s, (0.2 + 0.15 * b) * s));
            }
          }
          cv::perspectiveTransform(spread, spread_px, H);
          int plate_points = 0;
          for (const cv::Point2d& q : spread_px) {
            if (q.x < 0 || q.y < 0 || q.x > f.cols - 1 || q.y > f.rows - 1) continue;
            plate_points += (SampleBilinear(f, q.x, q.y) - hole_level) / contrast > 0.75;
          }
          if (5 * plate_points >= static_cast<int>(spread.size())) {
            pl.score -= 2;
            continue;
          }
          const double inner_rel = mean_level(inner), ring_rel = mean_level(ring);
          if (std::isnan(inner_rel) || std::isnan(ring_rel) || ring_rel < 0.65) continue;
          if (inner_rel > 0.65) {
            pl.score -= 2;
            continue;
          }
          if (inner_rel > 0.35) continue;
          ++pl.score;
          Hole predicted;
          for (int k = 0; k < 4; ++k)
            predicted.corners[k] = project(corner_in_target(lc - min_c, lr - min_r, k));
          predicted.centre = project(o + cv::Point2d(s / 2, s / 2));
          const double pitch_px = cv::norm(project(o + cv::Point2d(p, 0)) - project(o));
          const Hole* candidate = nullptr;
          for (int j = 0; j < static_cast<int>(best.holes.size()) && !candidate; ++j) {
            if (best.cell.count(j)) continue;
            bool near = true;
            for (int k = 0; k < 4; ++k)
              near &= cv::norm(best.holes[j].corners[k] - predicted.corners[k]) < 0.2 * pitch_px;
            if (near) candidate = &best.holes[j];
          }
          if (candidate) {
            pl.recovered[r * target.cols + c] = *candidate;
          } else if (RefineWithProfiles(f, options, predicted) && RefineWithProfiles(f, options, predicted)) {
            pl.recovered[r * target.cols + c] = predicted;
          }
        }
      }
      placements.push_back(std::move(pl));
    }
  }
  std::sort(placements.begin(), placements.end(),
            [](const Placement& a, const Placement& b) { return a.score > b.score; });
  if (placements.size() > 1 && placements[0].score == placements[1].score) {
    detection.reason = 2 * static_cast<int>(best.cell.size()) < holes_total
                           ? "found " + std::to_string(best.cell.size()) + " of " +
                                 std::to_string(holes_total) + " holes, fewer than half"
                           : "the holes found (" + std::to_string(span_r) + " rows x " +
                                 std::to_string(span_c) +
                                 " columns) fit several places in the grid";
    return detection;
  }
  const Placement& place = placements[0];
  std::map<int, const Hole*> by_id;
  for (const auto& [i, c] : best.cell) {
    by_id[(c.second - min_r + place.off_r) * target.cols + (c.first - min_c + place.off_c)] =
        &best.holes[i];
  }
  for (const auto& [id, hole] : place.recovered) by_id[id] = &hole;

  // The homography through the contour corners of every hole placed: where a hole's
  // refinement starts again when its contour corners were too far off for it.
  std::vector<cv::Point2d> contour_plane, contour_pixels;
  for (const auto& [id, hole] : by_id) {
    for (int k = 0; k < 4; ++k) {
      contour_plane.push_back(corner_in_target(id % target.cols, id / target.cols, k));
      contour_pixels.push_back(hole->corners[k]);
    }
  }
  const cv::Mat H_contour = cv::findHomography(contour_plane, contour_pixels, 0);
  std::vector<cv::Point2d> final_plane, final_pixels;
  for (auto& [id, hole] : by_id) {
    Hole h = *hole;
    if (options.refine && !RefineWithProfiles(f, options, h) && !H_contour.empty()) {
      std::vector<cv::Point2d> plane_corners, predicted;
      for (int k = 0; k < 4; ++k)
        plane_corners.push_back(corner_in_target(id % target.cols, id / target.cols, k));
      cv::perspectiveTransform(plane_corners, predicted, H_contour);
      Hole again = h;
      for (int k = 0; k < 4; ++k) again.corners[k] = predicted[static_cast<size_t>(k)];
      if (RefineWithProfiles(f, options, again)) h = again;
    }
    // A second pass samples its profiles across the refined sides.
    if (options.refine) RefineWithProfiles(f, options, h);
    for (int k = 0; k < 4; ++k) {
      detection.corner_ids.push_back(4 * id + k);
      detection.pixels.emplace_back(h.corners[k].x, h.corners[k].y);
      final_plane.push_back(corner_in_target(id % target.cols, id / target.cols, k));
      final_pixels.push_back(h.corners[k]);
    }
  }
  const cv::Mat H_final = cv::findHomography(final_plane, final_pixels, 0);
  if (H_final.empty()) {
    detection.reason = "no homography through the corners found";
    return detection;
  }
  std::vector<cv::Point2d> predicted;
  cv::perspectiveTransform(final_plane, predicted, H_final);
  double sum2 = 0;
  for (size_t k = 0; k < predicted.size(); ++k)
    sum2 += std::pow(cv::norm(predicted[k] - final_pixels[k]), 2);
  detection.homography_rms_px = std::sqrt(sum2 / static_cast<double>(predicted.size()));
  if (2 * static_cast<int>(by_id.size()) < holes_total) {
    detection.reason = "found " + std::to_string(by_id.size()) + " of " +
                       std::to_string(holes_total) + " holes, fewer than half";
    return detection;
  }
  if (detection.homography_rms_px > options.max_homography_rms_px) {
    detection.reason =
        "the corners fit a homography to " + std::to_string(detection.homography_rms_px) +
        " px RMS, more than max_homography_rms_px " + std::to_string(options.max_homography_rms_px);
    return detection;
  }
  detection.accepted = true;
  return detection;
}

}  // namespace hw::calibrate
