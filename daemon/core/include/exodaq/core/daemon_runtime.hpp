#pragma once
// The daemon's process-level wiring: configuration, logging, signals
// (SIGTERM/SIGINT stop, SIGHUP reloads), systemd notification and the
// acquisition. main() only parses the command line.
#include <string>

namespace exodaq::core {

struct DaemonOptions {
  std::string config_path;
  std::string log_level;  // empty: config, then SPDLOG_LEVEL
  bool check_only = false;
  bool print_config = false;
};

// Returns the process exit code: 0 clean stop, 1 configuration or start-up error.
int run_daemon(const DaemonOptions& options);

}  // namespace exodaq::core
