#pragma once

#include <string>

namespace hw::core {

// printf into a std::string (summaries, tables, messages).
std::string StringPrintf(const char* format, ...) __attribute__((format(printf, 1, 2)));

}  // namespace hw::core
