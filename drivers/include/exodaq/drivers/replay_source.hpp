#pragma once
// The `replay` encoder backend: a recorded stream played back through the same
// pipeline the rig runs (docs/replay.md). Two input formats:
//
//   lcm      a log written by lcm-logger (LCM's event-log format). The source
//            of truth is the encoder_raw_t channel (<prefix>EXO_ENCODER_RAW):
//            each message becomes one EncoderSample, field for field. The
//            recorded utime is kept exactly (wall_ns = utime * 1000, which the
//            daemon's replay path turns back into the same utime), mono_ns and
//            seq are the recorded ones. Loop-side bits the raw channel does not
//            carry (LATE, CLOCK_STEP, CLOCK_UNSYNC) and the channels a PARTIAL
//            sample really had are taken from the recorded joint_state_t of
//            the same seq when the log has it.
//   candump  a text log as `candump -l` / `candump -L` write it:
//              (1700000000.123456) can0 181#34120000FFFF0005
//            every line parsed by parse_candump_line(), the frames decoded by
//            the CAN codec and assembled by the BoardDecoder, exactly as the
//            SocketCAN backend does live. Cycles the board skipped (sequence
//            gaps) are replayed as missing samples. Timestamps are the file's
//            (wall clock); mono_ns = wall_ns. Malformed lines are kept in
//            issues() with their line number, counted in stats().bad_frames,
//            and the rest of the file is processed.
//
// Everything is loaded and decoded in start() (which allocates); read() copies
// one prepared sample and allocates nothing. next_sample_mono_ns() is the
// recorded instant of the next sample, so the loop can be paced by the
// recording or run flat out. Same file in, same samples out.
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "exodaq/drivers/board_decoder.hpp"
#include "exodaq/drivers/can_codec.hpp"
#include "exodaq/drivers/encoder_source.hpp"
#include "exodaq/drivers/source_options.hpp"

namespace exodaq::drivers {

// ---------------------------------------------------------------------------
// candump text
// ---------------------------------------------------------------------------

enum class CandumpError : std::uint8_t {
  kNone = 0,
  kBlank,      // empty or whitespace-only line (skipped, not an error)
  kTimestamp,  // no "(seconds.micros)" at the start
  kInterface,  // no interface name after the timestamp
  kId,         // identifier: not 3 or 8 hex digits, or flag bits that cannot be there
  kSeparator,  // no '#' / '##' after the identifier
  kData,       // odd number of hex digits, a non-hex character, or misplaced '.'
  kLength,     // more bytes than the frame type allows, or a bad RTR length / len8_dlc
  kFdFlags,    // CAN FD '##' without a hex flags digit
  kTrailing,   // something after the frame that candump does not write
};

std::string_view to_string(CandumpError e) noexcept;

// Parses one line of a candump log file. On kNone `out` holds the frame with
// wall_ns = mono_ns = the line's timestamp in ns (microsecond resolution).
// Understood: standard (3 hex digits) and extended (8 hex digits) IDs, error
// frames (8 digits with CAN_ERR_FLAG 0x20000000 set: kError, id = error
// classes), RTR ("#R", "#R5"), data with optional '.' separators and the
// optional "_<dlc>" len8_dlc suffix, CAN FD ("##<flags><data>", up to 64
// bytes; bytes beyond 8 are not kept), and the optional trailing " R"/" T"
// direction of newer candump versions. Pure and allocation-free: safe to fuzz.
CandumpError parse_candump_line(std::string_view line, can::CanFrame& out) noexcept;

// ---------------------------------------------------------------------------
// The source
// ---------------------------------------------------------------------------

enum class ReplayFormat : std::uint8_t { kLcm, kCandump };

// Something in the input that was not replayed as it stands.
struct ReplayIssue {
  std::int64_t line = 0;  // candump: 1-based line number; lcm: event number
  std::string what;
};

struct ReplayLoadSummary {
  ReplayFormat format = ReplayFormat::kLcm;
  std::string channel;                  // lcm: the raw channel used
  std::string prefix;                   // lcm: the channel prefix the recording used ("" for none)
  std::int64_t run_id = 0;              // lcm: the run replayed; candump: derived from the file
  std::int64_t events = 0;              // lcm events read / candump lines read
  std::int64_t samples = 0;             // samples prepared (incl. missing ones)
  std::int64_t missing = 0;             // of which present == false
  std::int64_t skipped_warmup = 0;      // lcm: the daemon's all-zero start-up messages
  std::int64_t skipped_other_runs = 0;  // lcm: raw messages of other daemon runs in the log
  std::int64_t loop_flags_from_joint_state = 0;  // lcm: samples that got recorded loop bits
  std::int64_t bad_lines = 0;                    // candump: malformed lines
  std::int64_t frames = 0;                       // candump: frames fed to the decoder
  double duration_s = 0.0;                       // last minus first sample instant
};

class ReplaySource final : public EncoderSource {
 public:
  // `context` gives the period (for missing cycles) and the joint -> channel
  // map (to read recorded per-joint flags). Throws std::runtime_error for an
  // unknown format name; the file is opened in start().
  ReplaySource(const ReplaySettings& settings, const SourceContext& context);

  std::string_view name() const noexcept override { return "replay"; }
  // Loads and decodes the whole input (idempotent: a second call does not
  // reload, it rewinds). Throws std::runtime_error naming the file on any
  // error that prevents a replay (unreadable, no raw channel, no sample).
  void start() override;
  ReadStatus read(const CycleTime& time, EncoderSample& out) noexcept override;
  std::int64_t next_sample_mono_ns() const noexcept override;
  std::int64_t recorded_seq() const noexcept override { return last_seq_; }
  SourceStats stats() const noexcept override { return stats_; }

  // After start().
  const ReplayLoadSummary& summary() const noexcept { return summary_; }
  const std::vector<ReplayIssue>& issues() const noexcept { return issues_; }
  std::int64_t run_id() const noexcept { return summary_.run_id; }
  std::int64_t sample_count() const noexcept { return static_cast<std::int64_t>(entries_.size()); }
  std::int64_t position() const noexcept { return static_cast<std::int64_t>(next_); }

  // "lcm" or "candump" from the file's first bytes (the LCM log magic or a
  // line starting with '('); throws when it is neither.
  static ReplayFormat detect_format(const std::string& path);

 private:
  struct Entry {
    EncoderSample sample;
    std::int64_t seq = -1;  // recorded seq (lcm); -1: the loop counts (candump)
  };
  void load_lcm();
  void load_candump();

  ReplaySettings settings_;
  SourceContext context_;
  bool loaded_ = false;
  std::vector<Entry> entries_;
  std::size_t next_ = 0;
  std::int64_t last_seq_ = -1;
  SourceStats stats_{};
  SourceStats loaded_stats_{};  // stats at the end of the input (frames, bad frames, ...)
  ReplayLoadSummary summary_{};
  std::vector<ReplayIssue> issues_;
};

}  // namespace exodaq::drivers
