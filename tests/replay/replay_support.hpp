#pragma once
// Helpers for the replay tests: LCM log files (read/write), a test copy of
// config/sim.yaml, and candump text produced from the simulated rig.
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "exodaq/drivers/sim_rig.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"

namespace exodaq::test {

using LogEvent = messages::OwnedEvent;
using messages::read_log;
using messages::write_log;

// Decodes every event of `channel` as Msg, keyed by seq (the daemon's
// all-zero start-up messages, utime == 0, are left out).
template <typename Msg>
std::map<std::int64_t, Msg> messages_by_seq(const std::vector<LogEvent>& log,
                                            const std::string& channel) {
  std::map<std::int64_t, Msg> out;
  for (const auto& e : log) {
    if (e.channel != channel) continue;
    Msg m;
    if (m.decode(e.data.data(), 0, static_cast<int>(e.data.size())) < 0) continue;
    if (m.utime == 0) continue;
    out[m.seq] = m;
  }
  return out;
}

// One log event carrying `m` on `channel`, stamped with its utime.
template <typename Msg>
LogEvent event(const std::string& channel, const Msg& m) {
  return LogEvent{channel, messages::encode(m), m.utime};
}

// The simulated rig's frames for cycles [0, cycles) as `candump -l` lines
// (wall-clock stamps from `wall_start_ns`). Also returns, per cycle, the
// counts the board sent (by board channel), for truth checks.
struct SimCandump {
  std::string text;
  std::vector<std::array<std::int64_t, 6>> counts;  // per cycle
  std::vector<std::int64_t> stamp_ns;               // per cycle
};
SimCandump sim_candump(const drivers::sim::SimOptions& options, std::int64_t cycles,
                       std::int64_t wall_start_ns);
// One frame as candump -l writes it.
std::string candump_line(const drivers::can::CanFrame& frame, std::int64_t stamp_ns,
                         const std::string& iface = "vcan0");

std::string read_text(const std::string& path);
void write_text(const std::string& path, const std::string& text);
std::int64_t file_size(const std::string& path);

}  // namespace exodaq::test
