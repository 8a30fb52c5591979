#include "exodaq/calibration/python_plot.hpp"

#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "exodaq/common/files.hpp"

#ifndef EXODAQ_CALIBRATE_SCRIPT_DIR
#define EXODAQ_CALIBRATE_SCRIPT_DIR ""
#endif

namespace exodaq::calibration {

namespace {

bool file_exists(const std::string& p) {
  return !p.empty() && std::ifstream(p).good();
}

std::string quote_shell(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

// <directory of this binary>/../share/exodaq/
std::string installed_dir() {
  char buf[4096];
  const ssize_t n = ::readlink("/proc/self/exe", buf, sizeof buf - 1);
  if (n <= 0) return "";
  const std::string exe(buf, static_cast<std::size_t>(n));
  const auto slash = exe.rfind('/');
  return slash == std::string::npos ? "" : exe.substr(0, slash) + "/../share/exodaq/";
}

std::string python_with_matplotlib() {
  for (const char* candidate : {"python3", "/usr/bin/python3"}) {
    const std::string probe = std::string(candidate) + " -c 'import matplotlib' >/dev/null 2>&1";
    if (std::system(probe.c_str()) == 0) return candidate;
  }
  return "";
}

}  // namespace

std::string find_plot_script(const char* env_var, const std::string& file_name) {
  if (const char* env = std::getenv(env_var); env != nullptr && file_exists(env)) return env;
  for (const std::string& dir : {installed_dir(), std::string(EXODAQ_CALIBRATE_SCRIPT_DIR) + "/"}) {
    if (dir.size() > 1 && file_exists(dir + file_name)) return dir + file_name;
  }
  return "";
}

bool run_plot_script(const std::string& script, const std::vector<std::string>& args,
                     const std::string& png, std::string& message,
                     const std::vector<std::string>& inputs) {
  const std::string python = python_with_matplotlib();
  if (python.empty()) {
    message = "figure skipped: no python3 with matplotlib (apt install python3-matplotlib)";
    return false;
  }
  files::OutputOptions oo;
  oo.inputs = inputs;
  files::check_output(png, oo);
  const char* tmp = std::getenv("TMPDIR");
  std::string dir =
      std::string(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") + "/exodaq-fig-XXXXXX";
  if (::mkdtemp(dir.data()) == nullptr) {
    message = "figure skipped: cannot create a temporary folder: " + files::errno_text(errno);
    return false;
  }
  struct Cleanup {
    std::string dir;
    ~Cleanup() {
      std::error_code ec;
      std::filesystem::remove_all(dir, ec);
    }
  } cleanup{dir};
  const std::string staged = dir + "/figure.png";
  std::string cmd = python + " " + quote_shell(script);
  for (const auto& a : args) cmd += " " + quote_shell(a);
  cmd += " " + quote_shell(staged);
  if (std::system(cmd.c_str()) != 0) {
    message = "figure skipped: " + cmd + " failed";
    return false;
  }
  files::write_output(png, files::read_input(staged, -1), oo);
  return true;
}

}  // namespace exodaq::calibration
