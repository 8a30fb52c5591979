#pragma once
// An LCM log to CSV, one row per cycle (exodaq export, exodaq plot).
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace exodaq::tools {

struct CsvExport {
  std::int64_t rows = 0;
  std::vector<std::string> joint_names;  // from the first joint_state_t
  std::string damage;                    // damaged stretches of the log ("" when none)
};

// `prefix`: the rig's channel prefix, or nullopt for the only one the log
// holds. Throws std::runtime_error (unreadable log, several rigs, no rig).
CsvExport export_log_csv(const std::string& log_path, const std::optional<std::string>& prefix,
                         const std::string& csv_path);

}  // namespace exodaq::tools
