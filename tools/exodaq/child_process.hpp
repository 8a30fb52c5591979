#pragma once
// What commands need to run another program (the plot script, `exodaq
// replay` for calibrate): a child process waited for, and a private
// temporary folder removed with everything in it.
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "exodaq/common/files.hpp"

extern char** environ;

namespace exodaq::tools {

// Runs argv[0] (searched in PATH) with stdin, stdout and stderr inherited;
// its exit code, or 128 + the signal that ended it. Throws when it cannot start.
inline int run_child(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, argv[0], nullptr, nullptr, argv.data(), environ);
  if (rc != 0) {
    throw std::runtime_error("cannot run '" + args[0] + "': " + files::errno_text(rc));
  }
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    if (errno != EINTR) throw std::runtime_error("waitpid failed: " + files::errno_text(errno));
  }
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  return 128 + (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
}

// This program's own path (to run another of its commands).
inline std::string self_path() {
  std::error_code ec;
  const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) throw std::runtime_error("cannot find this program: " + ec.message());
  return exe.string();
}

// A folder under $TMPDIR (or /tmp), removed with its content.
class TempDir {
 public:
  explicit TempDir(const std::string& tag) {
    const char* tmp = std::getenv("TMPDIR");
    std::string tmpl =
        std::string(tmp != nullptr && *tmp != '\0' ? tmp : "/tmp") + "/exodaq-" + tag + "-XXXXXX";
    if (::mkdtemp(tmpl.data()) == nullptr) {
      throw std::runtime_error("cannot create a temporary folder: " + files::errno_text(errno));
    }
    dir_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string file(const std::string& name) const { return dir_ + "/" + name; }
  const std::string& dir() const { return dir_; }

 private:
  std::string dir_;
};

}  // namespace exodaq::tools
