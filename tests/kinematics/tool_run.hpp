#pragma once
// Runs the built `exodaq` tool (EXODAQ_TOOL) with arguments and collects its
// exit code, stdout and stderr (for the command-line tests).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace exodaq::test {

struct ToolResult {
  int code = -1;
  std::string out;
  std::string err;
};

inline ToolResult run_tool(const std::string& args) {
  const std::string err_file = ::testing::TempDir() + "exodaq_tool_stderr.txt";
  const std::string cmd = std::string(EXODAQ_TOOL) + " " + args + " 2>" + err_file;
  ToolResult r;
  FILE* p = ::popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf{};
  std::size_t got = 0;
  while ((got = std::fread(buf.data(), 1, buf.size(), p)) > 0) r.out.append(buf.data(), got);
  const int status = ::pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (FILE* e = std::fopen(err_file.c_str(), "r")) {
    while ((got = std::fread(buf.data(), 1, buf.size(), e)) > 0) r.err.append(buf.data(), got);
    std::fclose(e);
  }
  return r;
}

}  // namespace exodaq::test
