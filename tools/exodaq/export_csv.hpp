#pragma once
// An LCM log to CSV, one row per cycle (exodaq export, exodaq plot), in the
// schema of exodaq/messages/csv.hpp.
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "exodaq/common/files.hpp"
#include "exodaq/messages/csv.hpp"

namespace exodaq::tools {

struct CsvExport {
  std::int64_t rows = 0;
  std::int64_t runs = 0;                    // daemon runs (run ids) in the rows
  std::string first_run;                    // run_id_text of the first row's run
  messages::csv::JointNames joint_names{};  // raw names of the first joint_state_t
  std::string rig;                          // status_t.rig of the first status message ("" if none)
  // Damage and anomalies, one line each ("" when none): damaged stretches of
  // the log (with the cycles each cost), events that do not decode, damaged
  // run ids, seq out of line or repeated. Any of them: exit 1.
  std::string damage;
  std::int64_t undecodable = 0;    // events on the rig's channels that do not decode
  std::string note;                // anything else the user should know ("" when none)
  std::vector<std::string> notes;  // per run: its cycles and seq holes (messages::describe)
  std::int64_t missing = 0;        // seq numbers missing between the rows, all runs
  std::int64_t lost = 0;  // of those, neither skipped by the daemon (its status counters) nor
                          // lost to damage in the log: lost by the recorder or the network
};

// The channel prefix to export: `given`, or the only one the log holds.
// Throws std::runtime_error: not an LCM log (messages::LogError), no joint_state_t
// channel, several rigs without --prefix.
std::string choose_prefix(const std::string& log_path, const std::optional<std::string>& given);

// Two runs interleaved in a log (two daemons published on one channel set):
// what() names both run ids and suggests --run-id.
class MixedRunsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Writes the log's cycles with prefix `prefix` to `out` (not committed: the
// caller commits when it is content); with `only_run`, the cycles of that run
// alone. Throws messages::LogError on a read error, files::FileError on a write
// error, MixedRunsError when two runs interleave (and `only_run` is not set).
CsvExport export_log_csv(const std::string& log_path, const std::string& prefix,
                         files::OutputFile& out,
                         std::optional<std::int64_t> only_run = std::nullopt);

}  // namespace exodaq::tools
