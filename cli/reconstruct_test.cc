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

}  // namespace
}  // namespace hw::cli
