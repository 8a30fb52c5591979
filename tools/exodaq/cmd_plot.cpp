// exodaq plot: figures of a recording in the spirit of seed 000 Figs. 16-18,
// drawn by matplotlib (tools/plot/exodaq_plot.py) from the CSV export.
//   exodaq plot LOG -o DIR [-c CONFIG] [--calibration FILE] [-p PREFIX]
//               [--script FILE] [--python EXE]
// Writes DIR/cycles.csv (the export) and DIR/joint_trajectories.png,
// DIR/palm_path_3d.png, DIR/shoulder_manipulability.png. Everything is made
// in a private temporary folder first; DIR is created, and the files put in
// it (as files::OutputFile), only when all of them were made.
#include <sys/stat.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "command.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/settings/service_config.hpp"
#include "export_csv.hpp"

namespace exodaq::tools {

namespace {

namespace fs = std::filesystem;

const char* const kFigures[] = {"joint_trajectories.png", "palm_path_3d.png",
                                "shoulder_manipulability.png"};
constexpr const char* kCsvName = "cycles.csv";

struct PlotOptions {
  std::string log;
  std::string out;
  std::string config;
  std::string calibration;
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
  const auto exe = fs::read_symlink("/proc/self/exe", ec);
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

// What the titles say: the log, its rig and first run, the calibration.
std::string title_of(const PlotOptions& o, const CsvExport& e, const std::string& calibration) {
  std::string t = fs::path(o.log).filename().string();
  t += "  |  rig " + (e.rig.empty() ? std::string("?") : e.rig);
  t += ", run " + e.first_run + (e.runs > 1 ? " (+" + std::to_string(e.runs - 1) + " more)" : "");
  t += "  |  calibration " +
       (calibration.empty() ? std::string("not given (-c/--calibration)") : calibration);
  return t;
}

int run_plot(const PlotOptions& o) {
  // The output folder: a directory or nothing yet (created only at the end).
  struct stat st {};
  if (::stat(o.out.c_str(), &st) == 0 && !S_ISDIR(st.st_mode)) {
    throw files::FileError(o.out, "is " + files::file_kind(st.st_mode) + ", not a directory");
  }
  std::string calibration = o.calibration;
  double threshold = -1.0;  // unknown: the script says so
  if (!o.config.empty()) {
    const settings::ServiceConfig cfg = settings::load_service_config(o.config);
    if (calibration.empty()) calibration = cfg.calibration_path;
    threshold = cfg.singularity_threshold;
  }
  const std::string prefix =
      choose_prefix(o.log, o.prefix_given ? std::optional(o.prefix) : std::nullopt);

  TempDir staging("plot");
  files::OutputFile csv(staging.file(kCsvName));
  const CsvExport exported = export_log_csv(o.log, prefix, csv);
  if (!exported.damage.empty()) print_error(exported.damage);
  if (exported.rows == 0) {
    print_error(o.log + ": no cycles (only the daemon's start-up messages?); nothing written");
    return kExitFailure;
  }
  csv.commit();
  std::string names;
  for (const auto& n : exported.joint_names) names += (names.empty() ? "" : ",") + n;
  std::vector<std::string> args{
      find_python(o),  find_script(o), "--csv",   staging.file(kCsvName),
      "--out",         staging.dir(),  "--title", title_of(o, exported, calibration),
      "--joint-names", names};
  if (threshold >= 0.0) {
    args.push_back("--threshold");
    args.push_back(messages::csv::number(threshold));
  }
  if (common_options().quiet) args.push_back("--quiet");
  const int rc = run_child(args);
  if (rc != 0) {
    print_error("the figures could not be made (" + args[1] + " exited with " + std::to_string(rc) +
                "); nothing written");
    return kExitFailure;
  }
  // Every file made: now the folder and the files, each put in place whole.
  fs::create_directories(o.out);
  files::OutputOptions oo;
  oo.inputs = {o.log};
  std::vector<std::string> made{kCsvName};
  for (const char* f : kFigures) made.emplace_back(f);
  for (const std::string& f : made) {
    const std::string target = (fs::path(o.out) / f).lexically_normal().string();
    files::write_output(target, files::read_input(staging.file(f), -1), oo);
    if (!common_options().quiet) std::printf("%s\n", target.c_str());
  }
  return exported.damage.empty() ? kExitOk : kExitFailure;
}

std::function<int()> setup_plot(CLI::App& sub) {
  auto o = std::make_shared<PlotOptions>();
  sub.add_option("log", o->log, "LCM log (lcm-logger or exodaq replay)")->required();
  sub.add_option("-o,--out", o->out, "folder for the figures and cycles.csv")->required();
  sub.add_option("-c,--config", o->config,
                 "the service config of the recording or replay: its calibration and "
                 "singularity threshold go into the figures");
  sub.add_option("--calibration", o->calibration,
                 "the calibration the log was computed with (default: the config's)");
  auto* prefix = add_prefix_option(sub, o->prefix, "default: the only one in the log");
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
                        "normalised shoulder manipulability (invalid and unhomed spans marked)",
                        exodaq::tools::setup_plot);
