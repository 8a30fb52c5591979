#pragma once
// The daemon's process-level wiring: configuration, logging, signals
// (SIGTERM/SIGINT stop, SIGHUP reloads, others logged), systemd notification and the
// acquisition. main() only parses the command line.
#include <string>

namespace exodaq::daemon {

struct DaemonOptions {
  std::string config_path;
  std::string log_level;  // empty: config, then SPDLOG_LEVEL
  bool check_only = false;
  bool print_config = false;
  double duration_s = 0.0;   // stop by itself after this long (0: run until signalled)
  std::string lateness_log;  // write each cycle's wake-up lateness (ns, one per line) here at exit
};

// The first thing exodaqd does (main(), and again in run_daemon()): SIGPIPE
// ignored; SIGTERM, SIGINT, SIGHUP and the signals the daemon has no use for
// (SIGUSR1, SIGUSR2, SIGALRM, SIGVTALRM, SIGPOLL, SIGPWR) blocked in this
// thread and every thread created after it. None ends the process by its
// default action: they stay pending through start-up and the supervisor takes
// them once the loop runs (a stop, a reload, or a warning). docs/operations.md.
void take_over_signals();

// Returns the process exit code: 0 clean stop, 1 configuration or start-up error.
int run_daemon(const DaemonOptions& options);

}  // namespace exodaq::daemon
