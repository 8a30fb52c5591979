#pragma once
// The seam every encoder backend sits behind (sim, socketcan, replay). The
// daemon's loop talks to this interface only, so tests inject fakes.
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "exodaq/drivers/encoder_sample.hpp"
#include "exodaq/drivers/source_diagnostics.hpp"

namespace exodaq::drivers {

struct CycleTime {
  std::int64_t deadline_mono_ns = 0;  // the cycle's scheduled start
  std::int64_t now_mono_ns = 0;       // when the loop woke
  std::int64_t period_ns = 1'000'000;
  std::int64_t cycle = 0;  // cycle number since start
  // A further read in the same wake, for a sample the source still holds
  // (backlog() > 0): deliver the next one without waiting and without
  // starting a new board cycle (no SYNC).
  bool catch_up = false;
};

enum class ReadStatus : std::uint8_t {
  kSample,       // out holds this cycle's sample (possibly flagged)
  kNoSample,     // nothing this cycle; out.present == false, counts held
  kEndOfStream,  // replay finished
  // Nothing to publish this wake: a free-running board's next sample is not
  // overdue yet (its clock drifted just past this wake), or a catch-up read
  // found nothing more. `out` is untouched; the loop publishes no cycle.
  kNothingDue,
};

// Where a live run's joint stood when a recording that starts in the middle
// of that run begins (the replay backend, from the recorded homing_t): the
// count the live tracker had unwrapped to, and its homing reference.
struct JointResume {
  bool counted = false;            // false: nothing known, the joint starts afresh
  std::int64_t count = 0;          // the live unwrapped count at the recording's first sample
  std::int64_t powerup_count = 0;  // the live run's first count (zero of the unhomed angle)
  std::int8_t homing = 0;          // status_t HOMING_* (0 unhomed, 1 homed, 2 rejected)
  std::int64_t index_count = 0;    // unwrapped count at the accepted index
  std::int64_t index_turns = 0;    // which index crossing that was
};
// By joint, in the configuration's joint order.
using JointResumeSet = std::array<JointResume, kChannelCount>;

class EncoderSource {
 public:
  virtual ~EncoderSource() = default;
  EncoderSource() = default;
  EncoderSource(const EncoderSource&) = delete;
  EncoderSource& operator=(const EncoderSource&) = delete;

  virtual std::string_view name() const noexcept = 0;

  // Opens devices and allocates; called before the loop starts. Throws on error.
  virtual void start() = 0;

  // Called once per cycle on the loop thread, after the wake-up. Must not
  // allocate, block or log. Fills `out` for this cycle.
  virtual ReadStatus read(const CycleTime& time, EncoderSample& out) noexcept = 0;

  // Sources that play a recording carry its time: utime and seq come from
  // it, and it paces the loop at this speed (x real time; <= 0 as fast as
  // possible). Live sources: nullopt (paced by the loop clock).
  virtual std::optional<double> recording_speed() const noexcept { return std::nullopt; }

  // For replay: the mono_ns at which the next sample is due, so the loop can be
  // paced by the recording. Live sources return -1 (paced by the loop clock).
  virtual std::int64_t next_sample_mono_ns() const noexcept { return -1; }

  // For replay: the recorded cycle number (seq) of the sample the last read()
  // delivered, so a replay keeps the recording's seq across the live run's
  // skipped cycles. -1: none (live sources; the loop counts itself).
  virtual std::int64_t recorded_seq() const noexcept { return -1; }

  // A free-running board: it samples on its own clock and the source keeps
  // every sample it took until read (the socket queue holds them while the
  // loop is late). The loop then publishes one cycle per board sample: seq
  // counts samples, and a deadline the loop skipped is no gap, its sample
  // comes with the backlog. false: a sample per loop deadline (sync master,
  // the default sim), a skipped deadline is a sample never taken.
  virtual bool free_running() const noexcept { return false; }

  // Complete samples the source still holds after the last read() (0: none,
  // or the source does not queue). The loop reads them in the same wake with
  // CycleTime::catch_up set. A source may report 1 while more wait behind it
  // (a socket it has not drained yet).
  virtual int backlog() const noexcept { return 0; }

  // For replay, after start(): where the recorded run's joints stood at the
  // first sample (nullptr: start afresh, as live sources always do).
  virtual const JointResumeSet* resume_state() const noexcept { return nullptr; }

  virtual SourceStats stats() const noexcept = 0;

  // The backend's own counters and state (source_diagnostics.hpp) into `out`,
  // which the caller has cleared. Loop thread, once per status window:
  // allocation-free. The counters' names are the same on every call.
  virtual void diagnose(SourceDiagnostics& out) const noexcept { (void)out; }

  // Closes devices; called after the loop has stopped.
  virtual void stop() noexcept {}
};

}  // namespace exodaq::drivers
