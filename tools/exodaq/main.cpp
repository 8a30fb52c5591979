// exodaq: command-line tools beside the daemon (fk, ik, echo, view, status,
// record, replay, export, plot, calibrate, shoulder-cor). Each command is in its own
// cmd_*.cpp; this file holds what they share: the common options, the error
// lines and the unknown-option check (command.hpp).
#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <iostream>
#include <optional>

#include "command.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/version.hpp"

namespace exodaq::tools {

namespace {
CommonOptions g_common;
std::string g_command;
}  // namespace

std::vector<Command>& command_registry() {
  static std::vector<Command> registry;
  return registry;
}

const CommonOptions& common_options() {
  return g_common;
}

const std::string& command_name() {
  return g_command;
}

void print_error(const std::string& what) {
  std::size_t start = 0;
  while (true) {  // one prefixed line per line of `what`
    const std::size_t nl = what.find('\n', start);
    const std::string line = what.substr(start, nl - start);
    std::fprintf(stderr, "exodaq%s%s: %s\n", g_command.empty() ? "" : " ", g_command.c_str(),
                 line.c_str());
    if (nl == std::string::npos) break;
    start = nl + 1;
  }
}

void print_note(const std::string& what) {
  if (!g_common.quiet) print_error(what);
}

namespace {

// A closed standard descriptor would be reused by the next open() (a socket,
// an output file) and writes meant for it would land there. /dev/null opened
// read-only keeps the slot: writes to it then fail (EBADF) and are reported.
void occupy_closed_std_fds() {
  for (int fd = 0; fd <= 2; ++fd) {
    if (::fcntl(fd, F_GETFD) == -1 && errno == EBADF) {
      const int n = ::open("/dev/null", fd == 2 ? O_WRONLY : O_RDONLY);
      if (n >= 0 && n != fd) {
        ::dup2(n, fd);
        ::close(n);
      }
    }
  }
}

std::vector<std::string> long_names(const CLI::App& app) {
  std::vector<std::string> out;
  for (const CLI::Option* o : app.get_options()) {
    for (const auto& l : o->get_lnames()) out.push_back("--" + l);
  }
  return out;
}

// The first option in argv that `sub` does not have ("" when none): checked
// before parsing, so an unknown option is named even when a required one is
// missing too (CLI11 would report the missing one first).
std::string unknown_option(const CLI::App& sub, int argc, char** argv, int from) {
  for (int i = from; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--") break;
    if (a.size() < 2 || a[0] != '-') continue;
    if (std::isdigit(static_cast<unsigned char>(a[1])) || a[1] == '.') continue;  // -90, -.5
    if (a[1] == '-') {
      std::string name = a.substr(0, a.find('='));
      if (sub.get_option_no_throw(name) == nullptr) return name;
      continue;
    }
    for (std::size_t k = 1; k < a.size(); ++k) {  // -c FILE, -cFILE, -qv
      std::string s = std::string("-") + a[k];
      const CLI::Option* o = sub.get_option_no_throw(s);
      if (o == nullptr) return s;
      if (o->get_items_expected_max() != 0) break;  // the rest is its value
    }
  }
  return "";
}

int report_unknown(const CLI::App& sub, const std::string& opt) {
  const std::string near = files::closest_match(opt, long_names(sub));
  print_error("unknown option '" + opt + "'" +
              (near.empty() ? std::string() : "; did you mean '" + near + "'?") + " (exodaq " +
              g_command + " --help lists the options)");
  return kExitUsage;
}

// Which registered command argv names, and where; nullopt when none.
std::optional<int> command_position(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    if (argv[i][0] != '-') return i;
  }
  return std::nullopt;
}

int run_main(int argc, char** argv) {
  CLI::App app{"exodaq: tools for the exoskeleton data-acquisition service"};
  app.set_version_flag(
      "--version", std::string("exodaq ") + exodaq::kVersion + " (" + exodaq::kGitDescribe + ")");
  app.require_subcommand(1);
  auto& commands = command_registry();
  std::sort(commands.begin(), commands.end(),
            [](const auto& a, const auto& b) { return a.name < b.name; });
  std::function<int()> run;
  std::vector<std::string> names;
  for (auto& c : commands) {
    CLI::App* sub = app.add_subcommand(c.name, c.help);
    sub->add_flag("-q,--quiet", g_common.quiet, "only data and errors");
    sub->add_flag("-v,--verbose", g_common.verbose, "more detail on what is read and done");
    auto fn = c.setup(*sub);
    sub->callback([&run, fn, name = c.name] {
      run = fn;
      g_command = name;
    });
    names.push_back(c.name);
  }

  if (const auto at = command_position(argc, argv)) {
    const std::string cmd = argv[*at];
    CLI::App* sub = nullptr;
    for (CLI::App* s : app.get_subcommands({})) {
      if (s->get_name() == cmd) sub = s;
    }
    if (sub == nullptr) {
      const std::string near = files::closest_match(cmd, names);
      print_error("unknown command '" + cmd + "'" +
                  (near.empty() ? std::string() : "; did you mean '" + near + "'?") +
                  " (exodaq --help lists the commands)");
      return kExitUsage;
    }
    g_command = cmd;
    if (const std::string opt = unknown_option(*sub, argc, argv, *at + 1); !opt.empty()) {
      return report_unknown(*sub, opt);
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    print_error(std::string(e.what()) +
                (g_command.empty() ? " (exodaq --help lists the commands)"
                                   : " (exodaq " + g_command + " --help lists the options)"));
    return kExitUsage;
  }
  if (g_common.quiet && g_common.verbose) {
    print_error("--quiet and --verbose exclude each other");
    return kExitUsage;
  }
  int rc = kExitUsage;
  try {
    rc = run ? run() : kExitUsage;
  } catch (const std::exception& e) {
    print_error(e.what());
    rc = kExitUsage;
  }
  // Text written through stdio: a full disk, a closed pipe or /dev/full
  // shows here.
  errno = 0;
  if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
    print_error("cannot write to standard output: " + files::errno_text(errno ? errno : EIO));
    if (rc == kExitOk) rc = kExitFailure;
  }
  return rc;
}

}  // namespace
}  // namespace exodaq::tools

// Nothing escapes main: an unexpected exception is reported and exits 1.
int main(int argc, char** argv) {
  exodaq::tools::occupy_closed_std_fds();
  try {
    return exodaq::tools::run_main(argc, argv);
  } catch (const std::exception& e) {
    exodaq::tools::print_error(e.what());
  } catch (...) {
    exodaq::tools::print_error("unknown error");
  }
  return 1;
}
