#include "core/atomic_file.h"

#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>

#include "core/error.h"

namespace hw::core {

namespace fs = std::filesystem;

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
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw OutputError(path, std::strerror(errno));
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
    out.flush();
    if (!out) throw OutputError(path, "write failed (disk full?)");
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

std::string ReadFile(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) throw InputError(path, "no such file");
  if (fs::is_directory(path, ec)) throw InputError(path, "is a folder, expected a file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
  // One read of the whole file (scan frames and meshes can be large).
  in.seekg(0, std::ios::end);
  const std::streamoff size = in.tellg();
  if (size < 0) throw InputError(path, "cannot determine the file size");
  in.seekg(0, std::ios::beg);
  std::string content(static_cast<size_t>(size), '\0');
  in.read(content.data(), size);
  if (in.gcount() != size) throw InputError(path, "read error");
  return content;
}

}  // namespace hw::core
