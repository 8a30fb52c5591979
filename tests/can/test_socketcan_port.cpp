// The real CanPort against a kernel vcan interface. Needs PF_CAN and an
// interface named by $EXODAQ_VCAN (default vcan0): skipped on machines whose
// kernel has no CAN (the usual build host), run for real inside the VM.
#include <gtest/gtest.h>

TEST(SocketCanPort, Placeholder) {
  SUCCEED();
}
