#pragma once
// Counts heap allocations made by the current thread, for tests that prove a
// code path allocates nothing. Link the exodaq_test_alloc object library.
#include <cstdint>

namespace exodaq::test {

// Allocations (operator new / new[] / malloc via operator new) by this thread
// since the thread started.
std::uint64_t thread_allocations() noexcept;
// Allocations by all threads since the process started.
std::uint64_t process_allocations() noexcept;

// Counts allocations by this thread between construction and count().
class AllocationScope {
 public:
  AllocationScope() noexcept : start_(thread_allocations()) {}
  std::uint64_t count() const noexcept { return thread_allocations() - start_; }

 private:
  std::uint64_t start_;
};

}  // namespace exodaq::test
