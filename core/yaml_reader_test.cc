#include "core/yaml_reader.h"

#include <sys/stat.h>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "core/atomic_file.h"
#include "core/error.h"
#include "core/rig.h"
#include "tests/support.h"

// The text rules every config reader shares (byte order mark, line ends, control
// characters, nesting, size, one-line messages), through ParseRig and ParseTarget; the
// .cameramodel reader's are in cameramodel_io_test.cc.

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using hw::test::LineOf;
using hw::test::Replace;
using ::testing::HasSubstr;
using ::testing::StartsWith;

// A rig with a depth and a thermal camera, each line distinct.
const char* const kRig = R"(version: 1
depth_scale: 1000.0
cameras:
  depth:
    width: 640
    height: 480
    model: pinhole
    fx: 525.0
    fy: 526.0
    cx: 319.5
    cy: 239.5
    distortion: []
  thermal:
    width: 160
    height: 120
    model: opencv
    fx: 180.5
    fy: 181.5
    cx: 79.5
    cy: 59.5
    distortion: [-0.3, 0.12, 0.0005, 0.0007]
extrinsics:
  depth_from_thermal: { q_xyzw: [0.0, 0.0, 0.6, 0.8], t_m: [0.03, 0.01, -0.002] }
time_offset_s:
  thermal: -0.04
thermal:
  raw_scale: 0.01
  raw_offset: -273.15
  spectral_band_um: [7.5, 14.0]
  netd_k: 0.04
  emissivity: 0.95
  reflected_c: 20.0
)";

// The what() of the InputError that ParseRig / ParseTarget throws on `text`, or "<no error>".
std::string RigError(const std::string& text) {
  try {
    ParseRig(text, "rig.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "<no error>";
}

std::string TargetError(const std::string& text) {
  try {
    ParseTarget(text, "target.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "<no error>";
}

// ---------------------------------------------------------------------------------------
// The helpers themselves.

TEST(ConfigTextTest, PrepareConfigTextNormalisesOnlyWhatItMust) {
  EXPECT_EQ(PrepareConfigText("a: 1\r\nb: 2\rc: 3\n", "x"), "a: 1\nb: 2\nc: 3\n");
  EXPECT_EQ(PrepareConfigText("\xEF\xBB\xBF"
                              "a:\t1\r\r\n",
                              "x"),
            "a:\t1\n\n");
  EXPECT_EQ(PrepareConfigText("", "x"), "");
  // A byte order mark elsewhere, and any other UTF-8, is text.
  EXPECT_EQ(PrepareConfigText("# \xEF\xBB\xBF 20 \xC2\xB0"
                              "C\n",
                              "x"),
            "# \xEF\xBB\xBF 20 \xC2\xB0"
            "C\n");
}

TEST(ConfigTextTest, MessageHelpers) {
  EXPECT_EQ(OneLine("a\nb\rc\td\x01"
                    "e\x7f"),
            "a\\nb\\rc\\td\\x01e\\x7F");
  EXPECT_EQ(Printable(std::string(50, 'x')), std::string(40, 'x') + "...");
  EXPECT_EQ(MessageNumber(1e300), "1e300");
  EXPECT_EQ(MessageNumber(1e-320), "1e-320");
  EXPECT_EQ(MessageNumber(-2.5e-7), "-2.5e-7");
  EXPECT_EQ(MessageNumber(0.01), "0.01");
  EXPECT_EQ(MessageNumber(-273.15), "-273.15");
  EXPECT_EQ(MessageNumber(std::numeric_limits<double>::quiet_NaN()), "nan");
  EXPECT_EQ(MessageNumber(-std::numeric_limits<double>::infinity()), "-inf");
  EXPECT_EQ(RangeProblem("k", 5, 1, 10, "m"), "");
  EXPECT_EQ(RangeProblem("k", 1, 1, 10, "m"), "");
  EXPECT_EQ(RangeProblem("k", 10, 1, 10, "m"), "");
  EXPECT_EQ(RangeProblem("k", 0.5, 1, 1e6, "m"), "k: must be in [1, 1e6] m, got 0.5");
  EXPECT_EQ(RangeProblem("k", 2, 0, 1, ""), "k: must be in [0, 1], got 2");
  EXPECT_EQ(RangeProblem("k", std::numeric_limits<double>::quiet_NaN(), 0, 1, ""),
            "k: must be finite, got nan");
  try {
    ThrowInputError("a.yaml", "line 1\nline 2");
    ADD_FAILURE() << "no throw";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "a.yaml: line 1\\nline 2");
  }
}

// ---------------------------------------------------------------------------------------
// Through the readers.

std::string WithLineEnds(const std::string& text, const std::string& line_end) {
  std::string out;
  for (const char c : text) out += c == '\n' ? line_end : std::string(1, c);
  return out;
}

TEST(ConfigTextTest, AcceptsAByteOrderMarkAndEveryLineEnd) {
  const std::string expected = FormatRig(ParseRig(kRig, "rig.yaml"));
  const std::string bad = Replace(kRig, "fx: 180.5", "fx: -3");
  const std::string bad_message =
      "rig.yaml: cameras.thermal.fx: must be in [1, 1e6] px, got -3 (line " +
      std::to_string(LineOf(kRig, "fx: 180.5")) + ")";
  for (const std::string bom : {"", "\xEF\xBB\xBF"}) {
    for (const std::string line_end : {"\n", "\r\n", "\r"}) {
      SCOPED_TRACE(::testing::Message() << "BOM " << !bom.empty() << " line end "
                                        << (line_end == "\n"   ? "LF"
                                            : line_end == "\r" ? "CR"
                                                               : "CRLF"));
      // FormatRig writes every number exactly: the same text is the same rig.
      EXPECT_EQ(FormatRig(ParseRig(bom + WithLineEnds(kRig, line_end), "rig.yaml")), expected);
      // Lines are counted as an editor counts them, whatever the line end.
      EXPECT_EQ(RigError(bom + WithLineEnds(bad, line_end)), bad_message);
      const std::string syntax = RigError(
          bom + WithLineEnds(Replace(kRig, "    fy: 526.0\n", "   fy: 526.0\n"), line_end));
      EXPECT_THAT(syntax, StartsWith("rig.yaml: line " + std::to_string(LineOf(kRig, "fy: 526.0")) +
                                     ": YAML syntax error: "));
    }
  }
  // Mixed line ends (a file edited on two systems): CR, then CRLF, are two line ends.
  const std::string mixed = Replace(Replace(kRig, "version: 1\n", "version: 1\r\r"),
                                    "depth_scale: 1000.0\n", "depth_scale: 0\r\n");
  EXPECT_EQ(RigError(mixed),
            "rig.yaml: depth_scale: must be in [1, 1e6] raw units per metre, got 0 (line 3)");
  // Targets too.
  const Target target =
      ParseTarget("\xEF\xBB\xBFtype: chessboard\rrows: 6\rcols: 9\rsquare_m: 0.025\r", "t.yaml");
  EXPECT_EQ(target.cols, 9);
  EXPECT_EQ(target.square_m, 0.025);
}

TEST(ConfigTextTest, ControlCharactersAreReportedWithLineAndColumn) {
  const std::string full = kRig;
  const int line = LineOf(full, "fx: 525.0");
  EXPECT_EQ(RigError(Replace(full, "fx: 525.0", "fx: 5" + std::string(1, '\0') + "25.0")),
            "rig.yaml: NUL byte at line " + std::to_string(line) + ", column 10");
  // yaml-cpp 0.7 made this "unknown escape character: " followed by the line break itself.
  EXPECT_EQ(RigError("version: 1" + std::string(1, '\0') + "\n"),
            "rig.yaml: NUL byte at line 1, column 11");
  EXPECT_EQ(RigError(std::string(1, '\0')), "rig.yaml: NUL byte at line 1, column 1");
  EXPECT_EQ(RigError(Replace(full, "fx: 525.0", std::string("fx: 5") + '\x01' + "25.0")),
            "rig.yaml: control character 0x01 at line " + std::to_string(line) + ", column 10");
  EXPECT_EQ(RigError(Replace(full, "fx: 525.0", "fx: 525.0 # \x1b[31m")),
            "rig.yaml: control character 0x1B at line " + std::to_string(line) + ", column 17");
  EXPECT_EQ(RigError(Replace(full, "fx: 525.0", "fx: 525.0\x7f")),
            "rig.yaml: control character 0x7F at line " + std::to_string(line) + ", column 14");
  // Columns count characters, not bytes: "°" is two bytes of UTF-8.
  EXPECT_EQ(RigError("# 20 °C\x02\nversion: 1\n"),
            "rig.yaml: control character 0x02 at line 1, column 8");
  // After a byte order mark and CRLF line ends, positions are the editor's.
  EXPECT_EQ(RigError("\xEF\xBB\xBFversion: 1\r\ndepth_scale: 1\x03\r\n"),
            "rig.yaml: control character 0x03 at line 2, column 15");
  EXPECT_EQ(RigError("\xFF\xFEv\0e\0r\0"),
            "rig.yaml: starts with a UTF-16 or UTF-32 byte order mark: save the file as UTF-8");
  // Tabs are text (inside a line; as indentation YAML itself refuses them).
  EXPECT_EQ(RigError(Replace(full, "fx: 525.0", "fx:\t525.0")), "<no error>");
  EXPECT_EQ(TargetError("type: chessboard\nrows: 6" + std::string(1, '\0') +
                        "\ncols: 9\nsquare_m: 0.025\n"),
            "target.yaml: NUL byte at line 2, column 8");
}

TEST(ConfigTextTest, DeepNestingIsReportedAsSuch) {
  // yaml-cpp 0.7 reported 500 nested nodes as "bad file"; heatwave stops at 32 levels.
  EXPECT_EQ(RigError("version: " + std::string(3000, '[') + std::string(3000, ']') + "\n"),
            "rig.yaml: line 1: YAML nesting deeper than 32 levels of mappings and lists");
  std::string flow_maps = "version: ";
  for (int i = 0; i < 3000; ++i) flow_maps += "{a: ";
  flow_maps += "1" + std::string(3000, '}') + "\n";
  EXPECT_EQ(RigError(flow_maps),
            "rig.yaml: line 1: YAML nesting deeper than 32 levels of mappings and lists");
  // Block style: a mapping per line, each indented one more.
  std::string block = "version:\n";
  for (int i = 1; i < 600; ++i) block += std::string(static_cast<size_t>(i), ' ') + "a:\n";
  EXPECT_EQ(RigError(block),
            "rig.yaml: line 33: YAML nesting deeper than 32 levels of mappings and lists");
  // 32 levels (the top-level mapping and 31 lists) are YAML heatwave reads, and reports on.
  EXPECT_EQ(RigError("version: " + std::string(31, '[') + std::string(31, ']') + "\n"),
            "rig.yaml: version: must be an integer, got a list (line 1)");
  EXPECT_THAT(RigError("version: " + std::string(32, '[') + std::string(32, ']') + "\n"),
              HasSubstr("nesting deeper than 32 levels"));
  EXPECT_THAT(TargetError("type: " + std::string(100, '[') + "\n"),
              HasSubstr("nesting deeper than 32 levels"));
}

TEST(ConfigTextTest, EveryErrorMessageIsOneLine) {
  // Malformed inputs chosen to put line breaks, carriage returns and control characters
  // wherever a message quotes the file: keys, names, strings, yaml-cpp's own messages.
  const std::string full = kRig;
  const std::string april =
      "type: aprilgrid\nrows: 6\ncols: 6\nsquare_m: 0.088\npitch_m: 0.11\nfamily: tag36h11\n";
  std::vector<std::string> rigs, targets;
  // YAML escapes (in double quotes they become the character), raw characters, broken
  // escapes yaml-cpp reports with the character in its message.
  std::vector<std::string> injections = {"\\n",     "\\r",  "\\t",  "\\x01",      "\\0", "\\e",
                                         "\\u2028", "\\\n", "\\\r", "\\\r\n",     "\n",  "\r",
                                         "\r\n",    "\x01", "\x1b", "\x7f",       "\\q", "\\",
                                         "\"",      "'",    "\\x",  "\\U0000000A"};
  injections.push_back(std::string(1, '\0'));
  for (const std::string& inject : injections) {
    for (const std::string quote : {"\"", "'", ""}) {
      const std::string value = quote + "pin" + inject + "hole" + quote;
      rigs.push_back(Replace(full, "model: pinhole", "model: " + value));
      rigs.push_back(Replace(full, "    fx: 525.0\n", "    " + value + ": 525.0\n"));
      rigs.push_back(Replace(full, "version: 1", "version: " + value));
      rigs.push_back(Replace(full, "fx: 525.0", "fx: " + value));
      rigs.push_back(Replace(full, "version: 1", "version: 1\n" + value));
      rigs.push_back(value);
      rigs.push_back("version: !<" + value + "> 1\n");
      targets.push_back(Replace(april, "family: tag36h11", "family: " + value));
      targets.push_back(Replace(april, "type: aprilgrid", "type: " + value));
      targets.push_back(april + value + ": 1\n");
    }
  }
  int errors = 0;
  const auto expect_one_line = [&](const std::string& error, const std::string& input) {
    if (error == "<no error>") return;
    ++errors;
    for (const char c : error) {
      ASSERT_FALSE(static_cast<unsigned char>(c) < 0x20 || c == 0x7f)
          << "control character " << static_cast<int>(c) << " in " << error << "\ninput: " << input;
    }
  };
  for (const std::string& text : rigs) expect_one_line(RigError(text), text);
  for (const std::string& text : targets) expect_one_line(TargetError(text), text);
  EXPECT_GT(errors, 500);
}

TEST(ConfigTextTest, OversizedFilesAndFifosAreRefusedAtOnce) {
  const fs::path dir = hw::test::TestFolder();
  // 2 MB: a valid rig padded with a comment, so that only the size is wrong.
  const std::string big = kRig + ("#" + std::string(2'000'000, 'x'));
  WriteFileAtomically(dir / "big" / "rig.yaml", big);
  const auto start = std::chrono::steady_clock::now();
  try {
    ReadRig(dir / "big" / "rig.yaml");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.path(), dir / "big" / "rig.yaml");
    EXPECT_EQ(e.reason(), "file is " + std::to_string(big.size()) +
                              " bytes, more than the 1 MiB this kind of file may have");
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
  WriteFileAtomically(dir / "big" / "target.yaml", std::string(2'000'000, '#'));
  EXPECT_THROW(ReadTarget(dir / "big" / "target.yaml"), InputError);

  // A FIFO with no writer: opening it for reading would block forever. Read in a child
  // process, so that a hang fails the test instead of stalling it.
  for (const std::string name : {"rig.yaml", "target.yaml"}) {
    SCOPED_TRACE(name);
    const fs::path fifo = dir / "fifo" / name;
    fs::create_directories(fifo.parent_path());
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
    const int exit_code = hw::test::RunInChild(
        [&] {
          try {
            if (name == "rig.yaml") {
              ReadRig(fifo);
            } else {
              ReadTarget(fifo);
            }
          } catch (const InputError& e) {
            return std::string(e.what()) == fifo.string() + ": is a FIFO, expected a regular file"
                       ? 0
                       : 2;
          }
          return 1;
        },
        10);
    EXPECT_EQ(exit_code, 0) << "1: no error, 2: another message, -1: hung";
  }
}

}  // namespace
}  // namespace hw::core
