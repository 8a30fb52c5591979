#pragma once
// `exodaq <command>`: each command lives in its own cmd_*.cpp and registers
// itself here, so commands are added without touching main.cpp.
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

}  // namespace exodaq::tools

#define EXODAQ_REGISTER_COMMAND(ident, ...)                               \
  static const ::exodaq::tools::CommandRegistrar exodaq_command_##ident { \
    ::exodaq::tools::Command {                                            \
      __VA_ARGS__                                                         \
    }                                                                     \
  }
