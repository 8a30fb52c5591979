// One publisher per channel set (issue 15.1), with real processes: a second
// exodaqd on the same URL and prefix is refused (the lock, then the start-up
// listening window); a running daemon that hears another run id flags its
// samples FOREIGN_RUN, names it in status_t.foreign_run_id and goes degraded;
// export refuses a log where two runs interleave. Each daemon gets the test's
// own RUNTIME_DIRECTORY, so tests on one machine never share a lock.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <string>
#include <thread>

#include "exodaq/daemon/instance_guard.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/messages/run_mix.hpp"
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/status_t.hpp"
#include "process.hpp"
#include "recording.hpp"
#include "sim_daemon.hpp"
#include "status_wait.hpp"

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
      if (messages::parse_run_id(kv["run_id"])) return kv;
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
  messages::Subscriber sub(test::kLcmUrl);
  std::set<std::int64_t> got;
  sub.subscribe(channel, messages::Kind::kStatus, [&got](const messages::Received& r) {
    got.insert(std::get<status_t>(r.msg).run_id);
  });
  const auto end = std::chrono::steady_clock::now() + 20s;
  while (got.size() < runs && std::chrono::steady_clock::now() < end) sub.handle(100);
  return got.size() >= runs;
}

}  // namespace

TEST(RunMix, InterleavedRunsAreAMixARestartIsNot) {
  messages::RunMixDetector d;
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

// Issue 25.7: the lock is keyed on the channel set (group, port, prefix),
// not on the URL's text.
TEST(InstanceLockKey, UrlOptionsAndSpellingsOfOneChannelSetShareALock) {
  using daemon::lock_path;
  const std::string a = lock_path("/d", "udpm://239.255.76.67:7667?ttl=0", "P_");
  EXPECT_EQ(lock_path("/d", "udpm://239.255.76.67:7667", "P_"), a);
  EXPECT_EQ(lock_path("/d", "udpm://239.255.76.67:7667?ttl=1&recv_buf_size=2097152", "P_"), a);
  EXPECT_EQ(lock_path("/d", "udpm://0xef.255.76.67:07667?ttl=0", "P_"),
            a);                                    // as inet_aton reads it
  EXPECT_EQ(lock_path("/d", "udpm://", "P_"), a);  // LCM's default group and port
  EXPECT_NE(lock_path("/d", "udpm://239.255.76.67:7668?ttl=0", "P_"), a);
  EXPECT_NE(lock_path("/d", "udpm://239.255.76.68:7667?ttl=0", "P_"), a);
  EXPECT_NE(lock_path("/d", "udpm://239.255.76.67:7667?ttl=0", "Q_"), a);
  EXPECT_EQ(daemon::channel_set_key("udpm://239.255.76.67:7667?ttl=0", "P_"),
            "udpm://239.255.76.67:7667\nP_");
  EXPECT_EQ(a.rfind("/d/exodaqd-", 0), 0u);
}

// The reproduction: two daemons on one channel set, one URL with
// `?ttl=0` and one without, started together. Before: two locks, both ran
// (9 391 of 9 590 samples FOREIGN_RUN). Now exactly one runs.
TEST(Instance, TwoDaemonsStartedTogetherWithAndWithoutTtlOneIsRefused) {
  const std::string dir = test::make_temp_dir("instance-ttl");
  const std::string prefix = test::unique_prefix("ttl");
  const std::string dir_a = dir + "/a";
  const std::string dir_b = dir + "/b";
  std::filesystem::create_directories(dir_a);
  std::filesystem::create_directories(dir_b);
  const std::string config_a = test::write_sim_config(dir_a, prefix);
  std::string text = test::sim_config_text(prefix);
  test::replace_once(text, "udpm://239.255.76.67:7667?ttl=0", "udpm://239.255.76.67:7667");
  const std::string config_b = test::write_config_text(dir_b, text);
  test::Process a({EXODAQD, "--config", config_a}, dir + "/a.out", dir + "/a.err",
                  runtime_env(dir));
  test::Process b({EXODAQD, "--config", config_b}, dir + "/b.out", dir + "/b.err",
                  runtime_env(dir));
  // The loser exits by itself; the winner runs until stopped.
  std::optional<int> a_rc;
  std::optional<int> b_rc;
  ASSERT_TRUE(test::wait_until(
      [&] {
        if (!a_rc && !a.running()) a_rc = a.wait(std::chrono::seconds(1));
        if (!b_rc && !b.running()) b_rc = b.wait(std::chrono::seconds(1));
        return a_rc || b_rc;
      },
      std::chrono::seconds(60)))
      << "neither daemon was refused\n"
      << test::read_file(dir + "/a.err") << test::read_file(dir + "/b.err");
  const bool a_lost = a_rc.has_value();
  test::Process& winner = a_lost ? b : a;
  const std::string loser_err = test::read_file(dir + (a_lost ? "/a.err" : "/b.err"));
  EXPECT_EQ(a_lost ? a_rc : b_rc, std::optional<int>(1)) << loser_err;
  EXPECT_NE(loser_err.find("another exodaqd already publishes"), std::string::npos) << loser_err;
  EXPECT_NE(loser_err.find("pid " + std::to_string(winner.pid())), std::string::npos) << loser_err;
  EXPECT_NE(loser_err.find(dir + "/exodaqd-"), std::string::npos) << loser_err;  // the lock named
  EXPECT_TRUE(winner.running());
  winner.signal(SIGTERM);
  EXPECT_EQ(winner.wait(20s), std::optional<int>(0));
}

// Issue 25.7: a lock file that another user made (and holds) is not
// believed: it is replaced with a warning naming its owner, and the daemon
// starts, never citing the squatter's "pid 1". Needs root (chown).
TEST(Instance, ALockFileOwnedByAnotherUserIsNotTrusted) {
  if (geteuid() != 0) GTEST_SKIP() << "needs root to give the lock file to another uid";
  const std::string dir = test::make_temp_dir("instance-squat");
  const std::string prefix = test::unique_prefix("squat");
  const std::string config = test::write_sim_config(dir, prefix);
  const std::string lock = daemon::lock_path(dir, test::kLcmUrl, prefix);
  {
    std::ofstream out(lock);
    out << "pid=1\nrun_id=0000000000000001\nrig=squatter\nconfig=/fake\n";
  }
  ASSERT_EQ(chown(lock.c_str(), 4242, 4242), 0);
  // --no-fork: the holder is the process signalled below, not a child of it
  // that would keep the lock (and this test's output) for its 60 s. Blocking,
  // not --nonblock: a probe below may hold the lock for an instant while the
  // holder starts, and a non-blocking holder would then give up for good.
  test::Process holder({"flock", "--exclusive", "--no-fork", lock, "sleep", "60"},
                       dir + "/holder.out", dir + "/holder.err");
  ASSERT_TRUE(test::wait_until([&] {
    const auto probe = test::run({"flock", "--exclusive", "--nonblock", lock, "true"});
    return probe.exit_code != 0;  // held
  }));
  const auto r = test::run({EXODAQD, "--config", config, "--duration", "2"}, 60s, runtime_env(dir));
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.err.find("instance lock " + lock + ": not trusted (it is owned by uid 4242"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(r.err.find("pid 1,"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("squatter"), std::string::npos) << r.err;
  struct stat st {};
  ASSERT_EQ(stat(lock.c_str(), &st), 0);
  EXPECT_EQ(st.st_uid, 0u);  // the daemon's own file now
  holder.signal(SIGTERM);
  holder.wait(10s);
}

// Without a runtime directory of its own the daemon refuses to start, saying
// what to set, instead of taking a lock in /tmp that any user could squat.
TEST(Instance, NoRuntimeDirectoryIsAClearErrorNotATmpLock) {
  if (geteuid() != 0) GTEST_SKIP() << "needs root to run the daemon as another uid";
  struct stat run_dir {};
  if (stat("/run/exodaq", &run_dir) == 0 && (run_dir.st_mode & S_IWOTH) != 0)
    GTEST_SKIP() << "/run/exodaq is world-writable here";
  const std::string dir = test::make_temp_dir("instance-nodir");
  ASSERT_EQ(chmod(dir.c_str(), 0755), 0);
  const std::string config = test::write_sim_config(dir, test::unique_prefix("nodir"));
  const auto r = test::run(
      {"setpriv", "--reuid=4242", "--regid=4242", "--clear-groups", "env", "-u", "XDG_RUNTIME_DIR",
       "-u", "RUNTIME_DIRECTORY", EXODAQD, "--config", config, "--duration", "2"},
      60s);
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("no runtime directory for the instance lock"), std::string::npos) << r.err;
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
  ASSERT_TRUE(test::wait_for_udp_socket(recorder.pid(), 7667));
  std::int64_t own_run = 0;
  {
    test::Process daemon({EXODAQD, "--config", config}, dir + "/daemon.out", dir + "/daemon.err",
                         runtime_env(dir));
    const auto lock = wait_for_lock(dir, 20s);
    ASSERT_FALSE(lock.empty()) << test::read_file(dir + "/daemon.err");
    own_run = *messages::parse_run_id(lock.at("run_id"));
    // Running (past its start-up listening window): its own statuses come.
    const auto own = [own_run](const status_t& st) { return st.run_id == own_run; };
    ASSERT_EQ(test::wait_for_status(test::kLcmUrl, prefix, own).run_id, own_run);
    // 2 s of a foreign run at 20 Hz, then quiet: an episode and its end.
    const auto pub = test::run(publisher_argv(prefix + "EXO_STATUS", 20, 2), 30s);
    EXPECT_EQ(pub.exit_code, 0) << pub.err;
    ASSERT_TRUE(test::wait_until(
        [&] {
          return test::read_file(dir + "/daemon.err").find("no longer heard") != std::string::npos;
        },
        60s))
        << test::read_file(dir + "/daemon.err");
    // FOREIGN_RUN was cleared before that line was written: the statuses
    // from here on, and their windows' samples, are unflagged.
    const status_t after = test::wait_for_status(test::kLcmUrl, prefix, own);
    ASSERT_EQ(after.run_id, own_run);
    EXPECT_EQ(after.foreign_run_id, 0);
    ASSERT_TRUE(test::wait_for_seq(test::kLcmUrl, prefix, after.seq + 100));
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

  const auto foreign = static_cast<std::int64_t>(*messages::parse_run_id(kForeignRun));
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
    messages::LogWriter w(log);
    for (int i = 0; i < 40; ++i) {
      joint_state_t js{};
      js.run_id = i % 2 == 0 ? 0x1111111111111111 : 0x2222222222222222;
      js.seq = i / 2;
      js.utime = 1'000'000 + i * 500;
      for (auto& n : js.name) n = "j";
      const auto bytes = messages::encode(js);
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

namespace {
struct Heard {
  std::int64_t own_joint_states = 0;     // the daemon's, run id and source its own
  std::int64_t flagged_foreign = 0;      // ... of them flagged FOREIGN_RUN
  std::int64_t replay_joint_states = 0;  // SAMPLE_REPLAY, the daemon's run id
  std::int64_t replay_statuses = 0;      // source "replay", the daemon's run id
  std::int64_t degraded_naming_own = 0;  // the daemon's statuses: degraded, foreign_run_id = own
};

Heard analyse(const std::string& file, const std::string& prefix, std::int64_t own) {
  Heard h;
  for (const auto& m : test::read_recorder_file(file)) {
    if (m.channel == prefix + "EXO_JOINT_STATE") {
      const auto js = test::decode<joint_state_t>(m.data);
      if (js.run_id != own) continue;
      if ((js.sample_flags & joint_state_t::SAMPLE_REPLAY) != 0) {
        ++h.replay_joint_states;
      } else {
        ++h.own_joint_states;
        if ((js.sample_flags & joint_state_t::SAMPLE_FOREIGN_RUN) != 0) ++h.flagged_foreign;
      }
    } else if (m.channel == prefix + "EXO_STATUS") {
      const auto st = test::decode<status_t>(m.data);
      if (st.run_id != own) continue;
      if (st.source == "replay") {
        ++h.replay_statuses;
      } else if (st.foreign_run_id == own && st.state == status_t::STATE_DEGRADED) {
        ++h.degraded_naming_own;
      }
    }
  }
  return h;
}
}  // namespace

// Issue 25.5, the reproduction: `exodaq replay first.lcm --live` while the
// same run is live. replay --live refuses (a live run is heard there); forced
// with --share-channels, its statuses (source "replay", the live run id, seq
// from the recording's start) interleave with the daemon's, and the daemon
// flags them as another publisher: FOREIGN_RUN, foreign_run_id = its own run
// id, degraded, an error naming the seq heard; cleared when it ends.
TEST(Instance, AReplayOfTheLiveRunBesideItIsRefusedOrFlaggedForeign) {
  const std::string dir = test::make_temp_dir("instance-replay");
  const std::string prefix = test::unique_prefix("ownrun");
  const std::string config = test::write_sim_config(dir, prefix);
  const std::string first = dir + "/first.lcm";
  test::Process recorder({EXODAQ_RECORDER, test::kRecordUrl, prefix + ".*", dir + "/recorder.bin"},
                         "", dir + "/recorder.err");
  test::Process logger(test::lcm_logger_argv(test::kRecordUrl, prefix + "EXO_.*", first), "",
                       dir + "/logger.err");
  std::this_thread::sleep_for(300ms);
  test::Process daemon({EXODAQD, "--config", config}, dir + "/daemon.out", dir + "/daemon.err",
                       runtime_env(dir));
  const auto lock = wait_for_lock(dir, 20s);
  ASSERT_FALSE(lock.empty()) << test::read_file(dir + "/daemon.err");
  const std::string own_text = lock.at("run_id");
  const std::int64_t own = *messages::parse_run_id(own_text);
  std::this_thread::sleep_for(2s);  // the run's first seconds
  logger.signal(SIGINT);
  ASSERT_TRUE(logger.wait(10s).has_value());

  const auto refused = test::run({EXODAQ_TOOL, "replay", first, "-c", config, "--live"}, 60s);
  EXPECT_EQ(refused.exit_code, 1) << refused.out << refused.err;
  // Heard on its joint states or its status, whichever came first.
  EXPECT_NE(refused.err.find("exodaq replay: run id " + own_text), std::string::npos)
      << refused.err;
  EXPECT_NE(refused.err.find("publishes on LCM " + test::kLcmUrl + " with prefix '" + prefix + "'"),
            std::string::npos)
      << refused.err;
  EXPECT_NE(refused.err.find("--share-channels"), std::string::npos) << refused.err;

  const auto forced =
      test::run({EXODAQ_TOOL, "replay", first, "-c", config, "--live", "--share-channels"}, 60s);
  EXPECT_EQ(forced.exit_code, 0) << forced.out << forced.err;
  std::this_thread::sleep_for(2s);  // the episode ends 1 s after the last replayed status
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(20s), std::optional<int>(0));
  std::this_thread::sleep_for(300ms);
  recorder.signal(SIGTERM);
  recorder.wait(5s);

  const std::string err = test::read_file(dir + "/daemon.err");
  EXPECT_NE(err.find("error another publisher on " + prefix +
                     "EXO_STATUS uses this daemon's own run id " + own_text + " (status seq "),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("source replay, rig sim-macaque): a replay of this run or a forged stream"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("warning run id " + own_text + " no longer heard"), std::string::npos) << err;
  const Heard h = analyse(dir + "/recorder.bin", prefix, own);
  std::printf(
      "daemon: %lld joint states, %lld flagged FOREIGN_RUN, %lld degraded statuses naming its own "
      "run; replay: %lld joint states, %lld statuses (source replay)\n",
      static_cast<long long>(h.own_joint_states), static_cast<long long>(h.flagged_foreign),
      static_cast<long long>(h.degraded_naming_own), static_cast<long long>(h.replay_joint_states),
      static_cast<long long>(h.replay_statuses));
  EXPECT_GT(h.replay_statuses, 0);  // the replay mark on its statuses
  EXPECT_GT(h.replay_joint_states, 0);
  EXPECT_GT(h.flagged_foreign, 0);
  EXPECT_GT(h.degraded_naming_own, 0);
  EXPECT_LT(h.flagged_foreign, h.own_joint_states);  // cleared after the replay ended
}

// A forged status with the daemon's own run id (seq from 0, a rig with a
// line break and ANSI escapes): foreign, and the rig is escaped in the log.
TEST(Instance, AForgedStatusWithTheOwnRunIdIsForeignAndItsRigEscaped) {
  const std::string dir = test::make_temp_dir("instance-forged");
  const std::string prefix = test::unique_prefix("forged");
  const std::string config = test::write_sim_config(dir, prefix);
  test::Process daemon({EXODAQD, "--config", config}, dir + "/daemon.out", dir + "/daemon.err",
                       runtime_env(dir));
  const auto lock = wait_for_lock(dir, 20s);
  ASSERT_FALSE(lock.empty()) << test::read_file(dir + "/daemon.err");
  const std::string own_text = lock.at("run_id");
  std::this_thread::sleep_for(1s);  // its own statuses heard first
  const std::string rig = "evil\n2030-01-01 00:00:00.000 [sim-macaque] info forged\x1b[31m";
  const auto pub = test::run(
      {EXODAQ_STATUS_PUBLISHER, test::kLcmUrl, prefix + "EXO_STATUS", own_text, "20", "1", rig},
      30s);
  EXPECT_EQ(pub.exit_code, 0) << pub.err;
  EXPECT_TRUE(test::wait_until([&] {
    return test::read_file(dir + "/daemon.err").find("no longer heard") != std::string::npos;
  })) << test::read_file(dir + "/daemon.err");
  daemon.signal(SIGTERM);
  EXPECT_EQ(daemon.wait(20s), std::optional<int>(0));
  const std::string err = test::read_file(dir + "/daemon.err");
  EXPECT_NE(err.find("uses this daemon's own run id " + own_text + " (status seq 0 after"),
            std::string::npos)
      << err;
  EXPECT_NE(err.find("source fake, rig evil\\n2030-01-01 00:00:00.000 [sim-macaque] info "
                     "forged\\x1b[31m)"),
            std::string::npos)
      << err;
  EXPECT_EQ(err.find('\x1b'), std::string::npos) << "a raw ESC reached the log";
  EXPECT_EQ(err.find("\n2030-01-01"), std::string::npos) << "a forged log line";
}
