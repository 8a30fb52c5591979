#pragma once
// The daemon's process-level wiring: configuration, logging (never waited
// for), signals (SIGTERM/SIGINT/SIGQUIT stop, SIGHUP reloads, job-control
// stops refused, others logged), systemd notification and the acquisition.
// main() only parses the command line.
#include <chrono>
#include <string>
#include <string_view>

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
// ignored; every other signal whose default action ends or stops a process
// blocked in this thread and every thread created after it (all but the
// program errors SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT; SIGRTMIN..SIGRTMAX
// included). None ends or stops the process by its default action: they stay
// pending through start-up and the supervisor takes them once the loop runs
// (a stop, a reload, a refused job-control stop, or a warning).
// docs/operations.md, "Signals".
void take_over_signals();

// Writes `text` to stderr, waiting at most `limit` for the output to take it
// (a pipe nobody reads, a paused terminal): what exodaqd says outside its log
// (command-line and configuration errors). False when it was not written.
bool write_stderr(std::string_view text,
                  std::chrono::milliseconds limit = std::chrono::milliseconds(1000));

// Returns the process exit code: 0 clean stop, 1 configuration or start-up error.
int run_daemon(const DaemonOptions& options);

}  // namespace exodaq::daemon
