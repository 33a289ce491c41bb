#include "cli/reconstruct.h"

#include <string>

#include <gtest/gtest.h>

namespace hw::cli {
namespace {

// A summary line that appears only when its count is set: absent (no `absent_key`) for a
// run where every frame tracked, then `line` after `set` fills the count in.
void ExpectLineOnlyWhenCounted(const char* absent_key, void (*set)(ReconstructCommandResult&),
                               const std::string& line) {
  ReconstructCommandResult r;
  r.depth_frames = r.fused = r.tracked = 10;
  EXPECT_EQ(FormatReconstructSummary(r).find(absent_key), std::string::npos);
  set(r);
  const std::string summary = FormatReconstructSummary(r);
  EXPECT_NE(summary.find(line), std::string::npos) << summary;
}

// The summary says how many recovered frames came back from a keyframe, only when some did.
TEST(ReconstructSummary, SaysWhichRecoveriesCameFromKeyframes) {
  ExpectLineOnlyWhenCounted(
      "keyframe",
      [](ReconstructCommandResult& r) {
        r.recovered = 2;
        r.recovered_from_keyframe = 1;
        r.keyframes = 7;
      },
      "Tracking   1 of the 2 recovered frames relocalised from a keyframe's pose (7 keyframes kept; "
      "--relocalisation-candidates)");
}

// ... and how many relocalisation candidates the model's free space rejected, only when any.
TEST(ReconstructSummary, SaysHowManyRelocalisationsTheModelRejected) {
  ExpectLineOnlyWhenCounted(
      "relocalisation candidates", [](ReconstructCommandResult& r) { r.relocalisations_rejected = 4; },
      "Tracking   4 relocalisation candidates rejected: the live depth contradicted the model seen from there "
      "(--relocalisation-max-conflict)");
}

// ... and how many pre-aligned rotations the depth refused, only when any.
TEST(ReconstructSummary, SaysHowManyPrealignmentsTheDepthRefused) {
  ExpectLineOnlyWhenCounted(
      "pre-alignments", [](ReconstructCommandResult& r) { r.prealign_rejected_by_depth = 3; },
      "Tracking   3 rotation pre-alignments not used: the depth disagreed with the rotation the grey images gave");
}

}  // namespace
}  // namespace hw::cli
