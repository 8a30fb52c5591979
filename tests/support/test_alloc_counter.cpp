// The allocation counter itself: a zero-allocation test is only as good as
// the counter that can see an allocation.
#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "alloc_counter.hpp"

TEST(AllocationCounter, SeesOperatorNewAndTheCAllocator) {
  exodaq::test::AllocationScope scope;
  auto p = std::make_unique<int>(1);
  EXPECT_EQ(scope.count(), 1u);
  std::vector<double> v(100);
  EXPECT_EQ(scope.count(), 2u);
  void* c = std::malloc(16);  // what LCM and glib use
  EXPECT_EQ(scope.count(), 3u);
  c = std::realloc(c, 64);
  EXPECT_EQ(scope.count(), 4u);
  std::free(c);
  std::string s(200, 'x');
  EXPECT_EQ(scope.count(), 5u);
}

TEST(AllocationCounter, CountsPerThreadAndPerProcess) {
  exodaq::test::AllocationScope scope;
  const auto before = exodaq::test::process_allocations();
  std::thread([] { auto p = std::make_unique<long>(3); }).join();
  EXPECT_GE(exodaq::test::process_allocations() - before, 1u);
}
