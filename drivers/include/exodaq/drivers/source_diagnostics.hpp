#pragma once
// A backend's own counters and state, beyond SourceStats (what every backend
// counts): a SocketCAN port's interface losses and reopens, a board
// decoder's resyncs, a replay's progress. A source fills one of these
// through EncoderSource::diagnose(); the status assembler publishes it as
// source_status_t at the status rate and the daemon's last log line names the
// counters that are not zero (docs/messages.md, "source_status_t").
// Fixed capacity, filled on the loop thread: nothing allocates. Names are
// string literals (snake_case, the same set for the whole run).
#include <array>
#include <cstdint>
#include <span>
#include <string_view>

namespace exodaq::drivers {

struct SourceCounter {
  std::string_view name;
  std::int64_t value = 0;
};

class SourceDiagnostics {
 public:
  static constexpr int kMaxCounters = 32;
  static constexpr int kMaxNameBytes = 24;
  static constexpr int kMaxStateBytes = 96;

  // Appends a counter; beyond kMaxCounters it is dropped and counted.
  void add(std::string_view name, std::int64_t value) noexcept;
  // The source's state in one line ("can0 open"); cut at kMaxStateBytes - 1.
  void set_state(std::string_view text) noexcept;
  // Empties it (a source's diagnose() starts from an empty one).
  void clear() noexcept;

  std::span<const SourceCounter> counters() const noexcept {
    return {counters_.data(), static_cast<std::size_t>(count_)};
  }
  std::string_view state() const noexcept { return {state_.data(), state_size_}; }
  // The counter of that name (nullptr: none).
  const SourceCounter* find(std::string_view name) const noexcept;
  // Counters add() could not hold (a source listing more than kMaxCounters).
  int dropped() const noexcept { return dropped_; }

 private:
  std::array<SourceCounter, kMaxCounters> counters_{};
  int count_ = 0;
  int dropped_ = 0;
  std::array<char, kMaxStateBytes> state_{};
  std::size_t state_size_ = 0;
};

}  // namespace exodaq::drivers
