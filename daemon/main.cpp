// exodaqd: the 1 kHz acquisition service. Reads the encoder source, computes
// joint angles and the palm pose, publishes them over LCM. See docs/operations.md.
// The command line follows the tools' grammar (tools/exodaq/command.hpp):
// -c/--config, -q/--quiet, -v/--verbose, errors "exodaqd: <what>", an
// unknown option named with the closest valid one.
#include <signal.h>
#include <spdlog/async.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/systemd_sink.h>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>
#include <time.h>

#include <CLI/CLI.hpp>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <iostream>

#include "exodaq/common/files.hpp"
#include "exodaq/daemon/daemon_runtime.hpp"
#include "exodaq/version.hpp"

namespace {

// stderr may be a pipe nobody reads: the signals are blocked already, so a
// write that waited for ever would make exodaqd unstoppable.
void print_error(const std::string& what) {
  exodaq::daemon::write_stderr("exodaqd: " + what + "\n");
}

// The first option in argv the app does not have ("" when none), found
// before parsing so it is named even when another error would come first.
std::string unknown_option(const CLI::App& app, int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--") break;
    if (a.size() < 2 || a[0] != '-' || std::isdigit(static_cast<unsigned char>(a[1]))) continue;
    std::string name = a[1] == '-' ? a.substr(0, a.find('=')) : a.substr(0, 2);
    if (app.get_option_no_throw(name) == nullptr) return name;
  }
  return "";
}

int run_main(int argc, char** argv) {
  CLI::App app{"exodaqd: exoskeleton encoder acquisition service (1 kHz, LCM)"};
  std::string config_path;
  bool check_only = false;
  bool print_config = false;
  bool quiet = false;
  bool verbose = false;
  std::string log_level;
  app.add_option("-c,--config", config_path, "service configuration file (YAML)");
  app.add_flag("--check-config", check_only, "validate the configuration and exit 0 (valid) or 1");
  app.add_flag("--print-config", print_config, "print the effective configuration and exit");
  app.add_option("--log-level", log_level,
                 "trace|debug|info|warn|error|critical|off (overrides config and SPDLOG_LEVEL)");
  app.add_flag("-q,--quiet", quiet, "log warnings and errors only (--log-level warn)");
  app.add_flag("-v,--verbose", verbose, "log debug messages too (--log-level debug)");
  double duration_s = 0.0;
  std::string lateness_log;
  app.add_option("--duration", duration_s,
                 "stop by itself after this many seconds (default: run until SIGTERM/SIGINT)");
  app.add_option("--lateness-log", lateness_log,
                 "benchmarks: write each cycle's wake-up lateness in ns to FILE at exit");
  app.set_version_flag(
      "--version", std::string("exodaqd ") + exodaq::kVersion + " (" + exodaq::kGitDescribe + ")");
  if (const std::string opt = unknown_option(app, argc, argv); !opt.empty()) {
    std::vector<std::string> names;
    for (const CLI::Option* o : app.get_options()) {
      for (const auto& l : o->get_lnames()) names.push_back("--" + l);
    }
    const std::string near = exodaq::files::closest_match(opt, names);
    print_error("unknown option '" + opt + "'" +
                (near.empty() ? std::string() : "; did you mean '" + near + "'?") +
                " (exodaqd --help lists the options)");
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    print_error(std::string(e.what()) + " (exodaqd --help lists the options)");
    return 2;
  }
  if (config_path.empty()) {
    print_error("-c/--config FILE is required");
    return 2;
  }
  if (quiet && verbose) {
    print_error("--quiet and --verbose exclude each other");
    return 2;
  }
  if (log_level.empty() && quiet) log_level = "warn";
  if (log_level.empty() && verbose) log_level = "debug";
  exodaq::daemon::DaemonOptions options;
  options.config_path = config_path;
  options.log_level = log_level;
  options.check_only = check_only;
  options.print_config = print_config;
  options.duration_s = duration_s;
  options.lateness_log = lateness_log;
  return exodaq::daemon::run_daemon(options);
}

}  // namespace

// Nothing escapes main: an unexpected exception is reported and exits 1.
int main(int argc, char** argv) {
  exodaq::daemon::take_over_signals();  // before anything slow: no signal is fatal from here on
  try {
    return run_main(argc, argv);
  } catch (const std::exception& e) {
    print_error(e.what());
  } catch (...) {
    print_error("unknown error");
  }
  return 1;
}
