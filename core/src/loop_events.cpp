#include "exodaq/core/loop_events.hpp"

namespace exodaq::core {

void EventRing::push(const LogEvent& e) noexcept {
  const std::uint64_t head = head_.load(std::memory_order_relaxed);
  if (head - tail_.load(std::memory_order_acquire) >= kCapacity) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  events_[head % kCapacity] = e;
  head_.store(head + 1, std::memory_order_release);
}

bool EventRing::pop(LogEvent& out) noexcept {
  const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
  if (tail == head_.load(std::memory_order_acquire)) return false;
  out = events_[tail % kCapacity];
  tail_.store(tail + 1, std::memory_order_release);
  return true;
}

}  // namespace exodaq::core
