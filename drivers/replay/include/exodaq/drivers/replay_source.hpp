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
//            (wall clock); mono_ns = wall_ns. Malformed lines (and lines over
//            4096 characters) are kept in issues() with their line number,
//            counted in stats().bad_frames, and the rest of the file is
//            processed.
//
// The input is read as a stream, never held whole: start() reads it once to
// count (summary(), issues() and the final stats() are complete before the
// first cycle), then a reader thread reads it again, decoding ahead into a
// ring of buffer_samples entries (rounded up to a power of two) allocated in
// start(); read() takes one entry and allocates nothing. Paced (speed > 0),
// read() finds the ring full and waits only if the disk falls a whole ring
// behind; flat out, it waits for the reader when the ring runs dry
// (docs/replay.md, "Memory and speed").
// next_sample_mono_ns() is the recorded instant of the next sample, so the
// loop can be paced by the recording or run flat out. Same file in, same
// samples out; the file must not change while it is replayed.
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "exodaq/drivers/board_decoder.hpp"
#include "exodaq/drivers/candump.hpp"
#include "exodaq/drivers/encoder_source.hpp"
#include "exodaq/drivers/replay_backend.hpp"
#include "exodaq/drivers/source_options.hpp"

namespace exodaq::drivers {

namespace replay {
struct State;
}  // namespace replay

enum class ReplayFormat : std::uint8_t { kLcm, kCandump };

// Something in the input that was not replayed as it stands.
struct ReplayIssue {
  std::int64_t line = 0;  // candump: 1-based line number; lcm: event number
  std::string what;
  // Damage or a malformed input (exodaq replay exits 1); false for a note
  // (another daemon run in the log, not replayed).
  bool problem = true;
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
  std::int64_t bad_lines = 0;           // candump: malformed lines
  std::int64_t frames = 0;              // candump: frames fed to the decoder
  double duration_s = 0.0;              // last minus first sample instant
  // lcm: homing_t records of the replayed run; the first one taken to
  // continue the live homing (its seq; -1: none, the joints start afresh).
  std::int64_t homing_records = 0;
  std::int64_t resumed_at_seq = -1;
  std::int64_t first_seq = -1;  // lcm: the recorded seq of the first sample
  // lcm: damaged stretches of the log and the cycles of the run lost with
  // them (seq numbers missing across each; a stretch at the end costs an
  // unknown number, not counted).
  std::int64_t damaged_stretches = 0;
  std::int64_t damaged_cycles = 0;
};

class ReplaySource final : public EncoderSource {
 public:
  static constexpr std::size_t kBufferSamples = 8192;  // 8 s at 1 kHz, 640 KiB

  // `context` gives the period (for missing cycles) and the joint -> channel
  // map (to read recorded per-joint flags). Throws std::runtime_error for an
  // unknown format name; the file is opened in start().
  ReplaySource(const ReplaySettings& settings, const SourceContext& context,
               std::size_t buffer_samples = kBufferSamples);
  ~ReplaySource() override;

  std::string_view name() const noexcept override { return "replay"; }
  // Reads the input through once and starts the reader (a second call does
  // not count again, it rewinds). Throws std::runtime_error naming the file
  // on any error that prevents a replay (unreadable, no raw channel, no
  // sample). A read error later ends the stream and joins issues().
  void start() override;
  ReadStatus read(const CycleTime& time, EncoderSample& out) noexcept override;
  // Stops the reader; read() then gives what the ring holds, then the end.
  void stop() noexcept override;
  std::optional<double> recording_speed() const noexcept override { return settings_.speed; }
  std::int64_t next_sample_mono_ns() const noexcept override;
  std::int64_t recorded_seq() const noexcept override { return last_seq_; }
  SourceStats stats() const noexcept override { return stats_; }
  const JointResumeSet* resume_state() const noexcept override;
  // The samples delivered of the recording's; the state: "playing" or "at the end".
  void diagnose(SourceDiagnostics& out) const noexcept override;

  // After start().
  const ReplayLoadSummary& summary() const noexcept;
  const std::vector<ReplayIssue>& issues() const noexcept;
  std::int64_t run_id() const noexcept { return summary().run_id; }
  std::int64_t sample_count() const noexcept;
  std::int64_t position() const noexcept { return position_; }
  // The read-ahead ring: its size in samples, and how often read() or
  // next_sample_mono_ns() found it empty and waited for the reader.
  std::size_t buffer_capacity() const noexcept;
  std::int64_t buffer_waits() const noexcept;

  // "lcm" or "candump" from the file's first bytes (the LCM log magic or a
  // line starting with '('); throws when it is neither.
  static ReplayFormat detect_format(const std::string& path);

 private:
  void load();
  std::size_t batch() const noexcept;
  void report_stream_error() noexcept;

  ReplaySettings settings_;
  SourceContext context_;
  std::size_t buffer_samples_;
  std::unique_ptr<replay::State> state_;
  std::int64_t position_ = 0;
  std::int64_t last_seq_ = -1;
  SourceStats stats_{};
};

}  // namespace exodaq::drivers
