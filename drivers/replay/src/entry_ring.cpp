#include "entry_ring.hpp"

#include <algorithm>

namespace exodaq::drivers::replay {

EntryRing::EntryRing(std::size_t capacity) {
  std::size_t n = 2;
  while (n < capacity) n <<= 1;
  slots_.resize(n);
  mask_ = n - 1;
}

// The waiting side: publish what it waits for, look again (the other side
// may have got there meanwhile), then sleep on the word. The other side
// stores its counter before it reads the target (wake()): with both orders
// sequentially consistent, either this side sees the counter or that side
// sees the target and bumps the word, which ends the wait.
template <typename Ready>
void EntryRing::wait_until(std::atomic<std::uint64_t>& target, std::uint64_t wanted,
                           std::atomic<std::uint32_t>& word, Ready ready) noexcept {
  while (!ready()) {
    const std::uint32_t seen = word.load();
    target.store(wanted);
    if (!ready()) word.wait(seen);
    target.store(0);
  }
}

void EntryRing::wake(std::atomic<std::uint64_t>& target, std::uint64_t reached,
                     std::atomic<std::uint32_t>& word) noexcept {
  const std::uint64_t wanted = target.load();
  if (wanted != 0 && reached >= wanted) {
    word.fetch_add(1);
    word.notify_one();
  }
}

bool EntryRing::push(const Entry& entry) noexcept {
  const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
  if (tail - head_.load(std::memory_order_acquire) == capacity()) {
    const std::uint64_t wanted = tail - capacity() / 2;  // half of it free
    wait_until(producer_wants_head_, wanted, producer_word_,
               [&] { return head_.load() >= wanted || cancelled_.load(); });
  }
  if (cancelled_.load(std::memory_order_acquire)) return false;
  slots_[tail & mask_] = entry;
  tail_.store(tail + 1);
  wake(consumer_wants_tail_, tail + 1, consumer_word_);
  return true;
}

void EntryRing::finish() noexcept {
  finished_.store(true);
  const std::uint64_t wanted = consumer_wants_tail_.load();
  if (wanted != 0) wake(consumer_wants_tail_, wanted, consumer_word_);
}

void EntryRing::wait_for(std::size_t count) noexcept {
  const std::uint64_t wanted =
      head_.load(std::memory_order_relaxed) + std::clamp<std::size_t>(count, 1, capacity());
  wait_until(consumer_wants_tail_, wanted, consumer_word_,
             [&] { return tail_.load() >= wanted || finished_.load(); });
}

const Entry* EntryRing::peek(std::size_t batch) noexcept {
  const std::uint64_t head = head_.load(std::memory_order_relaxed);
  if (tail_.load(std::memory_order_acquire) == head) {
    if (!finished_.load(std::memory_order_acquire)) {
      consumer_waits_.fetch_add(1, std::memory_order_relaxed);
      wait_for(batch);
    }
    if (tail_.load(std::memory_order_acquire) == head) return nullptr;  // finished
  }
  return &slots_[head & mask_];
}

void EntryRing::wait_filled() noexcept {
  wait_for(capacity());
}

void EntryRing::pop() noexcept {
  const std::uint64_t head = head_.load(std::memory_order_relaxed) + 1;
  head_.store(head);
  wake(producer_wants_head_, head, producer_word_);
}

void EntryRing::cancel() noexcept {
  cancelled_.store(true);
  const std::uint64_t wanted = producer_wants_head_.load();
  if (wanted != 0) wake(producer_wants_head_, wanted, producer_word_);
}

void EntryRing::reset() noexcept {
  head_.store(0);
  tail_.store(0);
  finished_.store(false);
  cancelled_.store(false);
  consumer_wants_tail_.store(0);
  producer_wants_head_.store(0);
}

std::size_t EntryRing::size() const noexcept {
  return static_cast<std::size_t>(tail_.load() - head_.load());
}

}  // namespace exodaq::drivers::replay
