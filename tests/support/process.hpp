#pragma once
// Real processes for integration tests: spawn, signal, wait with a timeout,
// capture output to files.
#include <sys/types.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace exodaq::test {

class Process {
 public:
  // Starts `argv[0]` with `argv`; stdout/stderr go to the given files (empty:
  // inherited). `env` entries are added to the current environment.
  Process(const std::vector<std::string>& argv, const std::string& stdout_file = {},
          const std::string& stderr_file = {}, const std::map<std::string, std::string>& env = {});
  ~Process();  // kills (SIGKILL) if still running
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  pid_t pid() const noexcept { return pid_; }
  bool running();
  void signal(int sig);
  // Exit code (or 128 + signal), or nullopt on timeout.
  std::optional<int> wait(std::chrono::milliseconds timeout);

 private:
  pid_t pid_ = -1;
  std::optional<int> status_;
};

// The real lcm-logger recording `channels` (a regex) from `url` into `file`.
// lcm-logger keeps LCM's 30-message subscription queue, 10 ms of exodaq's
// traffic, and drops silently behind a busy CPU (docs/robustness.md): where
// the test may (root), it runs at SCHED_FIFO 10, as docs/operations.md advises.
std::vector<std::string> lcm_logger_argv(const std::string& url, const std::string& channels,
                                         const std::string& file);

// The UDP sockets process `pid` holds (its /proc/PID/fd socket inodes found
// in /proc/PID/net/udp, so in its own network namespace): each one's local
// port and the datagrams the kernel dropped on it because its receive buffer
// was full. A recorder's own measure of what it lost, read while it runs
// (its sockets close when it exits).
struct UdpSocket {
  int local_port = 0;
  std::int64_t drops = 0;
};
std::vector<UdpSocket> udp_sockets(pid_t pid);
// The sum of udp_sockets(pid)'s drops.
std::int64_t udp_drops(pid_t pid);
// Until `pid` has a UDP socket bound to `port` (an LCM subscriber is then
// subscribed: LCM binds and joins the group in one step); false after `timeout`.
bool wait_for_udp_socket(pid_t pid, int port,
                         std::chrono::milliseconds timeout = std::chrono::seconds(30));

// Runs to completion; returns exit code and the captured stdout + stderr.
struct RunResult {
  int exit_code = -1;
  std::string out;
  std::string err;
};
RunResult run(const std::vector<std::string>& argv,
              std::chrono::milliseconds timeout = std::chrono::seconds(60),
              const std::map<std::string, std::string>& env = {});

// Polls `done` every 10 ms: true once it holds, false when `timeout` passed first.
bool wait_until(const std::function<bool()>& done,
                std::chrono::milliseconds timeout = std::chrono::seconds(20));

std::string read_file(const std::string& path);
// A fresh directory under $TMPDIR (or /tmp), removed by nobody: test logs stay for inspection.
std::string make_temp_dir(const std::string& tag);
// A per-process-unique LCM channel prefix, so concurrent tests do not hear each other.
std::string unique_prefix(const std::string& tag);

}  // namespace exodaq::test
