// SIGHUP reloads the configuration and calibration at a cycle boundary
// without dropping a cycle; a bad file is rejected and the old values stay. A
// calibration change starts a new segment (issue 25.10: flagged
// SAMPLE_NEW_SEGMENT, logged, in the status); a reload that leaves
// restart-only settings unapplied takes the file's hash out of the status.
#include <gtest/gtest.h>
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <regex>
#include <set>
#include <thread>

#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/drivers/source_factory.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/settings/content_hash.hpp"
#include "exodaq/settings/service_config.hpp"
#include "exodaq/status_t.hpp"
#include "process.hpp"
#include "recording.hpp"
#include "sim_daemon.hpp"
#include "status_wait.hpp"

using namespace exodaq;
using namespace std::chrono_literals;

namespace {
std::string calibration_text(double joint1_offset_deg, bool broken) {
  std::string t = test::read_file(std::string(EXODAQ_SOURCE_DIR) + "/config/calibration/sim.yaml");
  const std::string from = "encoder_offsets_deg: [49, -93, 85, 6, -5, -4]";
  const std::string to = broken ? "encoder_offsets_deg: [49, -93, 85, 6, -5]"
                                : "encoder_offsets_deg: [" + std::to_string(joint1_offset_deg) +
                                      ", -93, 85, 6, -5, -4]";
  t.replace(t.find(from), from.size(), to);
  return t;
}

void write_atomically(const std::string& path, const std::string& text) {
  std::ofstream(path + ".tmp") << text;
  std::rename((path + ".tmp").c_str(), path.c_str());
}
}  // namespace

namespace {
int occurrences(const std::string& text, const std::string& what) {
  int n = 0;
  for (auto at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

// Within 60 s, a hang guard (the daemon writes each line as it is logged).
bool wait_for(const std::string& path, const std::string& text, int count = 1) {
  return test::wait_until([&] { return occurrences(test::read_file(path), text) >= count; },
                          std::chrono::seconds(60));
}

// The seqs from which each reload applied, in order ("new configuration in
// effect from seq S").
std::vector<std::int64_t> reload_seqs(const std::string& log) {
  std::vector<std::int64_t> out;
  const std::regex applied(R"(new configuration in effect from seq (\d+))");
  for (auto it = std::sregex_iterator(log.begin(), log.end(), applied);
       it != std::sregex_iterator(); ++it) {
    out.push_back(std::stoll((*it)[1]));
  }
  return out;
}

constexpr const char* kApplied = "new configuration in effect from seq";
}  // namespace

TEST(Reload, SighupAppliesANewCalibrationWithoutAGapAndRejectsABadOne) {
  const std::string dir = test::make_temp_dir("reload");
  const std::string prefix = test::unique_prefix("reload");
  const std::string cal = dir + "/calibration.yaml";
  const std::string log_path = dir + "/d.err";
  write_atomically(cal, calibration_text(49.0, false));
  const std::string config = test::write_sim_config(dir, prefix, cal);
  // The rig as it started (its motion depends on the index angles): the truth.
  const auto rig_config = settings::load_service_config(config);
  test::Process recorder(
      {EXODAQ_RECORDER, test::kRecordUrl, prefix + "EXO_(JOINT_STATE|STATUS)", dir + "/rec.bin"},
      "", dir + "/rec.err");
  ASSERT_TRUE(test::wait_for_udp_socket(recorder.pid(), 7667));
  test::Process daemon({EXODAQD, "--config", config}, dir + "/d.out", log_path);
  // Joint 1 homes at ~0.95 s of the rig's time; a status after it says so.
  ASSERT_NE(test::wait_for_status(test::kLcmUrl, prefix,
                                  [](const exodaq::status_t& st) {
                                    return st.homing[0] == exodaq::status_t::HOMING_HOMED;
                                  })
                .run_id,
            0)
      << "joint 1 never homed";
  // +1 deg on joint 1, applied before the next file is written.
  write_atomically(cal, calibration_text(50.0, false));
  daemon.signal(SIGHUP);
  ASSERT_TRUE(wait_for(log_path, kApplied)) << test::read_file(log_path);
  // A broken file: rejected, 50 deg stays.
  write_atomically(cal, calibration_text(0.0, true));
  daemon.signal(SIGHUP);
  ASSERT_TRUE(wait_for(log_path, "reload rejected")) << test::read_file(log_path);
  // A storm: alternating good and bad files, 20 reloads 25 ms apart (the
  // daemon may take several SIGHUPs as one: any file it reads is 50 deg or
  // rejected).
  for (int i = 0; i < 20; ++i) {
    write_atomically(cal, calibration_text(50.0, i % 2 == 1));
    daemon.signal(SIGHUP);
    std::this_thread::sleep_for(25ms);
  }
  // A last good reload, and half a second of the rig's time after it.
  write_atomically(cal, calibration_text(50.0, false));
  const int applied_before = occurrences(test::read_file(log_path), kApplied);
  daemon.signal(SIGHUP);
  ASSERT_TRUE(wait_for(log_path, kApplied, applied_before + 1)) << test::read_file(log_path);
  const std::int64_t last_reload = reload_seqs(test::read_file(log_path)).back();
  ASSERT_TRUE(test::wait_for_seq(test::kLcmUrl, prefix, last_reload + 500));
  daemon.signal(SIGTERM);
  ASSERT_EQ(daemon.wait(20s).value_or(-1), 0);
  std::this_thread::sleep_for(300ms);
  const std::int64_t recorder_drops = test::udp_drops(recorder.pid());
  recorder.signal(SIGTERM);
  recorder.wait(5s);

  const std::string log = test::read_file(log_path);
  EXPECT_NE(log.find("reload rejected, previous configuration stays: " + cal), std::string::npos)
      << log;
  EXPECT_NE(log.find("must have 6 numbers, has 5"), std::string::npos);
  const std::vector<std::int64_t> applied = reload_seqs(log);
  ASSERT_FALSE(applied.empty());
  // One calibration change, one new segment: the bad files were rejected and
  // the storm's good ones equal the one in effect.
  std::smatch segment_line;
  ASSERT_TRUE(std::regex_search(
      log, segment_line,
      std::regex("warning new segment from seq ([0-9]+): the calibration or model changed, "
                 "joint shoulder_azimuth moved (-?[0-9.]+) deg from the sample before")))
      << log;
  const std::int64_t segment_seq = std::stoll(segment_line[1]);
  const double logged_jump_deg = std::stod(segment_line[2]);
  EXPECT_EQ(occurrences(log, "new segment from seq"), 1) << log;

  // The joint-1 angle relative to the simulator's truth: 0 before the
  // reload, +1 deg from the seq the first reload applied at, switching once.
  auto source = drivers::make_source(rig_config.source, settings::make_source_context(rig_config));
  const auto* sim = dynamic_cast<const drivers::SimSource*>(source.get());
  ASSERT_NE(sim, nullptr);
  const double count = 2.0 * M_PI / 10000.0;
  const double deg = M_PI / 180.0;
  std::int64_t prev = -1;
  std::int64_t switched_at = -1;
  std::int64_t gaps = 0;
  int before = 0;
  int after_last_reload = 0;
  std::set<std::int64_t> received;
  std::map<std::int64_t, double> joint1_rad;  // joint 1's published angle by seq
  std::vector<std::int64_t> flagged;          // SAMPLE_NEW_SEGMENT
  std::vector<exodaq::status_t> statuses;
  for (const auto& m : test::read_recorder_file(dir + "/rec.bin")) {
    if (m.channel == prefix + "EXO_STATUS") {
      statuses.push_back(test::decode<exodaq::status_t>(m.data));
      continue;
    }
    const auto js = test::decode<exodaq::joint_state_t>(m.data);
    received.insert(js.seq);
    joint1_rad[js.seq] = js.position[0];
    if ((js.sample_flags & exodaq::joint_state_t::SAMPLE_NEW_SEGMENT) != 0) {
      flagged.push_back(js.seq);
    }
    if (prev >= 0) gaps += js.seq - prev - 1;
    prev = js.seq;
    if (!js.homed[0]) continue;
    const double err =
        js.position[0] - sim->rig().motion().truth(sim->rig().sample_time_s(js.seq)).position[0];
    if (switched_at < 0) {
      if (std::fabs(err - deg) <= count + 1e-9) {
        switched_at = js.seq;
      } else {
        ASSERT_LE(std::fabs(err), count + 1e-9) << "seq " << js.seq;
        ++before;
      }
    } else {
      ASSERT_LE(std::fabs(err - deg), count + 1e-9)
          << "the bad file changed the angle at seq " << js.seq;
      after_last_reload += js.seq >= applied.back() ? 1 : 0;
    }
  }
  // The switch is where the daemon says the first reload applied (or the
  // first cycle after it the recorder holds), with homed cycles on either side.
  EXPECT_GT(before, 0);
  EXPECT_GE(switched_at, applied.front());
  EXPECT_LT(switched_at, applied.size() > 1 ? applied[1] : INT64_MAX);
  EXPECT_GT(after_last_reload, 0);
  // No cycle lost to a reload: every gap is a deadline the loop itself
  // reported skipping (a late wake-up on this shared machine), a message its
  // publish path counted as dropped, or a datagram the recorder's socket dropped.
  const test::DaemonTotals t = test::daemon_totals(log);
  EXPECT_LE(gaps, t.overruns + t.publish_failures + recorder_drops)
      << "cycles lost around the reloads";
  // The flag is on the first sample with the new calibration, and only there
  // (when the recorder received it: a datagram the recorder lost is its own).
  EXPECT_LE(flagged.size(), 1U);
  std::printf("new segment at seq %lld (%s), %zu sample(s) flagged\n",
              static_cast<long long>(segment_seq),
              received.count(segment_seq) != 0 ? "received" : "lost on the way", flagged.size());
  if (received.count(segment_seq) != 0) {
    ASSERT_EQ(flagged.size(), 1U);
    EXPECT_EQ(flagged[0], segment_seq);
    EXPECT_EQ(switched_at, segment_seq);
  }
  // The logged jump is the published angle's step from the sample before: the
  // +1 deg of the new offset (checked against the truth above) plus the
  // joint's own motion since that sample. Exact when the recorder holds both
  // (the recorder's socket dropped nothing, so the seq before it in the
  // recording is the daemon's sample before).
  const auto at = joint1_rad.find(segment_seq);
  if (at != joint1_rad.end() && at != joint1_rad.begin() && recorder_drops == 0) {
    const double step_deg = (at->second - std::prev(at)->second) * 180.0 / M_PI;
    EXPECT_NEAR(logged_jump_deg, step_deg, 0.0011) << "sample before: seq " << std::prev(at)->first;
  }
  // The status whose window holds it says so (when received).
  for (const auto& st : statuses) {
    if (st.state == exodaq::status_t::STATE_STOPPING || st.seq < segment_seq) continue;
    if (st.seq - segment_seq < 100) {
      EXPECT_NE(st.message.find("new segment from seq " + std::to_string(segment_seq)),
                std::string::npos)
          << st.message;
    }
    break;
  }
  std::printf(
      "reloads applied at seq %lld ... %lld (%zu), switch seen at %lld; %lld gaps, %lld "
      "overruns, recorder socket drops %lld\n",
      static_cast<long long>(applied.front()), static_cast<long long>(applied.back()),
      applied.size(), static_cast<long long>(switched_at), static_cast<long long>(gaps),
      static_cast<long long>(t.overruns), static_cast<long long>(recorder_drops));
}

namespace {
// The statuses recorded so far.
std::vector<exodaq::status_t> statuses_in(const std::string& file) {
  std::vector<exodaq::status_t> out;
  for (const auto& m : test::read_recorder_file(file))
    out.push_back(test::decode<exodaq::status_t>(m.data));
  return out;
}

bool wait_for_status(const std::string& file, int reloads) {
  return test::wait_until([&] {
    const auto all = statuses_in(file);
    return std::any_of(all.begin(), all.end(),
                       [reloads](const exodaq::status_t& s) { return s.reloads == reloads; });
  });
}
}  // namespace

// Issue 15.4: each setting the reproductions changed is either applied live
// or warned about, on every SIGHUP that carries it, and status_t names the
// configuration and calibration in effect.
TEST(Reload, EveryRestartOnlyChangeIsWarnedOnEverySighupAndStatusShowsTheFilesInEffect) {
  const std::string dir = test::make_temp_dir("reload-truth");
  const std::string prefix = test::unique_prefix("reloadtruth");
  const std::string config = test::write_sim_config(dir, prefix);
  const std::string started_text = test::read_file(config);
  const auto started = settings::load_service_config(config);
  const std::string log = dir + "/d.err";
  test::Process recorder({EXODAQ_RECORDER, test::kRecordUrl, prefix + "EXO_STATUS", dir + "/s.bin"},
                         "", dir + "/rec.err");
  ASSERT_TRUE(wait_for(dir + "/rec.err", "lcm_recorder: ready"));
  test::Process daemon({EXODAQD, "--config", config}, dir + "/d.out", log);
  ASSERT_TRUE(wait_for_status(dir + "/s.bin", 0)) << test::read_file(log);

  // The reproductions: lock_memory, fault_after_ms, status_rate_hz,
  // publish_raw: false, a renamed joint, logging.level.
  const std::string model = dir + "/model.yaml";
  std::ofstream(model) << std::regex_replace(
      test::read_file(std::string(EXODAQ_SOURCE_DIR) + "/config/models/macaque_exo.yaml"),
      std::regex("elbow_flexion"), "elbow");
  std::string text = started_text;
  const auto edit = [&text](const std::string& from, const std::string& to) {
    const auto at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
  };
  edit("lock_memory: false", "lock_memory: true");
  edit("fault_after_ms: 500", "fault_after_ms: 400\n  status_rate_hz: 20");
  edit("publish_raw: true", "publish_raw: false");
  edit("level: info", "level: debug");
  edit("model: " + started.model_path, "model: " + model);
  write_atomically(config, text);
  const std::string changed_sha = settings::sha256_hex(text);

  const std::string warned = "restart-only setting(s) changed, NOT applied until exodaqd restarts";
  daemon.signal(SIGHUP);
  ASSERT_TRUE(wait_for(log, warned)) << test::read_file(log);
  // The same file again: the running values still differ, so it warns again.
  daemon.signal(SIGHUP);
  ASSERT_TRUE(wait_for(log, warned, 2)) << test::read_file(log);
  ASSERT_TRUE(wait_for_status(dir + "/s.bin", 2)) << test::read_file(log);
  // The file as started again: every setting in effect, its hash back.
  write_atomically(config, started_text);
  daemon.signal(SIGHUP);
  ASSERT_TRUE(wait_for_status(dir + "/s.bin", 3)) << test::read_file(log);
  daemon.signal(SIGTERM);
  ASSERT_EQ(daemon.wait(20s).value_or(-1), 0);
  std::this_thread::sleep_for(300ms);
  recorder.signal(SIGTERM);
  recorder.wait(5s);

  const std::string out = test::read_file(log);
  EXPECT_EQ(occurrences(out, "warning reload: 5 " + warned + ": loop.lock_memory (false -> true)"),
            2)
      << out;
  EXPECT_EQ(occurrences(out, "status_t.config_sha256 is empty until then"), 2) << out;
  for (const char* change : {"loop.lock_memory (false -> true)", "loop.fault_after_ms (500 -> 400)",
                             "loop.status_rate_hz (10 -> 20)", "lcm.publish_raw (true -> false)",
                             "model.joint_names[4] (elbow_flexion -> elbow)"}) {
    EXPECT_EQ(occurrences(out, change), 2) << change << "\n" << out;
  }
  // logging.level is live: applied at the first reload, reported once.
  EXPECT_EQ(occurrences(out, "logging.level (info -> debug)"), 1) << out;
  EXPECT_NE(out.find("; 0 live change(s)"), std::string::npos) << out;

  const auto statuses = statuses_in(dir + "/s.bin");
  ASSERT_GT(statuses.size(), 2U);
  const auto& first = statuses.front();
  EXPECT_EQ(first.reloads, 0);
  EXPECT_EQ(first.config_path, config);
  EXPECT_EQ(first.config_sha256, settings::sha256_hex(started_text));
  // Issue 25.10: after a reload that left restart-only settings unapplied no
  // file describes the settings in effect: the hash is empty, the message
  // says why (before: the new file's hash, its status_rate_hz not in effect).
  int pending = 0;
  for (const auto& s : statuses) {
    if (s.reloads != 1 && s.reloads != 2) continue;
    EXPECT_EQ(s.config_path, config);
    EXPECT_EQ(s.config_sha256, "") << "reloads " << s.reloads;
    EXPECT_NE(s.message.find("restart pending: config not in effect as a whole"), std::string::npos)
        << s.message;
    ++pending;
  }
  EXPECT_GT(pending, 0);
  EXPECT_NE(changed_sha, settings::sha256_hex(started_text));
  const auto& last = statuses.back();
  EXPECT_EQ(last.state, static_cast<std::int8_t>(exodaq::status_t::STATE_STOPPING));
  EXPECT_EQ(last.reloads, 3);
  EXPECT_EQ(last.config_path, config);
  EXPECT_EQ(last.config_sha256, settings::sha256_hex(started_text));
  EXPECT_EQ(last.message.find("restart pending"), std::string::npos) << last.message;
  EXPECT_EQ(last.calibration_path, started.calibration_path);
  EXPECT_EQ(last.calibration_sha256,
            settings::sha256_hex(test::read_file(started.calibration_path)));
  EXPECT_EQ(last.calibration_provenance, "hand-written for the simulated rig, 2026-11-22");
  // The restart-only settings kept their running values: the joint names
  // published are the start-up ones, statuses still at 10 Hz. A status closes
  // its window on a multiple of the status period in cycles (1 kHz / 10 Hz:
  // 100, ending at seq 99, 199, ...); at 20 Hz half of them would end at 49, 149, ...
  EXPECT_EQ(last.joint_name[4], "elbow_flexion");
  int after_reloads = 0;
  for (const auto& s : statuses) {
    if (s.state == exodaq::status_t::STATE_STOPPING) continue;  // the final one, any seq
    EXPECT_EQ((s.seq + 1) % 100, 0)
        << "status at seq " << s.seq << " after " << s.reloads << " reload(s)";
    after_reloads += s.reloads > 0 ? 1 : 0;
  }
  EXPECT_GT(after_reloads, 0);
}
