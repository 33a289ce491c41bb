#include "core/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <system_error>

#include "core/error.h"
#include "core/interrupt.h"
#include "core/strings.h"

namespace hw::core {

namespace fs = std::filesystem;

namespace {

std::string SpecialKindName(mode_t mode) {
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  return "not a regular file";
}

std::string FormatCap(uint64_t bytes) {
  if (bytes >= (uint64_t{1} << 30) && bytes % (uint64_t{1} << 30) == 0) {
    return std::to_string(bytes >> 30) + " GiB";
  }
  if (bytes >= (uint64_t{1} << 20) && bytes % (uint64_t{1} << 20) == 0) {
    return std::to_string(bytes >> 20) + " MiB";
  }
  return std::to_string(bytes) + " bytes";
}

// Closes a descriptor on scope exit.
struct FdCloser {
  int fd;
  ~FdCloser() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

PathInfo ProbePath(const fs::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0) {
    if (S_ISREG(st.st_mode)) return {PathKind::kRegularFile, ""};
    if (S_ISDIR(st.st_mode)) return {PathKind::kDirectory, ""};
    return {PathKind::kSpecial, SpecialKindName(st.st_mode)};
  }
  const int stat_errno = errno;
  if (stat_errno == ELOOP) return {PathKind::kLinkLoop, ""};
  if (stat_errno == ENOENT || stat_errno == ENOTDIR) {
    // Missing, or a symlink whose target is missing.
    struct stat lst {};
    if (::lstat(path.c_str(), &lst) == 0 && S_ISLNK(lst.st_mode)) {
      std::error_code ec;
      const fs::path target = fs::read_symlink(path, ec);
      return {PathKind::kDanglingLink, ec ? std::string() : target.string()};
    }
    return {PathKind::kMissing, ""};
  }
  return {PathKind::kUnreadable, std::strerror(stat_errno)};
}

std::string DescribeNotRegular(const PathInfo& info) {
  switch (info.kind) {
    case PathKind::kMissing:
      return "no such file";
    case PathKind::kRegularFile:
      return "is a regular file";
    case PathKind::kDirectory:
      return "is a folder, expected a file";
    case PathKind::kSpecial:
      return "is " + info.detail + ", expected a regular file";
    case PathKind::kDanglingLink:
      return "dangling symbolic link" +
             (info.detail.empty() ? std::string() : " (to '" + info.detail + "')");
    case PathKind::kLinkLoop:
      return "symbolic link loop";
    case PathKind::kUnreadable:
      return "cannot access: " + info.detail;
  }
  return "not a regular file";
}

std::string ReadFile(const fs::path& path, uint64_t max_bytes) {
  // Open first, then check what was opened (no window between check and open). O_NONBLOCK
  // makes opening a FIFO return at once instead of waiting for a writer.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) {
    const int open_errno = errno;
    const PathInfo info = ProbePath(path);
    if (info.kind != PathKind::kRegularFile && info.kind != PathKind::kUnreadable) {
      throw InputError(path, DescribeNotRegular(info));
    }
    if (open_errno == EACCES || open_errno == EPERM) throw InputError(path, "permission denied");
    throw InputError(path, std::string("cannot open: ") + std::strerror(open_errno));
  }
  FdCloser closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    throw InputError(path, std::string("cannot stat: ") + std::strerror(errno));
  }
  if (S_ISDIR(st.st_mode)) throw InputError(path, "is a folder, expected a file");
  if (!S_ISREG(st.st_mode)) {
    throw InputError(path, "is " + SpecialKindName(st.st_mode) + ", expected a regular file");
  }
  const auto size = static_cast<uint64_t>(st.st_size);
  if (size > max_bytes) {
    throw InputError(path, "file is " + std::to_string(size) + " bytes, more than the " +
                               FormatCap(max_bytes) + " this kind of file may have");
  }
  // A regular file never blocks; clear O_NONBLOCK anyway so that reads are plain.
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  std::string content(static_cast<size_t>(size), '\0');
  size_t done = 0;
  while (done < content.size()) {
    const ssize_t n = ::read(fd, content.data() + done, content.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno == EISDIR) throw InputError(path, "is a folder, expected a file");
      throw InputError(path, std::string("read error: ") + std::strerror(errno));
    }
    if (n == 0) {
      throw InputError(path, "file shrank while being read (" + std::to_string(done) + " of " +
                                 std::to_string(size) + " bytes)");
    }
    done += static_cast<size_t>(n);
  }
  return content;
}

fs::path TemporaryPathFor(const fs::path& path) {
  static std::atomic<unsigned> counter{0};
  const std::string name = "." + path.stem().string() + ".tmp" + std::to_string(::getpid()) +
                           "-" + std::to_string(counter++) + path.extension().string();
  return path.parent_path() / name;
}

void WriteAtomically(const fs::path& path, const std::function<bool(const fs::path&)>& write) {
  std::error_code ec;
  if (path.has_parent_path()) {
    fs::create_directories(path.parent_path(), ec);
    if (ec) throw OutputError(path, "cannot create folder: " + ec.message());
  }
  const fs::path tmp = TemporaryPathFor(path);
  // Registered before the file exists, so a signal at any point removes it.
  const RemoveOnInterrupt guard(tmp);
  bool ok = false;
  try {
    ok = write(tmp);
  } catch (...) {
    fs::remove(tmp, ec);
    throw;
  }
  if (!ok) {
    fs::remove(tmp, ec);
    throw OutputError(path, "writing failed");
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw OutputError(path, ec.message());
  }
}

void WriteFileAtomically(const fs::path& path, std::string_view content) {
  WriteAtomically(path, [&](const fs::path& tmp) {
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0) throw OutputError(path, std::strerror(errno));
    size_t done = 0;
    while (done < content.size()) {
      const ssize_t n = ::write(fd, content.data() + done, content.size() - done);
      if (n < 0 && errno == EINTR) continue;
      if (n <= 0) {
        const int write_errno = n < 0 ? errno : ENOSPC;
        ::close(fd);
        throw OutputError(path, StringPrintf("write failed after %zu of %zu bytes: %s", done,
                                             content.size(), std::strerror(write_errno)));
      }
      done += static_cast<size_t>(n);
    }
    // Network and some local file systems report a full disk only here.
    if (::close(fd) != 0) {
      throw OutputError(path, std::string("write failed on close: ") + std::strerror(errno));
    }
    return true;
  });
}

uint64_t FolderSizeBytes(const fs::path& folder) {
  uint64_t bytes = 0;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code size_ec;
    if (it->is_regular_file(size_ec)) {
      const auto size = it->file_size(size_ec);
      if (!size_ec) bytes += size;
    }
  }
  return bytes;
}

}  // namespace hw::core
