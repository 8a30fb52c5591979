#pragma once
// A bounded single-producer single-consumer queue of replay entries (private
// to the replay backend): the reader thread pushes, the loop pops. Its
// storage is allocated once, in the constructor; push, peek and pop allocate
// nothing. Each side waits (std::atomic wait, a futex) only when it cannot go
// on: the producer when the ring is full, until half of it is free; the
// consumer when it is empty, until `batch` entries are in or the producer has
// finished. Each side wakes the other only when the other waits and its
// condition is met, so a consumer that never finds the ring empty makes no
// system call but one wake-up of the producer per half ring.
#include <atomic>
#include <cstdint>
#include <vector>

#include "recording.hpp"

namespace exodaq::drivers::replay {

class EntryRing {
 public:
  // `capacity` entries (rounded up to a power of two, at least 2).
  explicit EntryRing(std::size_t capacity);

  // Producer. Waits while full; false once cancel() was called.
  bool push(const Entry& entry) noexcept;
  // No more entries will come.
  void finish() noexcept;

  // Consumer. The oldest entry, waiting while the ring is empty until
  // `batch` entries are in or the producer has finished; nullptr at the end.
  const Entry* peek(std::size_t batch) noexcept;
  void pop() noexcept;
  // Waits until the ring is full or the producer has finished (not counted
  // as a wait).
  void wait_filled() noexcept;

  // Makes a waiting or later push() return false (any thread).
  void cancel() noexcept;
  // Empties the ring for a new producer; only while neither side runs.
  void reset() noexcept;

  std::size_t capacity() const noexcept { return slots_.size(); }
  std::size_t size() const noexcept;
  bool finished() const noexcept { return finished_.load(std::memory_order_acquire); }
  bool cancelled() const noexcept { return cancelled_.load(std::memory_order_acquire); }
  // How often the consumer had to wait.
  std::int64_t consumer_waits() const noexcept {
    return consumer_waits_.load(std::memory_order_relaxed);
  }

 private:
  // Waits until `ready()`; `target` is where the other side must get for it,
  // published so the other side knows to wake this one.
  template <typename Ready>
  static void wait_until(std::atomic<std::uint64_t>& target, std::uint64_t wanted,
                         std::atomic<std::uint32_t>& word, Ready ready) noexcept;
  static void wake(std::atomic<std::uint64_t>& target, std::uint64_t reached,
                   std::atomic<std::uint32_t>& word) noexcept;
  // Consumer: waits until `count` entries are in or the producer has finished.
  void wait_for(std::size_t count) noexcept;

  std::vector<Entry> slots_;
  std::uint64_t mask_;
  alignas(64) std::atomic<std::uint64_t> head_{0};  // next to pop (consumer writes)
  alignas(64) std::atomic<std::uint64_t> tail_{0};  // next to push (producer writes)
  std::atomic<bool> finished_{false};
  std::atomic<bool> cancelled_{false};
  // A waiting side stores the counter value of the other side it waits for
  // (0: not waiting) and sleeps on its word, which the other side bumps.
  alignas(64) std::atomic<std::uint64_t> consumer_wants_tail_{0};
  std::atomic<std::uint32_t> consumer_word_{0};
  alignas(64) std::atomic<std::uint64_t> producer_wants_head_{0};
  std::atomic<std::uint32_t> producer_word_{0};
  std::atomic<std::int64_t> consumer_waits_{0};
};

}  // namespace exodaq::drivers::replay
