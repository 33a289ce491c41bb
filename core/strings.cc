#include "core/strings.h"

#include <algorithm>
#include <cstdarg>
#include <cstdio>

namespace hw::core {

std::string StringPrintf(const char* format, ...) {
  va_list args;
  va_start(args, format);
  va_list copy;
  va_copy(copy, args);
  const int size = std::max(std::vsnprintf(nullptr, 0, format, copy), 0);
  va_end(copy);
  std::string out(static_cast<size_t>(size) + 1, '\0');
  std::vsnprintf(out.data(), out.size(), format, args);
  va_end(args);
  out.resize(static_cast<size_t>(size));
  return out;
}

std::string OneLineMessage(std::string_view text) {
  std::string line(text);
  for (char& c : line) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '\n' || c == '\r' || c == '\t') {
      c = ' ';
    } else if (u < 0x20 || u == 0x7f) {
      c = '?';
    }
  }
  return line;
}

}  // namespace hw::core
