#pragma once
// The figure scripts of `exodaq calibrate` and `exodaq shoulder-cor` (python3
// with matplotlib): finding them and running them. A missing Python or
// matplotlib skips the figure with a message; it never fails the command.
#include <string>
#include <vector>

namespace exodaq::calibration {

// Path of the script `file_name`: the file named by the environment variable
// `env_var` if it exists, else the installed copy (<binary>/../share/exodaq/),
// else the source tree's (tools/calibrate/). "" when none exists.
std::string find_plot_script(const char* env_var, const std::string& file_name);

// Runs `python3 script args...`. Returns false with `message` set to
// "figure skipped: <why>" when python3 with matplotlib is missing or the
// script fails; true otherwise (message untouched).
bool run_plot_script(const std::string& script, const std::vector<std::string>& args,
                     std::string& message);

}  // namespace exodaq::calibration
