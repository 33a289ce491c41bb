#pragma once

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>

namespace hw::core {

// A progress bar for long jobs, drawn on stderr:
//   render  [##########..........]  52/100  52%  17.3 frames/s  ETA 0:03
// Redrawn at most every `min_interval_s`; silent when quiet, and reduced to a line per
// 10 % when stderr is not a terminal (CI logs stay readable). Not thread-safe: call
// Advance() from one thread.
class ProgressBar {
 public:
  ProgressBar(std::string label, int64_t total, std::string unit = "items", bool quiet = false);
  ~ProgressBar();  // calls Finish()
  ProgressBar(const ProgressBar&) = delete;
  ProgressBar& operator=(const ProgressBar&) = delete;

  void Advance(int64_t n = 1);
  void Set(int64_t done);
  // Draws the final state and ends the line. Idempotent.
  void Finish();
  double ElapsedSeconds() const;

  // Formats seconds as H:MM:SS or M:SS.
  static std::string FormatDuration(double seconds);

 private:
  void Draw(bool force);

  std::string label_;
  std::string unit_;
  int64_t total_;
  int64_t done_ = 0;
  int64_t drawn_done_ = -1;  // done_ at the last draw
  bool quiet_;
  bool tty_;
  bool finished_ = false;
  int last_decile_ = -1;
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_draw_;
};

// While one lives, every ProgressBar created is labelled "<prefix> <label>": a job of
// several stages (heatwave audit) shows one display, "[2/3] analyze [#####.....] ...",
// without the stages knowing they are part of it. Nests (the innermost wins); main thread.
class ProgressStage {
 public:
  explicit ProgressStage(std::string prefix);
  ~ProgressStage();
  ProgressStage(const ProgressStage&) = delete;
  ProgressStage& operator=(const ProgressStage&) = delete;

 private:
  std::string prefix_;
  std::string* outer_;
};

}  // namespace hw::core
