#include "core/atomic_file.h"

#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "core/error.h"
#include "core/interrupt.h"
#include "tests/support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;

size_t CountFiles(const fs::path& dir) {
  size_t n = 0;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) n += entry.is_regular_file();
  return n;
}

TEST(AtomicFile, TemporaryNameKeepsFolderAndExtension) {
  const fs::path tmp = TemporaryPathFor("/a/b/frame.png");
  EXPECT_EQ(tmp.parent_path(), fs::path("/a/b"));
  EXPECT_EQ(tmp.extension(), ".png");
  EXPECT_EQ(tmp.filename().string().front(), '.');
  EXPECT_NE(TemporaryPathFor("/a/b/frame.png"), tmp);  // unique per call
}

TEST(AtomicFile, WritesAndReadsBack) {
  const fs::path dir = hw::test::TestFolder("roundtrip");
  const fs::path path = dir / "sub" / "x.txt";
  WriteFileAtomically(path, "hello\n");
  EXPECT_EQ(ReadFile(path, kMaxMeshFileBytes), "hello\n");
  WriteFileAtomically(path, "replaced");
  EXPECT_EQ(ReadFile(path, kMaxMeshFileBytes), "replaced");
  EXPECT_EQ(CountFiles(dir), 1u);
}

TEST(AtomicFile, FailedWriteLeavesOldFileAndNoTemporary) {
  const fs::path dir = hw::test::TestFolder("fail");
  const fs::path path = dir / "out.txt";
  WriteFileAtomically(path, "old");
  EXPECT_THROW(WriteAtomically(path,
                               [](const fs::path& tmp) {
                                 std::ofstream(tmp) << "half";
                                 throw std::runtime_error("interrupted");
                                 return true;
                               }),
               std::runtime_error);
  EXPECT_THROW(WriteAtomically(path,
                               [](const fs::path& tmp) {
                                 std::ofstream(tmp) << "half";
                                 return false;
                               }),
               OutputError);
  EXPECT_EQ(ReadFile(path, kMaxMeshFileBytes), "old");
  EXPECT_EQ(CountFiles(dir), 1u);
}

TEST(AtomicFile, UnwritableFolderIsOutputError) {
  const fs::path dir = hw::test::TestFolder("unwritable");
  // A regular file where a folder is expected: cannot create the parent.
  WriteFileAtomically(dir / "blocker", "x");
  try {
    WriteFileAtomically(dir / "blocker" / "child.txt", "y");
    FAIL() << "expected OutputError";
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("blocker"), std::string::npos) << e.what();
  }
}

TEST(AtomicFile, ReadFileErrorsNameThePath) {
  const fs::path dir = hw::test::TestFolder("read");
  try {
    ReadFile(dir / "missing.yaml", kMaxMeshFileBytes);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), dir / "missing.yaml");
    EXPECT_EQ(e.reason(), "no such file");
    EXPECT_EQ(std::string(e.what()), (dir / "missing.yaml").string() + ": no such file");
  }
  EXPECT_THROW(ReadFile(dir, kMaxMeshFileBytes), InputError);
}


// Each of these used to be opened as a file: a FIFO blocked forever, /dev/zero read without
// end, dangling links and loops read as "no such file".
TEST(AtomicFile, ReadFileRefusesEverythingButRegularFiles) {
  const fs::path dir = hw::test::TestFolder();
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0644), 0);
  fs::create_symlink("fifo", dir / "link-to-fifo");
  fs::create_symlink("/dev/zero", dir / "zero");
  fs::create_symlink("absent.yaml", dir / "dangling");
  fs::create_symlink("loop", dir / "loop");
  fs::create_directories(dir / "folder");
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"fifo", "is a FIFO, expected a regular file"},
      {"link-to-fifo", "is a FIFO, expected a regular file"},
      {"zero", "is a character device, expected a regular file"},
      {"dangling", "dangling symbolic link (to 'absent.yaml')"},
      {"loop", "symbolic link loop"},
      {"folder", "is a folder, expected a file"},
      {"absent", "no such file"}};
  for (const auto& [name, reason] : cases) {
    const int code = hw::test::RunInChild(
        [&] {
          try {
            ReadFile(dir / name, kMaxConfigFileBytes);
          } catch (const InputError& e) {
            return e.reason() == reason ? 0 : 1;
          }
          return 2;
        },
        10);
    EXPECT_EQ(code, 0) << name << (code == hw::test::kTimedOut ? ": hung" : ": wrong reason");
  }
  EXPECT_EQ(ProbePath(dir / "fifo").kind, PathKind::kSpecial);
  EXPECT_EQ(ProbePath(dir / "dangling").kind, PathKind::kDanglingLink);
  EXPECT_EQ(ProbePath(dir / "loop").kind, PathKind::kLinkLoop);
  EXPECT_EQ(ProbePath(dir / "absent").kind, PathKind::kMissing);
  EXPECT_EQ(ProbePath(dir / "folder").kind, PathKind::kDirectory);
}

// The cap is checked on the size before anything is read or allocated: a sparse file that
// claims 2 GB costs nothing.
TEST(AtomicFile, ReadFileRefusesFilesOverTheCapBeforeReading) {
  const fs::path dir = hw::test::TestFolder();
  const fs::path sparse = dir / "rig.yaml";
  { std::ofstream(sparse) << "version: 1\n"; }
  fs::resize_file(sparse, uint64_t{2} << 30);
  try {
    ReadFile(sparse, kMaxConfigFileBytes);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.reason(), "file is 2147483648 bytes, more than the 1 MiB this kind of file may have");
  }
  fs::resize_file(sparse, kMaxConfigFileBytes);
  EXPECT_EQ(ReadFile(sparse, kMaxConfigFileBytes).size(), kMaxConfigFileBytes);
}

TEST(AtomicFile, ReadFileSaysPermissionDenied) {
  const fs::path dir = hw::test::TestFolder();
  WriteFileAtomically(dir / "secret.yaml", "x");
  fs::permissions(dir / "secret.yaml", fs::perms::none);
  const int code = hw::test::RunInChild([&] {
    if (::geteuid() == 0 && (::setgid(65534) != 0 || ::setuid(65534) != 0)) return 10;
    try {
      ReadFile(dir / "secret.yaml", kMaxConfigFileBytes);
    } catch (const InputError& e) {
      return e.reason() == "permission denied" ? 0 : 1;
    }
    return 2;
  });
  EXPECT_EQ(code, 0);
}

// A file size limit fails writes as a full disk does, at the byte we choose.
TEST(AtomicFile, FullDiskIsAnErrorAndLeavesNothing) {
  const fs::path dir = hw::test::TestFolder();
  WriteFileAtomically(dir / "old.txt", "old");
  const std::string content(100000, 'x');
  const int code = hw::test::RunInChild([&] {
    InstallInterruptHandlers();  // SIGXFSZ ignored: EFBIG instead of a core dump
    rlimit limit{};
    limit.rlim_cur = 50000;
    limit.rlim_max = RLIM_INFINITY;
    if (::setrlimit(RLIMIT_FSIZE, &limit) != 0) return 10;
    try {
      WriteFileAtomically(dir / "old.txt", content);
      return 11;
    } catch (const OutputError& e) {
      const std::string what = e.what();
      return what.find("old.txt") != std::string::npos &&
                     what.find("after 50000 of 100000 bytes") != std::string::npos
                 ? 0
                 : 12;
    }
  });
  EXPECT_EQ(code, 0);
  EXPECT_EQ(ReadFile(dir / "old.txt", kMaxConfigFileBytes), "old");
  EXPECT_EQ(CountFiles(dir), 1u);
}

// SIGINT / SIGTERM during a write: the temporary is removed and the process still ends
// by the signal.
TEST(AtomicFile, InterruptRemovesTheTemporary) {
  for (const int signal_number : {SIGINT, SIGTERM}) {
    const fs::path dir = hw::test::TestFolder("signal" + std::to_string(signal_number));
    const int code = hw::test::RunInChild([&] {
      InstallInterruptHandlers();
      WriteAtomically(dir / "frame.png", [&](const fs::path& tmp) {
        std::ofstream(tmp) << "half a frame";
        ::raise(signal_number);
        return true;
      });
      return 0;
    });
    EXPECT_EQ(code, 128 + signal_number);
    EXPECT_TRUE(fs::is_empty(dir)) << "temporary left after signal " << signal_number;
  }
  EXPECT_EQ(NumPathsRegisteredForInterrupt(), 0);
}

}  // namespace
}  // namespace hw::core
