#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

namespace hw::core {

// The median of `values` taken as the upper of the two middle ones for an even count (an
// element of the set, O(n) by nth_element); 0 for none. Takes a copy: the caller's order stays.
inline double Median(std::vector<double> values) {
  if (values.empty()) return 0;
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

}  // namespace hw::core
