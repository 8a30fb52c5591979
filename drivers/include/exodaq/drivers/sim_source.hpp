#pragma once
// The `sim` encoder backend: a simulated rig (sim_rig.hpp) behind the
// EncoderSource seam. Each read() advances the rig one sampling cycle, encodes
// that cycle's CAN frames with the protocol v1 codec and decodes them through
// the same BoardDecoder the SocketCAN path uses, so a simulated run exercises
// the real decode path (sequence checks, partial cycles, index merging,
// heartbeats).
//
// Options: SimOptions (declared in sim_rig.hpp, a plain value type with
// defaults; every field documented there):
//   seed            motion, jitter and loss randomness; same seed → same stream
//   period_ns       sampling period (1 000 000 = 1 kHz)
//   jitter_ns       sample instant t_k = k·period + uniform[−jitter, +jitter]
//   loss_percent    cycles lost whole (read() returns kNoSample, kMissing;
//                   the next sample has kSeqGap)
//   partial_percent cycles whose COUNTS_B is lost (kPartial sample)
//   encoders[6]     per joint: channel, direction, counts_per_rev, gear_ratio,
//                   index_angle_rad (Δθ⁰), power_up_count
//   motion          SimMotionOptions: home, limits, task windows, speed caps,
//                   homing sweep, hold times, round trips
//   board           SimBoardOptions: protocol IDs, heartbeat rate, first seq,
//                   reported state and error bits
//   start_mono_ns, wall_offset_ns   time base (0 = from the clocks at start())
//
// Sample stamps: mono_ns = start_mono_ns + t_k (the simulated sampling
// instant, so truth(t_k) is the exact angle behind the counts), wall_ns =
// mono_ns + (CLOCK_REALTIME − CLOCK_MONOTONIC taken once at start()). A lost
// cycle's kNoSample carries the same stamps for that cycle.
//
// The sim paces nothing: read() simulates board cycle max(time.cycle, next),
// so it stays locked to the loop's cycle numbers across skipped deadlines.
// A scripted `stall` fault makes the read that reaches its start block for its
// duration (real time), as a host held off would.
#include <cstdint>
#include <string_view>

#include "exodaq/drivers/board_decoder.hpp"
#include "exodaq/drivers/encoder_source.hpp"
#include "exodaq/drivers/sim_rig.hpp"

namespace exodaq::drivers {

using sim::SimOptions;

class SimSource final : public EncoderSource {
 public:
  // Throws std::invalid_argument on inconsistent options (also a stall without a duration).
  explicit SimSource(const SimOptions& options = {});

  std::string_view name() const noexcept override { return "sim"; }
  // Fixes the time base and rewinds to cycle 0.
  void start() override;
  // Allocation-free; blocks only in a scripted `stall` fault.
  ReadStatus read(const CycleTime& time, EncoderSample& out) noexcept override;
  SourceStats stats() const noexcept override { return decoder_.stats(); }

  // For tests and the daemon's truth checks.
  const sim::SimRig& rig() const noexcept { return rig_; }
  const BoardDecoder& decoder() const noexcept { return decoder_; }
  std::int64_t start_mono_ns() const noexcept { return start_mono_ns_; }
  std::int64_t wall_offset_ns() const noexcept { return wall_offset_ns_; }
  std::int64_t cycles() const noexcept { return cycle_; }  // read() calls since start()
  // Simulated time (s) of a sample stamped mono_ns: feed it to rig().motion().truth().
  double sim_time_s(std::int64_t mono_ns) const noexcept {
    return static_cast<double>(mono_ns - start_mono_ns_) * 1e-9;
  }

 private:
  // A scripted stall whose start lies in (previous read, t_s]: sleeps its duration.
  void stall_if_due(double t_s) noexcept;

  SimOptions options_;
  sim::SimRig rig_;
  BoardDecoder decoder_;
  sim::SimBoard::Frames frames_{};
  std::int64_t start_mono_ns_ = 0;
  std::int64_t wall_offset_ns_ = 0;
  std::int64_t cycle_ = 0;
  double last_read_s_ = -1.0;  // simulated time of the previous read (stall faults)
};

}  // namespace exodaq::drivers
