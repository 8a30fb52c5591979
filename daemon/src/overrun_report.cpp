#include "overrun_report.hpp"

#include <fmt/format.h>

namespace exodaq::daemon {

std::string OverrunLine::text() const {
  if (late_wakes == 1) {
    return fmt::format(
        "loop overrun at seq {}: the wake was {:.1f} us late, the cycle's work {:.1f} us; {} "
        "deadline(s) skipped in 1 late wake",
        last_seq, worst_lateness_us, longest_work_us, skipped);
  }
  return fmt::format(
      "loop overruns from seq {} to {}{}: {} deadline(s) skipped in {} late wakes; the latest "
      "wake {:.1f} us late (seq {}), the longest cycle's work {:.1f} us",
      first_seq, last_seq,
      span_ns > 0 ? fmt::format(" ({:.1f} s)", static_cast<double>(span_ns) * 1e-9) : "", skipped,
      late_wakes, worst_lateness_us, worst_seq, longest_work_us);
}

std::optional<OverrunLine> OverrunReport::add(const core::LogEvent& e, std::int64_t now_ns) {
  OverrunLine& p = pending_;
  if (p.late_wakes == 0) p.first_seq = e.seq;
  p.last_seq = e.seq;
  ++p.late_wakes;
  p.skipped += e.count;
  if (p.late_wakes == 1 || e.value > p.worst_lateness_us) {
    p.worst_lateness_us = e.value;
    p.worst_seq = e.seq;
  }
  if (p.late_wakes == 1 || e.work_us > p.longest_work_us) p.longest_work_us = e.work_us;
  return due(now_ns);
}

std::optional<OverrunLine> OverrunReport::due(std::int64_t now_ns, bool stopping) {
  if (pending_.late_wakes == 0) return std::nullopt;
  if (stopping || !last_line_ns_ || now_ns - *last_line_ns_ >= interval_ns_) return flush(now_ns);
  return std::nullopt;
}

std::optional<OverrunLine> OverrunReport::flush(std::int64_t now_ns) {
  OverrunLine line = pending_;
  line.span_ns = last_line_ns_ ? now_ns - *last_line_ns_ : 0;
  pending_ = {};
  last_line_ns_ = now_ns;
  return line;
}

}  // namespace exodaq::daemon
