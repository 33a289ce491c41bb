#pragma once

// Test support shared by every test executable (linked by hw_add_test).

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace hw::test {

// A fresh, empty folder for the running test:
//   <gtest TempDir>/heatwave-<pid>/<Suite>.<Test>[/<name>]
// The per-process root is removed when the test program exits, so tests running in
// parallel (ctest runs each TEST in its own process) never share files and reruns start
// clean. FreshPath is the same path, absent (its parent exists): for writers that must
// create their output folder themselves.
std::filesystem::path TestFolder(const std::string& name = "");
std::filesystem::path FreshPath(const std::string& name = "");

// argc/argv for calling a command's Run* function directly.
class Argv {
 public:
  explicit Argv(std::vector<std::string> args);
  int argc() const { return static_cast<int>(pointers_.size()); }
  char** argv() { return pointers_.data(); }

 private:
  std::vector<std::string> storage_;
  std::vector<char*> pointers_;
};

// Runs a shell command; stdout and stderr together, and the exit code (128 + signal when
// killed by one).
struct CommandResult {
  int exit_code = -1;
  std::string output;
};
CommandResult RunCommand(const std::string& command);

// Runs fn() in a forked child process (for code that may hang, kill the process, or change
// process-wide state such as resource limits and signal handlers). Returns fn's return
// value as the child's exit code (0..255), 128 + signal when the child was killed by one,
// or kTimedOut when it had not ended after timeout_s (it is then killed).
inline constexpr int kTimedOut = -1;
int RunInChild(const std::function<int()>& fn, double timeout_s = 20);

// `text` with the one occurrence of `from` replaced by `to`; fails the running test if
// `from` does not occur exactly once (a silently unchanged text makes an error test vacuous).
std::string Replace(const std::string& text, const std::string& from, const std::string& to);
// 1-based line of the first occurrence of `needle` in `text` (fails the test if absent).
int LineOf(const std::string& text, const std::string& needle);

// Number of '\n' in s.
int CountLines(const std::string& s);

}  // namespace hw::test
