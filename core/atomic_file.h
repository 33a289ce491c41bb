#pragma once

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>

namespace hw::core {

// Every file heatwave reads and writes goes through here, so that the defences are in one
// place:
// - reading: only regular files (after following symlinks) are opened for reading — a FIFO,
//   a device, a socket, a dangling link or a link loop is an InputError saying so, never a
//   hang; the size is checked against a cap before anything is allocated;
// - writing: the content is written under a temporary name in the same folder (same file
//   system, so the rename is atomic), every byte and the final close are checked (a full
//   disk is an OutputError, never a short file), and only then renamed over `path`.
//   Temporaries are registered so that SIGINT/SIGTERM removes them (core/interrupt.h).

// Size caps (bytes) for ReadFile, by kind of file. A file over its cap is refused before
// it is read: a hostile or broken file costs no more than its cap in memory and time.
// Configuration files: rig.yaml, target.yaml, .cameramodel, job/QA/emissivity files.
inline constexpr uint64_t kMaxConfigFileBytes = uint64_t{1} << 20;  // 1 MiB
// Line-based indexes and trajectories: depth.txt, rgb.txt, thermal.txt, ffc.txt,
// groundtruth.txt (a 10-hour 30 Hz stream is ~50 MB).
inline constexpr uint64_t kMaxIndexFileBytes = uint64_t{256} << 20;  // 256 MiB
// One encoded image frame (a 16-bit 4K PNG is < 50 MB).
inline constexpr uint64_t kMaxFrameFileBytes = uint64_t{256} << 20;  // 256 MiB
// Meshes and point clouds (PLY).
inline constexpr uint64_t kMaxMeshFileBytes = uint64_t{8} << 30;  // 8 GiB

// What is at a path, following symlinks, without opening it.
enum class PathKind {
  kMissing,       // nothing there (lstat: ENOENT / ENOTDIR)
  kRegularFile,   // a regular file (possibly through symlinks)
  kDirectory,     // a folder (possibly through symlinks)
  kSpecial,       // FIFO, socket, character or block device
  kDanglingLink,  // a symlink whose target does not exist
  kLinkLoop,      // a symlink loop (ELOOP)
  kUnreadable,    // stat failed otherwise, e.g. permission denied on a parent folder
};
struct PathInfo {
  PathKind kind = PathKind::kMissing;
  std::string detail;  // why, for kSpecial ("a FIFO", ...), kDanglingLink, kUnreadable
};
PathInfo ProbePath(const std::filesystem::path& path);
// One-line reason for a path that is not a regular file, e.g. "is a FIFO, expected a
// regular file", "dangling symbolic link (to 'x.png')", "no such file".
std::string DescribeNotRegular(const PathInfo& info);

// Reads a whole regular file. Throws InputError naming the path when it does not exist, is
// not a regular file (see above), cannot be opened (permission), is larger than
// max_bytes (the message states the cap), or a read fails. Never blocks on special files:
// the file is opened non-blocking and checked with fstat on the opened descriptor.
std::string ReadFile(const std::filesystem::path& path, uint64_t max_bytes);

// Temporary name for `path`: same folder and extension, hidden, unique per process.
std::filesystem::path TemporaryPathFor(const std::filesystem::path& path);

// Calls write(tmp) to write the file at the temporary name, then renames it to `path`.
// If write throws or returns false, the temporary file is removed and OutputError is
// thrown (or the exception rethrown). Creates missing parent folders. The temporary is
// registered for removal on SIGINT/SIGTERM while it exists. write() must itself detect
// short writes; prefer WriteFileAtomically, which does.
void WriteAtomically(const std::filesystem::path& path,
                     const std::function<bool(const std::filesystem::path& tmp)>& write);

// Writes `content` as the whole file `path`, atomically, checking every write and the
// close (a full disk or a file size limit is an OutputError naming the path and leaves
// neither a temporary nor a half file). Throws OutputError.
void WriteFileAtomically(const std::filesystem::path& path, std::string_view content);

// Total size in bytes of the regular files below `folder` (0 when it does not exist).
uint64_t FolderSizeBytes(const std::filesystem::path& folder);

}  // namespace hw::core
