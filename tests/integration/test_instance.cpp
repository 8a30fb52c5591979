// One publisher per channel set (issue 15.1), with real processes: a second
// exodaqd on the same URL and prefix is refused (the lock, then the start-up
// listening window); a running daemon that hears another run id flags its
// samples FOREIGN_RUN, names it in status_t.foreign_run_id and goes degraded;
// export refuses a log where two runs interleave. Each daemon gets the test's
// own RUNTIME_DIRECTORY, so tests on one machine never share a lock.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <thread>

#include "exodaq/joint_state_t.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/messages/run_mix.hpp"
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/status_t.hpp"
#include "process.hpp"
#include "recording.hpp"
#include "sim_daemon.hpp"

using namespace exodaq;
using namespace std::chrono_literals;

namespace {

constexpr const char* kForeignRun = "0123456789abcdef";

std::map<std::string, std::string> runtime_env(const std::string& dir) {
  return {{"RUNTIME_DIRECTORY", dir}};
}

// The lock file's key=value lines, once it names a run id (or empty after `wait`).
std::map<std::string, std::string> wait_for_lock(const std::string& dir,
                                                 std::chrono::seconds wait) {
  const auto end = std::chrono::steady_clock::now() + wait;
  while (std::chrono::steady_clock::now() < end) {
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
      const std::string name = entry.path().filename();
      if (name.rfind("exodaqd-", 0) != 0) continue;
      std::map<std::string, std::string> kv;
      std::ifstream in(entry.path());
      for (std::string line; std::getline(in, line);) {
        if (const auto eq = line.find('='); eq != std::string::npos)
          kv[line.substr(0, eq)] = line.substr(eq + 1);
      }
      if (msg::parse_run_id(kv["run_id"])) return kv;
    }
    std::this_thread::sleep_for(50ms);
  }
  return {};
}

std::vector<std::string> publisher_argv(const std::string& channel, double rate_hz,
                                        double seconds) {
  return {EXODAQ_STATUS_PUBLISHER, test::kLcmUrl,          channel, kForeignRun,
          std::to_string(rate_hz), std::to_string(seconds)};
}

// Until `runs` fake publishers are heard on `channel` (they may start slowly
// on a loaded machine).
bool heard(const std::string& channel, std::size_t runs = 1) {
  msg::Subscriber sub(test::kLcmUrl);
  std::set<std::int64_t> got;
  sub.subscribe(channel, msg::Kind::kStatus,
                [&got](const msg::Received& r) { got.insert(std::get<status_t>(r.msg).run_id); });
  const auto end = std::chrono::steady_clock::now() + 20s;
  while (got.size() < runs && std::chrono::steady_clock::now() < end) sub.handle(100);
  return got.size() >= runs;
}

}  // namespace

TEST(RunMix, InterleavedRunsAreAMixARestartIsNot) {
  msg::RunMixDetector d;
  EXPECT_FALSE(d.observe("A_", 0));
  EXPECT_FALSE(d.observe("A_", 1));
  EXPECT_FALSE(d.observe("A_", 2));  // a restart: 1 then 2
  EXPECT_FALSE(d.observe("B_", 1));  // another rig is not a mix
  const auto mix = d.observe("A_", 1);
  ASSERT_TRUE(mix);
  EXPECT_EQ(mix->prefix, "A_");
  EXPECT_EQ(mix->first, 1);
  EXPECT_EQ(mix->second, 2);
  EXPECT_FALSE(d.observe("A_", 2));  // reported once
  EXPECT_TRUE(d.mixed());
}

// Same config twice: the second is refused by the lock, naming pid, run id and
// config; a third with another prefix starts.
TEST(Instance, SecondDaemonOnTheSameChannelsIsRefused) {
  const std::string dir = test::make_temp_dir("instance");
  const std::string prefix = test::unique_prefix("inst");
  const std::string config = test::write_sim_config(dir, prefix);
  test::Process first({EXODAQD, "--config", config}, dir + "/first.out", dir + "/first.err",
                      runtime_env(dir));
  const auto lock = wait_for_lock(dir, 20s);
  ASSERT_FALSE(lock.empty()) << test::read_file(dir + "/first.err");
  EXPECT_EQ(lock.at("pid"), std::to_string(first.pid()));
  EXPECT_EQ(lock.at("config"), config);

  const auto second =
      test::run({EXODAQD, "--config", config, "--duration", "5"}, 30s, runtime_env(dir));
  EXPECT_NE(second.exit_code, 0);
  EXPECT_NE(second.err.find("another exodaqd already publishes"), std::string::npos) << second.err;
  EXPECT_NE(second.err.find("pid " + lock.at("pid")), std::string::npos) << second.err;
  EXPECT_NE(second.err.find("run id " + lock.at("run_id")), std::string::npos) << second.err;
  EXPECT_NE(second.err.find(config), std::string::npos) << second.err;

  const std::string other_dir = test::make_temp_dir("instance-other");
  const std::string other = test::write_sim_config(other_dir, test::unique_prefix("inst_other"));
  const auto third =
      test::run({EXODAQD, "--config", other, "--duration", "1"}, 30s, runtime_env(dir));
  EXPECT_EQ(third.exit_code, 0) << third.err;
  EXPECT_NE(third.err.find("channel set claimed"), std::string::npos) << third.err;

  first.signal(SIGTERM);
  EXPECT_EQ(first.wait(20s), std::optional<int>(0));
}

// A publisher of another run id on the status channel before start (another
// host: it holds no lock here) makes the daemon refuse, naming its run id and rig.
TEST(Instance, RunIdHeardAtStartUpIsRefused) {
  const std::string dir = test::make_temp_dir("instance-heard");
  const std::string prefix = test::unique_prefix("heard");
  const std::string config = test::write_sim_config(dir, prefix);
  test::Process foreign(publisher_argv(prefix + "EXO_STATUS", 100, 60), dir + "/pub.out",
                        dir + "/pub.err");
  ASSERT_TRUE(heard(prefix + "EXO_STATUS"));
  const auto r = test::run({EXODAQD, "--config", config, "--duration", "3"}, 30s, runtime_env(dir));
  EXPECT_NE(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find(std::string("run id ") + kForeignRun), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("fake-rig"), std::string::npos) << r.err;
  foreign.signal(SIGTERM);
  foreign.wait(10s);
}

// A foreign run id appears while the daemon runs, then goes away.
TEST(Instance, ForeignRunWhileRunningFlagsSamplesAndDegrades) {
  const std::string dir = test::make_temp_dir("instance-foreign");
  const std::string prefix = test::unique_prefix("foreign");
  const std::string config = test::write_sim_config(dir, prefix);
  test::Process recorder({EXODAQ_RECORDER, test::kRecordUrl, prefix + ".*", dir + "/recorder.bin"},
                         "", dir + "/recorder.err");
  std::this_thread::sleep_for(300ms);
  std::int64_t own_run = 0;
  {
    test::Process daemon({EXODAQD, "--config", config}, dir + "/daemon.out", dir + "/daemon.err",
                         runtime_env(dir));
    const auto lock = wait_for_lock(dir, 20s);
    ASSERT_FALSE(lock.empty()) << test::read_file(dir + "/daemon.err");
    own_run = *msg::parse_run_id(lock.at("run_id"));
    std::this_thread::sleep_for(1s);
    // 2 s of a foreign run at 20 Hz, then 3 s without: an episode and its end.
    const auto pub = test::run(publisher_argv(prefix + "EXO_STATUS", 20, 2), 30s);
    EXPECT_EQ(pub.exit_code, 0) << pub.err;
    std::this_thread::sleep_for(3s);
    daemon.signal(SIGTERM);
    EXPECT_EQ(daemon.wait(20s), std::optional<int>(0));
  }
  std::this_thread::sleep_for(300ms);
  recorder.signal(SIGTERM);
  recorder.wait(5s);
  const std::string err = test::read_file(dir + "/daemon.err");
  // An error names the other run and the channel it was heard on (issue 15.1:
  // "logs an error"), a warning its end.
  EXPECT_NE(err.find("error another publisher on " + prefix + "EXO_STATUS: run id " + kForeignRun),
            std::string::npos)
      << err;
  EXPECT_NE(err.find(std::string("warning run id ") + kForeignRun + " no longer heard"),
            std::string::npos)
      << err;

  const auto foreign = static_cast<std::int64_t>(*msg::parse_run_id(kForeignRun));
  std::int64_t flagged = 0;
  std::int64_t unflagged_after = 0;
  std::int64_t degraded_naming_it = 0;
  for (const auto& m : test::read_recorder_file(dir + "/recorder.bin")) {
    if (m.channel == prefix + "EXO_JOINT_STATE") {
      const auto js = test::decode<joint_state_t>(m.data);
      if (js.run_id != own_run) continue;
      if ((js.sample_flags & joint_state_t::SAMPLE_FOREIGN_RUN) != 0) {
        ++flagged;
      } else if (flagged > 0) {
        ++unflagged_after;
      }
    } else if (m.channel == prefix + "EXO_STATUS") {
      const auto st = test::decode<status_t>(m.data);
      if (st.run_id == own_run && st.foreign_run_id == foreign &&
          st.state == status_t::STATE_DEGRADED)
        ++degraded_naming_it;
    }
  }
  std::printf("flagged samples %lld, unflagged after the episode %lld, degraded statuses %lld\n",
              static_cast<long long>(flagged), static_cast<long long>(unflagged_after),
              static_cast<long long>(degraded_naming_it));
  EXPECT_GT(flagged, 0);
  EXPECT_GT(unflagged_after, 0);  // FOREIGN_RUN cleared once it was no longer heard
  EXPECT_GT(degraded_naming_it, 0);
}

// A log where two runs interleave: export refuses, naming both and --run-id;
// with --run-id it exports that run alone.
TEST(Instance, ExportOfInterleavedRunsFailsClearly) {
  const std::string dir = test::make_temp_dir("instance-export");
  const std::string log = dir + "/mixed.lcm";
  {
    msg::LogWriter w(log);
    for (int i = 0; i < 40; ++i) {
      joint_state_t js{};
      js.run_id = i % 2 == 0 ? 0x1111111111111111 : 0x2222222222222222;
      js.seq = i / 2;
      js.utime = 1'000'000 + i * 500;
      for (auto& n : js.name) n = "j";
      const auto bytes = msg::encode(js);
      w.write("MIX_EXO_JOINT_STATE", js.utime, bytes.data(), bytes.size());
    }
    w.close();
  }
  const auto mixed = test::run({EXODAQ_TOOL, "export", log, "-o", dir + "/out.csv"});
  EXPECT_NE(mixed.exit_code, 0);
  EXPECT_NE(mixed.err.find("1111111111111111"), std::string::npos) << mixed.err;
  EXPECT_NE(mixed.err.find("2222222222222222"), std::string::npos) << mixed.err;
  EXPECT_NE(mixed.err.find("--run-id"), std::string::npos) << mixed.err;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out.csv"));

  const auto one = test::run(
      {EXODAQ_TOOL, "export", log, "-o", dir + "/one.csv", "--run-id", "2222222222222222"});
  EXPECT_EQ(one.exit_code, 0) << one.err;
  const std::string csv = test::read_file(dir + "/one.csv");
  std::size_t lines = 0;
  for (const char c : csv) lines += c == '\n' ? 1 : 0;
  EXPECT_EQ(lines, 21u);  // header + 20 cycles of the one run
  EXPECT_EQ(csv.find("1111111111111111"), std::string::npos);
}

// Two publishers interleaved on one status channel: exodaq status, exodaq echo
// and the Python Subscriber each warn on stderr, naming both run ids.
TEST(Instance, SubscribersWarnWhenTwoRunsInterleave) {
  const std::string dir = test::make_temp_dir("instance-mix");
  const std::string prefix = test::unique_prefix("mix");
  const std::string channel = prefix + "EXO_STATUS";
  test::Process a(publisher_argv(channel, 50, 60), dir + "/a.out", dir + "/a.err");
  test::Process b({EXODAQ_STATUS_PUBLISHER, test::kLcmUrl, channel, "00000000000000bb", "50", "60"},
                  dir + "/b.out", dir + "/b.err");
  ASSERT_TRUE(heard(channel, 2));
  const auto status = test::run({EXODAQ_TOOL, "status", "--prefix", prefix, "-t", "10"}, 30s);
  EXPECT_EQ(status.exit_code, 0) << status.err;
  EXPECT_NE(status.err.find("WARNING: two runs interleaved"), std::string::npos) << status.err;
  const auto echo = test::run(
      {EXODAQ_TOOL, "echo", "--channel", "status", "--prefix", prefix, "--csv", "--duration", "1"},
      30s);
  EXPECT_EQ(echo.exit_code, 0) << echo.err;
  EXPECT_NE(echo.err.find("WARNING: two runs interleaved"), std::string::npos) << echo.err;
  EXPECT_NE(echo.err.find(kForeignRun), std::string::npos) << echo.err;
  EXPECT_NE(echo.err.find("00000000000000bb"), std::string::npos) << echo.err;
  const auto py = test::run({EXODAQ_PYTHON, "-c",
                             "import exodaq\n"
                             "s = exodaq.Subscriber(url='" +
                                 test::kLcmUrl + "', prefix='" + prefix +
                                 "', kinds=('status',))\n"
                                 "for m in s.messages(count=40, timeout=10): pass\n"
                                 "print(sorted(exodaq.run_id_text(r) for r in s.mixed_runs))\n"},
                            30s, {{"PYTHONPATH", EXODAQ_PYTHONPATH}});
  EXPECT_EQ(py.exit_code, 0) << py.err;
  EXPECT_NE(py.out.find("['00000000000000bb', '0123456789abcdef']"), std::string::npos)
      << py.out << py.err;
  EXPECT_NE(py.err.find("WARNING: two runs interleaved"), std::string::npos) << py.err;
  a.signal(SIGTERM);
  b.signal(SIGTERM);
  a.wait(10s);
  b.wait(10s);
}
