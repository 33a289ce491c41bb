#include "core/error.h"

#include "core/strings.h"

namespace hw::core {

// what() is one line (core/strings.h OneLineMessage), whatever the path or reason holds.
InputError::InputError(const std::filesystem::path& path, const std::string& reason)
    : std::runtime_error(OneLineMessage(path.string() + ": " + reason)), path_(path), reason_(reason) {}

OutputError::OutputError(const std::filesystem::path& path, const std::string& reason)
    : std::runtime_error(OneLineMessage("cannot write " + path.string() + ": " + reason)), path_(path) {}

}  // namespace hw::core
