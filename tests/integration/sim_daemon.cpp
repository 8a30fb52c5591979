#include "sim_daemon.hpp"

#include <unistd.h>

#include <fstream>
#include <regex>

#include "process.hpp"

namespace exodaq::test {

std::string write_sim_config(const std::string& dir, const std::string& prefix,
                             const std::string& calibration) {
  std::string text = read_file(std::string(EXODAQ_SOURCE_DIR) + "/config/sim.yaml");
  const std::string cfg_dir = std::string(EXODAQ_SOURCE_DIR) + "/config/";
  text = std::regex_replace(text, std::regex("model: models/"), "model: " + cfg_dir + "models/");
  text = std::regex_replace(text, std::regex("task: tasks/"), "task: " + cfg_dir + "tasks/");
  if (calibration.empty()) {
    text = std::regex_replace(text, std::regex("calibration: calibration/"),
                              "calibration: " + cfg_dir + "calibration/");
  } else {
    text = std::regex_replace(text, std::regex("calibration: calibration/sim.yaml"),
                              "calibration: " + calibration);
  }
  text = std::regex_replace(text, std::regex("prefix: \"\""), "prefix: \"" + prefix + "\"");
  // sim.yaml asks for SCHED_FIFO 50; without privilege ask for none, to keep the log quiet.
  if (geteuid() != 0) text = std::regex_replace(text, std::regex("priority: 50 "), "priority: 0 ");
  const std::string path = dir + "/exodaqd.yaml";
  std::ofstream(path) << text;
  return path;
}

}  // namespace exodaq::test
