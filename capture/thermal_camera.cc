#include "capture/thermal_camera.h"

#include <chrono>

namespace hw::capture {

double MonotonicNowS() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace hw::capture
