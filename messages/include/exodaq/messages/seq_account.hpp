#pragma once
// The cycles of one daemon run as a receiver has them (a recorder, a log, a
// live client): which seq numbers arrived, which are missing, and of the
// missing ones how many the daemon itself never published and how many were
// lost on the way (docs/messages.md, "Counting what was lost").
//
// The daemon's own share comes from its status_t counters, which are totals
// since its start, covering the cycles up to status_t.seq:
//   unpublished = seq + 1 - cycles    seq numbers it skipped (overruns as
//                                     sync master; 0 following a free-running
//                                     board, whose backlog keeps every sample)
//   failures    = publish_failures    messages it could not send
// A hole between two statuses is the daemon's up to the growth of those
// counters over that window; the rest is lost. Holes after the last status
// heard are lost until a status covers them (`unconfirmed`).
//
// A seq that is not new (repeated, or older than what came after it) and
// fills no hole is counted as repeated, never as a cycle: two streams with one
// run id (a replay --live of a live run), or a log holding a run twice.
#include <array>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "exodaq/messages/channels.hpp"
#include "exodaq/status_t.hpp"

namespace exodaq::messages {

// What one status_t says about the daemon's publishing up to its seq.
struct DaemonCounts {
  std::int64_t seq = -1;
  std::int64_t unpublished = 0;
  std::int64_t failures = 0;
};
DaemonCounts daemon_counts(const status_t& s) noexcept;

enum class SeqStep : std::uint8_t {
  kFirst,   // the first of the stream
  kNext,    // seq = last + 1
  kGap,     // after a hole
  kLate,    // fills a hole (arrived out of order)
  kRepeat,  // a seq already received, or older than the first: not a cycle
};

struct SeqTally {
  std::int64_t received = 0;  // distinct seq numbers
  std::int64_t first = -1;
  std::int64_t last = -1;
  std::int64_t missing = 0;       // seq numbers between first and last not received
  std::int64_t unpublished = 0;   // of those: skipped by the daemon (its status counters)
  std::int64_t failed = 0;        // of those: publishes the daemon counted as failed
  std::int64_t lost = 0;          // the rest: lost between the daemon and the receiver
  std::int64_t unconfirmed = 0;   // of `lost`: after the last status heard
  std::int64_t repeated = 0;      // messages whose seq was not new (SeqStep::kRepeat)
  std::int64_t late = 0;          // messages that filled a hole
  std::int64_t holes = 0;         // stretches of missing seq numbers
  std::int64_t widest_from = -1;  // the widest hole: its first seq and its size
  std::int64_t widest = 0;
};

class RunAccount {
 public:
  // One message of a per-cycle kind (is_per_cycle(); others are ignored: kNext).
  SeqStep add(Kind kind, std::int64_t seq);
  // One status_t of this run; an older one than the last (by seq) is ignored.
  void add_status(const DaemonCounts& counts);
  const std::optional<DaemonCounts>& last_status() const noexcept { return last_status_; }
  // The stream of `kind` with its holes attributed to the statuses heard.
  SeqTally tally(Kind kind) const;
  std::int64_t last_seq(Kind kind) const noexcept;

 private:
  struct Stream {
    std::int64_t first = -1;
    std::int64_t last = -1;
    std::int64_t received = 0;
    std::int64_t repeated = 0;
    std::int64_t late = 0;
    std::map<std::int64_t, std::int64_t> holes;  // first missing seq -> how many
  };
  static int index(Kind k) noexcept;

  std::array<Stream, kKindCount> streams_;  // by kind; only the per-cycle kinds' are used
  std::vector<DaemonCounts> statuses_;      // increasing seq
  std::optional<DaemonCounts> last_status_;
};

// "1000 cycles (seq 0..999), 3 missing: 2 skipped by the daemon, 1 lost" and
// the like, for summaries.
std::string describe(const SeqTally& t);

}  // namespace exodaq::messages
