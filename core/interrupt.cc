#include "core/interrupt.h"

#include <limits.h>
#include <signal.h>
#include <unistd.h>

#include <atomic>
#include <cassert>
#include <cstring>
#include <mutex>

namespace hw::core {

namespace {

// A slot is free (0), being filled (1) or holds a path the handler may unlink (2).
constexpr int kFree = 0, kFilling = 1, kActive = 2;
struct Slot {
  std::atomic<int> state{kFree};
  char path[PATH_MAX];
};
Slot g_slots[kMaxRegisteredPaths];
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler needs lock-free atomics");

// StopOnInterrupt: 0 = not active, 1 = active and no signal yet, 2 = a signal asked to stop.
std::atomic<int> g_stop_state{0};
static_assert(std::atomic<int>::is_always_lock_free);

void HandleSignal(int signal_number) {
  if (signal_number != SIGHUP) {
    int expected = 1;
    if (g_stop_state.compare_exchange_strong(expected, 2)) return;  // the job stops itself
  }
  for (Slot& slot : g_slots) {
    if (slot.state.load(std::memory_order_acquire) == kActive) ::unlink(slot.path);
  }
  // Default action, then re-raise: the parent sees the process killed by this signal.
  struct sigaction action {};
  action.sa_handler = SIG_DFL;
  sigemptyset(&action.sa_mask);
  ::sigaction(signal_number, &action, nullptr);
  ::raise(signal_number);
}

}  // namespace

void InstallInterruptHandlers() {
  static std::once_flag once;
  std::call_once(once, [] {
    struct sigaction action {};
    action.sa_handler = HandleSignal;
    sigemptyset(&action.sa_mask);
    for (const int s : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&action.sa_mask, s);
    for (const int s : {SIGINT, SIGTERM, SIGHUP}) {
      struct sigaction previous {};
      ::sigaction(s, nullptr, &previous);
      // A signal ignored by whoever started us (nohup, a shell's background job) stays so.
      if (previous.sa_handler != SIG_IGN) ::sigaction(s, &action, nullptr);
    }
    struct sigaction ignore {};
    ignore.sa_handler = SIG_IGN;
    sigemptyset(&ignore.sa_mask);
    ::sigaction(SIGXFSZ, &ignore, nullptr);
  });
}

RemoveOnInterrupt::RemoveOnInterrupt(const std::filesystem::path& path) {
  const std::string& text = path.native();
  if (text.size() >= PATH_MAX) return;
  for (int i = 0; i < kMaxRegisteredPaths; ++i) {
    int expected = kFree;
    if (g_slots[i].state.compare_exchange_strong(expected, kFilling, std::memory_order_acq_rel)) {
      std::memcpy(g_slots[i].path, text.c_str(), text.size() + 1);
      g_slots[i].state.store(kActive, std::memory_order_release);
      slot_ = i;
      return;
    }
  }
}

RemoveOnInterrupt::~RemoveOnInterrupt() {
  if (slot_ >= 0) g_slots[slot_].state.store(kFree, std::memory_order_release);
}

StopOnInterrupt::StopOnInterrupt() {
  int expected = 0;
  const bool first = g_stop_state.compare_exchange_strong(expected, 1);
  assert(first && "one StopOnInterrupt at a time");
  (void)first;
}

StopOnInterrupt::~StopOnInterrupt() { g_stop_state.store(0); }

bool StopOnInterrupt::StopRequested() { return g_stop_state.load() == 2; }

void StopOnInterrupt::RequestStop() {
  int expected = 1;
  g_stop_state.compare_exchange_strong(expected, 2);
}

int NumPathsRegisteredForInterrupt() {
  int n = 0;
  for (const Slot& slot : g_slots) n += slot.state.load() == kActive;
  return n;
}

}  // namespace hw::core
