// Fault-matrix scenarios that need real processes (issue 11): exodaqd on the
// simulated rig with a separate recorder process subscribed, under CPU stress
// on both cores, and killed with SIGKILL then restarted. A real-process test
// tolerates only the gaps the daemon itself counted and the datagrams the
// recorder's own socket dropped (the kernel counts those); runs last until
// the daemon reaches a seq, not for a time. Nothing here asserts on
// wall-clock speed (lateness is reported, not judged).
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <thread>
#include <vector>

#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/drivers/source_factory.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
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

struct Stream {
  std::vector<exodaq::joint_state_t> joints;  // receive order
  std::vector<std::int64_t> joint_received;   // the recorder's receive mono ns of each joint state
  std::vector<exodaq::palm_pose_t> palms;
  std::vector<exodaq::encoder_raw_t> raws;
  std::vector<exodaq::status_t> statuses;
  std::vector<std::int64_t> run_order;  // run_id of every message, receive order
};

Stream decode_all(const std::vector<test::RecordedMessage>& recorded, const std::string& prefix) {
  Stream s;
  for (const auto& m : recorded) {
    if (m.channel == prefix + "EXO_JOINT_STATE") {
      s.joints.push_back(test::decode<exodaq::joint_state_t>(m.data));
      s.joint_received.push_back(m.time);
      s.run_order.push_back(s.joints.back().run_id);
    } else if (m.channel == prefix + "EXO_ENCODER_RAW") {
      s.raws.push_back(test::decode<exodaq::encoder_raw_t>(m.data));
      s.run_order.push_back(s.raws.back().run_id);
    } else if (m.channel == prefix + "EXO_PALM_POSE") {
      s.palms.push_back(test::decode<exodaq::palm_pose_t>(m.data));
      s.run_order.push_back(s.palms.back().run_id);
    } else if (m.channel == prefix + "EXO_STATUS") {
      s.statuses.push_back(test::decode<exodaq::status_t>(m.data));
      s.run_order.push_back(s.statuses.back().run_id);
    }
  }
  return s;
}

// Cycles missing from a strictly increasing seq stream (asserts the order).
std::int64_t seq_holes(const std::vector<exodaq::joint_state_t>& joints) {
  std::int64_t holes = 0;
  for (std::size_t i = 1; i < joints.size(); ++i) {
    EXPECT_GT(joints[i].seq, joints[i - 1].seq) << "seq not increasing at message " << i;
    holes += joints[i].seq - joints[i - 1].seq - 1;
  }
  return holes;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::ceil(p / 100.0 * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, i == 0 ? 0 : i - 1)];
}

// The sim config on a private UDP port (concurrent tests' daemons do not
// reach this recorder's socket); returns the recorder's URL (4 MiB buffer).
std::string private_port_config(const std::string& dir, const std::string& prefix,
                                std::string& config) {
  const int port = 8668 + static_cast<int>(getpid() % 1000);
  std::string text = test::read_file(test::write_sim_config(dir, prefix));
  const std::string from = ":7667?";
  const auto at = text.find(from);
  if (at == std::string::npos) throw std::runtime_error("no LCM port 7667 in the sim config");
  text.replace(at, from.size(), ":" + std::to_string(port) + "?");
  config = dir + "/exodaqd-private.yaml";
  std::ofstream(config) << text;
  return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0&recv_buf_size=4194304";
}

// The port of a udpm:// URL.
int port_of(const std::string& url) {
  const auto colon = url.rfind(':');
  return std::stoi(url.substr(colon + 1, url.find('?') - colon - 1));
}

bool have(const char* program) {
  return test::run({"sh", "-c", std::string("command -v ") + program}).exit_code == 0;
}

}  // namespace

TEST(ProcessFault, CpuStressOnBothCoresLosesNothingUncountedAndValidStaysRight) {
  if (!have("stress-ng")) GTEST_SKIP() << "stress-ng not installed (scripts/setup installs it)";
  const std::string dir = test::make_temp_dir("stress");
  const std::string prefix = test::unique_prefix("stress");
  std::string config;
  const std::string url = private_port_config(dir, prefix, config);
  test::Process recorder(
      {EXODAQ_RECORDER, url, prefix + "EXO_(JOINT_STATE|PALM_POSE|STATUS)", dir + "/rec.bin"}, "",
      dir + "/rec.err");
  ASSERT_TRUE(test::wait_for_udp_socket(recorder.pid(), port_of(url)));
  std::optional<int> daemon_code;
  std::optional<int> stress_code;
  bool reached = false;
  {
    test::Process daemon({EXODAQD, "--config", config, "--lateness-log", dir + "/late.txt"},
                         dir + "/d.out", dir + "/d.err");
    reached = test::wait_for_seq(url, prefix, 1000);
    // Two CPU hogs, one per core, for the rest of the run (homing included):
    // until seq 14000, 13 s of the rig's time, however long that takes.
    test::Process stress({"stress-ng", "--cpu", "2", "--quiet"}, dir + "/stress.out",
                         dir + "/stress.err");
    reached = reached && test::wait_for_seq(url, prefix, 14'000);
    stress.signal(SIGTERM);
    daemon.signal(SIGTERM);
    daemon_code = daemon.wait(40s);
    stress_code = stress.wait(20s);
  }
  std::this_thread::sleep_for(500ms);
  const std::int64_t drops = test::udp_drops(recorder.pid());
  recorder.signal(SIGTERM);
  recorder.wait(5s);
  ASSERT_TRUE(reached) << "the daemon never reached seq 14000";
  ASSERT_EQ(daemon_code, 0) << test::read_file(dir + "/d.err");
  EXPECT_EQ(stress_code, 0) << test::read_file(dir + "/stress.err");

  const Stream s = decode_all(test::read_recorder_file(dir + "/rec.bin"), prefix);
  ASSERT_FALSE(s.joints.empty());
  ASSERT_FALSE(s.statuses.empty());
  const test::DaemonTotals t = test::daemon_totals(test::read_file(dir + "/d.err"));
  const exodaq::status_t& last = s.statuses.back();
  if (drops == 0) {
    EXPECT_EQ(int{last.state}, int{exodaq::status_t::STATE_STOPPING});
  }
  // Every cycle the subscriber did not get is one the daemon counted as
  // skipped (an overrun) or as not sent (a publish failure), or a datagram
  // the subscriber's socket dropped (the kernel counts those); on the sim a
  // skipped cycle is a board seq gap, never a missing sample.
  const std::int64_t holes = seq_holes(s.joints);
  EXPECT_EQ(s.joints.front().seq, 0);
  EXPECT_LE(holes, t.overruns + t.publish_failures + drops) << "uncounted sequence gaps";
  EXPECT_EQ(static_cast<std::int64_t>(s.joints.size()) + holes, s.joints.back().seq + 1);
  EXPECT_LT(s.joints.back().seq, t.cycles + t.overruns);
  EXPECT_EQ(last.missing_samples, 0);
  EXPECT_LE(last.seq_gaps, last.overruns);

  // Valid means right: every sample of a valid palm pose within one count.
  const auto cfg = settings::load_service_config(config);
  auto source = drivers::make_source(cfg.source, settings::make_source_context(cfg));
  const auto* sim = dynamic_cast<const drivers::SimSource*>(source.get());
  ASSERT_NE(sim, nullptr);
  const double one_count = 2.0 * M_PI / 10000.0;  // gear ratio 1 on every joint of sim.yaml
  std::vector<bool> palm_valid(static_cast<std::size_t>(s.joints.back().seq + 1), false);
  for (const auto& p : s.palms) {
    if (p.valid && p.seq < static_cast<std::int64_t>(palm_valid.size())) {
      palm_valid[static_cast<std::size_t>(p.seq)] = true;
    }
  }
  std::int64_t valid = 0;
  double worst = 0.0;
  for (const auto& js : s.joints) {
    if (!palm_valid[static_cast<std::size_t>(js.seq)]) continue;
    ++valid;
    const auto truth = sim->rig().motion().truth(sim->rig().sample_time_s(js.seq));
    for (int j = 0; j < 6; ++j) {
      const double err = std::fabs(js.position[j] - truth.position[static_cast<std::size_t>(j)]);
      worst = std::max(worst, err / one_count);
      ASSERT_LE(err, one_count + 1e-12) << "joint " << j << " seq " << js.seq;
    }
  }
  // The run homed every joint (the sim homes them by ~10.5 s of its time).
  EXPECT_GT(valid, 0) << "the run never homed every joint";
  for (int j = 0; j < 6; ++j)
    EXPECT_EQ(int{last.homing[j]}, int{exodaq::status_t::HOMING_HOMED}) << "joint " << j + 1;

  // Lateness (reported, not judged): every cycle from the daemon's log, and
  // the 100 ms windows of the status channel.
  std::vector<double> late_us;
  {
    std::ifstream in(dir + "/late.txt");
    for (double ns = 0; in >> ns;) late_us.push_back(ns / 1000.0);
  }
  std::vector<double> win_p50, win_p99, win_max;
  for (const auto& st : s.statuses) {
    if (st.window_cycles <= 0) continue;
    win_p50.push_back(st.lateness_p50_us);
    win_p99.push_back(st.lateness_p99_us);
    win_max.push_back(st.lateness_max_us);
  }
  std::printf(
      "CPU-STRESS: %zu cycles received of %lld seq, %lld holes, %lld overruns (%lld board seq "
      "gaps), missing %lld, publish failures %lld, recorder socket drops %lld; %lld valid poses, "
      "worst error %.2f counts\n",
      s.joints.size(), static_cast<long long>(s.joints.back().seq + 1),
      static_cast<long long>(holes), static_cast<long long>(last.overruns),
      static_cast<long long>(last.seq_gaps), static_cast<long long>(last.missing_samples),
      static_cast<long long>(last.publish_failures), static_cast<long long>(drops),
      static_cast<long long>(valid), worst);
  std::printf(
      "CPU-STRESS: lateness per cycle (%zu cycles): p50 %.1f us, p99 %.1f us, p99.9 %.1f us, "
      "max %.1f us\n",
      late_us.size(), percentile(late_us, 50), percentile(late_us, 99), percentile(late_us, 99.9),
      percentile(late_us, 100));
  std::printf(
      "CPU-STRESS: status windows (%zu): median of p50 %.1f us, worst p99 %.1f us, worst max %.1f "
      "us\n",
      win_p50.size(), percentile(win_p50, 50), percentile(win_p99, 100), percentile(win_max, 100));
}

TEST(ProcessFault, SigkillThenRestartIsANewRunFromSeqZeroUnhomedWithNothingStale) {
  const std::string dir = test::make_temp_dir("sigkill");
  const std::string prefix = test::unique_prefix("sigkill");
  std::string config;
  const std::string url = private_port_config(dir, prefix, config);
  test::Process recorder(
      {EXODAQ_RECORDER, url, prefix + "EXO_(JOINT_STATE|PALM_POSE|STATUS)", dir + "/rec.bin"}, "",
      dir + "/rec.err");
  ASSERT_TRUE(test::wait_for_udp_socket(recorder.pid(), port_of(url)));
  // Joint 1 homes at ~0.95 s of the rig's time: each run until its status
  // says so (and a few hundred cycles more), whatever the machine's speed.
  const auto joint1_homed = [](const exodaq::status_t& st) {
    return st.homing[0] == exodaq::status_t::HOMING_HOMED && st.seq >= 1500;
  };
  std::optional<int> first_code;
  bool first_homed = false;
  {
    test::Process first({EXODAQD, "--config", config}, dir + "/a.out", dir + "/a.err");
    first_homed = test::wait_for_status(url, prefix, joint1_homed).run_id != 0;
    first.signal(SIGKILL);
    first_code = first.wait(5s);
  }
  std::optional<int> second_code;
  bool second_homed = false;
  {
    test::Process second({EXODAQD, "--config", config}, dir + "/b.out", dir + "/b.err");
    // The killed run publishes nothing any more: a status heard now is the new run's.
    second_homed = test::wait_for_status(url, prefix, joint1_homed).run_id != 0;
    second.signal(SIGTERM);
    second_code = second.wait(20s);
  }
  std::this_thread::sleep_for(500ms);
  const std::int64_t drops = test::udp_drops(recorder.pid());
  recorder.signal(SIGTERM);
  recorder.wait(5s);
  ASSERT_TRUE(first_homed) << test::read_file(dir + "/a.err");
  ASSERT_TRUE(second_homed) << test::read_file(dir + "/b.err");
  EXPECT_EQ(first_code, 128 + SIGKILL);
  ASSERT_EQ(second_code, 0) << test::read_file(dir + "/b.err");

  const Stream s = decode_all(test::read_recorder_file(dir + "/rec.bin"), prefix);
  ASSERT_FALSE(s.run_order.empty());
  const std::int64_t run_a = s.run_order.front();
  const std::int64_t run_b = s.run_order.back();
  EXPECT_NE(run_a, run_b) << "the restarted daemon reused the run identifier";
  // Exactly two runs, one after the other: nothing of the killed run arrives
  // after the first message of the new one (nothing stale republished).
  const auto first_b = std::find(s.run_order.begin(), s.run_order.end(), run_b);
  EXPECT_TRUE(
      std::all_of(s.run_order.begin(), first_b, [&](std::int64_t r) { return r == run_a; }));
  EXPECT_TRUE(std::all_of(first_b, s.run_order.end(), [&](std::int64_t r) { return r == run_b; }))
      << "a message of the killed run after the new run started";

  std::vector<exodaq::joint_state_t> a, b;
  for (const auto& js : s.joints) (js.run_id == run_a ? a : b).push_back(js);
  std::vector<exodaq::status_t> sa, sb;
  for (const auto& st : s.statuses) (st.run_id == run_a ? sa : sb).push_back(st);
  ASSERT_FALSE(a.empty());
  ASSERT_FALSE(b.empty());
  ASSERT_FALSE(sa.empty());
  ASSERT_FALSE(sb.empty());
  // Each run's seq starts at 0 and only counted gaps interrupt it: deadlines
  // skipped and messages not sent as its last status counted them (the
  // killed run's: up to that status's seq, and anything after it), or
  // datagrams the recorder's socket dropped.
  EXPECT_EQ(a.front().seq, 0);
  EXPECT_EQ(b.front().seq, 0) << "seq did not restart";
  const test::DaemonTotals tb = test::daemon_totals(test::read_file(dir + "/b.err"));
  const std::int64_t holes_b = seq_holes(b);
  EXPECT_LE(holes_b, tb.overruns + tb.publish_failures + drops);
  const std::int64_t holes_a = seq_holes(a);
  EXPECT_LE(holes_a, sa.back().overruns + sa.back().publish_failures +
                         std::max<std::int64_t>(0, a.back().seq - sa.back().seq) + drops);
  // The killed run had homed joint 1; the new one starts with every joint
  // unhomed and flagged, and homes joint 1 again when the simulated operator
  // sweeps it through its index.
  EXPECT_TRUE(a.back().homed[0]);
  for (int j = 0; j < 6; ++j) {
    EXPECT_FALSE(b.front().homed[j]) << j;
    EXPECT_TRUE(b.front().flags[j] & exodaq::joint_state_t::JOINT_UNHOMED) << j;
  }
  const auto rehomed =
      std::find_if(b.begin(), b.end(), [](const exodaq::joint_state_t& js) { return js.homed[0]; });
  ASSERT_NE(rehomed, b.end()) << "joint 1 never homed again";
  EXPECT_GT(rehomed->seq, 500);  // the sim's operator sweeps it through its index at ~0.95 s
  for (const auto& p : s.palms) {
    if (p.run_id == run_b) {
      ASSERT_FALSE(p.valid) << "valid palm before every joint homed, seq " << p.seq;
    }
  }
  // The new run's counters start from zero.
  EXPECT_TRUE(sb.front().state == exodaq::status_t::STATE_STARTING ||
              sb.front().state == exodaq::status_t::STATE_HOMING)
      << int{sb.front().state};
  EXPECT_LE(sb.front().cycles, sb.front().seq + 1);
  EXPECT_LE(sb.front().overruns, sb.front().seq + 1);
  if (drops == 0) {
    EXPECT_EQ(int{sb.back().state}, int{exodaq::status_t::STATE_STOPPING});
  }
  std::printf(
      "SIGKILL: run A %lld: %zu cycles to seq %lld (joint 1 homed), killed; run B %lld: seq from "
      "%lld, %zu cycles, %lld holes / %lld overruns, joint 1 re-homed at seq %lld, 0 messages "
      "of A after B's first\n",
      static_cast<long long>(run_a), a.size(), static_cast<long long>(a.back().seq),
      static_cast<long long>(run_b), static_cast<long long>(b.front().seq), b.size(),
      static_cast<long long>(holes_b), static_cast<long long>(sb.back().overruns),
      static_cast<long long>(rehomed->seq));
}

// Issue 15: a free-running board (the sim's own clock, 50 ppm slow, a third of
// a period out of phase) and the loop held off for 50 ms (the sim's stall
// fault blocks the read). The board keeps sampling; the daemon publishes every
// sample it took, once, in order: the recorder sees seq 0, 1, 2, … without a
// hole and board seq 0, 1, 2, … (mod 256) without a skip, nothing MISSING, and
// the stall's samples flagged LATE. A sample flagged LATE went out more than a
// period after its instant, so the recorder got it later still.
TEST(ProcessFault, FreeRunningBoardThroughALoopStallLosesNothing) {
  const std::string dir = test::make_temp_dir("freerun");
  const std::string prefix = test::unique_prefix("freerun");
  std::string config;
  const std::string url = private_port_config(dir, prefix, config);
  {
    std::string text = test::read_file(config);
    const auto at = text.find("  sim:\n");
    ASSERT_NE(at, std::string::npos);
    text.insert(at + 7,
                "    board_clock: {free_running: true, drift_ppm: 50, phase: 0.3}\n"
                "    faults: [{kind: stall, at_s: 2.0, for_s: 0.05}]\n");
    std::ofstream(config) << text;
  }
  test::Process recorder(
      {EXODAQ_RECORDER, url, prefix + "EXO_(JOINT_STATE|ENCODER_RAW|STATUS)", dir + "/rec.bin"}, "",
      dir + "/rec.err");
  ASSERT_TRUE(test::wait_for_udp_socket(recorder.pid(), port_of(url)));
  std::optional<int> code;
  bool reached = false;
  {
    test::Process daemon({EXODAQD, "--config", config}, dir + "/d.out", dir + "/d.err");
    // The stall is at 2 s of the board's time: until seq 3000, past it.
    reached = test::wait_for_seq(url, prefix, 3000);
    daemon.signal(SIGTERM);
    code = daemon.wait(30s);
  }
  std::this_thread::sleep_for(500ms);
  const std::int64_t drops = test::udp_drops(recorder.pid());
  recorder.signal(SIGTERM);
  recorder.wait(5s);
  ASSERT_TRUE(reached) << "the daemon never reached seq 3000";
  ASSERT_EQ(code, 0) << test::read_file(dir + "/d.err");

  const Stream s = decode_all(test::read_recorder_file(dir + "/rec.bin"), prefix);
  const auto& joints = s.joints;
  const auto& received = s.joint_received;
  const auto& raws = s.raws;
  const auto& statuses = s.statuses;
  ASSERT_FALSE(joints.empty());
  ASSERT_FALSE(raws.empty());
  ASSERT_FALSE(statuses.empty());
  const exodaq::status_t& last = statuses.back();
  const test::DaemonTotals t = test::daemon_totals(test::read_file(dir + "/d.err"));
  // Every board sample is a cycle, published once, in order: seq 0, 1, 2, ...
  // without a hole but for messages the publish path counted as not sent or
  // datagrams the recorder's socket dropped.
  EXPECT_EQ(joints.front().seq, 0);
  EXPECT_EQ(raws.front().seq, 0);
  const std::int64_t holes = seq_holes(joints);
  EXPECT_LE(holes, t.publish_failures + drops)
      << "a cycle lost between the daemon and the recorder";
  std::int64_t raw_holes = 0;
  for (std::size_t i = 0; i < raws.size(); ++i) {
    if (i > 0) {
      EXPECT_GT(raws[i].seq, raws[i - 1].seq);
      raw_holes += raws[i].seq - raws[i - 1].seq - 1;
    }
    EXPECT_TRUE(raws[i].present) << "seq " << raws[i].seq;
    EXPECT_EQ(raws[i].source_seq, raws[i].seq % 256) << "seq " << raws[i].seq;
  }
  EXPECT_LE(raw_holes, t.publish_failures + drops);
  // The stall's samples LATE: the longest run of LATE samples, counted in
  // seq (a sample the recorder lost inside it does not split it).
  std::int64_t late = 0;
  std::int64_t longest_late_run = 0;
  std::int64_t run_from = -1;
  for (std::size_t i = 0; i < joints.size(); ++i) {
    EXPECT_EQ(joints[i].sample_flags & exodaq::joint_state_t::SAMPLE_MISSING, 0);
    if ((joints[i].sample_flags & exodaq::joint_state_t::SAMPLE_LATE) == 0) {
      run_from = -1;
      continue;
    }
    ++late;
    if (run_from < 0) run_from = joints[i].seq;
    longest_late_run = std::max(longest_late_run, joints[i].seq - run_from + 1);
    EXPECT_GT(received[i] - joints[i].mono_ns, 1'000'000) << "LATE but received on time";
  }
  // The 50 ms stall: the samples it held back, all but the newest over a
  // period old when they went out.
  EXPECT_GE(longest_late_run, 48);
  EXPECT_EQ(last.missing_samples, 0);
  EXPECT_EQ(last.seq_gaps, 0);
  // The daemon's final line: nothing superseded (the sim's queue held every sample).
  const std::string log = test::read_file(dir + "/d.err") + test::read_file(dir + "/d.out");
  EXPECT_NE(log.find(" caught up after a late wake, 0 superseded, 0 late SYNCs; "),
            std::string::npos)
      << log;
  std::printf(
      "FREE-RUNNING: %zu cycles, seq 0..%lld, %lld holes (recorder socket drops %lld, publish "
      "failures %lld), 0 missing; %lld LATE (longest run %lld, the stall); %lld overruns "
      "(deadlines skipped, samples caught up)\n",
      joints.size(), static_cast<long long>(joints.back().seq), static_cast<long long>(holes),
      static_cast<long long>(drops), static_cast<long long>(t.publish_failures),
      static_cast<long long>(late), static_cast<long long>(longest_late_run),
      static_cast<long long>(last.overruns));
}
