#pragma once
// Helpers for tests that run exodaqd on the simulated rig as a process.
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace exodaq::test {

inline const std::string kLcmUrl = "udpm://239.255.76.67:7667?ttl=0";
// Subscribers in tests (recorders, lcm-logger): a 4 MiB socket buffer, so a
// busy test machine does not make the kernel drop what the daemon sent.
inline const std::string kRecordUrl = kLcmUrl + "&recv_buf_size=4194304";

// config/sim.yaml with absolute model and calibration paths, a private channel
// prefix and, where the system allows it (root), SCHED_FIFO for the loop
// thread. `calibration` replaces the calibration file when not empty.
std::string write_sim_config(const std::string& dir, const std::string& prefix,
                             const std::string& calibration = {});

// The text write_sim_config writes, for a test that edits it further
// (replace_once) before writing it (write_config_text).
std::string sim_config_text(const std::string& prefix, const std::string& calibration = {});

// Replaces the one occurrence of `from`; throws when the text has none (the
// config changed, and the test would run on settings it did not mean).
void replace_once(std::string& text, const std::string& from, const std::string& to);

// Writes `text` to dir/exodaqd.yaml; returns that path.
std::string write_config_text(const std::string& dir, const std::string& text);

// exodaqd's own account of a run, from its last log line ("stopped after N
// cycles (O overruns, F publish failures, M messages published; ...)"):
// what a test compares a recorder's holes with. Sync master: the cycles run
// and the deadlines skipped add up to the seqs used (cycles + overruns ==
// last seq + 1).
struct DaemonTotals {
  std::int64_t cycles = 0;
  std::int64_t overruns = 0;          // deadlines skipped
  std::int64_t publish_failures = 0;  // messages refused or dropped by the publish path
  std::int64_t published = 0;         // messages sent
};
// Throws std::runtime_error when `log` (the daemon's log text) has no such line.
DaemonTotals daemon_totals(const std::string& log);

template <typename Msg>
Msg decode(const std::vector<std::uint8_t>& d) {
  Msg m;
  if (m.decode(d.data(), 0, static_cast<int>(d.size())) < 0)
    throw std::runtime_error("decode failed");
  return m;
}

}  // namespace exodaq::test
