#pragma once
// Rate and loss of a message stream over the last second, measured from the
// publisher's seq and mono_ns (not from receive times, which carry network
// jitter). Used by `exodaq echo` and `exodaq view`. With the run's statuses
// (add_status), seq numbers the daemon itself never published (its skipped
// deadlines) are not counted as missing here (messages::RunAccount's rule).
#include <algorithm>
#include <cstdint>
#include <deque>
#include <optional>

#include "exodaq/messages/message.hpp"

namespace exodaq::tools {

class RateMeter {
 public:
  void add(const messages::Stamp& s, int64_t local_mono_ns) {
    if (!window_.empty() && (s.run_id != window_.back().run_id || s.seq <= window_.back().seq)) {
      window_.clear();  // daemon restarted or sequence went back
    }
    if (!statuses_.empty() && statuses_.back().run_id != s.run_id) statuses_.clear();
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
  // A status_t of the stream's run: its seq and the seq numbers the daemon
  // never published since its start (messages::daemon_counts).
  void add_status(int64_t run_id, int64_t seq, int64_t unpublished) {
    if (!statuses_.empty() && (statuses_.back().run_id != run_id || seq < statuses_.back().seq)) {
      statuses_.clear();
    }
    statuses_.push_back(Status{run_id, seq, unpublished});
    while (statuses_.size() > 64) statuses_.pop_front();  // 6 s of statuses
  }
  // Share of the cycles the daemon published in the window that arrived
  // here (its skipped deadlines, from its statuses, not counted).
  std::optional<double> received_fraction() const {
    if (window_.size() < 2) return std::nullopt;
    const int64_t span = window_.back().seq - window_.front().seq + 1 - skipped_in_window();
    if (span <= 0) return 1.0;
    return std::min(1.0, static_cast<double>(window_.size()) / static_cast<double>(span));
  }
  // Seq numbers the daemon skipped within the window (from the statuses
  // around its ends; 0 without statuses).
  int64_t skipped_in_window() const {
    if (window_.size() < 2 || statuses_.empty() ||
        statuses_.back().run_id != window_.back().run_id) {
      return 0;
    }
    return std::max<int64_t>(
        0, unpublished_at(window_.back().seq) - unpublished_at(window_.front().seq));
  }
  void clear() {
    window_.clear();
    statuses_.clear();
  }

 private:
  struct Sample {
    int64_t seq, mono_ns, run_id, local_ns;
  };
  struct Status {
    int64_t run_id, seq, unpublished;
  };
  // The daemon's skipped count by `seq`: the first status covering it (the
  // newest when none does yet).
  int64_t unpublished_at(int64_t seq) const {
    for (const Status& st : statuses_) {
      if (st.seq >= seq) return st.unpublished;
    }
    return statuses_.back().unpublished;
  }
  std::deque<Sample> window_;
  std::deque<Status> statuses_;
};

}  // namespace exodaq::tools
