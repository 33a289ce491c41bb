#pragma once

// Opens an HTML file in headless Chromium, the way the report's HTML tests check that the
// page's scripts run (the 3D view renders, no Content-Security-Policy violation) with no
// network and no GPU.

#include <filesystem>
#include <string>

namespace hw::report {

struct BrowserResult {
  bool available = false;  // Chromium ran (false: reason says why and how to fix it)
  std::string reason;      // when !available, or a run failed/timed out: one line
  std::string dom;         // the serialised DOM after the scripts ran (--dump-dom)
  // The screenshot, width × height px PNG, in a fresh temporary folder the caller owns
  // (remove screenshot_png.parent_path() when done); empty when it was not written.
  std::filesystem::path screenshot_png;
  int exit_code = 0;  // of the last Chromium run; -1 when killed at the time limit
};

// Opens `html` in headless /usr/bin/chromium (when absent: available = false, reason says
// so and how to install: scripts/install-deps.sh) with external requests blocked
// (--host-resolver-rules="MAP * ~NOTFOUND"), no sandbox (root in a container), a fresh
// profile in a temporary folder (removed afterwards), WebGL on the CPU (SwiftShader
// through ANGLE: --use-angle=swiftshader --enable-unsafe-swiftshader; without the latter,
// Chromium 156 still falls back to it but warns that the fallback is deprecated), and
// --virtual-time-budget so that scripts and animation frames run before the capture. Two
// runs: --dump-dom (stdout → dom) and --screenshot at --window-size=width_px,height_px.
// Each run is killed (its whole process group) after `timeout_s` seconds. Never throws
// for a browser failure: see available / reason / exit_code. A non-empty `fragment` is
// appended to the page's URL ("#fragment": the page opens scrolled to that id).
BrowserResult OpenInHeadlessChromium(const std::filesystem::path& html, int width_px, int height_px,
                                     double timeout_s = 60, const std::string& fragment = "");

}  // namespace hw::report
