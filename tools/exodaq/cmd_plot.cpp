// exodaq plot: figures of a recording in the spirit of seed 000 Figs. 16-18,
// drawn by matplotlib (tools/plot/exodaq_plot.py) from the CSV export.
//   exodaq plot LOG --out DIR [--prefix P] [--script FILE] [--python EXE]
// Writes DIR/cycles.csv (the export) and DIR/joint_trajectories.png,
// DIR/palm_path_3d.png, DIR/shoulder_manipulability.png.
#include <spawn.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "command.hpp"
#include "export_csv.hpp"

extern char** environ;

namespace exodaq::tools {

namespace {

const char* const kFigures[] = {"joint_trajectories.png", "palm_path_3d.png",
                                "shoulder_manipulability.png"};

struct PlotOptions {
  std::string log;
  std::string out;
  std::string prefix;
  bool prefix_given = false;
  std::string script;
  std::string python;
};

bool is_file(const std::string& p) {
  struct stat st {};
  return !p.empty() && stat(p.c_str(), &st) == 0 && S_ISREG(st.st_mode);
}

std::string find_script(const PlotOptions& o) {
  if (!o.script.empty()) return o.script;
  if (const char* env = std::getenv("EXODAQ_PLOT_SCRIPT")) return env;
  // Installed: <prefix>/bin/exodaq and <prefix>/share/exodaq/plot/; the build
  // tree mirrors it: build/tools/exodaq and build/share/exodaq/plot/.
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    std::string candidate =
        (exe.parent_path().parent_path() / "share/exodaq/plot/exodaq_plot.py").string();
    if (is_file(candidate)) return candidate;
  }
  throw std::runtime_error("cannot find exodaq_plot.py (give --script or set EXODAQ_PLOT_SCRIPT)");
}

std::string find_python(const PlotOptions& o) {
  if (!o.python.empty()) return o.python;
  if (const char* env = std::getenv("EXODAQ_PYTHON")) return env;
  // Debian's python3 has python3-matplotlib; a python3 earlier in PATH
  // (pyenv, a venv) may not.
  if (is_file("/usr/bin/python3")) return "/usr/bin/python3";
  return "python3";
}

int run_child(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, argv[0], nullptr, nullptr, argv.data(), environ);
  if (rc != 0) {
    throw std::runtime_error("cannot run '" + args[0] + "': " + std::strerror(rc));
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) throw std::runtime_error("waitpid failed");
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  return 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
}

int run_plot(const PlotOptions& o) {
  std::filesystem::create_directories(o.out);
  const std::string csv = o.out + "/cycles.csv";
  const CsvExport exported =
      export_log_csv(o.log, o.prefix_given ? std::optional(o.prefix) : std::nullopt, csv);
  const std::vector<std::string>& names = exported.joint_names;
  if (!exported.damage.empty()) std::fprintf(stderr, "exodaq plot: %s\n", exported.damage.c_str());
  if (exported.rows == 0) {
    std::fprintf(stderr, "exodaq plot: '%s' has no joint_state_t message\n", o.log.c_str());
    return kExitFailure;
  }
  std::string joined;
  for (const auto& n : names) joined += (joined.empty() ? "" : ",") + n;
  const std::vector<std::string> args{find_python(o),  find_script(o), "--csv",   csv,
                                      "--out",         o.out,          "--title", o.log,
                                      "--joint-names", joined};
  const int rc = run_child(args);
  if (rc != 0) {
    std::fprintf(stderr, "exodaq plot: %s exited with %d\n", args[1].c_str(), rc);
    return kExitFailure;
  }
  int missing = 0;
  for (const char* f : kFigures) {
    const std::string path = o.out + "/" + f;
    if (!is_file(path)) {
      std::fprintf(stderr, "exodaq plot: %s was not written\n", path.c_str());
      ++missing;
    } else {
      std::printf("%s\n", path.c_str());
    }
  }
  return missing == 0 ? kExitOk : kExitFailure;
}

std::function<int()> setup_plot(CLI::App& sub) {
  auto o = std::make_shared<PlotOptions>();
  sub.add_option("log", o->log, "LCM log (lcm-logger or exodaq replay)")
      ->required()
      ->check(CLI::ExistingFile);
  sub.add_option("-o,--out", o->out, "directory for the figures and cycles.csv")->required();
  auto* prefix =
      sub.add_option("--prefix", o->prefix, "channel prefix (default: the only one in the log)");
  sub.add_option("--script", o->script,
                 "plot script (default: share/exodaq/plot/exodaq_plot.py beside the tool)");
  sub.add_option("--python", o->python,
                 "Python with matplotlib (default: $EXODAQ_PYTHON, /usr/bin/python3, python3)");
  return [o, prefix] {
    o->prefix_given = prefix->count() > 0;
    return run_plot(*o);
  };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(plot, "plot",
                        "PNG figures of a recording: joint trajectories, palm path in 3D, "
                        "normalised shoulder manipulability (invalid spans shaded)",
                        exodaq::tools::setup_plot);
