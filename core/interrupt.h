#pragma once

#include <filesystem>

namespace hw::core {

// Clean-up on SIGINT / SIGTERM / SIGHUP: files registered here (the temporaries of atomic
// writes) are unlinked by the signal handler, which then re-raises the signal with its
// default action, so the process still ends as interrupted (exit status 128 + signal).
// Only async-signal-safe calls (unlink, sigaction, raise) run in the handler.

// Installs the handlers (idempotent; the CLI calls it first thing). Also ignores SIGXFSZ,
// so that exceeding a file size limit is a write error (EFBIG) reported as an OutputError,
// not a core dump. Without it, registered paths are simply never cleaned by a signal.
void InstallInterruptHandlers();

// Registers `path` for removal on a signal for the lifetime of this object. At most
// kMaxRegisteredPaths at once (one per thread writing a file in practice); beyond that, or
// for a path longer than PATH_MAX, the registration is skipped (best effort, never fails).
class RemoveOnInterrupt {
 public:
  explicit RemoveOnInterrupt(const std::filesystem::path& path);
  ~RemoveOnInterrupt();
  RemoveOnInterrupt(const RemoveOnInterrupt&) = delete;
  RemoveOnInterrupt& operator=(const RemoveOnInterrupt&) = delete;

 private:
  int slot_ = -1;
};

inline constexpr int kMaxRegisteredPaths = 256;

// How many paths are registered now (tests).
int NumPathsRegisteredForInterrupt();

// While one lives, the first SIGINT or SIGTERM does not end the process: it only sets a flag
// that StopRequested() returns, so that a job that runs until the user stops it (capture)
// can finish its files and exit normally. A second signal acts as without it (temporaries
// removed, process ends by the signal): a stuck job can still be interrupted. SIGHUP is
// unaffected. Needs InstallInterruptHandlers(). One at a time (asserted).
class StopOnInterrupt {
 public:
  StopOnInterrupt();
  ~StopOnInterrupt();
  StopOnInterrupt(const StopOnInterrupt&) = delete;
  StopOnInterrupt& operator=(const StopOnInterrupt&) = delete;

  // True once a signal arrived (async-signal-safe read of an atomic).
  static bool StopRequested();
  // Sets the flag as a signal would (tests, and callers with their own stop condition).
  static void RequestStop();
};

}  // namespace hw::core
