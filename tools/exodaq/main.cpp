// exodaq: command-line tools beside the daemon (fk, echo, view, status, replay,
// export, plot, calibrate). Each command is in its own cmd_*.cpp.
#include <algorithm>
#include <cstdio>
#include <exception>
#include <iostream>

#include "command.hpp"
#include "exodaq/version.hpp"

namespace exodaq::tools {
std::vector<Command>& command_registry() {
  static std::vector<Command> registry;
  return registry;
}
}  // namespace exodaq::tools

static int run_main(int argc, char** argv) {
  using exodaq::tools::command_registry;
  CLI::App app{"exodaq: tools for the exoskeleton data-acquisition service"};
  app.set_version_flag(
      "--version", std::string("exodaq ") + exodaq::kVersion + " (" + exodaq::kGitDescribe + ")");
  app.require_subcommand(1);
  auto& commands = command_registry();
  std::sort(commands.begin(), commands.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  std::function<int()> run;
  for (auto& c : commands) {
    CLI::App* sub = app.add_subcommand(c.name, c.help);
    auto fn = c.setup(*sub);
    sub->callback([&run, fn] { run = fn; });
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int rc = app.exit(e);
    return rc == 0 ? 0 : exodaq::tools::kExitUsage;
  }
  try {
    return run ? run() : exodaq::tools::kExitUsage;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "exodaq: %s\n", e.what());
    return exodaq::tools::kExitUsage;
  }
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
