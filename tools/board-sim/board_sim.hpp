#pragma once
// The encoder interface board on a CanPort: each cycle() simulates one board
// cycle of the shared SimRig (faults included: the one vocabulary of
// sim_rig.hpp), sends its frames when they are due and writes one truth line.
// docs/can-protocol.md ("Board simulator"), docs/simulator.md.
#include <array>
#include <cstdint>
#include <cstdio>
#include <string>

#include "exodaq/drivers/can_port.hpp"
#include "exodaq/drivers/sim_rig.hpp"

namespace exodaq::board_sim {

namespace sim = drivers::sim;

// Truth-file bit beyond SimCycle::applied (fault_bit(kind), kRandomLossBit,
// kRandomPartialBit): a frame of this cycle could not be sent.
inline constexpr std::uint32_t kSendFailedBit = 1U << 29;

struct Counters {
  std::int64_t cycles = 0;
  std::int64_t frames = 0;
  std::int64_t send_failures = 0;
};

// Writes "# k seq t_s q0..q5 c0..c5 fault_bits" (the truth file's header).
void write_truth_header(std::FILE* truth);

class BoardSim {
 public:
  // `truth` may be null. Throws std::invalid_argument on inconsistent options.
  BoardSim(const sim::SimOptions& options, drivers::CanPort& port, std::FILE* truth);

  // Simulates cycle k, sampled at start_mono_ns + t_k, and sends its frames,
  // each no earlier than its stamp (a scripted delay).
  void cycle(std::int64_t k, std::int64_t start_mono_ns);
  // Simulates cycle k sampled at `now_mono_ns` (t = now - `origin_mono_ns`,
  // not k periods) and sends its frames at once: a board answering SYNC
  // latches its counts when the SYNC reaches it (docs/simulator.md).
  void cycle_now(std::int64_t k, std::int64_t now_mono_ns, std::int64_t origin_mono_ns);

  const Counters& counters() const noexcept { return counters_; }
  const sim::SimRig& rig() const noexcept { return rig_; }
  // "BOARD-SIM: cycles=… frames=… send_failures=… random_loss=… <kind>=…":
  // cycles each fault kind changed, by the names of sim_fault_names().
  std::string summary() const;

 private:
  // 0, or −errno after a few tries on a full TX queue.
  int send(const drivers::can::CanFrame& frame) noexcept;
  // Sends the n frames the rig made for the cycle just simulated; one truth line.
  void send_cycle(int n);
  void write_truth(std::uint32_t bits) const;

  sim::SimRig rig_;
  drivers::CanPort& port_;
  std::FILE* truth_;
  Counters counters_{};
  sim::SimBoard::Frames frames_{};
};

}  // namespace exodaq::board_sim
