// exodaqd: the 1 kHz acquisition service. Reads the encoder source, computes
// joint angles and the palm pose, publishes them over LCM. See docs/operations.md.
#include <signal.h>
#include <spdlog/async.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/systemd_sink.h>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>
#include <time.h>
#include <exception>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <cstdlib>
#include <iostream>

#include "exodaq/daemon/daemon_runtime.hpp"
#include "exodaq/version.hpp"

static int run_main(int argc, char** argv) {
  CLI::App app{"exodaqd: exoskeleton encoder acquisition service (1 kHz, LCM)"};
  std::string config_path;
  bool check_only = false;
  bool print_config = false;
  std::string log_level;
  app.add_option("-c,--config", config_path, "service configuration file (YAML)");
  app.add_flag("--check-config", check_only, "validate the configuration and exit 0 (valid) or 1");
  app.add_flag("--print-config", print_config, "print the effective configuration and exit");
  app.add_option("--log-level", log_level,
                 "trace|debug|info|warn|error|critical|off (overrides config and SPDLOG_LEVEL)");
  double duration_s = 0.0;
  std::string lateness_log;
  app.add_option("--duration", duration_s,
                 "stop by itself after this many seconds (default: run until SIGTERM/SIGINT)");
  app.add_option("--lateness-log", lateness_log,
                 "benchmarks: write each cycle's wake-up lateness in ns to FILE at exit");
  app.set_version_flag(
      "--version", std::string("exodaqd ") + exodaq::kVersion + " (" + exodaq::kGitDescribe + ")");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  if (config_path.empty()) {
    std::fprintf(stderr, "exodaqd: --config FILE is required\n");
    return 2;
  }
  exodaq::daemon::DaemonOptions options;
  options.config_path = config_path;
  options.log_level = log_level;
  options.check_only = check_only;
  options.print_config = print_config;
  options.duration_s = duration_s;
  options.lateness_log = lateness_log;
  return exodaq::daemon::run_daemon(options);
}

// Nothing escapes main: an unexpected exception is reported and exits 1.
int main(int argc, char** argv) {
  try {
    return run_main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
  } catch (...) {
    std::fprintf(stderr, "%s: unknown error\n", argv[0]);
  }
  return 1;
}
