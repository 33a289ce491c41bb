#include "core/progress.h"

#include <limits>

#include <gtest/gtest.h>

namespace hw::core {
namespace {

TEST(Progress, FormatsDurations) {
  EXPECT_EQ(ProgressBar::FormatDuration(0), "0:00");
  EXPECT_EQ(ProgressBar::FormatDuration(59.4), "0:59");
  EXPECT_EQ(ProgressBar::FormatDuration(61), "1:01");
  EXPECT_EQ(ProgressBar::FormatDuration(3725), "1:02:05");
  EXPECT_EQ(ProgressBar::FormatDuration(-1), "--:--");
  EXPECT_EQ(ProgressBar::FormatDuration(std::numeric_limits<double>::quiet_NaN()), "--:--");
}

TEST(Progress, DrawsRateAndEtaOnStderr) {
  ::testing::internal::CaptureStderr();
  {
    ProgressBar bar("render", 10, "frames");
    for (int i = 0; i < 10; ++i) bar.Advance();
  }
  const std::string out = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(out.find("render"), std::string::npos) << out;
  EXPECT_NE(out.find("10/10"), std::string::npos) << out;
  EXPECT_NE(out.find("100%"), std::string::npos) << out;
  EXPECT_NE(out.find("frames/s"), std::string::npos) << out;
  EXPECT_NE(out.find("ETA"), std::string::npos) << out;
}

TEST(Progress, StagesPrefixTheLabelsAndNest) {
  ::testing::internal::CaptureStderr();
  {
    ProgressStage outer("[2/3]");
    { ProgressBar bar("analyze", 1, "views"); bar.Advance(); }
    {
      ProgressStage inner("[x]");
      ProgressBar bar("inner", 1);
    }
    ProgressBar bar("again", 1);
  }
  { ProgressBar bar("plain", 1); }
  const std::string out = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(out.find("[2/3] analyze"), std::string::npos) << out;
  EXPECT_NE(out.find("[x] inner"), std::string::npos) << out;
  EXPECT_NE(out.find("[2/3] again"), std::string::npos) << out;
  EXPECT_EQ(out.find("] plain"), std::string::npos) << out;
  EXPECT_NE(out.find("plain"), std::string::npos) << out;
}

TEST(Progress, QuietPrintsNothing) {
  ::testing::internal::CaptureStderr();
  {
    ProgressBar bar("render", 10, "frames", /*quiet=*/true);
    bar.Advance(10);
  }
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
}

TEST(Progress, ClampsToTotal) {
  ::testing::internal::CaptureStderr();
  {
    ProgressBar bar("x", 3, "items");
    bar.Advance(7);
  }
  const std::string out = ::testing::internal::GetCapturedStderr();
  EXPECT_NE(out.find("3/3"), std::string::npos) << out;
  EXPECT_EQ(out.find("7/3"), std::string::npos) << out;
}

}  // namespace
}  // namespace hw::core

namespace hw::core {
namespace {

TEST(Progress, LogOutputHasNoDuplicateFinalLine) {
  // Under ctest stderr is not a terminal: one line per 10 %, and the final state once.
  ::testing::internal::CaptureStderr();
  {
    ProgressBar bar("frames", 20, "frames");
    for (int i = 0; i < 20; ++i) bar.Advance();
  }
  const std::string out = ::testing::internal::GetCapturedStderr();
  size_t count = 0;
  for (size_t pos = out.find("20/20"); pos != std::string::npos; pos = out.find("20/20", pos + 1)) ++count;
  EXPECT_EQ(count, 1u) << out;
}

}  // namespace
}  // namespace hw::core
