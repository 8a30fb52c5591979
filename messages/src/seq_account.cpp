#include "exodaq/messages/seq_account.hpp"

#include <algorithm>
#include <climits>

namespace exodaq::messages {

DaemonCounts daemon_counts(const status_t& s) noexcept {
  DaemonCounts c;
  c.seq = s.seq;
  c.unpublished = std::max<std::int64_t>(0, s.seq + 1 - s.cycles);
  c.failures = std::max<std::int64_t>(0, s.publish_failures);
  return c;
}

int RunAccount::index(Kind k) noexcept {
  return is_per_cycle(k) ? static_cast<int>(k) : -1;
}

SeqStep RunAccount::add(Kind kind, std::int64_t seq) {
  const int i = index(kind);
  if (i < 0) return SeqStep::kNext;
  Stream& s = streams_[static_cast<std::size_t>(i)];
  if (s.received == 0) {
    s.first = s.last = seq;
    s.received = 1;
    return SeqStep::kFirst;
  }
  if (seq > s.last) {
    std::int64_t gap = 0;
    if (__builtin_sub_overflow(seq, s.last, &gap)) gap = INT64_MAX;
    if (gap > 1) s.holes.emplace(s.last + 1, gap - 1);
    s.last = seq;
    ++s.received;
    return gap > 1 ? SeqStep::kGap : SeqStep::kNext;
  }
  // Not new: a late arrival fills a hole; anything else is a repeat.
  auto it = s.holes.upper_bound(seq);
  if (it != s.holes.begin()) {
    --it;
    const std::int64_t from = it->first;
    const std::int64_t n = it->second;
    if (seq < from + n) {
      s.holes.erase(it);
      if (seq > from) s.holes.emplace(from, seq - from);
      if (seq + 1 < from + n) s.holes.emplace(seq + 1, from + n - seq - 1);
      ++s.received;
      ++s.late;
      return SeqStep::kLate;
    }
  }
  ++s.repeated;
  return SeqStep::kRepeat;
}

void RunAccount::add_status(const DaemonCounts& counts) {
  if (last_status_ && counts.seq < last_status_->seq) return;
  if (!statuses_.empty() && statuses_.back().seq == counts.seq) {
    statuses_.back() = counts;  // the final status repeats the last window's seq
  } else {
    statuses_.push_back(counts);
  }
  last_status_ = counts;
}

std::int64_t RunAccount::last_seq(Kind kind) const noexcept {
  const int i = index(kind);
  return i < 0 ? -1 : streams_[static_cast<std::size_t>(i)].last;
}

SeqTally RunAccount::tally(Kind kind) const {
  SeqTally t;
  const int i = index(kind);
  if (i < 0) return t;
  const Stream& s = streams_[static_cast<std::size_t>(i)];
  t.received = s.received;
  t.first = s.first;
  t.last = s.last;
  t.repeated = s.repeated;
  t.late = s.late;
  t.holes = static_cast<std::int64_t>(s.holes.size());
  for (const auto& [from, n] : s.holes) {
    t.missing += n;
    if (n > t.widest) {
      t.widest = n;
      t.widest_from = from;
    }
  }
  // Holes and status windows, both in seq order: each window's holes are the
  // daemon's up to what its counters grew by over the window.
  auto hole = s.holes.begin();
  std::int64_t at = hole != s.holes.end() ? hole->first : 0;
  std::int64_t left = hole != s.holes.end() ? hole->second : 0;
  DaemonCounts before;  // zero: the run's start
  for (const DaemonCounts& w : statuses_) {
    std::int64_t n = 0;
    while (hole != s.holes.end() && at <= w.seq) {
      const std::int64_t take = std::min(left, w.seq - at + 1);
      n += take;
      at += take;
      left -= take;
      if (left == 0 && ++hole != s.holes.end()) {
        at = hole->first;
        left = hole->second;
      }
    }
    const std::int64_t u =
        std::min(n, std::max<std::int64_t>(0, w.unpublished - before.unpublished));
    const std::int64_t f = std::min(n - u, std::max<std::int64_t>(0, w.failures - before.failures));
    t.unpublished += u;
    t.failed += f;
    t.lost += n - u - f;
    before.unpublished = std::max(before.unpublished, w.unpublished);
    before.failures = std::max(before.failures, w.failures);
  }
  std::int64_t after = hole != s.holes.end() ? left : 0;
  if (hole != s.holes.end()) {
    for (auto h = std::next(hole); h != s.holes.end(); ++h) after += h->second;
  }
  t.lost += after;
  t.unconfirmed = after;
  return t;
}

std::string describe(const SeqTally& t) {
  if (t.received == 0) return "none";
  std::string out = std::to_string(t.received) + " cycles (seq " + std::to_string(t.first) + ".." +
                    std::to_string(t.last) + ")";
  if (t.missing > 0) {
    out += ", " + std::to_string(t.missing) + " missing in " + std::to_string(t.holes) +
           (t.holes == 1 ? " hole" : " holes") + ": " + std::to_string(t.unpublished) +
           " skipped by the daemon";
    if (t.failed > 0) out += ", " + std::to_string(t.failed) + " the daemon failed to publish";
    out += ", " + std::to_string(t.lost) + " lost";
    if (t.unconfirmed > 0) {
      out += " (" + std::to_string(t.unconfirmed) + " after the daemon's last status)";
    }
  } else {
    out += ", none missing";
  }
  if (t.late > 0) out += ", " + std::to_string(t.late) + " arrived out of order";
  if (t.repeated > 0) out += ", " + std::to_string(t.repeated) + " with a seq not new (repeated)";
  return out;
}

}  // namespace exodaq::messages
