#include "tests/support.h"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <csignal>
#include <thread>
#include <cstdio>
#include <system_error>

#include <gtest/gtest.h>

namespace hw::test {

namespace fs = std::filesystem;

namespace {

const fs::path& ProcessRoot() {
  struct Root {
    fs::path path = fs::path(::testing::TempDir()) / ("heatwave-" + std::to_string(::getpid()));
    ~Root() {
      std::error_code ec;
      fs::remove_all(path, ec);
    }
  };
  static const Root root;
  return root.path;
}

fs::path PathForTest(const std::string& name) {
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  fs::path path = ProcessRoot() / (info != nullptr ? std::string(info->test_suite_name()) + "." +
                                                         info->name()
                                                   : std::string("no-test"));
  if (!name.empty()) path /= name;
  return path;
}

}  // namespace

fs::path TestFolder(const std::string& name) {
  const fs::path path = PathForTest(name);
  fs::remove_all(path);
  fs::create_directories(path);
  return path;
}

fs::path FreshPath(const std::string& name) {
  const fs::path path = PathForTest(name);
  fs::remove_all(path);
  fs::create_directories(path.parent_path());
  return path;
}

Argv::Argv(std::vector<std::string> args) : storage_(std::move(args)) {
  for (auto& s : storage_) pointers_.push_back(s.data());
}

CommandResult RunCommand(const std::string& command) {
  CommandResult result;
  FILE* pipe = ::popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return result;
  std::array<char, 4096> buffer;
  size_t n;
  while ((n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0) {
    result.output.append(buffer.data(), n);
  }
  const int status = ::pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return result;
}

int RunInChild(const std::function<int()>& fn, double timeout_s) {
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) return -2;
  if (pid == 0) {
    int code = 255;
    try {
      code = fn();
    } catch (...) {
      code = 254;
    }
    std::fflush(nullptr);
    ::_exit(code);
  }
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  int status = 0;
  while (true) {
    const pid_t done = ::waitpid(pid, &status, WNOHANG);
    if (done == pid) break;
    if (std::chrono::steady_clock::now() > deadline) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      return kTimedOut;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return WEXITSTATUS(status);
}

std::string Replace(const std::string& text, const std::string& from, const std::string& to) {
  const size_t at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at == std::string::npos) return text;
  EXPECT_EQ(text.find(from, at + 1), std::string::npos) << "not unique: " << from;
  return text.substr(0, at) + to + text.substr(at + from.size());
}

int LineOf(const std::string& text, const std::string& needle) {
  const size_t at = text.find(needle);
  EXPECT_NE(at, std::string::npos) << needle;
  if (at == std::string::npos) return 0;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(at), '\n'));
}

int CountLines(const std::string& s) {
  int n = 0;
  for (const char c : s) n += c == '\n';
  return n;
}

}  // namespace hw::test
