// The task-driven sim (config/sim.yaml's reach-grasp-feed loop) through the
// daemon's pipeline: every joint crosses its index during each trial, so the
// index re-verification runs on all six; a clean run has no LOST_COUNTS, and
// counts lost on joint 2 (which the hand-made curves never brought back to its
// index, docs/robustness.md) are caught at its next index crossing.
#include <gtest/gtest.h>

#include <array>
#include <vector>

#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/sim_task.hpp"
#include "matrix_checks.hpp"
#include "scenario.hpp"
#include "source_sections.hpp"

using exodaq::joint_state_t;
using exodaq::drivers::sim::SimFault;
using exodaq::test::Cycle;
using exodaq::test::run_scenario;
using exodaq::test::ScenarioResult;
using exodaq::test::sim_config;
using exodaq::test::valid_means_right;

namespace {

// Cycles (after `from`) at which joint j's true angle crossed its index.
std::vector<std::int64_t> index_crossings(const ScenarioResult& r, int j, std::int64_t from) {
  const double index = r.config.calibration.encoder_offset_rad[static_cast<std::size_t>(j)];
  std::vector<std::int64_t> out;
  const auto& rig = r.sim->rig();
  double prev = rig.motion().position(rig.sample_time_s(from))[static_cast<std::size_t>(j)];
  for (std::int64_t k = from + 1; k < static_cast<std::int64_t>(r.cycles.size()); ++k) {
    const double q = rig.motion().position(rig.sample_time_s(k))[static_cast<std::size_t>(j)];
    if ((prev < index) != (q < index)) out.push_back(k);
    prev = q;
  }
  return out;
}

double seconds_for_one_trial() {
  const auto cfg = sim_config();
  const exodaq::drivers::sim::SimRig rig(
      exodaq::drivers::sim_options_from(cfg.source, exodaq::settings::make_source_context(cfg)));
  // The second trial starts when the arm is back on the table (stop 4).
  return rig.motion().homing_end_s() + rig.motion().task_plan()->stops.at(4).arrive_s + 0.5;
}

TEST(SimTaskScenario, EveryJointIsReVerifiedAtItsIndexWithoutLostCounts) {
  const auto r = run_scenario(sim_config(), seconds_for_one_trial());
  const auto& s = r.last_status();
  for (int j = 0; j < 6; ++j) {
    EXPECT_EQ(int{s.homing[j]}, int{exodaq::status_t::HOMING_HOMED}) << j;
    // After homing (by 11 s) every joint crosses its index at least twice.
    EXPECT_GE(index_crossings(r, j, 11'000).size(), 2U) << "joint " << j + 1;
    EXPECT_EQ(s.lost_count_events[j], 0) << j;
    EXPECT_EQ(s.glitches[j], 0) << j;
    EXPECT_EQ(s.out_of_range_events[j], 0) << j;
  }
  EXPECT_EQ(r.first([](const Cycle& c) {
    for (int j = 0; j < 6; ++j) {
      if (c.joint.flags[j] & joint_state_t::JOINT_LOST_COUNTS) return true;
    }
    return false;
  }),
            -1);
  EXPECT_EQ(int{s.state}, int{exodaq::status_t::STATE_RUNNING});
  EXPECT_GT(valid_means_right(r, [](std::int64_t, int) { return 0.0; }), 10'000);
}

TEST(SimTaskScenario, LostCountsOnJointTwoAreCaughtAtItsNextIndexCrossing) {
  auto cfg = sim_config();
  // Five counts lost one per cycle from 13 s: each step plausible, only the
  // index can tell.
  SimFault f;
  f.kind = SimFault::Kind::kCountRamp;
  f.start_s = 13.0;
  f.joint = 1;
  f.counts = -5;
  exodaq::test::edit_section<exodaq::drivers::SimSourceSettings>(cfg.source, "sim")
      .faults.push_back(f);
  const auto r = run_scenario(cfg, seconds_for_one_trial());
  const auto& s = r.last_status();
  EXPECT_EQ(s.glitches[1], 0);
  EXPECT_EQ(s.lost_count_events[1], 1);
  const auto crossings = index_crossings(r, 1, 13'005);  // after the five counts are lost
  ASSERT_FALSE(crossings.empty());
  const std::int64_t detected =
      r.first([](const Cycle& c) { return c.joint.flags[1] & joint_state_t::JOINT_LOST_COUNTS; });
  // Flagged in the cycle joint 2 crossed its index (the latch is in that sample).
  EXPECT_EQ(detected, crossings.front());
  for (int j = 0; j < 6; ++j) {
    if (j != 1) {
      EXPECT_EQ(s.lost_count_events[j], 0) << j;
    }
  }
  // Between the loss and the index nothing can know; after it valid is right again.
  EXPECT_GT(valid_means_right(
                r, [](std::int64_t, int) { return 0.0; }, 13'000, detected + 1),
            5'000);
}

}  // namespace
