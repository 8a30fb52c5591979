#pragma once
// Checks shared by the fault-matrix tests (issue 11): what a published cycle
// must satisfy whatever the fault, against the simulator's truth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "scenario.hpp"

namespace exodaq::test {

inline constexpr std::int32_t kJointFaultFlags =
    std::int32_t{joint_state_t::JOINT_UNHOMED} | joint_state_t::JOINT_STALE |
    joint_state_t::JOINT_GLITCH | joint_state_t::JOINT_OUT_OF_RANGE |
    joint_state_t::JOINT_LOST_COUNTS | joint_state_t::JOINT_HOMING_REJECTED |
    joint_state_t::JOINT_BOARD_ERROR;

inline double truth_at(const ScenarioResult& r, std::int64_t seq, int j) {
  return r.sim->rig()
      .motion()
      .truth(r.sim->rig().sample_time_s(seq))
      .position[static_cast<std::size_t>(j)];
}

// Every cycle published once, in order; every palm pose published valid has
// every joint homed, unflagged and within one count of the truth (plus
// `extra_counts(seq, j)` of real motion a fault added, e.g. an excursion).
// Cycles in [skip_from, skip_to) are spared the one-count check (a loss no
// one can know of until the next index). Returns the number of valid poses.
template <typename Extra>
int valid_means_right(const ScenarioResult& r, Extra extra_counts, std::int64_t skip_from = -1,
                      std::int64_t skip_to = -1) {
  int valid = 0;
  for (std::size_t k = 0; k < r.cycles.size(); ++k) {
    const Cycle& c = r.cycles[k];
    const auto seq = static_cast<std::int64_t>(k);
    EXPECT_EQ(c.joint.seq, seq) << "missing cycle " << k;
    EXPECT_EQ(c.palm.seq, seq);
    if (!c.palm.valid) {
      EXPECT_NE(c.palm.invalid_reason, 0) << "invalid without a reason at seq " << k;
      continue;
    }
    ++valid;
    EXPECT_EQ(c.palm.invalid_reason, 0);
    for (int j = 0; j < 6; ++j) {
      if (!c.joint.homed[j] || (c.joint.flags[j] & kJointFaultFlags) != 0) {
        ADD_FAILURE() << "valid palm with joint " << j << " flags " << c.joint.flags[j]
                      << " at seq " << k;
        return valid;
      }
      if (seq >= skip_from && seq < skip_to) continue;
      const double err =
          c.joint.position[j] - truth_at(r, seq, j) - extra_counts(seq, j) * r.rad_per_count(j);
      if (std::fabs(err) > r.rad_per_count(j) + 1e-9) {
        ADD_FAILURE() << "valid sample wrong by " << err / r.rad_per_count(j) << " counts: joint "
                      << j << " seq " << k;
        return valid;
      }
    }
  }
  return valid;
}

inline int valid_means_right(const ScenarioResult& r) {
  return valid_means_right(r, [](std::int64_t, int) { return 0.0; });
}

// The seqs whose joint_state sample_flags have `flag`.
inline std::vector<std::int64_t> seqs_with(const ScenarioResult& r, std::int32_t flag) {
  std::vector<std::int64_t> out;
  for (const Cycle& c : r.cycles) {
    if ((c.joint.sample_flags & flag) != 0) out.push_back(c.joint.seq);
  }
  return out;
}

// The service states in order, consecutive repeats removed.
inline std::vector<int> state_sequence(const ScenarioResult& r) {
  std::vector<int> out;
  for (const auto& s : r.statuses) {
    if (out.empty() || out.back() != s.state) out.push_back(s.state);
  }
  return out;
}

}  // namespace exodaq::test
