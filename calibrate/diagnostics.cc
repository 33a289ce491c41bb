#include "calibrate/diagnostics.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "core/strings.h"

namespace hw::calibrate {
namespace {

int Upscale(int width_px) { return width_px < 640 ? 2 : 1; }

// A one-channel image of any depth stretched to 8 bits between its 1st and 99th
// percentiles (thermal images have their own range), as BGR.
cv::Mat Stretch(const cv::Mat& image) {
  cv::Mat f;
  image.convertTo(f, CV_32F);
  std::vector<float> values(f.begin<float>(), f.end<float>());
  values.erase(std::remove_if(values.begin(), values.end(), [](float v) { return !std::isfinite(v); }), values.end());
  double lo = 0, hi = 1;
  if (!values.empty()) {
    const size_t a = values.size() / 100, b = values.size() - 1 - values.size() / 100;
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(a), values.end());
    lo = static_cast<double>(values[a]);
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(b), values.end());
    hi = static_cast<double>(values[b]);
  }
  if (!(hi > lo)) hi = lo + 1;
  cv::Mat grey;
  const double a = 255.0 / (hi - lo);
  f.convertTo(grey, CV_8U, a, -a * lo);
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  return bgr;
}

cv::Scalar ViewColour(size_t view) {
  // Distinct hues, full saturation: golden-angle steps around the hue circle.
  cv::Mat hsv(1, 1, CV_8UC3, cv::Scalar(static_cast<double>((view * 111) % 180), 200, 230)), bgr;
  cv::cvtColor(hsv, bgr, cv::COLOR_HSV2BGR);
  const cv::Vec3b c = bgr.at<cv::Vec3b>(0, 0);
  return cv::Scalar(c[0], c[1], c[2]);
}

void Label(cv::Mat& image, const std::string& text, cv::Point at, double size = 0.5, cv::Scalar colour = {255, 255, 255}) {
  cv::putText(image, text, at, cv::FONT_HERSHEY_SIMPLEX, size, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
  cv::putText(image, text, at, cv::FONT_HERSHEY_SIMPLEX, size, colour, 1, cv::LINE_AA);
}

}  // namespace

cv::Mat DrawDetection(const cv::Mat& image, const Detection& d, int label_every) {
  const int k = Upscale(image.cols);
  cv::Mat out;
  cv::resize(Stretch(image), out, cv::Size(), k, k, cv::INTER_NEAREST);
  const cv::Scalar colour = d.accepted ? cv::Scalar(60, 220, 60) : cv::Scalar(40, 40, 230);
  // Pixel centres of the original image at (i + 0.5)·k − 0.5 in the upscaled one.
  auto at = [&](const Eigen::Vector2d& p) { return cv::Point2d((p.x() + 0.5) * k - 0.5, (p.y() + 0.5) * k - 0.5); };
  for (size_t i = 0; i < d.pixels.size(); ++i) {
    const cv::Point2d p = at(d.pixels[i]);
    cv::drawMarker(out, p, colour, cv::MARKER_CROSS, 6 * k, 1, cv::LINE_AA);
    if (d.corner_ids[i] == 0) cv::circle(out, p, 7 * k, cv::Scalar(0, 200, 255), 2, cv::LINE_AA);
    if (label_every > 0 && d.corner_ids[i] % label_every == 0) {
      Label(out, std::to_string(d.corner_ids[i]), p + cv::Point2d(4, -4), 0.35);
    }
  }
  const std::string verdict = d.accepted
                                  ? core::StringPrintf("%s: %zu corners, homography RMS %.2f px", d.view.c_str(),
                                                       d.pixels.size(), d.homography_rms_px)
                                  : d.view + ": rejected: " + d.reason;
  Label(out, verdict, cv::Point(8, 20), 0.5, colour);
  return out;
}

cv::Mat DrawResidualField(int width_px, int height_px, const std::vector<std::vector<Eigen::Vector2d>>& corners_px,
                          const std::vector<std::vector<Eigen::Vector2d>>& residuals_px,
                          const std::vector<std::vector<bool>>& outlier, double scale) {
  const int k = Upscale(width_px);
  cv::Mat out(height_px * k, width_px * k, CV_8UC3, cv::Scalar(30, 30, 30));
  for (size_t v = 0; v < corners_px.size(); ++v) {
    for (size_t i = 0; i < corners_px[v].size(); ++i) {
      const bool bad = v < outlier.size() && i < outlier[v].size() && outlier[v][i];
      const cv::Point2d from(corners_px[v][i].x() * k, corners_px[v][i].y() * k);
      const cv::Point2d to = from + cv::Point2d(residuals_px[v][i].x(), residuals_px[v][i].y()) * (scale * k);
      cv::arrowedLine(out, from, to, bad ? cv::Scalar(40, 40, 255) : ViewColour(v), 1, cv::LINE_AA, 0, 0.25);
    }
  }
  const int bar = static_cast<int>(std::lround(scale * k));
  cv::line(out, cv::Point(12, out.rows - 16), cv::Point(12 + bar, out.rows - 16), cv::Scalar(255, 255, 255), 2);
  Label(out, core::StringPrintf("1 px (arrows x%g); red: outliers", scale), cv::Point(16 + bar, out.rows - 11));
  return out;
}

cv::Mat DrawResidualHistogram(const std::vector<std::vector<Eigen::Vector2d>>& residuals_px,
                              const std::vector<std::vector<bool>>& outlier, double sigma_px) {
  std::vector<double> values;
  for (size_t v = 0; v < residuals_px.size(); ++v) {
    for (size_t i = 0; i < residuals_px[v].size(); ++i) {
      if (v < outlier.size() && i < outlier[v].size() && outlier[v][i]) continue;
      values.push_back(residuals_px[v][i].x());
      values.push_back(residuals_px[v][i].y());
    }
  }
  const int width = 640, height = 400, margin = 40, bins = 41;
  cv::Mat out(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const double range = std::max(4 * sigma_px, 1e-3);  // ± range
  std::vector<int> count(bins, 0);
  for (double x : values) {
    const int b = static_cast<int>(std::floor((x + range) / (2 * range) * bins));
    if (b >= 0 && b < bins) ++count[static_cast<size_t>(b)];
  }
  const double bin_w = 2 * range / bins;
  // Expected count per bin of a normal density with the estimated sigma.
  const double peak_expected = values.size() * bin_w / (sigma_px * std::sqrt(2 * M_PI));
  const double top = std::max({1.0, static_cast<double>(*std::max_element(count.begin(), count.end())), peak_expected}) * 1.1;
  const double plot_w = width - 2 * margin, plot_h = height - 2 * margin;
  for (int b = 0; b < bins; ++b) {
    const double x0 = margin + plot_w * b / bins, x1 = margin + plot_w * (b + 1) / bins;
    const double h = plot_h * count[static_cast<size_t>(b)] / top;
    cv::rectangle(out, cv::Point2d(x0 + 1, height - margin - h), cv::Point2d(x1 - 1, height - margin),
                  cv::Scalar(200, 140, 60), cv::FILLED);
  }
  cv::Point2d last;
  for (int i = 0; i <= 200; ++i) {
    const double x = -range + 2 * range * i / 200;
    const double expected = peak_expected * std::exp(-0.5 * x * x / (sigma_px * sigma_px));
    const cv::Point2d p(margin + plot_w * (x + range) / (2 * range), height - margin - plot_h * expected / top);
    if (i > 0) cv::line(out, last, p, cv::Scalar(40, 40, 200), 2, cv::LINE_AA);
    last = p;
  }
  cv::line(out, cv::Point(margin, height - margin), cv::Point(width - margin, height - margin), cv::Scalar(0, 0, 0));
  for (int t = -4; t <= 4; t += 2) {
    const double x = margin + plot_w * (t * sigma_px + range) / (2 * range);
    cv::line(out, cv::Point2d(x, height - margin), cv::Point2d(x, height - margin + 5), cv::Scalar(0, 0, 0));
    cv::putText(out, core::StringPrintf("%.2f", t * sigma_px), cv::Point2d(x - 16, height - margin + 20),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  cv::putText(out, core::StringPrintf("residual x and y, px (%zu inlier coordinates); red: normal, sigma %.3f px",
                                      values.size(), sigma_px),
              cv::Point(margin, 24), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  return out;
}

cv::Mat DrawUncertaintyMap(int width_px, int height_px, const std::vector<double>& uncertainty_px, int grid_cols,
                           int grid_rows, double max_px, const std::string& title) {
  const int k = Upscale(width_px);
  cv::Mat grid(grid_rows, grid_cols, CV_8U);
  for (int r = 0; r < grid_rows; ++r) {
    for (int c = 0; c < grid_cols; ++c) {
      const double u = uncertainty_px[static_cast<size_t>(r * grid_cols + c)];
      grid.at<uint8_t>(r, c) = static_cast<uint8_t>(std::clamp(std::isfinite(u) ? 255 * u / max_px : 255.0, 0.0, 255.0));
    }
  }
  cv::Mat big, out;
  cv::resize(grid, big, cv::Size(width_px * k, height_px * k), 0, 0, cv::INTER_NEAREST);
  cv::applyColorMap(big, out, cv::COLORMAP_TURBO);
  const double cell_w = static_cast<double>(out.cols) / grid_cols, cell_h = static_cast<double>(out.rows) / grid_rows;
  for (int r = 0; r < grid_rows; ++r) {
    for (int c = 0; c < grid_cols; ++c) {
      const double u = uncertainty_px[static_cast<size_t>(r * grid_cols + c)];
      Label(out, std::isfinite(u) ? core::StringPrintf("%.2f", u) : "-",
            cv::Point2d(c * cell_w + 3, r * cell_h + cell_h / 2 + 4), 0.33);
    }
  }
  Label(out, title + core::StringPrintf(" (colour 0 to %.2f px)", max_px), cv::Point(8, 18), 0.5);
  return out;
}

}  // namespace hw::calibrate
