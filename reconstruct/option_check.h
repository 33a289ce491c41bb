#pragma once

// Internal to reconstruct/: the shared Check() message helpers under their local names.

#include "core/option_check.h"

namespace hw::reconstruct::internal {

inline std::string Fail(const std::string& field, double value, const std::string& constraint) {
  return core::OptionFail(field, value, constraint);
}
using core::InRange;

}  // namespace hw::reconstruct::internal
