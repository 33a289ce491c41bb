#include "core/interrupt.h"

#include <signal.h>

#include <gtest/gtest.h>

namespace hw::core {
namespace {

// The first SIGINT/SIGTERM inside a StopOnInterrupt only raises the flag (the process goes
// on: this test would die otherwise); outside one, the flag is cleared again.
TEST(StopOnInterrupt, FirstSignalOnlyRequestsAStop) {
  InstallInterruptHandlers();
  EXPECT_FALSE(StopOnInterrupt::StopRequested());
  {
    StopOnInterrupt stop;
    EXPECT_FALSE(StopOnInterrupt::StopRequested());
    ASSERT_EQ(::raise(SIGINT), 0);
    EXPECT_TRUE(StopOnInterrupt::StopRequested());
  }
  EXPECT_FALSE(StopOnInterrupt::StopRequested());
  {
    StopOnInterrupt stop;
    ASSERT_EQ(::raise(SIGTERM), 0);
    EXPECT_TRUE(StopOnInterrupt::StopRequested());
  }
  {
    StopOnInterrupt stop;
    StopOnInterrupt::RequestStop();
    EXPECT_TRUE(StopOnInterrupt::StopRequested());
  }
}

// A second signal ends the process by that signal, as without StopOnInterrupt.
TEST(StopOnInterrupt, SecondSignalEndsTheProcess) {
  EXPECT_EXIT(
      {
        InstallInterruptHandlers();
        StopOnInterrupt stop;
        ::raise(SIGINT);
        ::raise(SIGINT);
        std::_Exit(0);
      },
      ::testing::KilledBySignal(SIGINT), "");
}

}  // namespace
}  // namespace hw::core
