#pragma once
// Loop overruns as log lines, at most one per interval (10 s): the first
// overrun after a quiet interval is said at once; the ones after it are summed
// up and said when the interval since the last line has passed, and at stop.
// Each line says what it stands for: the deadlines skipped, the late wakes
// that skipped them, the latest wake and the longest cycle's work (a late
// wake, not a long cycle, is the usual cause). Main thread: the loop only
// counts and hands its events over (core::LogEvent).
#include <cstdint>
#include <optional>
#include <string>

#include "exodaq/core/loop_events.hpp"

namespace exodaq::daemon {

struct OverrunLine {
  std::int64_t late_wakes = 0;  // overrun events the line stands for
  std::int64_t skipped = 0;     // deadlines skipped by them
  std::int64_t first_seq = 0;   // the seq after the first one's skip
  std::int64_t last_seq = 0;
  double worst_lateness_us = 0.0;  // the latest wake ...
  std::int64_t worst_seq = 0;      // ... at this seq
  double longest_work_us = 0.0;
  std::int64_t span_ns = 0;  // since the line before (0: the first line)

  std::string text() const;
};

class OverrunReport {
 public:
  static constexpr std::int64_t kInterval = 10'000'000'000;  // ns
  explicit OverrunReport(std::int64_t interval_ns = kInterval) : interval_ns_(interval_ns) {}

  // One overrun event from the loop, taken at `now_ns`: the line to log now, if any.
  std::optional<OverrunLine> add(const core::LogEvent& e, std::int64_t now_ns);
  // The summed-up line once the interval since the last line has passed, or
  // whatever is pending when `stopping`.
  std::optional<OverrunLine> due(std::int64_t now_ns, bool stopping = false);

 private:
  std::optional<OverrunLine> flush(std::int64_t now_ns);

  std::int64_t interval_ns_;
  std::optional<std::int64_t> last_line_ns_;
  OverrunLine pending_;
};

}  // namespace exodaq::daemon
