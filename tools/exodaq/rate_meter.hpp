#pragma once
// Rate and loss of a message stream over the last second, measured from the
// publisher's seq and mono_ns (not from receive times, which carry network
// jitter). Used by `exodaq echo` and `exodaq view`.
#include <cstdint>
#include <deque>
#include <optional>

#include "exodaq/messages/message.hpp"

namespace exodaq::tools {

class RateMeter {
 public:
  void add(const msg::Stamp& s, int64_t local_mono_ns) {
    if (!window_.empty() && (s.run_id != window_.back().run_id || s.seq <= window_.back().seq)) {
      window_.clear();  // daemon restarted or sequence went back
    }
    window_.push_back(Sample{s.seq, s.mono_ns, s.run_id, local_mono_ns});
    while (window_.size() > 2 && local_mono_ns - window_.front().local_ns > 1'000'000'000) {
      window_.pop_front();
    }
  }
  // Cycles per second of the publisher's clock; nullopt until two samples.
  std::optional<double> rate_hz() const {
    if (window_.size() < 2) return std::nullopt;
    const auto& a = window_.front();
    const auto& b = window_.back();
    if (b.mono_ns <= a.mono_ns) return std::nullopt;
    return static_cast<double>(b.seq - a.seq) * 1e9 / static_cast<double>(b.mono_ns - a.mono_ns);
  }
  // Share of the cycles in the window that arrived here.
  std::optional<double> received_fraction() const {
    if (window_.size() < 2) return std::nullopt;
    const int64_t span = window_.back().seq - window_.front().seq + 1;
    return static_cast<double>(window_.size()) / static_cast<double>(span);
  }
  void clear() { window_.clear(); }

 private:
  struct Sample {
    int64_t seq, mono_ns, run_id, local_ns;
  };
  std::deque<Sample> window_;
};

}  // namespace exodaq::tools
