#include "report/browser_check.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <system_error>
#include <thread>
#include <vector>

namespace hw::report {
namespace {

constexpr const char* kChromium = "/usr/bin/chromium";

struct RunResult {
  int exit_code = 0;
  bool timed_out = false;
  std::string error;  // could not start
};

// Runs `args` (args[0] is the program) with stdout and stderr to files, in its own process
// group so that a time-out kills the browser's helpers too.
RunResult Run(const std::vector<std::string>& args, const std::filesystem::path& stdout_path,
              const std::filesystem::path& stderr_path, double timeout_s) {
  RunResult result;
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const pid_t pid = fork();
  if (pid < 0) {
    result.error = std::string("fork failed: ") + std::strerror(errno);
    return result;
  }
  if (pid == 0) {
    setpgid(0, 0);
    const int out = open(stdout_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    const int err = open(stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
    const int in = open("/dev/null", O_RDONLY);
    if (out < 0 || err < 0 || in < 0) _exit(126);
    dup2(in, 0);
    dup2(out, 1);
    dup2(err, 2);
    execv(argv[0], argv.data());
    _exit(127);
  }
  setpgid(pid, pid);  // also here: no race with the child's own call
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
  int status = 0;
  for (;;) {
    const pid_t done = waitpid(pid, &status, WNOHANG);
    if (done == pid) break;
    if (done < 0 && errno != EINTR) {
      result.error = std::string("waitpid failed: ") + std::strerror(errno);
      return result;
    }
    if (std::chrono::steady_clock::now() > deadline) {
      kill(-pid, SIGKILL);
      waitpid(pid, &status, 0);
      result.timed_out = true;
      result.exit_code = -1;
      return result;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // The browser's helpers may outlive it briefly: end the group.
  kill(-pid, SIGKILL);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return result;
}

std::string ReadText(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The last non-empty stderr line that is not D-Bus noise (no bus in a container).
std::string LastErrorLine(const std::filesystem::path& stderr_path) {
  std::istringstream lines(ReadText(stderr_path));
  std::string line, last;
  while (std::getline(lines, line)) {
    if (line.empty() || line.find("dbus") != std::string::npos) continue;
    last = line;
  }
  return last;
}

std::filesystem::path MakeTempFolder(const std::string& prefix) {
  std::string pattern = (std::filesystem::temp_directory_path() / (prefix + "XXXXXX")).string();
  if (mkdtemp(pattern.data()) == nullptr) return {};
  return pattern;
}

}  // namespace

BrowserResult OpenInHeadlessChromium(const std::filesystem::path& html, int width_px, int height_px,
                                     double timeout_s, const std::string& fragment) {
  BrowserResult result;
  std::error_code ec;
  const std::filesystem::path page = std::filesystem::absolute(html, ec);
  if (ec || !std::filesystem::is_regular_file(page, ec)) {
    result.reason = html.string() + ": no such file";
    return result;
  }
  if (access(kChromium, X_OK) != 0) {
    result.reason = std::string(kChromium) +
                    " not found: install Chromium with scripts/install-deps.sh (Debian package chromium)";
    return result;
  }
  const std::filesystem::path work = MakeTempFolder("hw-chromium-");
  const std::filesystem::path shots = MakeTempFolder("hw-screenshot-");
  if (work.empty() || shots.empty()) {
    result.reason = std::string("cannot create a temporary folder: ") + std::strerror(errno);
    return result;
  }
  result.available = true;
  const std::vector<std::string> common = {
      kChromium,
      "--headless",
      "--no-sandbox",
      "--disable-gpu",
      "--use-angle=swiftshader",
      "--enable-unsafe-swiftshader",
      "--disable-quic",
      "--no-first-run",
      "--no-default-browser-check",
      "--disable-background-networking",
      "--disable-component-update",
      "--disable-sync",
      "--disable-extensions",
      "--disable-dev-shm-usage",
      "--hide-scrollbars",
      "--mute-audio",
      "--host-resolver-rules=MAP * ~NOTFOUND",
      "--virtual-time-budget=10000",
      "--window-size=" + std::to_string(width_px) + "," + std::to_string(height_px),
  };
  const std::string url = "file://" + page.string() + (fragment.empty() ? "" : "#" + fragment);

  const auto run = [&](const std::string& name, const std::vector<std::string>& extra) {
    std::vector<std::string> args = common;
    args.push_back("--user-data-dir=" + (work / ("profile-" + name)).string());
    args.insert(args.end(), extra.begin(), extra.end());
    args.push_back(url);
    const RunResult r = Run(args, work / (name + ".out"), work / (name + ".err"), timeout_s);
    result.exit_code = r.exit_code;
    if (!r.error.empty()) {
      result.reason = name + ": " + r.error;
    } else if (r.timed_out) {
      result.reason = name + ": Chromium killed after " + std::to_string(timeout_s) + " s";
    } else if (r.exit_code != 0) {
      result.reason = name + ": Chromium exited with " + std::to_string(r.exit_code) + ": " +
                      LastErrorLine(work / (name + ".err"));
    }
    return r.error.empty() && !r.timed_out && r.exit_code == 0;
  };

  if (run("dom", {"--dump-dom"})) result.dom = ReadText(work / "dom.out");
  const std::filesystem::path png = shots / "screenshot.png";
  if (run("screenshot", {"--screenshot=" + png.string()}) && std::filesystem::exists(png, ec)) {
    result.screenshot_png = png;
  } else {
    std::filesystem::remove_all(shots, ec);
    if (result.reason.empty()) result.reason = "screenshot: Chromium wrote no file";
  }
  std::filesystem::remove_all(work, ec);
  return result;
}

}  // namespace hw::report
