#include "core/atomic_file.h"

#include <filesystem>
#include <fstream>

#include <gtest/gtest.h>

#include "core/error.h"
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
  EXPECT_EQ(ReadFile(path), "hello\n");
  WriteFileAtomically(path, "replaced");
  EXPECT_EQ(ReadFile(path), "replaced");
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
  EXPECT_EQ(ReadFile(path), "old");
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
    ReadFile(dir / "missing.yaml");
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), dir / "missing.yaml");
    EXPECT_EQ(e.reason(), "no such file");
    EXPECT_EQ(std::string(e.what()), (dir / "missing.yaml").string() + ": no such file");
  }
  EXPECT_THROW(ReadFile(dir), InputError);
}

}  // namespace
}  // namespace hw::core
