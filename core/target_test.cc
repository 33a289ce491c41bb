// target.yaml: core/target.cc, declared in core/rig.h.
#include "core/rig.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"
#include "tests/support.h"

namespace hw::core {
namespace {

namespace fs = std::filesystem;
using hw::test::LineOf;
using hw::test::Replace;
using ::testing::HasSubstr;
using ::testing::StartsWith;

// The what() of the InputError that ParseTarget throws on `text`, or "<no error>".
std::string TargetError(const std::string& text) {
  try {
    ParseTarget(text, "target.yaml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "<no error>";
}

void ExpectSameTarget(const Target& a, const Target& b) {
  EXPECT_EQ(a.type, b.type);
  EXPECT_EQ(a.rows, b.rows);
  EXPECT_EQ(a.cols, b.cols);
  EXPECT_EQ(a.square_m, b.square_m);
  EXPECT_EQ(a.pitch_m, b.pitch_m);
  EXPECT_EQ(a.family, b.family);
  EXPECT_EQ(a.thickness_m, b.thickness_m);
}

TEST(TargetTest, TypeNames) {
  EXPECT_EQ(TargetTypeName(TargetType::kSquareGrid), "square_grid");
  EXPECT_EQ(TargetTypeName(TargetType::kChessboard), "chessboard");
  EXPECT_EQ(TargetTypeName(TargetType::kAprilGrid), "aprilgrid");
}

TEST(TargetTest, ReadsTheSpecExample) {
  const Target target = ParseTarget(R"(type: square_grid    # square_grid | chessboard | aprilgrid
rows: 4              # square_grid: squares per column; chessboard: inner corners per column
cols: 6              # square_grid: squares per row;    chessboard: inner corners per row
square_m: 0.030      # side of one square (aprilgrid: side of one tag)
pitch_m: 0.050       # square_grid and aprilgrid: centre-to-centre distance
)",
                                    "target.yaml");
  EXPECT_EQ(target.type, TargetType::kSquareGrid);
  EXPECT_EQ(target.rows, 4);
  EXPECT_EQ(target.cols, 6);
  EXPECT_EQ(target.square_m, 0.030);
  EXPECT_EQ(target.pitch_m, 0.050);
  EXPECT_EQ(target.family, "");
}

TEST(TargetTest, RoundTripsEveryType) {
  const fs::path dir = hw::test::TestFolder();
  Target square_grid{TargetType::kSquareGrid, 4, 6, 0.03, 0.05, ""};
  Target thick_grid{TargetType::kSquareGrid, 4, 6, 0.03, 0.05, "", 0.003};
  Target chessboard{TargetType::kChessboard, 6, 9, 0.1 / 3.0, 0, ""};
  Target aprilgrid{TargetType::kAprilGrid, 1, 1, 0.088, 0.088 * 1.3, "tagStandard41h12"};
  for (const Target& target : {square_grid, thick_grid, chessboard, aprilgrid}) {
    SCOPED_TRACE(TargetTypeName(target.type));
    ASSERT_EQ(target.Check(), "");
    const fs::path path = dir / (TargetTypeName(target.type) + std::to_string(target.thickness_m) + ".yaml");
    WriteTarget(path, target);
    ExpectSameTarget(target, ReadTarget(path));
  }
}

TEST(TargetTest, MalformedTargetsThrowInputError) {
  const std::string grid = "type: square_grid\nrows: 4\ncols: 6\nsquare_m: 0.03\npitch_m: 0.05\n";
  const std::string chess = "type: chessboard\nrows: 6\ncols: 9\nsquare_m: 0.025\n";
  const std::string april =
      "type: aprilgrid\nrows: 6\ncols: 6\nsquare_m: 0.088\npitch_m: 0.11\nfamily: tag36h11\n";
  EXPECT_EQ(TargetError(grid), "<no error>");
  EXPECT_EQ(TargetError(chess), "<no error>");
  EXPECT_EQ(TargetError(april), "<no error>");
  EXPECT_EQ(TargetError(Replace(grid, "rows: 4", "rows: 1")), "<no error>");
  EXPECT_EQ(TargetError(grid + "thickness_m: 0.003\n"), "<no error>");
  EXPECT_EQ(ParseTarget(grid + "thickness_m: 0.003\n", "target.yaml").thickness_m, 0.003);
  EXPECT_EQ(ParseTarget(grid, "target.yaml").thickness_m, 0.0);
  const std::vector<std::pair<std::string, std::string>> cases = {
      {Replace(grid, "pitch_m: 0.05", "pitch_m: 0.03"),
       "target.yaml: pitch_m: must be > square_m (0.03) and <= 10 m for square_grid, got 0.03 "
       "(line 5)"},
      {Replace(grid, "pitch_m: 0.05\n", ""), "pitch_m: missing required key"},
      {Replace(april, "pitch_m: 0.11\n", ""), "pitch_m: missing required key"},
      {chess + "pitch_m: 0.03\n", "pitch_m: not used for chessboard"},
      {Replace(april, "family: tag36h11\n", ""), "family: missing required key"},
      {Replace(april, "tag36h11", "tag99h1"), "family: unknown AprilTag family 'tag99h1'"},
      {Replace(april, "tag36h11", "[tag36h11]"), "family: must be a name, got a list"},
      {grid + "family: tag36h11\n", "family: only for aprilgrid, not square_grid"},
      {chess + "thickness_m: 0.003\n", "thickness_m: only for square_grid, not chessboard"},
      {grid + "thickness_m: -0.001\n", "thickness_m: must be in [0, 0.05] m, got -0.001 (line 6)"},
      {grid + "thickness_m: 0.06\n", "thickness_m: must be in [0, 0.05] m, got 0.06 (line 6)"},
      {Replace(chess, "rows: 6", "rows: 1"), "rows: must be in [2, 1000] for chessboard, got 1"},
      {Replace(chess, "cols: 9", "cols: 1"), "cols: must be in [2, 1000] for chessboard, got 1"},
      {Replace(grid, "rows: 4", "rows: 0"), "rows: must be in [1, 1000] for square_grid, got 0"},
      {Replace(april, "cols: 6", "cols: -1"), "cols: must be in [1, 1000] for aprilgrid, got -1"},
      {Replace(grid, "rows: 4", "rows: 4.5"), "rows: must be an integer, got '4.5'"},
      {Replace(grid, "square_m: 0.03", "square_m: 0"), "square_m: must be in [1e-4, 10] m, got 0"},
      {Replace(grid, "square_m: 0.03", "square_m: '0.03'"),
       "square_m: must be a number, got string \"0.03\""},
      {Replace(grid, "square_grid", "checkerboard"),
       "type: must be square_grid, chessboard or aprilgrid, got 'checkerboard'"},
      {Replace(grid, "type: square_grid\n", ""), "type: missing required key"},
      {grid + "margin_m: 0.01\n", "top level: unknown key 'margin_m' (line 6)"},
      {grid + "rows: 5\n", "top level: duplicate key 'rows'"},
      {"", "target.yaml: empty file"},
      {"type: [chessboard\n", "YAML syntax error"},
  };
  for (const auto& [text, expected] : cases) {
    SCOPED_TRACE(text);
    EXPECT_THAT(TargetError(text), HasSubstr(expected));
  }
}

TEST(TargetTest, SizesAndCountsHaveRanges) {
  const std::string grid = "type: square_grid\nrows: 4\ncols: 6\nsquare_m: 0.03\npitch_m: 0.05\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {Replace(grid, "square_m: 0.03", "square_m: 1e-300"),
       "target.yaml: square_m: must be in [1e-4, 10] m, got 1e-300 (line 4)"},
      {Replace(grid, "square_m: 0.03", "square_m: 11"),
       "target.yaml: square_m: must be in [1e-4, 10] m, got 11 (line 4)"},
      {Replace(grid, "pitch_m: 0.05", "pitch_m: 1e300"),
       "target.yaml: pitch_m: must be > square_m (0.03) and <= 10 m for square_grid, got 1e300 "
       "(line 5)"},
      {Replace(grid, "rows: 4", "rows: 1001"),
       "target.yaml: rows: must be in [1, 1000] for square_grid, got 1001 (line 2)"},
      {Replace(grid, "cols: 6", "cols: 2000000000"),
       "target.yaml: cols: must be in [1, 1000] for square_grid, got 2000000000 (line 3)"},
  };
  for (const auto& [text, expected] : cases) {
    SCOPED_TRACE(text);
    EXPECT_EQ(TargetError(text), expected);
  }
  // The edges are targets.
  EXPECT_EQ(TargetError(Replace(grid, "square_m: 0.03", "square_m: 1e-4")), "<no error>");
  EXPECT_EQ(TargetError(Replace(Replace(grid, "square_m: 0.03", "square_m: 9"), "pitch_m: 0.05",
                                "pitch_m: 10")),
            "<no error>");
  EXPECT_EQ(TargetError(Replace(Replace(grid, "rows: 4", "rows: 1000"), "cols: 6", "cols: 1000")),
            "<no error>");
  // A family name is quoted on one line, whatever it holds.
  EXPECT_THAT((Target{TargetType::kAprilGrid, 6, 6, 0.088, 0.11, "tag\n36h11"}).Check(),
              StartsWith("family: unknown AprilTag family 'tag\\n36h11' (known: tag16h5, "));
}

TEST(TargetTest, CheckNamesTheBadField) {
  EXPECT_THAT((Target{TargetType::kChessboard, 6, 9, 0.02, 0.03, ""}).Check(),
              StartsWith("pitch_m: not used for chessboard"));
  EXPECT_THAT((Target{TargetType::kAprilGrid, 6, 9, 0.02, 0.03, ""}).Check(),
              StartsWith("family: unknown AprilTag family ''"));
  EXPECT_THAT((Target{TargetType::kSquareGrid, 6, 9, NAN, 0.03, ""}).Check(),
              StartsWith("square_m: must be finite, got nan"));
}

TEST(TargetTest, FuzzNeverCrashes) {
  const std::string april =
      "type: aprilgrid\nrows: 6\ncols: 6\nsquare_m: 0.088\npitch_m: 0.11\nfamily: tag36h11\n";
  std::mt19937 rng(99);
  int accepted = 0;
  for (int i = 0; i < 1000; ++i) {
    const size_t n = static_cast<size_t>(i);
    std::string text = april.substr(0, std::min(n, april.size()));
    if (n >= april.size()) text[rng() % text.size()] = static_cast<char>(rng() % 128);
    try {
      const Target target = ParseTarget(text, "target.yaml");
      EXPECT_EQ(target.Check(), "");
      ++accepted;
    } catch (const InputError&) {
    }
  }
  EXPECT_GT(accepted, 0);
}

}  // namespace
}  // namespace hw::core
