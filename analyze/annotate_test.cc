#include "analyze/annotate.h"

#include <gtest/gtest.h>

namespace hw::analyze {
namespace {
TEST(AnnotateTest, Placeholder) {}
}  // namespace
}  // namespace hw::analyze
