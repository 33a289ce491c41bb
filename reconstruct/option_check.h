#pragma once

// Internal to reconstruct/: the message every options Check() returns.

#include <cmath>
#include <sstream>
#include <string>

namespace hw::reconstruct::internal {

// "field: must be <constraint>, got <value>" with the value at full precision.
inline std::string Fail(const std::string& field, double value, const std::string& constraint) {
  std::ostringstream s;
  s.precision(17);
  s << field << ": must be " << constraint << ", got " << value;
  return s.str();
}

// True when lo <= value <= hi (false for NaN).
inline bool InRange(double value, double lo, double hi) { return value >= lo && value <= hi; }

}  // namespace hw::reconstruct::internal
