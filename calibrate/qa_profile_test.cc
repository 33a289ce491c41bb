#include "calibrate/qa_profile.h"

#include <cmath>

#include <gtest/gtest.h>

#include "core/error.h"

namespace hw::calibrate {
namespace {

std::string ErrorOf(const std::string& text) {
  try {
    ParseQaProfile(text, "qa.yaml");
  } catch (const core::InputError& e) {
    return e.what();
  }
  return "";
}

TEST(QaProfileTest, ParsesAndKeepsDefaults) {
  const QaProfile p = ParseQaProfile("version: 1\nmax_rms_px: 0.35\nmin_views: 12\n", "qa.yaml");
  EXPECT_DOUBLE_EQ(p.max_rms_px, 0.35);
  EXPECT_EQ(p.min_views, 12);
  EXPECT_DOUBLE_EQ(p.max_worst_px, QaProfile().max_worst_px);
}

TEST(QaProfileTest, ErrorsNameKeyAndLine) {
  EXPECT_EQ(ErrorOf("version: 1\nmax_rms: 1\n"), "qa.yaml: top level: unknown key 'max_rms' (line 2)");
  EXPECT_EQ(ErrorOf("version: 1\nmax_rms_px: big\n"), "qa.yaml: max_rms_px: must be a number, got 'big' (line 2)");
  EXPECT_EQ(ErrorOf("version: 1\nmin_coverage: 1.5\n"), "qa.yaml: min_coverage: must be in [0, 1], got 1.5 (line 2)");
  EXPECT_EQ(ErrorOf("version: 1\nmin_views: 2.5\n"), "qa.yaml: min_views: must be an integer, got '2.5' (line 2)");
}

TEST(QaProfileTest, VerdictsCompareMeasuredWithThreshold) {
  QaProfile p;
  QaMeasurements m;
  m.views = 12;
  m.rms_px = 0.2;
  m.worst_px = 1.1;
  m.max_view_rms_px = 0.4;
  m.outlier_fraction = 0.01;
  m.coverage = 0.7;
  m.max_uncertainty_px = 0.3;
  std::vector<QaCheck> checks = EvaluateQa(p, m);
  ASSERT_EQ(checks.size(), 7u);
  EXPECT_TRUE(AllPass(checks));
  m.rms_px = 0.5;  // at the threshold: passes
  m.coverage = 0.49;
  checks = EvaluateQa(p, m);
  EXPECT_TRUE(checks[1].pass);
  EXPECT_FALSE(checks[5].pass);
  EXPECT_FALSE(AllPass(checks));
  EXPECT_EQ(FailedCheckNames(checks), "coverage");
  EXPECT_EQ(FailedCheckNames(EvaluateQa(p, QaMeasurements{})).empty(), false);
  EXPECT_EQ(FormatQaCheck(checks[5]), "FAIL  coverage              0.49 >= 0.5  image cells (8 x 6) observed");
  m.worst_px = std::nan("");
  EXPECT_FALSE(EvaluateQa(p, m)[2].pass);  // NaN never passes
}

}  // namespace
}  // namespace hw::calibrate
