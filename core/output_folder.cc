#include "core/output_folder.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <ctime>
#include <system_error>

#include "core/error.h"
#include "core/strings.h"

namespace hw::core {

namespace fs = std::filesystem;

namespace {

// The marker's first line, printable characters only, for messages.
std::string ReadDetail(int fd) {
  char buffer[512];
  const ssize_t n = ::pread(fd, buffer, sizeof(buffer), 0);
  const std::string_view text(buffer, n > 0 ? static_cast<size_t>(n) : 0);
  return OneLineMessage(text.substr(0, text.find('\n')));
}

std::string NowUtc() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&now, &tm);
  char buffer[32];
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buffer;
}

}  // namespace

OutputFolder::OutputFolder(const fs::path& folder, const std::string& description)
    : folder_(folder) {
  std::error_code ec;
  fs::create_directories(folder_, ec);
  if (ec) throw OutputError(folder_, "cannot create folder: " + ec.message());
  if (!fs::is_directory(folder_, ec)) throw OutputError(folder_, "exists and is not a folder");
  const fs::path marker = folder_ / kRunMarkerName;
  struct stat before {};
  created_marker_ = ::lstat(marker.c_str(), &before) != 0;
  // A run that commits unlinks the marker; one that opened it just before then locks a file
  // no longer in the folder. Retry until the locked file is the one at the path.
  for (int attempt = 0; attempt < 100 && fd_ < 0; ++attempt) {
    const int fd = ::open(marker.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK,
                          0644);
    if (fd < 0) throw OutputError(marker, std::string("cannot create: ") + std::strerror(errno));
    struct stat opened {};
    if (::fstat(fd, &opened) != 0 || !S_ISREG(opened.st_mode)) {
      ::close(fd);
      throw OutputError(marker, "exists and is not a regular file");
    }
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      const int lock_errno = errno;
      const std::string detail = ReadDetail(fd);
      ::close(fd);
      if (lock_errno == EWOULDBLOCK) {
        throw OutputError(folder_, "another heatwave run is writing it (" +
                                       (detail.empty() ? std::string("starting") : detail) + ")");
      }
      throw OutputError(marker, std::string("cannot lock: ") + std::strerror(lock_errno));
    }
    struct stat at_path {};
    if (::stat(marker.c_str(), &at_path) == 0 && at_path.st_ino == opened.st_ino &&
        at_path.st_dev == opened.st_dev) {
      fd_ = fd;
    } else {
      ::close(fd);
    }
  }
  if (fd_ < 0) throw OutputError(marker, "cannot lock: the marker keeps being replaced");
  const std::string text = "pid " + std::to_string(::getpid()) + ", " + description +
                           ", started " + NowUtc() + "\n";
  if (::ftruncate(fd_, 0) != 0 ||
      ::pwrite(fd_, text.data(), text.size(), 0) != static_cast<ssize_t>(text.size())) {
    const int write_errno = errno;
    ::close(fd_);
    fd_ = -1;
    throw OutputError(marker, std::string("cannot write: ") + std::strerror(write_errno));
  }
}

OutputFolder::~OutputFolder() {
  if (fd_ >= 0) ::close(fd_);
}

bool OutputFolder::IsEmpty() const {
  std::error_code ec;
  for (fs::directory_iterator it(folder_, ec), end; !ec && it != end; it.increment(ec)) {
    if (it->path().filename() != kRunMarkerName) return false;
  }
  if (ec) throw OutputError(folder_, "cannot list: " + ec.message());
  return true;
}

void OutputFolder::Remove(const std::vector<std::string>& entries) const {
  for (const std::string& entry : entries) {
    std::error_code ec;
    fs::remove_all(folder_ / entry, ec);
    if (ec) throw OutputError(folder_ / entry, "cannot remove: " + ec.message());
  }
}

void OutputFolder::Commit() {
  if (committed_) return;
  const fs::path marker = folder_ / kRunMarkerName;
  if (::unlink(marker.c_str()) != 0 && errno != ENOENT) {
    throw OutputError(marker, std::string("cannot remove: ") + std::strerror(errno));
  }
  committed_ = true;
  ::close(fd_);
  fd_ = -1;
}

void OutputFolder::Abandon() {
  if (committed_) return;
  if (created_marker_) Commit();
}

FolderRun ProbeFolderRun(const fs::path& folder) {
  const fs::path marker = folder / kRunMarkerName;
  const int fd = ::open(marker.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK);
  if (fd < 0) {
    if (errno == ENOENT) return {FolderRunState::kComplete, ""};
    return {FolderRunState::kIncomplete, std::string("run marker: ") + std::strerror(errno)};
  }
  FolderRun run;
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    return {FolderRunState::kIncomplete, "run marker is not a regular file"};
  }
  run.detail = ReadDetail(fd);
  run.state = ::flock(fd, LOCK_SH | LOCK_NB) != 0 && errno == EWOULDBLOCK
                  ? FolderRunState::kBeingWritten
                  : FolderRunState::kIncomplete;
  ::close(fd);
  return run;
}

}  // namespace hw::core
