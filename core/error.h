#pragma once

#include <filesystem>
#include <stdexcept>
#include <string>

namespace hw::core {

// Bad input data: a file that is missing, unreadable, truncated or malformed.
// what() is one line naming the file and the problem, e.g.
//   "scan/rig.yaml: cameras.depth.fx: must be > 0, got -525"
// Bugs are asserts, bad command-line options are exit code 2; only bad inputs throw this.
class InputError : public std::runtime_error {
 public:
  InputError(const std::filesystem::path& path, const std::string& reason);
  const std::filesystem::path& path() const { return path_; }
  const std::string& reason() const { return reason_; }

 private:
  std::filesystem::path path_;
  std::string reason_;
};

// Failure to write an output file (disk full, permission denied, ...).
class OutputError : public std::runtime_error {
 public:
  OutputError(const std::filesystem::path& path, const std::string& reason);
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

}  // namespace hw::core
