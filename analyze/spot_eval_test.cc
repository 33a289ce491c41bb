#include "analyze/spot_eval.h"

#include <gtest/gtest.h>

namespace hw::analyze {
namespace {

Spot At(const std::string& id, double x) {
  Spot s;
  s.id = id;
  s.centroid_in_world = Eigen::Vector3d(x, 0, 0);
  s.area_m2 = 0.01;
  s.area_sigma_m2 = 0.001;
  s.length_m = s.width_m = 0.1;
  return s;
}

TruthSpot Truth(const std::string& id, double x, double fraction) {
  TruthSpot t;
  t.id = id;
  t.centroid_in_world = Eigen::Vector3d(x, 0, 0);
  t.area_m2 = 0.02;
  t.observed_area_m2 = fraction * t.area_m2;
  t.observed_fraction = fraction;
  t.length_m = t.width_m = 0.1;
  return t;
}

// A planted spot the scan saw less of than min_observed_fraction is neither scored nor
// missed, but a detection on it is no false spot (a pipe band seen 49 % from the room, cut
// at 50 %, once made its correct detection count as false); one never seen matches nothing.
TEST(SpotEvalTest, ADetectionOnAPartlyObservedSpotIsNotFalse) {
  const std::vector<TruthSpot> truth = {Truth("full", 0, 1.0), Truth("half", 1, 0.494), Truth("hidden", 2, 0.0),
                                        Truth("missed", 3, 0.8)};
  const std::vector<Spot> spots = {At("H1", 0.01), At("H2", 1.02), At("H3", 2.0), At("H4", 5)};
  const TruthScore score = ScoreAgainstTruth(spots, truth, true, 0.5);
  EXPECT_EQ(score.found, 1);
  EXPECT_EQ(score.missed, 1);
  ASSERT_EQ(score.matches.size(), 2u);  // the scored ones: full, missed
  EXPECT_EQ(score.matches[0].spot_id, "H1");
  EXPECT_NEAR(score.matches[0].area_error, -0.5, 1e-12);
  ASSERT_EQ(score.partly_observed.size(), 1u);
  EXPECT_EQ(score.partly_observed[0].first, "half");
  EXPECT_EQ(score.partly_observed[0].second, "H2");
  EXPECT_EQ(score.false_spots, (std::vector<std::string>{"H3", "H4"}));
  // Scoring everything (a truth mesh): all four considered, H3 takes "hidden".
  const TruthScore all = ScoreAgainstTruth(spots, truth, false);
  EXPECT_EQ(all.found, 3);
  EXPECT_TRUE(all.partly_observed.empty());
  EXPECT_EQ(all.false_spots, (std::vector<std::string>{"H4"}));
}

// Spots flagged as possible reflections are still scored as found or false; the score
// says which of each were flagged (a found one is a true spot wrongly suspected).
TEST(SpotEvalTest, FlaggedReflectionsAreCountedOnBothSides) {
  const std::vector<TruthSpot> truth = {Truth("a", 0, 1.0), Truth("b", 1, 1.0)};
  std::vector<Spot> spots = {At("H1", 0.0), At("H2", 1.0), At("H3", 3.0), At("H4", 4.0)};
  spots[1].possible_reflection = true;
  spots[3].possible_reflection = true;
  const TruthScore score = ScoreAgainstTruth(spots, truth, false);
  EXPECT_EQ(score.found, 2);
  EXPECT_EQ(score.false_spots, (std::vector<std::string>{"H3", "H4"}));
  EXPECT_EQ(score.false_flagged_as_reflections, (std::vector<std::string>{"H4"}));
  EXPECT_EQ(score.found_flagged_as_reflections, (std::vector<std::string>{"H2"}));
}

// ΔT against the truth's: its threshold is half-way from the background to the extreme, so
// the true ΔT is 2 (temperature − threshold); covered within 2 delta_sigma_k.
TEST(SpotEvalTest, DeltaIsScoredAgainstTwiceTheThresholdsDistance) {
  TruthSpot t = Truth("a", 0, 1.0);
  t.temperature_c = 60;
  t.threshold_c = 40;  // background 20, ΔT 40
  Spot s = At("H1", 0);
  s.delta_k = 38.5;
  s.delta_sigma_k = 1.0;
  TruthScore score = ScoreAgainstTruth({s}, {t}, false);
  ASSERT_EQ(score.matches.size(), 1u);
  EXPECT_NEAR(score.matches[0].delta_error_k, -1.5, 1e-12);
  EXPECT_TRUE(score.matches[0].delta_covered);
  EXPECT_NEAR(score.max_abs_delta_error_k, 1.5, 1e-12);
  s.delta_sigma_k = 0.7;
  score = ScoreAgainstTruth({s}, {t}, false);
  EXPECT_FALSE(score.matches[0].delta_covered);
}

}  // namespace
}  // namespace hw::analyze
