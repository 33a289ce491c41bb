#include "cli/audit.h"

#include <string>

#include <gtest/gtest.h>

namespace hw::cli {
namespace {

// The one-screen summary names the spots to verify from another angle, and only those.
TEST(AuditSummaryTest, PossibleReflectionsAreListedToVerify) {
  AuditResult r;
  r.analysis.detection = analyze::SpotDetection();
  for (const char* id : {"H1", "H2", "H3"}) {
    analyze::Spot s;
    s.id = id;
    s.possible_reflection = std::string(id) != "H1";
    r.analysis.detection->spots.push_back(s);
  }
  EXPECT_NE(FormatAuditSummary(r).find("Verify     2 spots may be reflections (H2, H3): re-image from another angle"),
            std::string::npos)
      << FormatAuditSummary(r);
  r.analysis.detection->spots[2].possible_reflection = false;
  EXPECT_NE(FormatAuditSummary(r).find("Verify     1 spot may be a reflection (H2)"), std::string::npos);
  r.analysis.detection->spots[1].possible_reflection = false;
  EXPECT_EQ(FormatAuditSummary(r).find("Verify"), std::string::npos);
}

}  // namespace
}  // namespace hw::cli
