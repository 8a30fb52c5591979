// exodaqd as its own process on the simulated rig, a separate recorder process
// and the real lcm-logger subscribing: what a decoder on the BMI host gets.
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <thread>

#include "exodaq/core/builder.hpp"
#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/drivers/source_factory.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/settings/service_config.hpp"
#include "exodaq/status_t.hpp"
#include "process.hpp"
#include "recording.hpp"
#include "sim_daemon.hpp"
#include "status_wait.hpp"

using namespace exodaq;
using namespace std::chrono_literals;

namespace {
const std::string& kUrl = test::kLcmUrl;

struct DaemonRecording {
  std::string dir;
  std::string prefix;
  std::string config;
  std::vector<test::RecordedMessage> recorded;
  std::vector<test::RecordedMessage> logged;
  int exit_code = -1;
  double stop_ms = 0;
  std::string daemon_err;
  test::DaemonTotals totals;        // the daemon's own account
  std::int64_t recorder_drops = 0;  // datagrams the kernel dropped on the recorder's socket
  std::int64_t logger_drops = 0;    // ... on lcm-logger's (it also drops in LCM's queue, uncounted)
};

constexpr int kPort = 7667;

// One run shared by the tests below: until the daemon has used seq 12000
// (12 s of the rig's time: the simulated operator homes joint by joint in
// ~10 s), however long the machine takes.
const DaemonRecording& the_run() {
  static DaemonRecording run = [] {
    DaemonRecording r;
    r.dir = test::make_temp_dir("e2e");
    r.prefix = test::unique_prefix("e2e");
    r.config = test::write_sim_config(r.dir, r.prefix);
    test::Process recorder(
        {EXODAQ_RECORDER, test::kRecordUrl, r.prefix + ".*", r.dir + "/recorder.bin"}, "",
        r.dir + "/recorder.err");
    test::Process logger(
        test::lcm_logger_argv(test::kRecordUrl, r.prefix + ".*", r.dir + "/run.lcm"),
        r.dir + "/logger.out", r.dir + "/logger.err");
    // Both subscribed before the first message.
    EXPECT_TRUE(test::wait_for_udp_socket(recorder.pid(), kPort));
    EXPECT_TRUE(test::wait_for_udp_socket(logger.pid(), kPort));
    {
      test::Process daemon({EXODAQD, "--config", r.config}, r.dir + "/daemon.out",
                           r.dir + "/daemon.err");
      EXPECT_TRUE(test::wait_for_seq(kUrl, r.prefix, 12'000))
          << "the daemon never reached seq 12000";
      const auto t0 = std::chrono::steady_clock::now();
      daemon.signal(SIGTERM);
      const auto code = daemon.wait(20s);
      r.stop_ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      r.exit_code = code ? *code : -1;
    }
    std::this_thread::sleep_for(500ms);  // the last datagrams in flight
    r.recorder_drops = test::udp_drops(recorder.pid());
    r.logger_drops = test::udp_drops(logger.pid());
    recorder.signal(SIGTERM);
    logger.signal(SIGINT);
    recorder.wait(5s);
    logger.wait(5s);
    r.daemon_err = test::read_file(r.dir + "/daemon.err");
    r.totals = test::daemon_totals(r.daemon_err);
    r.recorded = test::read_recorder_file(r.dir + "/recorder.bin");
    r.logged = test::read_lcm_log(r.dir + "/run.lcm");
    std::printf(
        "run dir %s: %zu recorded (socket drops %lld), %zu logged (socket drops %lld), SIGTERM "
        "to exit %.1f ms\n",
        r.dir.c_str(), r.recorded.size(), static_cast<long long>(r.recorder_drops), r.logged.size(),
        static_cast<long long>(r.logger_drops), r.stop_ms);
    return r;
  }();
  return run;
}

std::map<std::string, std::vector<const test::RecordedMessage*>> by_channel(
    const std::vector<test::RecordedMessage>& msgs) {
  std::map<std::string, std::vector<const test::RecordedMessage*>> out;
  for (const auto& m : msgs) out[m.channel].push_back(&m);
  return out;
}
}  // namespace

TEST(DaemonRun, StopsCleanlyOnSigtermAfterAFinalStatus) {
  const DaemonRecording& r = the_run();
  EXPECT_EQ(r.exit_code, 0) << r.daemon_err;
  const auto ch = by_channel(r.recorded);
  ASSERT_TRUE(ch.count(r.prefix + "EXO_STATUS"));
  const auto last = test::decode<exodaq::status_t>(ch.at(r.prefix + "EXO_STATUS").back()->data);
  // The final status is the last datagram: only a drop on the recorder's
  // socket (counted) excuses its absence.
  if (r.recorder_drops == 0) {
    EXPECT_EQ(static_cast<int>(last.state), int{exodaq::status_t::STATE_STOPPING});
  }
  EXPECT_EQ(last.rig, "sim-macaque");
  EXPECT_NE(r.daemon_err.find("SIGTERM received"), std::string::npos);
}

// The recorder (unbounded LCM queue, 4 MiB socket buffer) loses a datagram
// only when the kernel drops it on its socket, which the kernel counts
// (r.recorder_drops): every cycle the daemon ran reached it but those.
TEST(DaemonRun, SequenceRateAndTimestampsHold) {
  const DaemonRecording& r = the_run();
  const auto ch = by_channel(r.recorded);
  const auto& joints = ch.at(r.prefix + "EXO_JOINT_STATE");
  ASSERT_FALSE(joints.empty());
  std::int64_t prev_seq = -1;
  std::int64_t prev_utime = 0;
  std::int64_t prev_mono = 0;
  std::int64_t gaps = 0;
  std::int64_t run_id = 0;
  for (const auto* m : joints) {
    const auto js = test::decode<exodaq::joint_state_t>(m->data);
    if (prev_seq >= 0) {
      ASSERT_GT(js.seq, prev_seq);
      gaps += js.seq - prev_seq - 1;
      ASSERT_GE(js.utime, prev_utime) << "utime ran backwards at seq " << js.seq;
      ASSERT_GT(js.mono_ns, prev_mono) << "mono_ns ran backwards at seq " << js.seq;
      ASSERT_EQ(js.run_id, run_id);
    }
    run_id = js.run_id;
    prev_seq = js.seq;
    prev_utime = js.utime;
    prev_mono = js.mono_ns;
  }
  const auto first = test::decode<exodaq::joint_state_t>(joints.front()->data);
  const auto last = test::decode<exodaq::joint_state_t>(joints.back()->data);
  const test::DaemonTotals& t = r.totals;
  // The daemon's account: seqs 0 ... cycles + overruns - 1, each a cycle run
  // or a deadline skipped.
  EXPECT_EQ(first.seq, 0);
  EXPECT_LT(last.seq, t.cycles + t.overruns);
  // Every cycle it ran reached the subscriber, but for what its publish path
  // counted as refused or dropped and what the subscriber's own socket
  // dropped: no message lost uncounted, none invented.
  const std::int64_t lost = t.publish_failures + r.recorder_drops;
  const std::int64_t not_received = t.cycles - static_cast<std::int64_t>(joints.size());
  EXPECT_GE(not_received, 0);
  EXPECT_LE(not_received, lost) << joints.size() << " of " << t.cycles;
  // Every seq gap is a deadline the daemon counted as skipped, or one of those.
  EXPECT_LE(gaps, t.overruns + lost) << "uncounted sequence gaps";
  // The rate, measured by sequence over the sample clock.
  const double rate = static_cast<double>(last.seq - first.seq) /
                      (static_cast<double>(last.mono_ns - first.mono_ns) * 1e-9);
  EXPECT_NEAR(rate, 1000.0, 1.0);
  // All channels of one cycle share seq, utime and mono_ns.
  std::map<std::int64_t, std::pair<std::int64_t, std::int64_t>> stamps;
  for (const auto* m : joints) {
    const auto js = test::decode<exodaq::joint_state_t>(m->data);
    stamps[js.seq] = {js.utime, js.mono_ns};
  }
  const auto& palms = ch.at(r.prefix + "EXO_PALM_POSE");
  std::int64_t matched = 0;
  for (const auto* m : palms) {
    const auto p = test::decode<exodaq::palm_pose_t>(m->data);
    const auto it = stamps.find(p.seq);
    if (it == stamps.end()) continue;
    ASSERT_EQ(p.utime, it->second.first);
    ASSERT_EQ(p.mono_ns, it->second.second);
    ++matched;
  }
  // A palm pose without the joint state of its cycle: only where that joint
  // state was dropped (below).
  EXPECT_GT(matched, 0);
  std::printf(
      "cycles %lld, received %zu, gaps %lld, overruns %lld, socket drops %lld, rate %.3f Hz\n",
      static_cast<long long>(t.cycles), joints.size(), static_cast<long long>(gaps),
      static_cast<long long>(t.overruns), static_cast<long long>(r.recorder_drops), rate);
  EXPECT_LE(static_cast<std::int64_t>(palms.size()) - matched, lost);
}

TEST(DaemonRun, AnglesMatchTheSimulatorTruthAndPalmMatchesForwardKinematics) {
  const DaemonRecording& r = the_run();
  const auto cfg = settings::load_service_config(r.config);
  const auto pipeline = core::make_pipeline_config(cfg);
  auto source = drivers::make_source(cfg.source, settings::make_source_context(cfg));
  auto* sim = dynamic_cast<drivers::SimSource*>(source.get());
  ASSERT_NE(sim, nullptr);
  const double one_count = 2.0 * M_PI / 10000.0;  // gear ratio 1 on every joint of sim.yaml
  const auto ch = by_channel(r.recorded);
  std::map<std::int64_t, exodaq::joint_state_t> joint_by_seq;
  int homed_samples = 0;
  for (const auto* m : ch.at(r.prefix + "EXO_JOINT_STATE")) {
    const auto js = test::decode<exodaq::joint_state_t>(m->data);
    const auto truth = sim->rig().motion().truth(sim->rig().sample_time_s(js.seq));
    for (int j = 0; j < 6; ++j) {
      // Homed or not (before homing the rig powered up at home), the angle
      // is the truth to within one count.
      ASSERT_LE(std::fabs(js.position[j] - truth.position[static_cast<std::size_t>(j)]),
                one_count + 1e-12)
          << "joint " << j << " seq " << js.seq << " homed " << js.homed[j];
    }
    if (std::all_of(js.homed, js.homed + 6, [](bool h) { return h; })) ++homed_samples;
    joint_by_seq[js.seq] = js;
  }
  EXPECT_GT(homed_samples, 0) << "the sim run never homed every joint";
  int valid = 0;
  for (const auto* m : ch.at(r.prefix + "EXO_PALM_POSE")) {
    const auto p = test::decode<exodaq::palm_pose_t>(m->data);
    const auto it = joint_by_seq.find(p.seq);
    if (it == joint_by_seq.end()) continue;
    kinematics::JointVector q(6);
    for (int j = 0; j < 6; ++j) q[j] = it->second.position[j];
    kinematics::RigPose pose;
    kinematics::evaluate_rig(pipeline->chain, pipeline->rig, q, pose);
    for (int k = 0; k < 3; ++k) {
      ASSERT_NEAR(p.position[k], pose.palm_position[k], 1e-9);
      ASSERT_NEAR(p.elbow[k], pose.elbow_position[k], 1e-9);
    }
    for (int k = 0; k < 4; ++k) ASSERT_NEAR(p.orientation[k], pose.palm_quaternion_wxyz[k], 1e-9);
    ASSERT_NEAR(p.shoulder_manipulability, pose.shoulder_manipulability_normalised, 1e-9);
    const bool all_homed =
        std::all_of(it->second.homed, it->second.homed + 6, [](bool h) { return h; });
    if (p.valid) {
      ++valid;
      ASSERT_TRUE(all_homed) << "valid palm pose with an unhomed joint at seq " << p.seq;
    }
  }
  EXPECT_GT(valid, 0);
}

TEST(DaemonRun, LcmLoggerRecordedTheSameMessages) {
  // Two independent UDP subscribers: each may lose datagrams on a loaded
  // machine, so messages are matched by (channel, seq) and every message both
  // have must be byte-identical. What lcm-logger has and the recorder lacks
  // is the recorder's own loss, which its socket's drop count bounds;
  // lcm-logger's own loss (its kernel drops, and LCM's 30-message queue,
  // which nobody counts) is reported.
  const DaemonRecording& r = the_run();
  const auto a = by_channel(r.recorded);
  const auto b = by_channel(r.logged);
  for (const char* name : {"EXO_JOINT_STATE", "EXO_PALM_POSE", "EXO_ENCODER_RAW", "EXO_STATUS"}) {
    const std::string channel = r.prefix + name;
    ASSERT_TRUE(a.count(channel)) << channel;
    ASSERT_TRUE(b.count(channel)) << channel;
    // seq is the 3rd int64 after the 8-byte fingerprint in every exodaq message.
    const auto seq_of = [](const test::RecordedMessage* m) {
      std::int64_t v = 0;
      for (int i = 0; i < 8; ++i) v = (v << 8) | m->data[static_cast<std::size_t>(8 + 16 + i)];
      return v;
    };
    std::map<std::int64_t, const test::RecordedMessage*> logged;
    for (const auto* m : b.at(channel)) logged[seq_of(m)] = m;
    std::int64_t common = 0;
    for (const auto* m : a.at(channel)) {
      const auto it = logged.find(seq_of(m));
      if (it == logged.end()) continue;
      ++common;
      ASSERT_EQ(m->data, it->second->data) << channel << " seq " << it->first;
    }
    const auto recorded = static_cast<std::int64_t>(a.at(channel).size());
    const auto by_logger = static_cast<std::int64_t>(b.at(channel).size());
    EXPECT_GT(common, 0) << channel;
    EXPECT_LE(by_logger - common, r.recorder_drops) << channel << ": the recorder lost more";
    std::printf("%s: %lld recorded, %lld logged, %lld in both\n", channel.c_str(),
                static_cast<long long>(recorded), static_cast<long long>(by_logger),
                static_cast<long long>(common));
  }
}
