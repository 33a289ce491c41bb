#include "cli/reconstruct.h"

#include <gtest/gtest.h>

namespace hw::cli {
namespace {

// The summary says how many recovered frames came back from a keyframe, only when some did.
TEST(ReconstructSummary, SaysWhichRecoveriesCameFromKeyframes) {
  ReconstructCommandResult r;
  r.depth_frames = r.fused = r.tracked = 10;
  EXPECT_EQ(FormatReconstructSummary(r).find("keyframe"), std::string::npos);
  r.recovered = 2;
  r.recovered_from_keyframe = 1;
  r.keyframes = 7;
  const std::string summary = FormatReconstructSummary(r);
  EXPECT_NE(summary.find("Tracking   1 of the 2 recovered frames relocalised from a keyframe's pose (7 keyframes kept; "
                         "--relocalisation-candidates)"),
            std::string::npos)
      << summary;
}

// ... and how many relocalisation candidates the model's free space rejected, only when any.
TEST(ReconstructSummary, SaysHowManyRelocalisationsTheModelRejected) {
  ReconstructCommandResult r;
  r.depth_frames = r.fused = r.tracked = 10;
  EXPECT_EQ(FormatReconstructSummary(r).find("relocalisation candidates"), std::string::npos);
  r.relocalisations_rejected = 4;
  const std::string summary = FormatReconstructSummary(r);
  EXPECT_NE(summary.find("Tracking   4 relocalisation candidates rejected: the live depth contradicted the model "
                         "seen from there (--relocalisation-max-conflict)"),
            std::string::npos)
      << summary;
}

// ... and how many pre-aligned rotations the depth refused, only when any.
TEST(ReconstructSummary, SaysHowManyPrealignmentsTheDepthRefused) {
  ReconstructCommandResult r;
  r.depth_frames = r.fused = r.tracked = 10;
  EXPECT_EQ(FormatReconstructSummary(r).find("pre-alignments"), std::string::npos);
  r.prealign_rejected_by_depth = 3;
  const std::string summary = FormatReconstructSummary(r);
  EXPECT_NE(summary.find("Tracking   3 rotation pre-alignments not used: the depth disagreed with the rotation the "
                         "grey images gave"),
            std::string::npos)
      << summary;
}

}  // namespace
}  // namespace hw::cli
