#include "core/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace hw::core {

namespace {
constexpr double kMinIntervalS = 0.1;
constexpr int kBarWidth = 24;
// The innermost live ProgressStage's prefix; main thread only, like the bars.
std::string* g_stage_prefix = nullptr;
}  // namespace

ProgressStage::ProgressStage(std::string prefix) : prefix_(std::move(prefix)), outer_(g_stage_prefix) {
  g_stage_prefix = &prefix_;
}

ProgressStage::~ProgressStage() { g_stage_prefix = outer_; }

ProgressBar::ProgressBar(std::string label, int64_t total, std::string unit, bool quiet)
    : label_(g_stage_prefix ? *g_stage_prefix + " " + label : std::move(label)),
      unit_(std::move(unit)),
      total_(std::max<int64_t>(total, 0)),
      quiet_(quiet),
      tty_(::isatty(STDERR_FILENO) == 1),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_) {
  Draw(true);
}

ProgressBar::~ProgressBar() { Finish(); }

void ProgressBar::Advance(int64_t n) { Set(done_ + n); }

void ProgressBar::Set(int64_t done) {
  done_ = std::clamp<int64_t>(done, 0, total_ > 0 ? total_ : done);
  Draw(false);
}

double ProgressBar::ElapsedSeconds() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

std::string ProgressBar::FormatDuration(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "--:--";
  const auto s = static_cast<int64_t>(std::llround(seconds));
  char buf[32];
  if (s >= 3600) {
    std::snprintf(buf, sizeof(buf), "%lld:%02lld:%02lld", static_cast<long long>(s / 3600),
                  static_cast<long long>((s / 60) % 60), static_cast<long long>(s % 60));
  } else {
    std::snprintf(buf, sizeof(buf), "%lld:%02lld", static_cast<long long>(s / 60),
                  static_cast<long long>(s % 60));
  }
  return buf;
}

void ProgressBar::Draw(bool force) {
  if (quiet_ || finished_) return;
  const auto now = std::chrono::steady_clock::now();
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const double fraction = total_ > 0 ? static_cast<double>(done_) / static_cast<double>(total_) : 1.0;
  if (tty_) {
    if (!force && std::chrono::duration<double>(now - last_draw_).count() < kMinIntervalS) return;
  } else {
    const int decile = static_cast<int>(fraction * 10.0);
    if (!force && decile == last_decile_) return;
    last_decile_ = decile;
  }
  last_draw_ = now;
  drawn_done_ = done_;
  const double rate = elapsed > 0 ? static_cast<double>(done_) / elapsed : 0.0;
  const double eta =
      rate > 0 ? static_cast<double>(total_ - done_) / rate : std::numeric_limits<double>::quiet_NaN();
  std::string bar(kBarWidth, '.');
  std::fill_n(bar.begin(), static_cast<int>(fraction * kBarWidth), '#');
  std::fprintf(stderr, "%s%-10s [%s] %lld/%lld %3d%%  %.1f %s/s  ETA %s%s", tty_ ? "\r" : "",
               label_.c_str(), bar.c_str(), static_cast<long long>(done_),
               static_cast<long long>(total_), static_cast<int>(fraction * 100.0), rate,
               unit_.c_str(), FormatDuration(eta).c_str(), tty_ ? "\033[K" : "\n");
  std::fflush(stderr);
}

void ProgressBar::Finish() {
  if (finished_) return;
  if (!quiet_) {
    // A log (not a terminal) already has the line for this state unless done_ moved since.
    if (tty_ || done_ != drawn_done_) Draw(true);
    if (tty_) std::fputc('\n', stderr);
    std::fflush(stderr);
  }
  finished_ = true;
}

}  // namespace hw::core
