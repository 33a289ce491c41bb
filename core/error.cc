#include "core/error.h"

namespace hw::core {

namespace {

// what() is one line, as the CLI prints errors (cli/command.cc PrintError): a newline or
// tab in a path or a decoder's reason becomes a space, another control character '?'.
std::string OneLine(std::string text) {
  for (char& c : text) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '\n' || c == '\r' || c == '\t') {
      c = ' ';
    } else if (u < 0x20 || u == 0x7f) {
      c = '?';
    }
  }
  return text;
}

}  // namespace

InputError::InputError(const std::filesystem::path& path, const std::string& reason)
    : std::runtime_error(OneLine(path.string() + ": " + reason)), path_(path), reason_(reason) {}

OutputError::OutputError(const std::filesystem::path& path, const std::string& reason)
    : std::runtime_error(OneLine("cannot write " + path.string() + ": " + reason)), path_(path) {}

}  // namespace hw::core
