#pragma once
// The figure scripts of `exodaq calibrate` and `exodaq shoulder-cor` (python3
// with matplotlib): finding them and running them. A missing Python or
// matplotlib skips the figure with a message; it never fails the command.
#include <string>
#include <vector>

namespace exodaq::calibration {

// Path of the script `file_name`: the file named by the environment variable
// `env_var` if it exists, else the installed copy (<binary>/../share/exodaq/),
// else the source tree's (tools/calibration/). "" when none exists.
std::string find_plot_script(const char* env_var, const std::string& file_name);

// Runs `python3 script args... PNG` with PNG in a private temporary folder,
// then writes the figure to `png` as a files::OutputFile (complete or not at
// all; a symlink followed; never one of `inputs`). Returns false with
// `message` set to "figure skipped: <why>" when python3 with matplotlib is
// missing or the script fails; true otherwise (message untouched). Throws
// files::FileError when the figure was made but cannot be written.
bool run_plot_script(const std::string& script, const std::vector<std::string>& args,
                     const std::string& png, std::string& message,
                     const std::vector<std::string>& inputs = {});

}  // namespace exodaq::calibration
