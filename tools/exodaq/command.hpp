#pragma once
// `exodaq <command>`: each command lives in its own cmd_*.cpp and registers
// itself here, so commands are added without touching main.cpp.
//
// One grammar for every command (docs/operations.md "Command line"):
// -c/--config FILE, -o/--out FILE (- for standard output where the output is
// text), -q/--quiet and -v/--verbose (added to every command by main.cpp),
// --json where the output is data; errors are one line "exodaq <command>:
// <what>" on stderr (main.cpp prints whatever a command throws that way), and
// an unknown option is named with the closest valid one.
#include <CLI/CLI.hpp>

#include <functional>
#include <string>
#include <vector>

namespace exodaq::tools {

// Exit codes shared by every command.
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;  // the command ran and found a problem
inline constexpr int kExitUsage = 2;    // bad arguments or unreadable input

struct Command {
  std::string name;
  std::string help;
  // Adds the command's options to `sub` and returns the function to run.
  std::function<std::function<int()>(CLI::App& sub)> setup;
};

std::vector<Command>& command_registry();

struct CommandRegistrar {
  explicit CommandRegistrar(Command c) { command_registry().push_back(std::move(c)); }
};

// -q/--quiet and -v/--verbose of the command being run.
struct CommonOptions {
  bool quiet = false;    // only data and errors
  bool verbose = false;  // more detail (progress, what was read from where)
};
const CommonOptions& common_options();

// The command being run ("echo"), for messages.
const std::string& command_name();
// "exodaq <command>: <what>" on stderr, each line of `what` prefixed.
void print_error(const std::string& what);
// A note for people on stderr ("exodaq <command>: <what>"), unless --quiet.
void print_note(const std::string& what);

}  // namespace exodaq::tools

#define EXODAQ_REGISTER_COMMAND(ident, ...)                               \
  static const ::exodaq::tools::CommandRegistrar exodaq_command_##ident { \
    ::exodaq::tools::Command {                                            \
      __VA_ARGS__                                                         \
    }                                                                     \
  }
