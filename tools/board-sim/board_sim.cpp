#include "board_sim.hpp"

#include <bit>
#include <cerrno>

#include "exodaq/common/clock_now.hpp"

namespace exodaq::board_sim {
void write_truth_header(std::FILE* truth) {
  std::fprintf(truth, "# k seq t_s q0 q1 q2 q3 q4 q5 c0 c1 c2 c3 c4 c5 fault_bits\n");
}

BoardSim::BoardSim(const sim::SimOptions& options, drivers::CanPort& port, std::FILE* truth)
    : rig_(options), port_(port), truth_(truth) {}

int BoardSim::send(const drivers::can::CanFrame& frame) noexcept {
  int r = 0;
  for (int attempt = 0; attempt < 5; ++attempt) {
    r = port_.send(frame);
    if (r != -EAGAIN && r != -ENOBUFS) return r;
    exodaq::sleep_until_mono(port_.now_mono_ns() + 200'000);  // the TX queue drains
  }
  return r;
}

void BoardSim::cycle(std::int64_t k, std::int64_t start_mono_ns) {
  send_cycle(rig_.step(k, frames_, start_mono_ns, 0));
}

void BoardSim::cycle_now(std::int64_t k, std::int64_t now_mono_ns, std::int64_t origin_mono_ns) {
  send_cycle(rig_.step_at(k, now_mono_ns - origin_mono_ns, frames_, origin_mono_ns, 0));
}

void BoardSim::send_cycle(int n) {
  ++counters_.cycles;
  std::uint32_t bits = rig_.last_cycle().applied;
  for (int i = 0; i < n; ++i) {
    const auto& frame = frames_[static_cast<std::size_t>(i)];
    if (frame.mono_ns > port_.now_mono_ns()) exodaq::sleep_until_mono(frame.mono_ns);
    const int err = port_.is_open() ? send(frame) : -ENODEV;
    if (err == 0) {
      ++counters_.frames;
      continue;
    }
    ++counters_.send_failures;
    bits |= kSendFailedBit;
    if (drivers::is_interface_loss(-err)) break;
  }
  write_truth(bits);
}

void BoardSim::write_truth(std::uint32_t bits) const {
  if (truth_ == nullptr) return;
  const sim::SimCycle& c = rig_.last_cycle();
  std::fprintf(truth_, "%lld %u %.9f", static_cast<long long>(c.k),
               static_cast<unsigned>((rig_.options().board.first_seq + c.k) & 0xFF), c.t_s);
  for (double q : c.position) std::fprintf(truth_, " %.12f", q);
  for (std::int64_t n : c.count) std::fprintf(truth_, " %lld", static_cast<long long>(n));
  std::fprintf(truth_, " %u\n", bits);
  // Each line as its cycle is sent: a reader counting lines (the VM scenario
  // holding the daemon off for N board cycles) counts cycles sent, not
  // whatever a stdio buffer last released.
  std::fflush(truth_);
}

std::string BoardSim::summary() const {
  const auto& applied = rig_.applied_counts();
  std::string s =
      "BOARD-SIM: cycles=" + std::to_string(counters_.cycles) +
      " frames=" + std::to_string(counters_.frames) +
      " send_failures=" + std::to_string(counters_.send_failures) +
      " random_loss=" + std::to_string(applied[std::countr_zero(sim::kRandomLossBit)]) +
      " random_partial=" + std::to_string(applied[std::countr_zero(sim::kRandomPartialBit)]);
  for (const sim::SimFaultName& f : sim::sim_fault_names()) {
    s +=
        " " + std::string(f.name) + "=" + std::to_string(applied[static_cast<std::size_t>(f.kind)]);
  }
  return s;
}

}  // namespace exodaq::board_sim
