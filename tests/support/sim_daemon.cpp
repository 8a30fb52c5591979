#include "sim_daemon.hpp"

#include <unistd.h>

#include <fstream>
#include <regex>

#include "process.hpp"

namespace exodaq::test {

void replace_once(std::string& text, const std::string& from, const std::string& to) {
  const auto pos = text.find(from);
  if (pos == std::string::npos) throw std::runtime_error("the config text has no '" + from + "'");
  text.replace(pos, from.size(), to);
}

std::string sim_config_text(const std::string& prefix, const std::string& calibration) {
  const std::string src = std::string(EXODAQ_SOURCE_DIR) + "/config/";
  std::string text = read_file(src + "sim.yaml");
  replace_once(text, "\nmodel: ", "\nmodel: " + src);
  replace_once(text, "task: tasks/", "task: " + src + "tasks/");
  if (calibration.empty()) {
    replace_once(text, "\ncalibration: ", "\ncalibration: " + src);
  } else {
    replace_once(text, "\ncalibration: calibration/sim.yaml", "\ncalibration: " + calibration);
  }
  replace_once(text, "prefix: \"\"", "prefix: \"" + prefix + "\"");
  // sim.yaml asks for SCHED_FIFO 50; without privilege ask for none, to keep the log quiet.
  if (geteuid() != 0) replace_once(text, "priority: 50 ", "priority: 0 ");
  return text;
}

std::string write_config_text(const std::string& dir, const std::string& text) {
  const std::string path = dir + "/exodaqd.yaml";
  std::ofstream out(path);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path);
  return path;
}

DaemonTotals daemon_totals(const std::string& log) {
  static const std::regex line(
      R"(stopped after (\d+) cycles \((\d+) overruns, (\d+) publish failures, (\d+) messages )"
      R"(published)");
  std::smatch m;
  if (!std::regex_search(log, m, line)) {
    throw std::runtime_error("no 'stopped after N cycles' line in the daemon's log");
  }
  DaemonTotals t;
  t.cycles = std::stoll(m[1]);
  t.overruns = std::stoll(m[2]);
  t.publish_failures = std::stoll(m[3]);
  t.published = std::stoll(m[4]);
  return t;
}

std::string write_sim_config(const std::string& dir, const std::string& prefix,
                             const std::string& calibration) {
  return write_config_text(dir, sim_config_text(prefix, calibration));
}

}  // namespace exodaq::test
