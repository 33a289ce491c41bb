#include "core/error.h"

namespace hw::core {

InputError::InputError(const std::filesystem::path& path, const std::string& reason)
    : std::runtime_error(path.string() + ": " + reason), path_(path), reason_(reason) {}

OutputError::OutputError(const std::filesystem::path& path, const std::string& reason)
    : std::runtime_error("cannot write " + path.string() + ": " + reason), path_(path) {}

}  // namespace hw::core
