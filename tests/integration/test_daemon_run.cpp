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

#include "exodaq/config/service_config.hpp"
#include "exodaq/core/builder.hpp"
#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/drivers/source_factory.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"
#include "process.hpp"
#include "recording.hpp"
#include "sim_daemon.hpp"

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
};

// One run shared by the tests below (a few seconds of real time).
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
    std::this_thread::sleep_for(500ms);  // both subscribed before the first message
    {
      test::Process daemon({EXODAQD, "--config", r.config}, r.dir + "/daemon.out",
                           r.dir + "/daemon.err");
      std::this_thread::sleep_for(12000ms);  // the simulated operator homes joint by joint in ~10 s
      const auto t0 = std::chrono::steady_clock::now();
      daemon.signal(SIGTERM);
      const auto code = daemon.wait(10s);
      r.stop_ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      r.exit_code = code ? *code : -1;
    }
    std::this_thread::sleep_for(500ms);
    recorder.signal(SIGTERM);
    logger.signal(SIGINT);
    recorder.wait(5s);
    logger.wait(5s);
    r.daemon_err = test::read_file(r.dir + "/daemon.err");
    r.recorded = test::read_recorder_file(r.dir + "/recorder.bin");
    r.logged = test::read_lcm_log(r.dir + "/run.lcm");
    std::printf("run dir %s: %zu recorded, %zu logged, SIGTERM to exit %.1f ms\n", r.dir.c_str(),
                r.recorded.size(), r.logged.size(), r.stop_ms);
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
  EXPECT_EQ(static_cast<int>(last.state), int{exodaq::status_t::STATE_STOPPING});
  EXPECT_EQ(last.rig, "sim-macaque");
  EXPECT_NE(r.daemon_err.find("SIGTERM received"), std::string::npos);
}

TEST(DaemonRun, SequenceRateAndTimestampsHold) {
  const DaemonRecording& r = the_run();
  const auto ch = by_channel(r.recorded);
  const auto& joints = ch.at(r.prefix + "EXO_JOINT_STATE");
  ASSERT_GT(joints.size(), 3000u);
  const auto status = test::decode<exodaq::status_t>(ch.at(r.prefix + "EXO_STATUS").back()->data);
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
  // >= 99.9 % of the cycles the daemon ran reached the subscriber.
  EXPECT_GE(static_cast<double>(joints.size()), 0.999 * static_cast<double>(status.cycles))
      << joints.size() << " of " << status.cycles;
  // Every seq gap the subscriber saw is a deadline the daemon counted as
  // skipped, apart from datagrams UDP itself may drop (within the 0.1 %).
  EXPECT_LE(gaps - status.overruns,
            static_cast<std::int64_t>(0.001 * static_cast<double>(status.cycles)))
      << "uncounted sequence gaps";
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
  int matched = 0;
  for (const auto* m : ch.at(r.prefix + "EXO_PALM_POSE")) {
    const auto p = test::decode<exodaq::palm_pose_t>(m->data);
    const auto it = stamps.find(p.seq);
    if (it == stamps.end()) continue;
    ASSERT_EQ(p.utime, it->second.first);
    ASSERT_EQ(p.mono_ns, it->second.second);
    ++matched;
  }
  EXPECT_GT(matched, 3000);
  std::printf("cycles %lld, received %zu, gaps %lld, overruns %lld, rate %.3f Hz\n",
              static_cast<long long>(status.cycles), joints.size(), static_cast<long long>(gaps),
              static_cast<long long>(status.overruns), rate);
}

TEST(DaemonRun, AnglesMatchTheSimulatorTruthAndPalmMatchesForwardKinematics) {
  const DaemonRecording& r = the_run();
  const auto cfg = config::load_service_config(r.config);
  const auto pipeline = core::make_pipeline_config(cfg);
  auto source = drivers::make_source(cfg.source, config::make_source_context(cfg));
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
    kin::JointVector q(6);
    for (int j = 0; j < 6; ++j) q[j] = it->second.position[j];
    kin::RigPose pose;
    kin::evaluate_rig(pipeline->chain, pipeline->rig, q, pose);
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
  // Two independent UDP subscribers: each may lose a datagram under load, so
  // messages are matched by (channel, seq); every message both have must be
  // byte-identical and each must have >= 99.9 % of the other's.
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
    std::size_t common = 0;
    for (const auto* m : a.at(channel)) {
      const auto it = logged.find(seq_of(m));
      if (it == logged.end()) continue;
      ++common;
      ASSERT_EQ(m->data, it->second->data) << channel << " seq " << it->first;
    }
    EXPECT_GE(static_cast<double>(common), 0.999 * static_cast<double>(a.at(channel).size()))
        << channel;
    EXPECT_GE(static_cast<double>(common), 0.999 * static_cast<double>(b.at(channel).size()))
        << channel;
  }
}
