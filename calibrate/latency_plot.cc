// diagnostics/signals.png of the latency calibration (calibrate/latency.h).
#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "calibrate/latency.h"
#include "core/strings.h"

namespace hw::calibrate {
namespace {

void Label(cv::Mat& image, const std::string& text, cv::Point at, double size = 0.5, cv::Scalar colour = {30, 30, 30}) {
  cv::putText(image, text, at, cv::FONT_HERSHEY_SIMPLEX, size, colour, 1, cv::LINE_AA);
}

// A plot panel: data (x, y) to pixels of `box`.
struct Panel {
  cv::Rect box;
  double x0, x1, y0, y1;
  cv::Point2d At(double x, double y) const {
    return {box.x + (x - x0) / (x1 - x0) * box.width, box.y + box.height - (y - y0) / (y1 - y0) * box.height};
  }
  void Frame(cv::Mat& image, const std::string& x_label, const std::string& title) const {
    cv::rectangle(image, box, cv::Scalar(120, 120, 120), 1);
    Label(image, title, cv::Point(box.x, box.y - 8), 0.55);
    Label(image, x_label, cv::Point(box.x + box.width - 300, box.y + box.height + 34), 0.45);
    for (int k = 0; k <= 4; ++k) {
      const double x = x0 + (x1 - x0) * k / 4;
      const cv::Point2d p = At(x, y0);
      cv::line(image, p, p + cv::Point2d(0, 5), cv::Scalar(120, 120, 120));
      Label(image, core::StringPrintf("%.3g", x), p + cv::Point2d(-14, 20), 0.4);
    }
  }
  // A polyline through the finite points, broken at NaN and at jumps in x wider than max_dx.
  void Curve(cv::Mat& image, const std::vector<double>& xs, const std::vector<double>& ys, cv::Scalar colour,
             double max_dx) const {
    for (size_t i = 0; i + 1 < xs.size(); ++i) {
      if (!std::isfinite(ys[i]) || !std::isfinite(ys[i + 1]) || xs[i + 1] - xs[i] > max_dx) continue;
      cv::line(image, At(xs[i], std::clamp(ys[i], y0, y1)), At(xs[i + 1], std::clamp(ys[i + 1], y0, y1)), colour, 1,
               cv::LINE_AA);
    }
  }
};

}  // namespace

cv::Mat DrawLatencySignals(const LatencyResult& r) {
  cv::Mat image(700, 1000, CV_8UC3, cv::Scalar(255, 255, 255));
  const cv::Scalar depth_colour(40, 40, 40), rgb_colour(40, 160, 40), thermal_colour(30, 30, 220), closure_colour(200, 120, 30);

  // Signals on the depth clock: rgb and thermal shifted by their offsets and mapped onto
  // depth's scale by their fitted maps (depth ≈ P(other)).
  const LatencySignal& d = r.depth_signal;
  const double t0 = d.time_s.front(), t1 = d.time_s.back();
  Panel top{cv::Rect(70, 40, 900, 330), 0, t1 - t0, -2.5, 2.5};
  top.Frame(image, "time since the first depth frame, s", "blob motion after correction (normalised)");
  auto shifted = [&](const LatencySignal& s, const PairOffset& p, std::vector<double>* xs, std::vector<double>* ys) {
    for (size_t i = 0; i < s.time_s.size(); ++i) {
      xs->push_back(s.time_s[i] + p.offset_s - t0);
      double v = 0;
      for (size_t k = p.map_coefficients.size(); k-- > 0;) v = v * s.value[i] + p.map_coefficients[k];
      ys->push_back(std::isfinite(s.value[i]) ? v : std::nan(""));
    }
  };
  std::vector<double> xs, ys;
  for (size_t i = 0; i < d.time_s.size(); ++i) xs.push_back(d.time_s[i] - t0);
  top.Curve(image, xs, d.value, depth_colour, 2.5 * d.period_s);
  xs.clear(), ys.clear();
  shifted(r.rgb_signal, r.rgb, &xs, &ys);
  top.Curve(image, xs, ys, rgb_colour, 2.5 * r.rgb_signal.period_s);
  xs.clear(), ys.clear();
  shifted(r.thermal_signal, r.thermal, &xs, &ys);
  top.Curve(image, xs, ys, thermal_colour, 2.5 * r.thermal_signal.period_s);
  auto found = [](const BlobTrack& t) { return t.frames - t.missing; };
  Label(image, core::StringPrintf("depth (blob in %d/%d frames)", found(r.depth_track), r.depth_track.frames), cv::Point(80, 62), 0.45,
        depth_colour);
  Label(image,
        core::StringPrintf("rgb   offset %+.2f ms +- %.2f (blob in %d/%d frames)", 1e3 * r.rgb.offset_s, 1e3 * r.rgb.sigma_s,
                           found(r.rgb_track), r.rgb_track.frames),
        cv::Point(80, 82), 0.45, rgb_colour);
  Label(image,
        core::StringPrintf("thermal offset %+.2f ms +- %.2f (blob in %d/%d frames)", 1e3 * r.thermal.offset_s,
                           1e3 * r.thermal.sigma_s, found(r.thermal_track), r.thermal_track.frames),
        cv::Point(80, 102), 0.45, thermal_colour);

  // Correlation curves of the three pairs over the searched offsets.
  const PairOffset* pairs[] = {&r.rgb, &r.thermal, &r.thermal_rgb};
  const cv::Scalar colours[] = {rgb_colour, thermal_colour, closure_colour};
  double x0 = 0, x1 = 0;
  for (const PairOffset* p : pairs) {
    if (!p->curve_offset_s.empty()) x0 = std::min(x0, 1e3 * p->curve_offset_s.front()), x1 = std::max(x1, 1e3 * p->curve_offset_s.back());
  }
  if (!(x1 > x0)) x1 = x0 + 1;
  Panel bottom{cv::Rect(70, 440, 900, 200), x0, x1, -1, 1};
  bottom.Frame(image, "offset (t_ref = t_other + offset), ms", "correlation of the blob signals");
  cv::line(image, bottom.At(x0, 0), bottom.At(x1, 0), cv::Scalar(200, 200, 200));
  for (int k = 0; k < 3; ++k) {
    const PairOffset& p = *pairs[k];
    std::vector<double> ms;
    for (double o : p.curve_offset_s) ms.push_back(1e3 * o);
    bottom.Curve(image, ms, p.curve_correlation, colours[k], 1e9);
    cv::line(image, bottom.At(1e3 * p.offset_s, -1), bottom.At(1e3 * p.offset_s, 1), colours[k], 1, cv::LINE_AA);
    Label(image,
          core::StringPrintf("%s <- %s: %+.2f ms, peak r = %.3f", p.reference.c_str(), p.other.c_str(), 1e3 * p.offset_s,
                             p.peak_correlation),
          cv::Point(80, 462 + 18 * k), 0.45, colours[k]);
  }
  return image;
}

}  // namespace hw::calibrate
