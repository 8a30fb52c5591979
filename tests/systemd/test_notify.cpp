// exodaqd talking to systemd, for real: the daemon runs as its own process on
// the simulated rig with NOTIFY_SOCKET pointing at a datagram socket this test
// owns (what systemd gives a Type=notify service) and WATCHDOG_USEC set (what
// WatchdogSec= gives it). No systemd is involved; the protocol is the same.
// Timing is asserted as the daemon's own schedule (never faster than it
// should, a median ping interval, silence through a stall), never as a floor
// that a loaded machine's delays decide.
#include <gtest/gtest.h>
#include <poll.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "process.hpp"
#include "sim_daemon.hpp"

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

namespace {

constexpr int kWatchdogUsec = 200'000;  // pings expected every 100 ms

// One assignment ("READY=1", "STATUS=...") of one datagram, with its arrival time.
struct Notification {
  Clock::time_point at;
  int datagram = 0;
  std::string line;
  bool is(const std::string& assignment) const { return line == assignment; }
  bool starts(const std::string& prefix) const { return line.rfind(prefix, 0) == 0; }
};

// The socket systemd would own: AF_UNIX, SOCK_DGRAM, in a private directory.
class NotifySocket {
 public:
  explicit NotifySocket(const std::string& dir) : path_(dir + "/notify") {
    fd_ = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) throw std::runtime_error("socket");
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    if (path_.size() >= sizeof(addr.sun_path)) throw std::runtime_error("path too long");
    std::memcpy(addr.sun_path, path_.c_str(), path_.size() + 1);
    if (bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0)
      throw std::runtime_error("bind " + path_ + ": " + std::strerror(errno));
    reader_ = std::thread([this] { read_loop(); });
  }
  ~NotifySocket() {
    stop_ = true;
    if (reader_.joinable()) reader_.join();
    close(fd_);
    unlink(path_.c_str());
  }
  NotifySocket(const NotifySocket&) = delete;
  NotifySocket& operator=(const NotifySocket&) = delete;

  const std::string& path() const { return path_; }

  std::vector<Notification> all() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return received_;
  }

  // Waits until some line starts with `prefix`; returns it, or nullopt.
  std::optional<Notification> wait_for(const std::string& prefix,
                                       std::chrono::milliseconds timeout) const {
    const auto until = Clock::now() + timeout;
    while (Clock::now() < until) {
      {
        std::lock_guard<std::mutex> lock(mutex_);
        for (const auto& n : received_)
          if (n.starts(prefix)) return n;
      }
      std::this_thread::sleep_for(10ms);
    }
    return std::nullopt;
  }

 private:
  void read_loop() {
    std::vector<char> buf(4096);
    int datagram = 0;
    while (!stop_) {
      pollfd p{fd_, POLLIN, 0};
      if (poll(&p, 1, 20) <= 0) continue;
      const ssize_t n = recv(fd_, buf.data(), buf.size(), 0);
      if (n <= 0) continue;
      const auto now = Clock::now();
      ++datagram;
      std::istringstream in(std::string(buf.data(), static_cast<std::size_t>(n)));
      std::string line;
      std::lock_guard<std::mutex> lock(mutex_);
      while (std::getline(in, line))
        if (!line.empty()) received_.push_back({now, datagram, line});
    }
  }

  std::string path_;
  int fd_ = -1;
  std::atomic<bool> stop_{false};
  std::thread reader_;
  mutable std::mutex mutex_;
  std::vector<Notification> received_;
};

// config/sim.yaml with absolute paths, a private LCM prefix and stderr logging;
// `source_override`: what replaces its "source:\n  backend: sim\n" lines;
// `sim_faults`: a source.sim.faults list to add.
std::string write_config(const std::string& dir, const std::string& source_override = {},
                         const std::string& sim_faults = {}) {
  using exodaq::test::replace_once;
  std::string text = exodaq::test::sim_config_text(exodaq::test::unique_prefix("notify"));
  replace_once(text, "sink: auto", "sink: stderr");
  if (!source_override.empty()) replace_once(text, "source:\n  backend: sim\n", source_override);
  if (!sim_faults.empty()) {
    replace_once(text, "    jitter_us: 0\n", "    jitter_us: 0\n    faults: " + sim_faults + "\n");
  }
  return exodaq::test::write_config_text(dir, text);
}

std::vector<Notification> lines_starting(const std::vector<Notification>& all,
                                         const std::string& prefix) {
  std::vector<Notification> out;
  for (const auto& n : all)
    if (n.starts(prefix)) out.push_back(n);
  return out;
}

std::size_t count_between(const std::vector<Notification>& v, Clock::time_point from,
                          Clock::time_point to) {
  return static_cast<std::size_t>(std::count_if(
      v.begin(), v.end(), [&](const Notification& n) { return n.at >= from && n.at < to; }));
}

const std::set<std::string> kStates = {"starting", "homing", "running",
                                       "degraded", "fault",  "stopping"};

// "STATUS=homing 4/6, 1000.0 Hz, cycle 123; ..." -> "homing"
std::string status_state(const Notification& n) {
  const std::string body = n.line.substr(std::strlen("STATUS="));
  return body.substr(0, body.find_first_of(" ,"));
}

long long status_cycle(const Notification& n) {
  std::smatch m;
  if (!std::regex_search(n.line, m, std::regex(", cycle ([0-9]+);"))) return -1;
  return std::stoll(m[1]);
}

// "...; drops: 0 missing samples, 1 seq gaps, 6 overruns, ..." -> 6
long long status_overruns(const Notification& n) {
  std::smatch m;
  if (!std::regex_search(n.line, m, std::regex(" ([0-9]+) overruns,"))) return -1;
  return std::stoll(m[1]);
}

struct Daemon {
  std::string dir;
  std::unique_ptr<NotifySocket> notify;
  std::unique_ptr<exodaq::test::Process> process;
  std::string err_file() const { return dir + "/exodaqd.err"; }
};

Daemon start_daemon(const std::string& tag, std::map<std::string, std::string> env,
                    const std::string& source_override = {}, const std::string& sim_faults = {}) {
  Daemon d;
  d.dir = exodaq::test::make_temp_dir(tag);
  d.notify = std::make_unique<NotifySocket>(d.dir);
  env["NOTIFY_SOCKET"] = d.notify->path();
  const std::string config = write_config(d.dir, source_override, sim_faults);
  d.process =
      std::make_unique<exodaq::test::Process>(std::vector<std::string>{EXODAQD, "--config", config},
                                              d.dir + "/exodaqd.out", d.err_file(), env);
  return d;
}

}  // namespace

// READY=1 after the first cycle, WATCHDOG=1 at half of WATCHDOG_USEC while the
// loop cycles, STATUS= with the state, STOPPING=1 on SIGTERM, exit 0.
TEST(Notify, ReadyWatchdogStatusStopping) {
  Daemon d = start_daemon("notify", {{"WATCHDOG_USEC", std::to_string(kWatchdogUsec)}});
  const auto ready = d.notify->wait_for("READY=1", 20s);
  ASSERT_TRUE(ready) << exodaq::test::read_file(d.err_file());

  // Count the pings over a 3 s window starting 0.5 s after READY.
  const auto from = ready->at + 500ms;
  const auto to = from + 3s;
  std::this_thread::sleep_until(to + 300ms);
  ASSERT_TRUE(d.process->running()) << exodaq::test::read_file(d.err_file());
  d.process->signal(SIGTERM);
  const auto code = d.process->wait(20s);
  ASSERT_TRUE(code);
  EXPECT_EQ(*code, 0) << exodaq::test::read_file(d.err_file());
  std::this_thread::sleep_for(100ms);  // the last datagrams
  const auto all = d.notify->all();

  // READY=1 exactly once, with the first STATUS= in the same datagram, and that
  // status already counts a completed cycle.
  const auto readies = lines_starting(all, "READY=1");
  ASSERT_EQ(readies.size(), 1U);
  const auto statuses = lines_starting(all, "STATUS=");
  ASSERT_FALSE(statuses.empty());
  const auto first_status =
      std::find_if(statuses.begin(), statuses.end(),
                   [&](const Notification& n) { return n.datagram == readies[0].datagram; });
  ASSERT_NE(first_status, statuses.end()) << "READY=1 came without STATUS=";
  EXPECT_GE(status_cycle(*first_status), 1) << first_status->line;
  // Nothing comes before READY=1 (no watchdog ping before ready).
  for (const auto& n : all) {
    if (n.datagram >= readies[0].datagram) break;
    ADD_FAILURE() << "before READY=1: " << n.line;
  }

  // The pings: every 100 ms while cycling (half of WATCHDOG_USEC), so 30 in
  // 3 s. The daemon never pings faster than that: at most 31, and one more
  // read late at the window's start. A loaded machine delays some wake-ups
  // of the main thread (it checks every 20 ms), never most of them: the
  // median interval stays below 150 ms, where pinging at the whole
  // WATCHDOG_USEC (200 ms) or never would not.
  const auto pings = lines_starting(all, "WATCHDOG=1");
  const std::size_t in_window = count_between(pings, from, to);
  EXPECT_LE(in_window, 32U) << "pings in 3 s";
  std::vector<double> interval_ms;
  for (std::size_t i = 1; i < pings.size(); ++i) {
    if (pings[i - 1].at < from || pings[i].at >= to) continue;
    interval_ms.push_back(
        std::chrono::duration<double, std::milli>(pings[i].at - pings[i - 1].at).count());
  }
  ASSERT_GE(interval_ms.size(), 2U) << "pings in 3 s";
  std::nth_element(interval_ms.begin(), interval_ms.begin() + interval_ms.size() / 2,
                   interval_ms.end());
  const double median_ms = interval_ms[interval_ms.size() / 2];
  EXPECT_LT(median_ms, 150.0) << in_window << " pings in 3 s";
  for (const auto& p : pings) EXPECT_TRUE(p.is("WATCHDOG=1"));

  // STATUS= carries a service state, a rate and the cycle count; it is sent once
  // a second and on state changes, and the sim rig starts homing.
  std::set<std::string> seen;
  long long last_cycle = 0;
  for (const auto& s : statuses) {
    const std::string state = status_state(s);
    if (s.line == "STATUS=stopping") {
      seen.insert(state);
      continue;
    }
    EXPECT_TRUE(kStates.count(state)) << s.line;
    EXPECT_NE(s.line.find(" Hz, cycle "), std::string::npos) << s.line;
    EXPECT_NE(s.line.find("missing samples"), std::string::npos) << s.line;
    EXPECT_NE(s.line.find("overruns"), std::string::npos) << s.line;
    // The sim rig's clock.require_sync is ignore: not checked, never shouted.
    EXPECT_NE(s.line.find("; clock not checked"), std::string::npos) << s.line;
    EXPECT_EQ(s.line.find("UNSYNCHRONISED"), std::string::npos) << s.line;
    // Homing shows its progress; degraded and fault say why.
    if (state == "homing") {
      EXPECT_TRUE(std::regex_search(s.line, std::regex("^STATUS=homing [0-6]/6, "))) << s.line;
    }
    if (state == "degraded" || state == "fault") {
      EXPECT_TRUE(std::regex_search(s.line, std::regex("^STATUS=[a-z]+ \\([A-Z_]+\\)"))) << s.line;
    }
    const long long c = status_cycle(s);
    EXPECT_GE(c, last_cycle) << s.line;
    last_cycle = c;
    seen.insert(state);
  }
  // Once a second (and on state changes) from READY=1 to STOPPING=1.
  const auto stopping_at = lines_starting(all, "STOPPING=1");
  ASSERT_FALSE(stopping_at.empty());
  const auto seconds =
      std::chrono::duration_cast<std::chrono::seconds>(stopping_at[0].at - ready->at);
  EXPECT_GE(static_cast<long long>(statuses.size()), seconds.count() - 1);
  EXPECT_TRUE(seen.count("homing") || seen.count("running") || seen.count("degraded"))
      << "states seen: " << seen.size();

  // STOPPING=1 on SIGTERM, and it is the last word: no ping after it.
  const auto stopping = lines_starting(all, "STOPPING=1");
  ASSERT_EQ(stopping.size(), 1U);
  for (const auto& p : pings) EXPECT_LT(p.datagram, stopping[0].datagram);
}

// A stalled loop stops the pings (so systemd's watchdog would fire) while the
// main thread goes on answering: STATUS= keeps coming and shows 0 Hz. The
// stall is the simulator's: at 1.5 s the simulated host holds the loop off
// for 4 s (source.sim.faults kind stall); then it cycles and pings again.
TEST(Notify, StalledLoopStopsWatchdog) {
  Daemon d = start_daemon("notify-stall", {{"WATCHDOG_USEC", std::to_string(kWatchdogUsec)}}, {},
                          "[{kind: stall, at_s: 1.5, for_s: 4}]");
  const auto ready = d.notify->wait_for("READY=1", 20s);
  ASSERT_TRUE(ready) << exodaq::test::read_file(d.err_file());
  std::this_thread::sleep_until(ready->at + 8s);  // 1.5 s cycling, 4 s stalled, 2.5 s cycling
  ASSERT_TRUE(d.process->running());
  d.process->signal(SIGTERM);
  const auto code = d.process->wait(20s);
  ASSERT_TRUE(code);
  EXPECT_EQ(*code, 0) << exodaq::test::read_file(d.err_file());
  const auto all = d.notify->all();
  const auto pings = lines_starting(all, "WATCHDOG=1");
  ASSERT_GE(pings.size(), 2U);

  // The longest silence between two pings is the stall: 4 s, 20 times the
  // 200 ms systemd would have granted (pings are due every 100 ms).
  std::size_t gap_end = 1;
  for (std::size_t i = 1; i < pings.size(); ++i) {
    if (pings[i].at - pings[i - 1].at > pings[gap_end].at - pings[gap_end - 1].at) gap_end = i;
  }
  const auto stall_from = pings[gap_end - 1].at;
  const auto stall_to = pings[gap_end].at;
  EXPECT_GE(stall_to - stall_from, 3s);
  // Pings while the loop ran, before the stall and after it.
  EXPECT_GE(count_between(pings, Clock::time_point{}, stall_from + 1ms), 2U);
  EXPECT_GE(count_between(pings, stall_to, Clock::time_point::max()), 2U);

  // The main thread lives on: STATUS= once a second during the stall, at
  // 0 Hz, its counts where the stall began: the read of seq 1500 (1.5 s of
  // the rig's time) blocks, so the cycles run and the deadlines skipped
  // before it add up to 1500, however many a loaded machine skipped.
  const auto statuses = lines_starting(all, "STATUS=");
  std::size_t stalled_statuses = 0;
  for (const auto& s : statuses) {
    if (s.at < stall_from + 1600ms || s.at >= stall_to - 200ms) continue;
    ++stalled_statuses;
    EXPECT_NE(s.line.find(" 0.0 Hz,"), std::string::npos) << s.line;
    EXPECT_EQ(status_cycle(s) + status_overruns(s), 1500) << s.line;
  }
  EXPECT_GE(stalled_statuses, 1U);
  EXPECT_EQ(lines_starting(all, "STOPPING=1").size(), 1U);
}

// Without WATCHDOG_USEC (no WatchdogSec=) the daemon never pings.
TEST(Notify, NoWatchdogWithoutWatchdogUsec) {
  Daemon d = start_daemon("notify-nowd", {});
  ASSERT_TRUE(d.notify->wait_for("READY=1", 20s)) << exodaq::test::read_file(d.err_file());
  std::this_thread::sleep_for(1500ms);
  d.process->signal(SIGTERM);
  const auto code = d.process->wait(20s);
  ASSERT_TRUE(code);
  EXPECT_EQ(*code, 0);
  const auto all = d.notify->all();
  EXPECT_TRUE(lines_starting(all, "WATCHDOG=1").empty());
  EXPECT_EQ(lines_starting(all, "STOPPING=1").size(), 1U);
}

// A daemon that cannot start its source never says READY=1: it reports why in
// STATUS= and exits 1 (the unit's Restart=on-failure takes over).
TEST(Notify, NoReadyWhenStartFails) {
  Daemon d = start_daemon(
      "notify-fail", {{"WATCHDOG_USEC", std::to_string(kWatchdogUsec)}},
      "source:\n  backend: replay\n  replay:\n    path: /nonexistent/exodaq-recording.lcm\n");
  const auto code = d.process->wait(20s);
  ASSERT_TRUE(code);
  EXPECT_EQ(*code, 1) << exodaq::test::read_file(d.err_file());
  std::this_thread::sleep_for(100ms);
  const auto all = d.notify->all();
  EXPECT_TRUE(lines_starting(all, "READY=1").empty());
  EXPECT_TRUE(lines_starting(all, "WATCHDOG=1").empty());
  const auto statuses = lines_starting(all, "STATUS=cannot start");
  ASSERT_EQ(statuses.size(), 1U) << exodaq::test::read_file(d.err_file());
}
