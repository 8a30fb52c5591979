#pragma once
// An LCM log to CSV, one row per cycle (exodaq export, exodaq plot), in the
// schema of exodaq/messages/csv.hpp.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "exodaq/common/files.hpp"
#include "exodaq/messages/csv.hpp"

namespace exodaq::tools {

struct CsvExport {
  std::int64_t rows = 0;
  std::int64_t runs = 0;               // daemon runs (run ids) in the rows
  std::string first_run;               // run_id_text of the first row's run
  msg::csv::JointNames joint_names{};  // raw names of the first joint_state_t
  std::string rig;                     // status_t.rig of the first status message ("" if none)
  std::string damage;                  // damaged stretches of the log ("" when none)
  std::int64_t undecodable = 0;        // events on the rig's channels that do not decode
  std::string note;                    // anything else the user should know ("" when none)
};

// The channel prefix to export: `given`, or the only one the log holds.
// Throws std::runtime_error: not an LCM log (msg::LogError), no joint_state_t
// channel, several rigs without --prefix.
std::string choose_prefix(const std::string& log_path, const std::optional<std::string>& given);

// Writes the log's cycles with prefix `prefix` to `out` (not committed: the
// caller commits when it is content). Throws msg::LogError on a read error,
// files::FileError on a write error.
CsvExport export_log_csv(const std::string& log_path, const std::string& prefix,
                         files::OutputFile& out);

}  // namespace exodaq::tools
