#pragma once

// The message every options struct's Check() returns, shared by the modules (fixtures/,
// reconstruct/ …) so that a bad option reads the same wherever it is caught.

#include <sstream>
#include <string>

namespace hw::core {

// "field: must be <constraint>, got <value>" with the value at full precision (17
// significant digits: the value the user gave round-trips).
inline std::string OptionFail(const std::string& field, double value, const std::string& constraint) {
  std::ostringstream s;
  s.precision(17);
  s << field << ": must be " << constraint << ", got " << value;
  return s.str();
}

// True when lo <= value <= hi (false for NaN).
inline bool InRange(double value, double lo, double hi) { return value >= lo && value <= hi; }

}  // namespace hw::core
