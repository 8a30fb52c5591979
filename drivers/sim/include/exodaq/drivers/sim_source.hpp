#pragma once
// The `sim` encoder backend: a simulated rig (sim_rig.hpp) behind the
// EncoderSource seam. Each read() simulates one board cycle, and the frames
// that have reached the bus by then (scripted delays hold some back) go
// through the same BoardDecoder the SocketCAN path uses; the newest complete
// cycle is delivered. Sample stamps: mono_ns = start_mono_ns + the instant the
// cycle's count frames reached the bus (t_k, plus any delay), wall_ns = mono_ns
// + (CLOCK_REALTIME − CLOCK_MONOTONIC at start()). The sim paces nothing.
// Board clock (SimOptions::board_clock):
// - aligned (default): read() simulates board cycle max(time.cycle, next), so
//   it stays locked to the loop's cycle numbers across skipped deadlines (a
//   skipped deadline is a board cycle nobody read: a sequence gap);
// - free-running: the board samples on its own clock; read() simulates every
//   board cycle whose frames reached the bus by the reader's now
//   (time.now_mono_ns) and delivers them oldest first, one per read, like the
//   socketcan backend following a free-running board (backlog(), kNothingDue).
// A scripted `stall` makes the read that reaches its start block for its
// duration (real time), as a host held off would; the reader's now moves on by
// as much. docs/simulator.md.
#include <array>
#include <cstdint>
#include <string_view>

#include "exodaq/drivers/board_decoder.hpp"
#include "exodaq/drivers/encoder_source.hpp"
#include "exodaq/drivers/sim_rig.hpp"

namespace exodaq::drivers {

using sim::SimOptions;

class SimSource final : public EncoderSource {
 public:
  // Throws std::invalid_argument on inconsistent options (SimRig's checks).
  explicit SimSource(const SimOptions& options = {});

  std::string_view name() const noexcept override { return "sim"; }
  // Fixes the time base and rewinds to cycle 0.
  void start() override;
  // Allocation-free; blocks only in a scripted `stall` fault.
  ReadStatus read(const CycleTime& time, EncoderSample& out) noexcept override;
  SourceStats stats() const noexcept override { return decoder_.stats(); }
  // The decoder's counters and the board cycles simulated; the state names the
  // board clock ("simulated board, aligned clock").
  void diagnose(SourceDiagnostics& out) const noexcept override;
  bool free_running() const noexcept override { return options_.board_clock.free_running; }
  int backlog() const noexcept override;

  // For tests and the daemon's truth checks.
  const sim::SimRig& rig() const noexcept { return rig_; }
  const BoardDecoder& decoder() const noexcept { return decoder_; }
  std::int64_t start_mono_ns() const noexcept { return start_mono_ns_; }
  std::int64_t wall_offset_ns() const noexcept { return wall_offset_ns_; }
  // Board cycles simulated since start() (aligned: the next cycle to read).
  std::int64_t cycles() const noexcept { return cycle_; }
  // Simulated time (s) of a sample stamped mono_ns: feed it to rig().motion().truth().
  double sim_time_s(std::int64_t mono_ns) const noexcept {
    return static_cast<double>(mono_ns - start_mono_ns_) * 1e-9;
  }

 private:
  // A scripted stall whose start lies in (previous read, t_s]: sleeps its
  // duration; returns the nanoseconds slept (as scripted).
  std::int64_t stall_if_due(double t_s) noexcept;
  ReadStatus read_aligned(const CycleTime& time, EncoderSample& out) noexcept;
  ReadStatus read_free_running(const CycleTime& time, EncoderSample& out) noexcept;
  // Free-running: simulates board cycles and feeds their frames in bus order
  // while they reached the bus by `until` and the decoder has room; with
  // `first_only`, stops once one cycle is complete (a reader waiting for one).
  void run_board_until(std::int64_t until, bool first_only) noexcept;
  bool feed_one(std::int64_t until) noexcept;  // the next pending frame, if it arrived
  // Frames on the bus not yet seen by a read (a scripted delay), by stamp.
  static constexpr int kPendingCapacity =
      (sim::SimRig::kMaxDelayPeriods + 2) * sim::SimBoard::kMaxFramesPerCycle;
  void queue_frames(int n) noexcept;

  SimOptions options_;
  sim::SimRig rig_;
  BoardDecoder decoder_;
  sim::SimBoard::Frames frames_{};
  std::array<can::CanFrame, kPendingCapacity> pending_{};
  int pending_n_ = 0;
  std::int64_t start_mono_ns_ = 0;
  std::int64_t wall_offset_ns_ = 0;
  std::int64_t cycle_ = 0;
  double last_read_s_ = -1.0;                // simulated time of the previous read (stall faults)
  std::int64_t last_now_ns_ = 0;             // free-running: the reader's latest now
  std::int64_t last_delivered_mono_ns_ = 0;  // free-running: stamp of the last sample delivered
};

}  // namespace exodaq::drivers
