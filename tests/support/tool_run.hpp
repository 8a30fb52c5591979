#pragma once
// Runs the built `exodaq` tool (EXODAQ_TOOL) with arguments (a shell word
// list) and collects its exit code and output, for the command-line tests:
// run_tool keeps stdout and stderr apart, run_tool_merged interleaves them as
// a terminal would show them.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <string>

namespace exodaq::test {

struct ToolResult {
  int code = -1;
  std::string out;
  std::string err;
};

struct MergedResult {
  int code = -1;
  std::string output;  // stdout and stderr as written
};

namespace detail {
// Runs `cmd` through the shell; its stdout goes to `out`, the exit code back.
inline int run_shell(const std::string& cmd, std::string& out) {
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return -1;
  std::array<char, 4096> buf{};
  std::size_t got = 0;
  while ((got = std::fread(buf.data(), 1, buf.size(), p)) > 0) out.append(buf.data(), got);
  const int status = ::pclose(p);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}
}  // namespace detail

inline ToolResult run_tool(const std::string& args) {
  // Per process: tests of several executables run at once under ctest -j.
  const std::string err_file =
      ::testing::TempDir() + "exodaq_tool_stderr_" + std::to_string(::getpid()) + ".txt";
  ToolResult r;
  r.code = detail::run_shell(std::string(EXODAQ_TOOL) + " " + args + " 2>" + err_file, r.out);
  (void)detail::run_shell("cat " + err_file + " && rm -f " + err_file, r.err);
  return r;
}

inline MergedResult run_tool_merged(const std::string& args) {
  MergedResult r;
  r.code = detail::run_shell(std::string(EXODAQ_TOOL) + " " + args + " 2>&1", r.output);
  return r;
}

}  // namespace exodaq::test
