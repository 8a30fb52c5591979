// End to end, with real processes: exodaqd on the simulated rig recorded by
// exodaq record (lcm-logger's format; lcm-logger itself is compared with it
// in tests/record), then `exodaq replay` at --speed max must reproduce the
// live joint_state_t and palm_pose_t messages exactly; two replays give the
// same bytes; `exodaq export` and `exodaq plot` on the result.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <regex>
#include <set>
#include <sstream>
#include <thread>

#include "exodaq/calibration/marker_layout.hpp"
#include "exodaq/calibration/solver.hpp"
#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/homing_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/messages/csv.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/settings/service_config.hpp"
#include "exodaq/status_t.hpp"
#include "process.hpp"
#include "replay_support.hpp"
#include "sim_daemon.hpp"
#include "status_wait.hpp"
#include "synthetic.hpp"

namespace exodaq::test {
namespace {

namespace cal = exodaq::calibration;

constexpr std::int32_t kSampleReplay = 1024;  // joint_state_t::SAMPLE_REPLAY
constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0";
constexpr int kPort = 7667;
// The live run lasts until the daemon has used this seq: 16 s of the rig's
// time, whatever the machine's speed. Long enough for the sim's homing sweeps
// of all six joints (~10 s) and a few reaches after, past the last excerpt
// (to seq 13700) and with the calibration markers (all joints homed).
constexpr std::int64_t kLiveSeqs = 16'000;

// One live recording shared by every test of the suite.
struct Live {
  std::string dir;
  std::string prefix;
  std::string config;
  std::string log;
  std::string replay;  // exodaq replay --speed max of `log`
  std::string replay_out;
  std::string daemon_log;
  DaemonTotals totals;  // the daemon's own account of the run
  // Seqs the daemon used without a cycle: the deadlines it skipped, each
  // named in its log ("loop overrun at seq S: ..., K deadline(s) skipped"
  // skips S-K ... S-1). Never published.
  std::set<std::int64_t> skipped;
  // Cycles the daemon ran that the recorder did not record on the raw channel:
  // every seq from 0 to the last recorded that is neither recorded nor
  // skipped. a recorder drops datagrams on a loaded machine (its socket's, counted); the replay
  // never sees these cycles, so a velocity fit spanning one cannot match the live one
  // (expect_same_cycles).
  std::set<std::int64_t> recorder_lost;
  std::int64_t recorder_kernel_drops = 0;  // the recorder's socket, as the kernel counted
};
Live* g_live = nullptr;

RunResult exodaq(const std::vector<std::string>& args) {
  std::vector<std::string> argv{EXODAQ_TOOL};
  argv.insert(argv.end(), args.begin(), args.end());
  return run(argv, std::chrono::seconds(120));
}

// Every exodaq message begins with its fingerprint, utime, mono_ns and seq.
std::int64_t seq_of(const LogEvent& e) {
  std::int64_t v = 0;
  for (std::size_t i = 0; i < 8 && 24 + i < e.data.size(); ++i) v = (v << 8) | e.data[24 + i];
  return v;
}

std::set<std::int64_t> skipped_deadlines(const std::string& daemon_log) {
  std::set<std::int64_t> skipped;
  const std::regex overrun(R"(loop overrun at seq (\d+): .*?(\d+) deadline)");
  for (auto it = std::sregex_iterator(daemon_log.begin(), daemon_log.end(), overrun);
       it != std::sregex_iterator(); ++it) {
    const std::int64_t at = std::stoll((*it)[1]);
    for (std::int64_t k = std::stoll((*it)[2]); k > 0; --k) skipped.insert(at - k);
  }
  return skipped;
}

std::set<std::int64_t> recorder_losses(const std::map<std::int64_t, encoder_raw_t>& recorded,
                                       const std::set<std::int64_t>& skipped) {
  std::set<std::int64_t> lost;
  if (recorded.empty()) return lost;
  for (std::int64_t q = 0; q < recorded.rbegin()->first; ++q) {
    if (recorded.count(q) == 0 && skipped.count(q) == 0) lost.insert(q);
  }
  return lost;
}

class ReplayLive : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    auto* live = new Live;
    live->dir = make_temp_dir("replay-live");
    live->prefix = unique_prefix("rep");
    live->config = write_sim_config(live->dir, live->prefix);
    live->log = live->dir + "/live.lcm";
    {
      Process logger({EXODAQ_TOOL, "record", "-o", live->log, "-u", kUrl, "--channels",
                      live->prefix + ".*", "--priority", "10"},
                     live->dir + "/logger.out", live->dir + "/logger.err");
      ASSERT_TRUE(wait_for_udp_socket(logger.pid(), kPort))
          << "exodaq record did not subscribe: " << read_file(live->dir + "/logger.err");
      {
        // At debug level the daemon names every skipped deadline (skipped_deadlines).
        Process daemon({EXODAQD, "--config", live->config, "--log-level", "debug"},
                       live->dir + "/exodaqd.out", live->dir + "/exodaqd.err");
        const bool reached = wait_for_seq(kUrl, live->prefix, kLiveSeqs - 1);
        daemon.signal(SIGINT);
        const auto code = daemon.wait(std::chrono::seconds(20));
        ASSERT_TRUE(code.has_value());
        ASSERT_EQ(*code, 0) << read_file(live->dir + "/exodaqd.err");
        ASSERT_TRUE(reached) << "the daemon did not reach seq " << kLiveSeqs;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(500));  // the last datagrams
      live->recorder_kernel_drops = udp_drops(logger.pid());
      logger.signal(SIGINT);
      ASSERT_TRUE(logger.wait(std::chrono::seconds(10)).has_value());
    }
    live->daemon_log = read_file(live->dir + "/exodaqd.err");
    live->totals = daemon_totals(live->daemon_log);
    live->skipped = skipped_deadlines(live->daemon_log);
    const auto raw =
        messages_by_seq<encoder_raw_t>(read_log(live->log), live->prefix + "EXO_ENCODER_RAW");
    ASSERT_FALSE(raw.empty()) << "no encoder_raw_t recorded";
    live->recorder_lost = recorder_losses(raw, live->skipped);
    std::printf(
        "live: seq 0..%lld used by the daemon: %lld cycles run, %lld deadlines skipped, %lld "
        "publish failures; exodaq record recorded %zu raw messages, lost %zu (its socket's kernel "
        "drops: %lld)\n",
        static_cast<long long>(live->totals.cycles + live->totals.overruns - 1),
        static_cast<long long>(live->totals.cycles), static_cast<long long>(live->totals.overruns),
        static_cast<long long>(live->totals.publish_failures), raw.size(),
        live->recorder_lost.size(), static_cast<long long>(live->recorder_kernel_drops));
    live->replay = live->dir + "/replay.lcm";
    const RunResult r = exodaq(
        {"replay", live->log, "--config", live->config, "--out", live->replay, "--speed", "max"});
    live->replay_out = r.out + r.err;
    ASSERT_EQ(r.exit_code, 0) << live->replay_out;
    g_live = live;
  }
  static void TearDownTestSuite() {
    delete g_live;
    g_live = nullptr;
  }
  void SetUp() override {
    if (g_live == nullptr) GTEST_SKIP() << "the live recording failed (see the first test)";
  }
};

template <typename Msg>
std::vector<std::uint8_t> bytes_of(const Msg& m) {
  std::vector<std::uint8_t> b(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(b.data(), 0, static_cast<int>(b.size()));
  return b;
}

// What expect_same_cycles compared.
struct Compared {
  std::size_t cycles = 0;      // joint_state_t and palm_pose_t byte for byte
  std::size_t valid = 0;       // of them with a valid pose
  std::size_t velocities = 0;  // joint velocities compared (a full fit window behind them)
};

Compared expect_same_cycles(const std::map<std::int64_t, joint_state_t>& ref_joint,
                            const std::map<std::int64_t, palm_pose_t>& ref_palm,
                            const std::string& replay, const std::string& p, std::int64_t first_seq,
                            bool ref_is_replay, bool whole_run);

// How many of `seqs` the reference has a joint state and a palm pose of: the
// cycles both sides have, all of which a replay must reproduce.
std::size_t in_both(const std::set<std::int64_t>& seqs,
                    const std::map<std::int64_t, joint_state_t>& joint,
                    const std::map<std::int64_t, palm_pose_t>& palm) {
  return static_cast<std::size_t>(std::count_if(seqs.begin(), seqs.end(), [&](std::int64_t seq) {
    return joint.count(seq) != 0 && palm.count(seq) != 0;
  }));
}

template <typename Msg>
std::set<std::int64_t> seqs_of(const std::map<std::int64_t, Msg>& by_seq) {
  std::set<std::int64_t> out;
  for (const auto& entry : by_seq) out.insert(entry.first);
  return out;
}

TEST_F(ReplayLive, ReproducesLiveJointAndPalmMessagesExactly) {
  const auto live = read_log(g_live->log);
  const auto replay = read_log(g_live->replay);
  const std::string p = g_live->prefix;
  const auto live_joint = messages_by_seq<joint_state_t>(live, p + "EXO_JOINT_STATE");
  const auto live_palm = messages_by_seq<palm_pose_t>(live, p + "EXO_PALM_POSE");
  const auto live_raw = messages_by_seq<encoder_raw_t>(live, p + "EXO_ENCODER_RAW");
  const auto rep_joint = messages_by_seq<joint_state_t>(replay, p + "EXO_JOINT_STATE");
  const auto rep_palm = messages_by_seq<palm_pose_t>(replay, p + "EXO_PALM_POSE");
  ASSERT_FALSE(live_raw.empty());
  // One output cycle per recorded raw message, with the recorded seq.
  ASSERT_EQ(rep_joint.size(), live_raw.size());
  ASSERT_EQ(rep_palm.size(), live_raw.size());
  for (const auto& [seq, raw] : live_raw) {
    ASSERT_EQ(rep_joint.count(seq), 1U) << "seq " << seq;
  }

  // The daemon's own account holds: every seq it used is a cycle it ran or a
  // deadline it skipped, every skip is in its log (unless it said events went
  // unlogged), and a skipped seq is never published.
  const DaemonTotals& t = g_live->totals;
  EXPECT_LT(live_raw.rbegin()->first, t.cycles + t.overruns);
  if (g_live->daemon_log.find("loop events were not logged") == std::string::npos) {
    EXPECT_EQ(static_cast<std::int64_t>(g_live->skipped.size()), t.overruns);
  }
  for (const std::int64_t seq : g_live->skipped) {
    EXPECT_EQ(live_raw.count(seq), 0U) << "skipped seq " << seq << " was published";
  }

  // The live run got somewhere: every joint homed by its end (the rig's time,
  // seq 16000), valid poses.
  const joint_state_t& last = live_joint.rbegin()->second;
  for (int j = 0; j < 6; ++j) EXPECT_TRUE(last.homed[j]) << "joint " << j + 1;

  // Every cycle that the recorder caught on all three channels must match
  // byte for byte; the only difference allowed is the SAMPLE_REPLAY bit (and a
  // velocity fit over a cycle the recorder lost: expect_same_cycles).
  const Compared c = expect_same_cycles(live_joint, live_palm, g_live->replay, p, 0, false, true);
  EXPECT_EQ(c.cycles, in_both(seqs_of(live_raw), live_joint, live_palm));
  EXPECT_GT(c.valid, 0U);
  EXPECT_GT(c.velocities, 0U);
  std::printf("replay: %zu cycles compared (%zu valid poses), %zu lost by the recorder\n", c.cycles,
              c.valid, g_live->recorder_lost.size());
  // What the recorder lost (none, as a rule) it counted: the raw seq missing
  // beyond the daemon's logged skips are its summary's lost.
  const std::string summary = read_file(g_live->dir + "/live.summary.json");
  const auto lost_of = [&](const std::string& kind) {
    const std::size_t at = summary.find("\"" + kind + "\": {");
    const std::size_t f = summary.find("\"lost\": ", at);
    return at == std::string::npos || f == std::string::npos ? -1
                                                             : std::stoll(summary.substr(f + 8));
  };
  EXPECT_EQ(static_cast<std::int64_t>(g_live->recorder_lost.size()), lost_of("encoder_raw"))
      << summary;

  // Event timestamps are the messages' utime, as lcm-logger's are close to.
  for (const auto& e : replay) {
    if (e.channel == p + "EXO_JOINT_STATE") {
      joint_state_t m;
      ASSERT_GE(m.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
      ASSERT_EQ(e.timestamp, m.utime);
    }
  }
}

// Issue 16: a recording started while the service runs (an excerpt cut from
// the middle of the live recording) replays to the live values, continuing
// the live homing from the recorded homing_t. Excerpts are cut by cycle, seq
// [from, to) (the rig's time since start, in ms at 1 kHz), so that they hold
// the same part of the task on any machine.
struct Excerpt {
  std::string path;
  std::int64_t first_seq = -1;
  std::set<std::int64_t> raw_seqs;  // the raw messages it holds
};

Excerpt cut_excerpt(const std::vector<LogEvent>& log, const std::string& raw_channel,
                    std::int64_t from_seq, std::int64_t to_seq, const std::string& path) {
  std::vector<LogEvent> part;
  Excerpt x;
  x.path = path;
  for (const auto& e : log) {
    const std::int64_t seq = seq_of(e);
    if (seq < from_seq || seq >= to_seq) continue;
    part.push_back(e);
    if (e.channel == raw_channel) {
      if (x.first_seq < 0) x.first_seq = seq;
      x.raw_seqs.insert(seq);
    }
  }
  write_log(path, part);
  return x;
}

// Every replayed cycle equals the reference's of the same seq, the replay
// mark aside. A joint's velocity is compared from its 21st fresh sample on
// (velocity_window 21): in an excerpt (`whole_run` false) and after a cycle
// the recorder lost, the live fit used samples the replay never had.
Compared expect_same_cycles(const std::map<std::int64_t, joint_state_t>& ref_joint,
                            const std::map<std::int64_t, palm_pose_t>& ref_palm,
                            const std::string& replay, const std::string& p, std::int64_t first_seq,
                            bool ref_is_replay, bool whole_run) {
  const auto log = read_log(replay);
  const auto rep_joint = messages_by_seq<joint_state_t>(log, p + "EXO_JOINT_STATE");
  const auto rep_palm = messages_by_seq<palm_pose_t>(log, p + "EXO_PALM_POSE");
  constexpr int kWindow = 21;
  std::array<int, 6> fresh{};
  if (whole_run) fresh.fill(kWindow);
  const std::set<std::int64_t>& lost = g_live->recorder_lost;
  std::int64_t previous = -1;
  Compared c;
  for (const auto& [seq, rj0] : rep_joint) {
    // A cycle lost since the previous one (or before the first).
    if (lost.lower_bound(previous + 1) != lost.lower_bound(seq)) fresh.fill(0);
    previous = seq;
    for (std::size_t j = 0; j < 6; ++j) {
      if ((rj0.flags[j] & joint_state_t::JOINT_HELD) == 0) ++fresh[j];
    }
    if (ref_joint.count(seq) == 0 || ref_palm.count(seq) == 0 || rep_palm.count(seq) == 0) {
      continue;
    }
    joint_state_t rj = rj0;
    joint_state_t lj = ref_joint.at(seq);
    EXPECT_EQ(rj.sample_flags & kSampleReplay, kSampleReplay) << "seq " << seq;
    if (!ref_is_replay) rj.sample_flags &= ~kSampleReplay;
    for (std::size_t j = 0; j < 6; ++j) {
      if (fresh[j] < kWindow) {
        rj.velocity[j] = lj.velocity[j];
      } else {
        ++c.velocities;
      }
    }
    if (bytes_of(rj) != bytes_of(lj)) {
      std::ostringstream d;
      d << " sample_flags " << lj.sample_flags << "/" << rj.sample_flags;
      for (std::size_t j = 0; j < 6; ++j) {
        d << "; j" << j << " homed " << int(lj.homed[j]) << "/" << int(rj.homed[j]) << " count "
          << lj.raw_count[j] << "/" << rj.raw_count[j] << " pos " << lj.position[j] << "/"
          << rj.position[j] << " flags " << lj.flags[j] << "/" << rj.flags[j] << " vel "
          << lj.velocity[j] << "/" << rj.velocity[j] << " (fresh " << fresh[j] << ")";
      }
      ADD_FAILURE() << replay << ": joint_state_t differs at seq " << seq << " (excerpt from "
                    << first_seq << "):" << d.str();
      return c;
    }
    const palm_pose_t& lp = ref_palm.at(seq);
    const palm_pose_t& rp = rep_palm.at(seq);
    if (bytes_of(rp) != bytes_of(lp)) {
      ADD_FAILURE() << replay << ": palm_pose_t differs at seq " << seq << ": valid "
                    << int(lp.valid) << "/" << int(rp.valid) << " reason " << lp.invalid_reason
                    << "/" << rp.invalid_reason << " x " << lp.position[0] << "/" << rp.position[0];
      return c;
    }
    ++c.cycles;
    c.valid += lp.valid ? 1 : 0;
  }
  return c;
}

// Three excerpts from the middle of the live recording, in seq: while the sim
// homes its joints one by one, and after, when every joint is homed.
constexpr std::array<std::pair<std::int64_t, std::int64_t>, 3> kExcerpts = {
    {{4100, 6300}, {8350, 10900}, {11600, 13700}}};

TEST_F(ReplayLive, ExcerptsFromTheMiddleReplayToTheLiveValues) {
  const auto live = read_log(g_live->log);
  const std::string p = g_live->prefix;
  const auto live_joint = messages_by_seq<joint_state_t>(live, p + "EXO_JOINT_STATE");
  const auto live_palm = messages_by_seq<palm_pose_t>(live, p + "EXO_PALM_POSE");
  ASSERT_FALSE(messages_by_seq<homing_t>(live, p + "EXO_HOMING").empty())
      << "the daemon records no homing_t";
  for (std::size_t i = 0; i < kExcerpts.size(); ++i) {
    const Excerpt x =
        cut_excerpt(live, p + "EXO_ENCODER_RAW", kExcerpts[i].first, kExcerpts[i].second,
                    g_live->dir + "/excerpt" + std::to_string(i) + ".lcm");
    ASSERT_FALSE(x.raw_seqs.empty()) << x.path;
    const std::string out = g_live->dir + "/excerpt" + std::to_string(i) + "-replay.lcm";
    const RunResult r = exodaq({"replay", x.path, "-c", g_live->config, "-o", out});
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
    EXPECT_NE(r.out.find("homing: continued from the live run's record of seq"), std::string::npos)
        << r.out;
    EXPECT_EQ(r.err.find("no homing record"), std::string::npos) << r.err;
    const Compared c = expect_same_cycles(live_joint, live_palm, out, p, x.first_seq, false, false);
    // Every cycle of the excerpt that the recording holds whole, velocities
    // once a fit window of the excerpt's own samples is behind them.
    EXPECT_EQ(c.cycles, in_both(x.raw_seqs, live_joint, live_palm)) << x.path;
    EXPECT_GT(c.velocities, 0U) << x.path;
    std::printf("excerpt %zu: %zu raw messages, %zu cycles compared, %zu valid poses\n", i,
                x.raw_seqs.size(), c.cycles, c.valid);
    if (i == kExcerpts.size() - 1) {
      // Every joint is homed by then: every pose is valid.
      EXPECT_EQ(c.valid, c.cycles) << "an invalid pose after homing";
      EXPECT_GT(c.valid, 0U);
    }
  }
}

TEST_F(ReplayLive, ExcerptsWithANewCalibrationMatchTheWholeRecordingsReplay) {
  const std::string calibration = g_live->dir + "/new-calibration.yaml";
  write_text(calibration,
             "format: exodaq-calibration-1\n"
             "encoder_offsets_deg: [49.5, -92.2, 84.4, 6.3, -5.5, -3.6]\n"
             "dh_deviations_mm: {d2: 0.8, d3: -0.5, d5: 0.3, a3: 0.2, a5: -0.4}\n"
             "marker_offset_mm: [1, -2, 0.5]\n");
  const std::string whole = g_live->dir + "/whole-newcal.lcm";
  const RunResult w = exodaq(
      {"replay", g_live->log, "-c", g_live->config, "--calibration", calibration, "-o", whole});
  ASSERT_EQ(w.exit_code, 0) << w.out << w.err;
  const auto ref = read_log(whole);
  const std::string p = g_live->prefix;
  const auto ref_joint = messages_by_seq<joint_state_t>(ref, p + "EXO_JOINT_STATE");
  const auto ref_palm = messages_by_seq<palm_pose_t>(ref, p + "EXO_PALM_POSE");
  const auto live = read_log(g_live->log);
  const auto live_palm = messages_by_seq<palm_pose_t>(live, p + "EXO_PALM_POSE");
  for (std::size_t i = 0; i < kExcerpts.size(); ++i) {
    const Excerpt x =
        cut_excerpt(live, p + "EXO_ENCODER_RAW", kExcerpts[i].first, kExcerpts[i].second,
                    g_live->dir + "/excerpt-newcal" + std::to_string(i) + ".lcm");
    const std::string out = g_live->dir + "/excerpt-newcal" + std::to_string(i) + "-replay.lcm";
    const RunResult r =
        exodaq({"replay", x.path, "-c", g_live->config, "--calibration", calibration, "-o", out});
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
    const Compared c = expect_same_cycles(ref_joint, ref_palm, out, p, x.first_seq, true, false);
    // The whole recording's replay has a cycle for every raw message.
    EXPECT_EQ(c.cycles, x.raw_seqs.size()) << x.path;
    if (i == kExcerpts.size() - 1) {
      // Every joint is homed by then: every pose is valid.
      EXPECT_EQ(c.valid, c.cycles) << "an invalid pose after homing";
      EXPECT_GT(c.valid, 0U);
      // Recomputed, not copied: the palm moved with the new calibration.
      const auto rep = messages_by_seq<palm_pose_t>(read_log(out), p + "EXO_PALM_POSE");
      std::size_t moved = 0;
      std::size_t with_live = 0;
      for (const auto& [seq, m] : rep) {
        if (live_palm.count(seq) == 0 || !m.valid) continue;
        ++with_live;
        if (std::abs(m.position[0] - live_palm.at(seq).position[0]) > 1e-4) ++moved;
      }
      EXPECT_GT(with_live, 0U);
      EXPECT_GT(moved, with_live * 99 / 100);
    }
  }
}

TEST_F(ReplayLive, AnExcerptWithoutHomingRecordsSaysSo) {
  auto live = read_log(g_live->log);
  const std::string p = g_live->prefix;
  std::erase_if(live, [&](const LogEvent& e) { return e.channel == p + "EXO_HOMING"; });
  const Excerpt x =
      cut_excerpt(live, p + "EXO_ENCODER_RAW", 11600, 12600, g_live->dir + "/excerpt-nohoming.lcm");
  const std::string out = g_live->dir + "/excerpt-nohoming-replay.lcm";
  const RunResult r = exodaq({"replay", x.path, "-c", g_live->config, "-o", out});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.err.find("holds no homing record (EXO_HOMING)"), std::string::npos) << r.err;
  const auto rep = messages_by_seq<palm_pose_t>(read_log(out), p + "EXO_PALM_POSE");
  ASSERT_FALSE(rep.empty());
  EXPECT_FALSE(rep.begin()->second.valid);
  EXPECT_NE(rep.begin()->second.invalid_reason & palm_pose_t::INVALID_UNHOMED, 0);
}

TEST_F(ReplayLive, RawChannelIsReproducedButForReplayMarks) {
  const auto live =
      messages_by_seq<encoder_raw_t>(read_log(g_live->log), g_live->prefix + "EXO_ENCODER_RAW");
  const auto rep =
      messages_by_seq<encoder_raw_t>(read_log(g_live->replay), g_live->prefix + "EXO_ENCODER_RAW");
  ASSERT_EQ(rep.size(), live.size());
  for (const auto& [seq, l] : live) {
    encoder_raw_t r = rep.at(seq);
    EXPECT_EQ(r.wall_ns, r.utime * 1000);
    EXPECT_NE(r.source_flags & kSampleReplay, 0);
    r.source_flags = (r.source_flags & ~kSampleReplay) & ~(256 | 64 | 128);  // loop bits
    r.wall_ns = l.wall_ns;
    ASSERT_EQ(bytes_of(r), bytes_of(l)) << "seq " << seq;
  }
}

TEST_F(ReplayLive, TwoReplaysAreByteIdenticalWhateverTheSpeed) {
  const std::string again = g_live->dir + "/replay2.lcm";
  RunResult r = exodaq({"replay", g_live->log, "--config", g_live->config, "--out", again});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_EQ(read_text(again), read_text(g_live->replay));
  // Pacing is for --live only: a file is always written flat out.
  const std::string paced = g_live->dir + "/replay-paced.lcm";
  r = exodaq({"replay", g_live->log, "--config", g_live->config, "--out", paced, "--speed", "8"});
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  EXPECT_NE(r.err.find("--speed 8 goes with --live"), std::string::npos) << r.err;
  EXPECT_EQ(file_size(paced), -1);
}

// Issue 16 point 6: `exodaq replay --live` publishes a recording over LCM with
// the daemon's channels and types; `exodaq echo` (another process) receives
// the live run's joint states, the replay flag set, values as recorded.
TEST_F(ReplayLive, LiveReplayIsSeenByEchoWithTheReplayFlag) {
  const auto live = read_log(g_live->log);
  const std::string p = g_live->prefix;
  const Excerpt x =
      cut_excerpt(live, p + "EXO_ENCODER_RAW", 11600, 13100, g_live->dir + "/excerpt-live.lcm");
  const auto live_joint = messages_by_seq<joint_state_t>(live, p + "EXO_JOINT_STATE");
  const std::string out_prefix = unique_prefix("replive");
  const std::string echo_csv = g_live->dir + "/echo-live.csv";
  Process echo({EXODAQ_TOOL, "echo", "--url", std::string(kUrl) + "&recv_buf_size=4194304",
                "--prefix", out_prefix, "--channel", "joint_state", "--count", "300", "--csv"},
               echo_csv, g_live->dir + "/echo-live.err");
  ASSERT_TRUE(wait_for_udp_socket(echo.pid(), kPort)) << "echo did not subscribe";
  // 1.5 s of recording at 2x; echo needs 300 of its joint states (one per
  // raw message of the excerpt).
  ASSERT_GT(x.raw_seqs.size(), 300U);
  const RunResult r = exodaq({"replay", x.path, "-c", g_live->config, "--live", "--speed", "2",
                              "--url", kUrl, "--prefix", out_prefix});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("messages published"), std::string::npos) << r.out;
  const auto code = echo.wait(std::chrono::seconds(30));
  ASSERT_TRUE(code.has_value()) << "echo got fewer than 300 joint states";
  ASSERT_EQ(*code, 0) << read_file(g_live->dir + "/echo-live.err");

  std::istringstream csv(read_file(echo_csv));
  std::string line;
  ASSERT_TRUE(std::getline(csv, line));
  const auto split = [](const std::string& s) {
    std::vector<std::string> f;
    std::stringstream ss(s);
    std::string c;
    while (std::getline(ss, c, ',')) f.push_back(c);
    return f;
  };
  const auto header = split(line);
  const auto column = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    return it == header.end() ? std::size_t{9999} : static_cast<std::size_t>(it - header.begin());
  };
  const std::size_t c_seq = column("seq");
  const std::size_t c_flags = column("sample_flags");
  ASSERT_LT(c_seq, header.size()) << line;
  ASSERT_LT(c_flags, header.size()) << line;
  // Every row is a cycle of the excerpt (one joint state per raw message it
  // holds), flagged as a replay, its flags the live ones where the recording
  // also holds the live joint state (lcm-logger may have lost that one).
  int rows = 0;
  int with_live = 0;
  while (std::getline(csv, line)) {
    const auto f = split(line);
    ASSERT_GT(f.size(), c_flags) << line;
    const std::int64_t seq = std::stoll(f[c_seq]);
    const std::int64_t flags = std::stoll(f[c_flags]);
    EXPECT_EQ(flags & kSampleReplay, kSampleReplay) << line;
    ASSERT_EQ(x.raw_seqs.count(seq), 1U) << "seq " << seq << " not in the excerpt";
    ++rows;
    if (live_joint.count(seq) == 0) continue;
    EXPECT_EQ(flags & ~std::int64_t{kSampleReplay}, live_joint.at(seq).sample_flags) << line;
    ++with_live;
  }
  EXPECT_EQ(rows, 300);
  EXPECT_GT(with_live, 0);
}

TEST_F(ReplayLive, StatusIsWrittenAndRunIdIsTheRecordings) {
  const auto replay = read_log(g_live->replay);
  const auto live_raw =
      messages_by_seq<encoder_raw_t>(read_log(g_live->log), g_live->prefix + "EXO_ENCODER_RAW");
  const std::int64_t run_id = live_raw.begin()->second.run_id;
  int status = 0;
  for (const auto& e : replay) {
    if (e.channel != g_live->prefix + "EXO_STATUS") continue;
    status_t s;
    ASSERT_GE(s.decode(e.data.data(), 0, static_cast<int>(e.data.size())), 0);
    EXPECT_EQ(s.run_id, run_id);
    EXPECT_EQ(s.source, "replay");
    ++status;
  }
  // A status window closes after each cycle whose seq ends a status period
  // (seq 99, 199, ...: 10 Hz at 1 kHz), as live; the recording decides how
  // many it holds, and one more may close the replay.
  const auto windows = std::count_if(live_raw.begin(), live_raw.end(),
                                     [](const auto& e) { return (e.first + 1) % 100 == 0; });
  EXPECT_GE(status, windows);
  EXPECT_LE(status, windows + 1);
}

// --- export -----------------------------------------------------------------

std::vector<std::vector<std::string>> read_csv(const std::string& path) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(read_text(path));
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::size_t start = 0;
    while (true) {
      const std::size_t comma = line.find(',', start);
      cells.push_back(line.substr(start, comma - start));
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    rows.push_back(std::move(cells));
  }
  return rows;
}

TEST_F(ReplayLive, ExportHasOneRowPerCycleWithTheLogsValues) {
  const std::string csv = g_live->dir + "/cycles.csv";
  const RunResult r = exodaq({"export", g_live->replay, "-o", csv});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  const auto rows = read_csv(csv);
  const auto log = read_log(g_live->replay);
  const auto joints = messages_by_seq<joint_state_t>(log, g_live->prefix + "EXO_JOINT_STATE");
  const auto palms = messages_by_seq<palm_pose_t>(log, g_live->prefix + "EXO_PALM_POSE");
  ASSERT_EQ(rows.size(), joints.size() + 1);  // + header
  std::map<std::string, std::size_t> col;
  for (std::size_t i = 0; i < rows[0].size(); ++i) col[rows[0][i]] = i;
  const auto& j0 = joints.begin()->second;
  // The schema of docs/messages.md: joints by name, units in the names.
  ASSERT_EQ(rows[0][0], "utime_us");
  for (const std::string name :
       {"seq", "run_id", "mono_ns", "sample_flags", "palm_x_m", "palm_qw", "elbow_z_m",
        "manipulability", "palm_valid", "palm_invalid_reason"}) {
    ASSERT_EQ(col.count(name), 1U) << name;
  }
  std::size_t i = 1;
  for (const auto& [seq, j] : joints) {
    const auto& row = rows[i++];
    ASSERT_EQ(row.size(), rows[0].size());
    ASSERT_EQ(std::stoll(row[col["seq"]]), seq);
    EXPECT_EQ(std::stoll(row[col["utime_us"]]), j.utime);
    ASSERT_EQ(row[col["run_id"]], messages::run_id_text(j.run_id));
    for (int k = 0; k < 6; ++k) {
      const std::string n = j0.name[k];
      // Exact: the shortest text that reads back to the same double; no "-0".
      ASSERT_EQ(std::strtod(row[col[n + "_rad"]].c_str(), nullptr), j.position[k]);
      ASSERT_EQ(std::strtod(row[col[n + "_vel_rad_s"]].c_str(), nullptr), j.velocity[k]);
      ASSERT_NE(row[col[n + "_vel_rad_s"]], "-0");
      ASSERT_EQ(row[col[n + "_homed"]], j.homed[k] ? "1" : "0");
      ASSERT_EQ(std::stoi(row[col[n + "_flags"]]), j.flags[k]);
      ASSERT_EQ(std::stoll(row[col[n + "_count"]]), j.raw_count[k]);
    }
    ASSERT_EQ(std::stoi(row[col["sample_flags"]]), j.sample_flags);
    const palm_pose_t& p = palms.at(seq);
    ASSERT_EQ(std::strtod(row[col["palm_x_m"]].c_str(), nullptr), p.position[0]);
    ASSERT_EQ(std::strtod(row[col["palm_qw"]].c_str(), nullptr), p.orientation[0]);
    ASSERT_EQ(std::strtod(row[col["elbow_z_m"]].c_str(), nullptr), p.elbow[2]);
    ASSERT_EQ(std::strtod(row[col["manipulability"]].c_str(), nullptr), p.shoulder_manipulability);
    ASSERT_EQ(row[col["palm_valid"]], p.valid ? "1" : "0");
    ASSERT_EQ(std::stoi(row[col["palm_invalid_reason"]]), p.invalid_reason);
  }
  // The same bytes to standard output (-o -, the default).
  const RunResult piped = exodaq({"export", g_live->replay, "-q"});
  ASSERT_EQ(piped.exit_code, 0) << piped.err;
  EXPECT_EQ(piped.out, read_text(csv));
  EXPECT_EQ(piped.err, "");
}

// Issue 15 point 8: a damaged log exports what can be read, exits 1 and
// names the damaged bytes; garbage after the last good event loses nothing.
TEST_F(ReplayLive, ExportOfADamagedLogNamesTheBytesAndKeepsEveryGoodEvent) {
  const std::string good = read_text(g_live->replay);
  const std::string reference = g_live->dir + "/reference.csv";
  ASSERT_EQ(exodaq({"export", g_live->replay, "-o", reference}).exit_code, 0);
  const auto ref_rows = read_csv(reference);

  const std::string tail = g_live->dir + "/garbage-appended.lcm";
  const std::string garbage = "\xde\xad\xbe\xef garbage after the last event";
  write_text(tail, good + garbage);
  const std::string tail_csv = g_live->dir + "/garbage-appended.csv";
  RunResult r = exodaq({"export", tail, "-o", tail_csv});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  const std::string range = "bytes " + std::to_string(good.size()) + ".." +
                            std::to_string(good.size() + garbage.size()) + ": ";
  EXPECT_NE(r.err.find("exodaq export: " + tail + ", " + range), std::string::npos) << r.err;
  EXPECT_EQ(read_text(tail_csv), read_text(reference));  // every good event kept

  // Bytes overwritten in the middle: the rows around them stay, the damaged
  // stretch is named.
  std::string mid = good;
  std::int64_t at = 0;  // the header of the first joint state past the middle
  {
    messages::LogReader reader(g_live->replay);
    messages::LogEvent ev;
    while (reader.next(ev) && (ev.offset < static_cast<std::int64_t>(mid.size() / 2) ||
                               ev.channel != g_live->prefix + "EXO_JOINT_STATE")) {
    }
    at = ev.offset;
  }
  for (std::size_t k = 0; k < 64; ++k) mid[static_cast<std::size_t>(at) + k] = 'x';
  const std::string mid_log = g_live->dir + "/damaged-middle.lcm";
  write_text(mid_log, mid);
  const std::string mid_csv = g_live->dir + "/damaged-middle.csv";
  r = exodaq({"export", mid_log, "-o", mid_csv});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find(mid_log + ", bytes " + std::to_string(at) + ".."), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find(": no event header here"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("; 1 event lost (after event "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("cycles lost with it: 1 (seq "), std::string::npos) << r.err;
  // That cycle's joint state is lost (its row with it), nothing else.
  EXPECT_EQ(read_csv(mid_csv).size() + 1, ref_rows.size());
}

// --- plot -------------------------------------------------------------------

TEST_F(ReplayLive, PlotWritesOneNonEmptyPngPerPanel) {
  const std::string dir = g_live->dir + "/plots/";
  const RunResult r = exodaq({"plot", g_live->replay, "-o", dir, "-c", g_live->config});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  // Paths as the user would type them (not "plots//x.png").
  EXPECT_NE(r.out.find(g_live->dir + "/plots/joint_trajectories.png\n"), std::string::npos)
      << r.out;
  EXPECT_EQ(r.out.find("//"), std::string::npos) << r.out;
  for (const char* f :
       {"joint_trajectories.png", "palm_path_3d.png", "shoulder_manipulability.png"}) {
    const std::string path = dir + "/" + f;
    EXPECT_GT(file_size(path), 1000) << path;
    EXPECT_EQ(read_text(path).substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8)) << path;
  }
  EXPECT_GT(file_size(dir + "/cycles.csv"), 0);
}

// --- calibrate from the recording (issue 16 point 2) -------------------------

// Markers synthesised from the recorded joint angles: θᴿ = position − the sim
// calibration's offsets (the sim puts each index at those angles), the
// markers of config/calibration/markers_example.yaml through forward
// kinematics with a known calibration (seed 000 Table 4 "Results") every 10th
// cycle in which all six joints are homed and unflagged and the sample is there.
struct Markers {
  std::string csv;
  std::string bounds;
  cal::ParamVector truth{};
  std::size_t rows = 0;
};

// config/calibration/bounds_seed000.yaml with every parameter but the six
// encoder offsets held at the truth. The offsets are what reading the
// recording decides (θᴿ = recorded angle − the recording's Δθ⁰); the few
// seconds of motion after the sim's homing do not identify all 20 parameters
// together (calibrate says which it holds, and which follow that choice), but
// with the others held every offset must come back exactly.
std::string bounds_holding_all_but_offsets(const std::string& dir, const cal::ParamVector& truth) {
  std::string text =
      read_text(std::string(EXODAQ_SOURCE_DIR) + "/config/calibration/bounds_seed000.yaml");
  for (int p = cal::kTheta1 + 6; p < cal::kParams; ++p) {
    const std::string key = cal::param_key(p);
    const std::size_t at = text.find("\n  " + key + ": {initial: ");
    EXPECT_NE(at, std::string::npos) << key;
    const std::size_t end = text.find('}', at);
    const std::size_t comma = text.find(',', at);
    text = text.substr(0, at) + "\n  " + key +
           ": {initial: " + messages::csv::number(cal::to_display(p, truth[p])) +
           text.substr(comma, end - comma) + ", fixed: true" + text.substr(end);
  }
  const std::string path = dir + "/bounds.yaml";
  write_text(path, text);
  return path;
}

Markers synthesise_markers(const std::string& dir) {
  Markers m;
  m.truth = cal::synth::table4_results();
  const settings::ServiceConfig cfg = settings::load_service_config(g_live->config);
  const cal::NominalModel model = cal::nominal_from_chain(cfg.model.chain);
  const cal::MarkerLayout layout = cal::load_marker_layout_file(
      std::string(EXODAQ_SOURCE_DIR) + "/config/calibration/markers_example.yaml");
  // The recording's angles as the replay computes them from its raw channel:
  // the live ones exactly when the logger lost nothing (the first test), and
  // what `calibrate -c` computes from the same recording either way.
  const auto joints =
      messages_by_seq<joint_state_t>(read_log(g_live->replay), g_live->prefix + "EXO_JOINT_STATE");
  std::ostringstream out;
  out << "utime_us,x_mm,y_mm,z_mm,marker_id\n";
  out.precision(12);
  std::int64_t k = 0;
  for (const auto& [seq, j] : joints) {
    bool clean = (j.sample_flags & joint_state_t::SAMPLE_MISSING) == 0;
    for (int i = 0; i < 6; ++i) clean = clean && j.homed[i] && j.flags[i] == 0;
    if (!clean || k++ % 10 != 0) continue;
    std::array<double, 6> theta_r{};
    for (int i = 0; i < 6; ++i) {
      theta_r[static_cast<std::size_t>(i)] =
          j.position[i] - cfg.calibration.encoder_offset_rad[static_cast<std::size_t>(i)];
    }
    for (const cal::MarkerSite& site : layout.sites) {
      const Eigen::Vector3d p = cal::predict_marker(model, m.truth, theta_r, site);
      out << j.utime << "," << p.x() * 1e3 << "," << p.y() * 1e3 << "," << p.z() * 1e3 << ","
          << site.id << "\n";
      ++m.rows;
    }
  }
  m.csv = dir + "/markers.csv";
  write_text(m.csv, out.str());
  m.bounds = bounds_holding_all_but_offsets(dir, m.truth);
  return m;
}

// Runs exodaq calibrate on `encoders` and returns the written calibration.
settings::Calibration calibrate(const std::string& encoders, const Markers& m,
                                const std::vector<std::string>& extra, const std::string& out) {
  const std::string src = EXODAQ_SOURCE_DIR;
  std::vector<std::string> args{"calibrate",
                                "--encoders",
                                encoders,
                                "--markers",
                                m.csv,
                                "--bounds",
                                m.bounds,
                                "--marker-layout",
                                src + "/config/calibration/markers_example.yaml",
                                "--max-points",
                                "150",
                                "-q",
                                "-o",
                                out};
  args.insert(args.end(), extra.begin(), extra.end());
  const RunResult r = exodaq(args);
  EXPECT_EQ(r.exit_code, 0) << r.out << r.err;
  return settings::load_calibration_file(out);
}

void expect_truth(const settings::Calibration& c, const cal::ParamVector& truth,
                  const std::string& what) {
  constexpr double kDeg = std::numbers::pi / 180.0;
  for (int j = 0; j < 6; ++j) {
    // Noise-free markers: the offsets come back to within a thousandth of a degree.
    EXPECT_NEAR(c.encoder_offset_rad[static_cast<std::size_t>(j)], truth[cal::kTheta1 + j],
                0.001 * kDeg)
        << what << ": joint " << j + 1;
  }
  ASSERT_TRUE(c.provenance.rms_after_m.has_value());
  EXPECT_LT(*c.provenance.rms_after_m, 1e-6) << what;
}

TEST_F(ReplayLive, CalibrateReadsTheRecordingAndFindsTheKnownCalibration) {
  const std::string dir = g_live->dir + "/calibrate";
  std::filesystem::create_directories(dir);
  const Markers m = synthesise_markers(dir);
  // Every tenth clean cycle of the last ~5 s of the rig's time, five markers
  // each: what the fit of six offsets needs is a few postures per offset,
  // far fewer than even a loop that ran a tenth of its deadlines gives.
  ASSERT_GT(m.rows, 5U * 30) << "too few clean cycles recorded to fit six offsets";
  const std::string sim_cal = std::string(EXODAQ_SOURCE_DIR) + "/config/calibration/sim.yaml";

  // The lcm-logger recording, raw channel re-processed with the config.
  expect_truth(calibrate(g_live->log, m, {"-c", g_live->config}, dir + "/from-raw.yaml"), m.truth,
               "LCM log, raw channel");
  // Joint states (the replay's log of the recording), less the calibration
  // they were computed with.
  expect_truth(calibrate(g_live->replay, m, {"--recorded-calibration", sim_cal},
                         dir + "/from-joint-states.yaml"),
               m.truth, "LCM log, joint states");
  // The CSV of exodaq export, with the config (its calibration).
  const std::string csv = dir + "/export.csv";
  ASSERT_EQ(exodaq({"export", g_live->replay, "-o", csv, "-q"}).exit_code, 0);
  expect_truth(calibrate(csv, m, {"-c", g_live->config}, dir + "/from-export.yaml"), m.truth,
               "export CSV");

  // The wrong recorded calibration (nominal: zero offsets, the sim's are up to
  // 93 degrees): no fit at all, said so (it crashed in the identifiability
  // analysis before).
  const RunResult wrong =
      exodaq({"calibrate", "--encoders", g_live->replay, "--recorded-calibration",
              std::string(EXODAQ_SOURCE_DIR) + "/config/calibration/nominal.yaml", "--markers",
              m.csv, "--bounds", m.bounds, "--marker-layout",
              std::string(EXODAQ_SOURCE_DIR) + "/config/calibration/markers_example.yaml", "-q",
              "-o", dir + "/wrong.yaml"});
  EXPECT_EQ(wrong.exit_code, 2) << wrong.err;
  EXPECT_NE(wrong.err.find("exodaq calibrate: no parameter is identifiable from these data"),
            std::string::npos)
      << wrong.err;
  EXPECT_EQ(file_size(dir + "/wrong.yaml"), -1);

  // Calibrated angles without their calibration: refused, saying what to give.
  const RunResult r =
      exodaq({"calibrate", "--encoders", csv, "--markers", m.csv, "--bounds",
              std::string(EXODAQ_SOURCE_DIR) + "/config/calibration/bounds_seed000.yaml", "-o",
              dir + "/never.yaml"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("exodaq calibrate: " + csv +
                       ":1: holds calibrated joint angles (theta = offset + theta_R): name the "
                       "calibration they were computed with"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(file_size(dir + "/never.yaml"), -1);
}

// --- candump through the whole tool -------------------------------------------

TEST(ReplayCandumpTool, SimFramesReplayToTheTruthWithinOneCount) {
  const std::string dir = make_temp_dir("replay-candump");
  const std::string config = write_sim_config(dir, unique_prefix("cd"));
  const settings::ServiceConfig cfg = settings::load_service_config(config);
  const drivers::SourceContext ctx = settings::make_source_context(cfg);
  const drivers::sim::SimOptions opt = drivers::sim_options_from(cfg.source, ctx);
  const drivers::sim::SimRig truth_rig(opt);
  const double homing_end = truth_rig.motion().homing_end_s();
  const auto cycles = static_cast<std::int64_t>((homing_end + 2.0) * 1000.0);
  constexpr std::int64_t kWallStart = 1'700'000'000'000'000'000LL;
  const SimCandump cd = sim_candump(opt, cycles, kWallStart);
  // Two malformed lines, whose numbers must be reported.
  std::string text = cd.text;
  const std::size_t cut = text.find('\n', text.size() / 2) + 1;
  const auto line_of = [&](std::size_t pos) {
    return 1 + std::count(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(pos), '\n');
  };
  text.insert(cut, "(1700000000.5) vcan0 181#ZZ\nnot a candump line\n");
  const auto bad1 = line_of(cut);
  const std::string input = dir + "/sim.candump";
  write_text(input, text);

  const std::string out = dir + "/replay.lcm";
  // Malformed lines: the replay goes on, names them and exits 1.
  const RunResult r = exodaq({"replay", input, "--config", config, "--out", out});
  ASSERT_EQ(r.exit_code, 1) << r.out << r.err;
  EXPECT_NE(r.err.find(input + ": damaged or malformed input (problems above)"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find(input + ":" + std::to_string(bad1) + ": bad data"), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find(input + ":" + std::to_string(bad1 + 1) + ": bad or missing timestamp"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.out.find("2 malformed lines"), std::string::npos) << r.out;

  const auto joints =
      messages_by_seq<joint_state_t>(read_log(out), cfg.lcm.prefix + "EXO_JOINT_STATE");
  ASSERT_EQ(static_cast<std::int64_t>(joints.size()), cycles);
  std::int64_t checked = 0;
  for (const auto& [seq, j] : joints) {
    const double t = static_cast<double>(j.mono_ns - kWallStart) * 1e-9;
    const auto truth = truth_rig.motion().position(t);
    for (int i = 0; i < 6; ++i) {
      if (!j.homed[i]) continue;
      const auto& e = ctx.joints[static_cast<std::size_t>(i)];
      const double one_count =
          2 * std::numbers::pi / (static_cast<double>(ctx.counts_per_rev) * e.gear_ratio);
      ASSERT_LE(std::abs(j.position[i] - truth[static_cast<std::size_t>(i)]), one_count + 1e-12)
          << "seq " << seq << " joint " << i;
      ++checked;
    }
  }
  // Every joint homed for the last two seconds at least.
  EXPECT_GT(checked, 6 * 2000);
  EXPECT_TRUE(joints.rbegin()->second.homed[5]);
}

// A recording made before encoder_raw_t version 2: tests/replay/fixtures/
// v1-sim-10000.lcm is seq 10000..10499 of a live run of the exodaqd of that
// time on v1-sim.yaml (recorded by exodaq record; the homing record of seq
// 10000, five joints homed, the sixth homing at seq 10229). Its replay
// reproduces the joint states and palm poses that daemon published, bit for
// bit, and re-publishes its raw samples as version 2.
TEST(ReplayLcm, ARecordingOfVersion1ReplaysToItsLiveValuesBitForBit) {
  const std::string fixtures = std::string(EXODAQ_SOURCE_DIR) + "/tests/replay/fixtures";
  const std::string in = fixtures + "/v1-sim-10000.lcm";
  const std::string out = make_temp_dir("replay-v1") + "/replay.lcm";
  const RunResult r = exodaq({"replay", in, "-c", fixtures + "/v1-sim.yaml", "-o", out});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_NE(r.out.find("homing: continued from the live run's record of seq 10000"),
            std::string::npos)
      << r.out;
  const auto live = read_log(in);
  const auto replay = read_log(out);
  const auto live_joint = messages_by_seq<joint_state_t>(live, "EXO_JOINT_STATE");
  const auto live_palm = messages_by_seq<palm_pose_t>(live, "EXO_PALM_POSE");
  const auto rep_joint = messages_by_seq<joint_state_t>(replay, "EXO_JOINT_STATE");
  const auto rep_palm = messages_by_seq<palm_pose_t>(replay, "EXO_PALM_POSE");
  const auto rep_raw = messages_by_seq<encoder_raw_t>(replay, "EXO_ENCODER_RAW");
  ASSERT_EQ(live_joint.size(), 499U);
  ASSERT_EQ(rep_joint.size(), live_joint.size());
  ASSERT_EQ(rep_raw.size(), live_joint.size());
  constexpr int kWindow = 21;  // velocity_window: the live fit had samples before the excerpt
  std::array<int, 6> fresh{};
  std::size_t valid = 0;
  for (const auto& [seq, lj] : live_joint) {
    ASSERT_EQ(rep_joint.count(seq), 1U) << "seq " << seq;
    joint_state_t rj = rep_joint.at(seq);
    EXPECT_EQ(rj.sample_flags & kSampleReplay, kSampleReplay);
    rj.sample_flags &= ~kSampleReplay;
    for (std::size_t j = 0; j < 6; ++j) {
      if ((lj.flags[j] & joint_state_t::JOINT_HELD) == 0) ++fresh[j];
      if (fresh[j] < kWindow) rj.velocity[j] = lj.velocity[j];
    }
    ASSERT_EQ(bytes_of(rj), bytes_of(lj)) << "joint_state_t at seq " << seq;
    ASSERT_EQ(bytes_of(rep_palm.at(seq)), bytes_of(live_palm.at(seq))) << "palm at seq " << seq;
    valid += live_palm.at(seq).valid ? 1 : 0;
    // Version 2 of the same sample: protocol v1's moduli, no absolute channel.
    const encoder_raw_t& raw = rep_raw.at(seq);
    EXPECT_EQ(raw.source_seq_modulus, 256);
    for (std::size_t c = 0; c < 6; ++c) {
      EXPECT_EQ(raw.modulus[c], 65536);
      EXPECT_TRUE(raw.position[c] >= 0 && raw.position[c] < 65536);
    }
    EXPECT_EQ(raw.absolute, 0);
  }
  EXPECT_FALSE(live_joint.begin()->second.homed[5]);  // the sixth joint homes in the excerpt
  EXPECT_TRUE(live_joint.rbegin()->second.homed[5]);
  EXPECT_GT(valid, 200U);
}
}  // namespace
}  // namespace exodaq::test
