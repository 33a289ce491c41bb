#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>

namespace hw::core {

// Every file heatwave writes goes through here, so that a failed or interrupted run
// never leaves a half-written output: the content is written under a temporary name in
// the same folder (same file system, so the rename is atomic) and renamed over `path`
// only when complete.

// Temporary name for `path`: same folder and extension (so that writers that pick the
// format from the extension, like cv::imwrite, still work), hidden, unique per process.
std::filesystem::path TemporaryPathFor(const std::filesystem::path& path);

// Calls write(tmp) to write the file at the temporary name, then renames it to `path`.
// If write throws or returns false, the temporary file is removed and OutputError is
// thrown (or the exception rethrown). Creates missing parent folders.
void WriteAtomically(const std::filesystem::path& path,
                     const std::function<bool(const std::filesystem::path& tmp)>& write);

// Writes `content` as the whole file `path`, atomically. Throws OutputError.
void WriteFileAtomically(const std::filesystem::path& path, std::string_view content);

// Total size in bytes of the regular files below `folder` (0 when it does not exist).
uint64_t FolderSizeBytes(const std::filesystem::path& folder);

// Reads a whole file. Throws InputError naming the path if it cannot be read.
std::string ReadFile(const std::filesystem::path& path);

}  // namespace hw::core
