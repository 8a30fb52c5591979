// Scripted faults on the simulated rig, through the real decode path, the
// joint trackers and the status channel (issues 5 and 11): each fault shows
// up on the right joint, in the right flag and counter, clears as documented,
// and no sample is ever published valid when it is wrong.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "exodaq/drivers/sim_backend.hpp"
#include "matrix_checks.hpp"
#include "scenario.hpp"
#include "source_sections.hpp"

using exodaq::joint_state_t;
using exodaq::palm_pose_t;
using exodaq::status_t;
using exodaq::drivers::sim::SimFault;
using exodaq::test::Cycle;
using exodaq::test::kHomedBy;
using exodaq::test::run_scenario;
using exodaq::test::ScenarioResult;
using exodaq::test::sim_config;
using exodaq::test::valid_means_right;

namespace {
std::int64_t count_flag(const ScenarioResult& r, int j, std::int32_t flag) {
  return std::count_if(r.cycles.begin(), r.cycles.end(),
                       [&](const Cycle& c) { return (c.joint.flags[j] & flag) != 0; });
}

std::int64_t count_sample_flag(const ScenarioResult& r, std::int32_t flag) {
  return static_cast<std::int64_t>(exodaq::test::seqs_with(r, flag).size());
}

const int kRunning = status_t::STATE_RUNNING;
const int kHoming = status_t::STATE_HOMING;
const int kDegraded = status_t::STATE_DEGRADED;
const int kFault = status_t::STATE_FAULT;

SimFault fault(SimFault::Kind kind, double at, double dur, int joint = 0, std::int64_t counts = 0) {
  SimFault f;
  f.kind = kind;
  f.start_s = at;
  f.duration_s = dur;
  f.joint = joint;
  f.counts = counts;
  return f;
}
}  // namespace

TEST(SimScenario, HomingJointByJointThenRunning) {
  const auto r = run_scenario(sim_config(), 14.0);
  // Joints home in order as the simulated operator sweeps each through its index.
  std::int64_t previous = -1;
  for (int j = 0; j < 6; ++j) {
    const std::int64_t homed = r.first([&](const Cycle& c) { return c.joint.homed[j]; });
    ASSERT_GT(homed, previous) << "joint " << j;
    previous = homed;
    // Unhomed until then, flagged, and the palm invalid for that reason.
    EXPECT_TRUE(r.cycles[static_cast<std::size_t>(homed - 1)].joint.flags[j] &
                joint_state_t::JOINT_UNHOMED);
    EXPECT_TRUE(r.cycles[static_cast<std::size_t>(homed - 1)].palm.invalid_reason &
                palm_pose_t::INVALID_UNHOMED);
    // Homed exactly on the index: the published angle is delta_theta0 there.
    EXPECT_EQ(
        r.cycles[static_cast<std::size_t>(homed)].joint.flags[j] & joint_state_t::JOINT_UNHOMED, 0);
  }
  EXPECT_LT(previous, static_cast<std::int64_t>(kHomedBy * 1000));
  const auto& s = r.last_status();
  for (int j = 0; j < 6; ++j) EXPECT_EQ(int{s.homing[j]}, int{status_t::HOMING_HOMED});
  EXPECT_EQ(exodaq::test::state_sequence(r), (std::vector<int>{kHoming, kRunning}));
  // The first valid palm pose is the cycle where the last joint homed.
  EXPECT_EQ(r.first([](const Cycle& c) { return c.palm.valid; }), previous);
  EXPECT_GT(valid_means_right(r), 2000);
  EXPECT_EQ(s.missing_samples, 0);
  EXPECT_EQ(s.seq_gaps, 0);
}

TEST(SimScenario, HomingWithBeltGearRatiosPicksTheCrossingNearestHome) {
  auto cfg = sim_config();
  cfg.encoders.joints[3].gear_ratio = 2.5;  // belt-driven joints 4 and 6
  cfg.encoders.joints[5].gear_ratio = 3.0;
  const auto r = run_scenario(cfg, 14.0);
  for (int j = 0; j < 6; ++j) {
    EXPECT_GE(r.first([&](const Cycle& c) { return c.joint.homed[j]; }), 0) << "joint " << j;
  }
  EXPECT_GT(valid_means_right(r), 2000);
  EXPECT_EQ(int{r.last_status().state}, kRunning);
}

TEST(SimScenario, HomingOutsideTheLimitsIsRejected) {
  // The rig's joint-5 index sits at -5 deg, but the daemon was given a
  // calibration saying -120 deg (another rig's file): homing there would put
  // the elbow outside Table 3's [-88.7, 8.1] deg.
  const auto rig = sim_config();
  auto daemon = rig;
  daemon.calibration.encoder_offset_rad[4] = -120.0 * M_PI / 180.0;
  const auto r = run_scenario(daemon, 12.0, &rig);
  const auto& s = r.last_status();
  EXPECT_EQ(int{s.homing[4]}, int{status_t::HOMING_REJECTED});
  EXPECT_GT(count_flag(r, 4, joint_state_t::JOINT_HOMING_REJECTED), 0);
  for (int j = 0; j < 6; ++j) {
    if (j != 4) {
      EXPECT_EQ(int{s.homing[j]}, int{status_t::HOMING_HOMED}) << j;
    }
  }
  // Never valid, always for the unhomed joint.
  EXPECT_EQ(r.first([](const Cycle& c) { return c.palm.valid; }), -1);
  EXPECT_TRUE(r.cycles.back().palm.invalid_reason & palm_pose_t::INVALID_UNHOMED);
  EXPECT_EQ(int{s.state}, kHoming);
}

TEST(SimScenario, CounterGlitchIsFlaggedUntilTheNextIndexThenReHomed) {
  auto cfg = sim_config();
  exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
      .faults.push_back(fault(SimFault::Kind::kCountOffset, 12.0, 0.0, 0, 1000));
  const auto r = run_scenario(cfg, 30.0);
  const std::int64_t at =
      r.first([](const Cycle& c) { return c.joint.flags[0] & joint_state_t::JOINT_GLITCH; });
  EXPECT_EQ(at, 12000);
  const std::int64_t fixed = r.first(
      [](const Cycle& c) { return c.joint.flags[0] & joint_state_t::JOINT_LOST_COUNTS; }, at);
  ASSERT_GT(fixed, at) << "joint 1 never crossed its index again";
  // GLITCH on every sample from the glitch to the correcting index, on joint 1 only.
  for (std::int64_t k = at; k < fixed; ++k) {
    ASSERT_TRUE(r.cycles[static_cast<std::size_t>(k)].joint.flags[0] & joint_state_t::JOINT_GLITCH)
        << k;
    ASSERT_FALSE(r.cycles[static_cast<std::size_t>(k)].palm.valid) << k;
  }
  for (int j = 1; j < 6; ++j) EXPECT_EQ(count_flag(r, j, joint_state_t::JOINT_GLITCH), 0) << j;
  const auto& s = r.last_status();
  EXPECT_EQ(s.glitches[0], 1);
  EXPECT_EQ(s.lost_count_events[0], 1);
  // LOST_COUNTS holds for fault_hold_ms (100 ms) after the correction.
  EXPECT_EQ(count_flag(r, 0, joint_state_t::JOINT_LOST_COUNTS), 100);
  // After the correction the angles are right again (valid poses are checked).
  EXPECT_GT(valid_means_right(r), 10000);
  const auto st = exodaq::test::state_sequence(r);
  EXPECT_EQ(st.front(), kHoming);
  EXPECT_NE(std::find(st.begin(), st.end(), kDegraded), st.end());
  EXPECT_EQ(st.back(), kRunning);
}

TEST(SimScenario, IndexDriftOfFiveCountsIsLostCountsAtTheNextIndex) {
  auto cfg = sim_config();
  // Five counts lost one per cycle: each step is plausible, only the index can tell.
  exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
      .faults.push_back(fault(SimFault::Kind::kCountRamp, 12.0, 0.0, 2, -5));
  const auto r = run_scenario(cfg, 30.0);
  const auto& s = r.last_status();
  EXPECT_EQ(s.glitches[2], 0);
  EXPECT_EQ(s.lost_count_events[2], 1);
  const std::int64_t detected =
      r.first([](const Cycle& c) { return c.joint.flags[2] & joint_state_t::JOINT_LOST_COUNTS; });
  ASSERT_GT(detected, 12000);
  EXPECT_EQ(count_flag(r, 2, joint_state_t::JOINT_LOST_COUNTS), 100);
  for (int j = 0; j < 6; ++j) {
    if (j != 2) {
      EXPECT_EQ(s.lost_count_events[j], 0) << j;
    }
  }
  // Between the loss and the index nothing can know: those samples are
  // excluded from the one-count check (docs/operations.md says so); after the
  // re-homing on the index every valid sample is right again.
  EXPECT_GT(valid_means_right(
                r, [](std::int64_t, int) { return 0.0; }, 12000, detected + 1),
            10000);
}

TEST(SimScenario, FiftyMillisecondsOfSilenceIsMissingStaleThenRecovers) {
  auto cfg = sim_config();
  exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
      .faults.push_back(fault(SimFault::Kind::kSilence, 12.0, 0.050));
  const auto r = run_scenario(cfg, 16.0);
  const auto& s = r.last_status();
  EXPECT_EQ(s.missing_samples, 50);
  EXPECT_EQ(count_sample_flag(r, joint_state_t::SAMPLE_MISSING), 50);
  for (std::int64_t k = 12000; k < 12050; ++k) {
    const auto& c = r.cycles[static_cast<std::size_t>(k)];
    ASSERT_TRUE(c.joint.sample_flags & joint_state_t::SAMPLE_MISSING) << k;
    ASSERT_FALSE(c.palm.valid);
    ASSERT_TRUE(c.palm.invalid_reason & palm_pose_t::INVALID_SAMPLE);
    for (int j = 0; j < 6; ++j) ASSERT_TRUE(c.joint.flags[j] & joint_state_t::JOINT_HELD);
  }
  // STALE after stale_ms (20 ms) without a fresh count: cycles 12020..12049.
  for (int j = 0; j < 6; ++j) {
    EXPECT_EQ(count_flag(r, j, joint_state_t::JOINT_STALE), 30) << j;
    EXPECT_EQ(s.stale_events[j], 1) << j;
  }
  // The first sample after the silence is flagged as following a gap, and good.
  EXPECT_TRUE(r.cycles[12050].joint.sample_flags & joint_state_t::SAMPLE_SEQ_GAP);
  EXPECT_TRUE(r.cycles[12050].palm.valid);
  EXPECT_EQ(s.seq_gaps, 1);
  EXPECT_GT(valid_means_right(r), 4000);
  EXPECT_EQ(exodaq::test::state_sequence(r),
            (std::vector<int>{kHoming, kRunning, kDegraded, kRunning}));
}

TEST(SimScenario, TwoSecondsOfSilenceIsAFaultThenRecoversWithoutReHoming) {
  auto cfg = sim_config();
  exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
      .faults.push_back(fault(SimFault::Kind::kSilence, 12.0, 2.0));
  const auto r = run_scenario(cfg, 18.0);
  const auto& s = r.last_status();
  EXPECT_EQ(s.missing_samples, 2000);
  EXPECT_EQ(exodaq::test::state_sequence(r),
            (std::vector<int>{kHoming, kRunning, kDegraded, kFault, kDegraded, kRunning}));
  // The counters survive the silence: still homed, and right (unwrap is safe
  // for 2 s at these speeds).
  for (int j = 0; j < 6; ++j) EXPECT_EQ(int{s.homing[j]}, int{status_t::HOMING_HOMED});
  EXPECT_TRUE(r.cycles[14000].palm.valid);
  EXPECT_GT(valid_means_right(r), 5000);
}

TEST(SimScenario, TenPercentFrameLossIsCountedAndFlaggedCycleByCycle) {
  auto cfg = sim_config();
  SimFault f = fault(SimFault::Kind::kDrop, 12.0, 3.0);
  f.percent = 10.0;
  exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
      .faults.push_back(f);
  const auto r = run_scenario(cfg, 16.0);
  const auto& s = r.last_status();
  const std::int64_t missing = count_sample_flag(r, joint_state_t::SAMPLE_MISSING);
  EXPECT_EQ(s.missing_samples, missing);
  EXPECT_NEAR(static_cast<double>(missing), 300.0, 60.0);
  for (const auto& c : r.cycles) {
    if (c.joint.sample_flags & joint_state_t::SAMPLE_MISSING) {
      ASSERT_FALSE(c.palm.valid);
    }
  }
  EXPECT_EQ(s.seq_gaps, count_sample_flag(r, joint_state_t::SAMPLE_SEQ_GAP));
  EXPECT_GT(valid_means_right(r), 3000);
}

TEST(SimScenario, LostCountsBFrameIsAPartialSample) {
  auto cfg = sim_config();
  exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
      .faults.push_back(fault(SimFault::Kind::kPartial, 12.0, 0.1));
  const auto r = run_scenario(cfg, 14.0);
  EXPECT_EQ(count_sample_flag(r, joint_state_t::SAMPLE_PARTIAL), 100);
  for (std::int64_t k = 12000; k < 12100; ++k) {
    const auto& c = r.cycles[static_cast<std::size_t>(k)];
    ASSERT_FALSE(c.palm.valid);
    // Channels 3..5 (joints 4-6) held, 0..2 fresh.
    ASSERT_FALSE(c.joint.flags[0] & joint_state_t::JOINT_HELD);
    ASSERT_TRUE(c.joint.flags[4] & joint_state_t::JOINT_HELD);
  }
  for (int j = 3; j < 6; ++j) EXPECT_EQ(r.last_status().stale_events[j], 1);
  EXPECT_GT(valid_means_right(r), 1000);
}

TEST(SimScenario, DuplicatedFramesAreDroppedCountedAndFlagged) {
  auto cfg = sim_config();
  exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
      .faults.push_back(fault(SimFault::Kind::kDuplicate, 12.0, 0.1));
  const auto r = run_scenario(cfg, 14.0);
  EXPECT_EQ(r.last_status().duplicates, 100);
  EXPECT_EQ(count_sample_flag(r, joint_state_t::SAMPLE_DUPLICATE), 100);
  // A dropped duplicate does not spoil the sample: still valid and right.
  EXPECT_TRUE(r.cycles[12050].palm.valid);
  EXPECT_GT(valid_means_right(r), 2000);
}

TEST(SimScenario, BoardErrorBitsInvalidateUntilTheHeartbeatClears) {
  auto cfg = sim_config();
  SimFault f = fault(SimFault::Kind::kBoardError, 12.0, 0.5);
  f.error_bits = 0x01;  // quadrature error
  exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
      .faults.push_back(f);
  const auto r = run_scenario(cfg, 15.0);
  // Heartbeats come every 100 ms: the error shows from the first heartbeat in
  // the window (12.0 s) to the first heartbeat after it (12.5 s).
  const std::int64_t on = r.first(
      [](const Cycle& c) { return c.joint.sample_flags & joint_state_t::SAMPLE_BOARD_ERROR; });
  EXPECT_EQ(on, 12000);
  EXPECT_EQ(count_sample_flag(r, joint_state_t::SAMPLE_BOARD_ERROR), 500);
  for (std::int64_t k = on; k < on + 500; ++k) {
    ASSERT_FALSE(r.cycles[static_cast<std::size_t>(k)].palm.valid);
    ASSERT_TRUE(r.cycles[static_cast<std::size_t>(k)].palm.invalid_reason &
                palm_pose_t::INVALID_SOURCE);
  }
  EXPECT_EQ(r.last_status().board_errors, 0);
  EXPECT_GT(valid_means_right(r), 2000);
}

TEST(SimScenario, AJointDrivenBeyondItsLimitIsOutOfRangeWhileThere) {
  auto cfg = sim_config();
  // The elbow (joint 5) is pushed 900 counts (32 deg) up and back over 2 s,
  // past its 8.1 deg limit + 2 deg margin: on the hand-made curves, whose
  // elbow is near its upper limit at 12 s.
  auto& rig = exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim");
  rig.motion = "curves";
  rig.faults.push_back(fault(SimFault::Kind::kExcursion, 12.0, 2.0, 4, 900));
  const auto r = run_scenario(cfg, 16.0);
  const auto& s = r.last_status();
  EXPECT_EQ(s.out_of_range_events[4], 1);
  const double limit = (8.1 + 2.0) * M_PI / 180.0;
  for (const auto& c : r.cycles) {
    const bool beyond = c.joint.homed[4] && c.joint.position[4] > limit;
    ASSERT_EQ(beyond, (c.joint.flags[4] & joint_state_t::JOINT_OUT_OF_RANGE) != 0) << c.joint.seq;
    if (beyond) {
      ASSERT_FALSE(c.palm.valid);
    }
  }
  EXPECT_GT(count_flag(r, 4, joint_state_t::JOINT_OUT_OF_RANGE), 100);
  const auto* sim = r.sim;
  // Valid samples follow the joint wherever it really went, excursion included.
  const auto excursion_counts = [sim](std::int64_t k, int j) {
    return sim->rig().fault_excursion_rad(j, sim->rig().sample_time_s(k)) / (2.0 * M_PI / 10000.0);
  };
  EXPECT_GT(valid_means_right(r, excursion_counts), 2000);
}

TEST(SimScenario, AStuckChannelIsCaughtWhenItResumes) {
  auto cfg = sim_config();
  // On the hand-made curves: joint 3 moves while its counter is frozen.
  auto& rig = exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim");
  rig.motion = "curves";
  rig.faults.push_back(fault(SimFault::Kind::kStuck, 12.0, 1.0, 2));
  const auto r = run_scenario(cfg, 30.0);
  const auto& s = r.last_status();
  // A frozen counter looks like a joint at rest; when it resumes, the jump is
  // faster than joint 3 can move: a glitch, flagged until the next index.
  EXPECT_EQ(s.glitches[2], 1);
  const std::int64_t at =
      r.first([](const Cycle& c) { return c.joint.flags[2] & joint_state_t::JOINT_GLITCH; });
  EXPECT_EQ(at, 13000);
  EXPECT_EQ(s.lost_count_events[2], 0) << "the counter itself lost nothing";
  // While stuck the angle was wrong but not yet knowable; afterwards valid means right.
  EXPECT_GT(valid_means_right(
                r, [](std::int64_t, int) { return 0.0; }, 12000, 13000),
            10000);
}

TEST(SimScenario, VelocityFollowsTheTruthWithinTheFitsBound) {
  const auto r = run_scenario(sim_config(), 20.0);
  // The 21-sample fit is centred 10 ms back: compare with the truth there.
  // Quantisation noise of the fit is q / (dt sqrt(N (N^2 - 1))) = 0.0065 rad/s (1 sigma).
  std::vector<double> err;
  double worst = 0.0;
  for (std::int64_t k = 1000; k < static_cast<std::int64_t>(r.cycles.size()); ++k) {
    const auto truth_v = r.sim->rig().motion().truth(r.sim->rig().sample_time_s(k - 10)).velocity;
    for (int j = 0; j < 6; ++j) {
      const double e = r.cycles[static_cast<std::size_t>(k)].joint.velocity[j] -
                       truth_v[static_cast<std::size_t>(j)];
      err.push_back(e);
      worst = std::max(worst, std::fabs(e));
    }
  }
  double ss = 0.0;
  for (double e : err) ss += e * e;
  const double rms = std::sqrt(ss / static_cast<double>(err.size()));
  std::printf("velocity error vs truth 10 ms back: rms %.4f rad/s, max %.4f rad/s\n", rms, worst);
  EXPECT_LT(rms, 0.01);
  EXPECT_LT(worst, 0.05);
}
