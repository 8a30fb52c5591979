// Sample time: the monotonic-to-wall mapping never runs backwards, passes NTP
// slews through, detects, counts and slews out steps; clock health from
// ntp_adjtime() thresholds.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "exodaq/core/clock.hpp"

using exodaq::core::ClockHealth;
using exodaq::core::ClockMonitor;
using exodaq::core::ClockPolicy;
using exodaq::core::ClockShared;
using exodaq::core::ClockSource;
using exodaq::core::WallTimeMapper;

namespace {
constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kS = 1'000'000'000;
constexpr std::int64_t kEpoch = 1'790'000'000LL * kS;  // a wall clock in 2026

// Runs the mapper at 1 kHz for `seconds`, with the wall-mono offset given by
// `offset(t)` and re-measured every 100 ms (as ClockMonitor does). Returns
// (utime_us, stepping) per sample and the true wall time in us.
struct Trace {
  std::vector<std::int64_t> utime_us;
  std::vector<std::int64_t> true_us;
  std::vector<bool> stepping;
};

template <typename Offset>
Trace run(WallTimeMapper& m, double seconds, Offset offset) {
  Trace tr;
  std::int64_t generation = 0;
  std::int64_t measured = offset(0);
  const auto n = static_cast<std::int64_t>(seconds * 1000);
  for (std::int64_t k = 0; k < n; ++k) {
    const std::int64_t mono = 5 * kS + k * kMs;
    if (k % 100 == 0) {
      measured = offset(k * kMs);
      ++generation;
    }
    const auto r = m.map(mono, measured, generation);
    tr.utime_us.push_back(r.utime_us);
    tr.true_us.push_back((mono + offset(k * kMs)) / 1000);
    tr.stepping.push_back(r.stepping);
  }
  return tr;
}

void expect_never_backwards(const Trace& tr) {
  for (std::size_t i = 1; i < tr.utime_us.size(); ++i) {
    ASSERT_GE(tr.utime_us[i], tr.utime_us[i - 1]) << "at sample " << i;
  }
}
}  // namespace

TEST(WallTimeMapper, SteadyClockMapsExactly) {
  WallTimeMapper m;
  const auto tr = run(m, 2.0, [](std::int64_t) { return kEpoch; });
  for (std::size_t i = 0; i < tr.utime_us.size(); ++i) {
    ASSERT_EQ(tr.utime_us[i], tr.true_us[i]);
    ASSERT_FALSE(tr.stepping[i]);
  }
  EXPECT_EQ(m.steps(), 0);
}

// The kernel stamps a CAN frame in CLOCK_REALTIME; the driver turns it into
// mono_ns with its own REALTIME - MONOTONIC estimate, the mapper back with the
// clock monitor's. Two estimates differ by their brackets' noise (2 us in the
// QEMU VM): utime is the stamp itself, not the stamp moved by that noise.
TEST(WallTimeMapper, AWallStampThatAgreesIsUtimeItself) {
  WallTimeMapper m;
  constexpr std::int64_t kDriverError = 2'345;  // ns: the driver's estimate is off by this
  std::int64_t last = 0;
  for (std::int64_t k = 0; k < 1000; ++k) {
    const std::int64_t wall = kEpoch + 5 * kS + k * kMs + 123'456;  // the kernel's stamp
    const std::int64_t mono = wall - (kEpoch - kDriverError);
    const auto r = m.map(mono, kEpoch, 1, wall);
    ASSERT_EQ(r.utime_us, wall / 1000) << k;
    ASSERT_FALSE(r.stepping);
    last = r.utime_us;
  }
  // A stamp further off than kStampAgreementNs is not this clock's reading as
  // mapped (a step the monitor has not measured yet): the mapping stands, and
  // utime does not go back from the last stamp.
  const std::int64_t mono = 6 * kS + kDriverError;
  const std::int64_t far = kEpoch + mono + 3 * WallTimeMapper::kStampAgreementNs;
  EXPECT_EQ(m.map(mono, kEpoch, 1, far).utime_us, (mono + kEpoch) / 1000);
  EXPECT_GE((mono + kEpoch) / 1000, last);
  const std::int64_t just_after = 6 * kS + kMs;
  EXPECT_EQ(m.map(just_after, kEpoch, 1).utime_us, (just_after + kEpoch) / 1000)
      << "no wall stamp: the mapping";
}

TEST(WallTimeMapper, NtpSlewOf500ppmPassesThroughUnflagged) {
  WallTimeMapper m;
  // chrony/ntpd slew at most 500 ppm: the offset grows 0.5 ms per second.
  const auto tr = run(m, 5.0, [](std::int64_t t) { return kEpoch + t / 2000; });
  expect_never_backwards(tr);
  for (std::size_t i = 0; i < tr.utime_us.size(); ++i) {
    ASSERT_FALSE(tr.stepping[i]);
    // Within one 100 ms measurement interval of slew (50 us) of the truth.
    ASSERT_LE(std::llabs(tr.utime_us[i] - tr.true_us[i]), 51) << i;
  }
  EXPECT_EQ(m.steps(), 0);
}

class ClockStep : public ::testing::TestWithParam<std::int64_t> {};

TEST_P(ClockStep, IsDetectedCountedFlaggedAndSlewedOutWithoutGoingBackwards) {
  const std::int64_t step = GetParam();
  ClockPolicy policy;  // 2 ms threshold, 10 % step slew
  WallTimeMapper m;
  m.set_policy(policy);
  const std::int64_t at = 1 * kS;
  const auto tr = run(m, 1.0 + 1.0 + std::fabs(static_cast<double>(step)) / kS * 12.0,
                      [&](std::int64_t t) { return kEpoch + (t >= at ? step : 0); });
  expect_never_backwards(tr);
  EXPECT_EQ(m.steps(), 1);
  const auto first = static_cast<std::size_t>(at / kMs);
  // Before the step (and before it is measured): no flag, exact.
  for (std::size_t i = 0; i < first; ++i) ASSERT_FALSE(tr.stepping[i]);
  // The step is seen at the first measurement after it and flagged while
  // utime is further from the wall clock than the threshold.
  ASSERT_TRUE(tr.stepping[first]);
  const double slew_seconds = std::fabs(static_cast<double>(step)) / 1e9 / 0.1;
  const auto settled = first + static_cast<std::size_t>(slew_seconds * 1000.0) + 50;
  ASSERT_LT(settled, tr.utime_us.size());
  for (std::size_t i = first; i < tr.utime_us.size(); ++i) {
    const std::int64_t err_us = std::llabs(tr.utime_us[i] - tr.true_us[i]);
    if (!tr.stepping[i]) {
      // Every unflagged sample is within the threshold of the wall clock.
      ASSERT_LE(err_us, policy.step_threshold_ns / 1000 + 1) << "sample " << i;
    }
  }
  for (std::size_t i = settled; i < tr.utime_us.size(); ++i) {
    ASSERT_FALSE(tr.stepping[i]) << "still flagged at " << i;
    ASSERT_LE(std::llabs(tr.utime_us[i] - tr.true_us[i]), 2) << i;
  }
}

INSTANTIATE_TEST_SUITE_P(PlusMinusOneSecondAndTenMs, ClockStep,
                         ::testing::Values(1 * kS, -1 * kS, 10 * kMs, -10 * kMs));

TEST(WallTimeMapper, BackwardStepAdvancesUtimeAtNinetyPercentRate) {
  WallTimeMapper m;
  const auto tr = run(m, 3.0, [](std::int64_t t) { return kEpoch - (t >= kS ? kS : 0); });
  // During the slew utime advances 0.9 ms per 1 ms sample (10 % step slew).
  const std::size_t i = 1500;
  EXPECT_TRUE(tr.stepping[i]);
  EXPECT_NEAR(static_cast<double>(tr.utime_us[i + 100] - tr.utime_us[i]), 90'000.0, 2.0);
}

namespace {
class FakeClock : public ClockSource {
 public:
  std::int64_t mono = 10 * kS;
  std::int64_t wall = kEpoch;
  int reads = 0;
  ClockHealth health;
  std::int64_t mono_ns() noexcept override {
    // The second of every three brackets is preempted for 50 us.
    mono += (reads++ % 6 == 2) ? 50'000 : 100;
    return mono;
  }
  std::int64_t wall_ns() noexcept override { return wall + mono; }
  ClockHealth ntp_health() noexcept override { return health; }
};
}  // namespace

TEST(ClockMonitor, MeasuresOffsetFromTheTightestBracket) {
  FakeClock clock;
  clock.health.valid = true;
  ClockShared shared;
  ClockMonitor monitor(clock, ClockPolicy{}, shared);
  // wall = kEpoch + mono at the instant of the wall read; the tight brackets
  // put it at their midpoint within 50 ns.
  EXPECT_NEAR(static_cast<double>(shared.offset_ns.load() - kEpoch), 0.0, 100.0);
  EXPECT_GE(shared.offset_generation.load(), 1);
}

TEST(ClockMonitor, SynchronisedFollowsErrorBoundsNotTheUnsyncBit) {
  FakeClock clock;
  ClockShared shared;
  ClockPolicy policy;
  policy.max_est_error_us = 5000;
  policy.max_max_error_us = 100000;
  clock.health.valid = true;
  clock.health.unsync_flag = true;  // chrony without rtcsync leaves it set
  clock.health.est_error_us = 30;
  clock.health.max_error_us = 20000;
  ClockMonitor monitor(clock, policy, shared);
  EXPECT_TRUE(shared.synchronised.load());
  clock.health.max_error_us = 16'000'000;  // the kernel's value when nothing disciplines the clock
  monitor.read_health();
  EXPECT_FALSE(shared.synchronised.load());
  EXPECT_DOUBLE_EQ(shared.max_error_us.load(), 16'000'000.0);
  clock.health.max_error_us = 20000;
  clock.health.est_error_us = 6000;
  monitor.read_health();
  EXPECT_FALSE(shared.synchronised.load());
  clock.health.valid = false;
  clock.health.est_error_us = 0;
  monitor.read_health();
  EXPECT_FALSE(shared.synchronised.load());
}

TEST(ClockMonitor, ReadsTheRealKernelClockState) {
  auto clock = exodaq::core::make_system_clock();
  const ClockHealth h = clock->ntp_health();
  // Read-only ntp_adjtime needs no privilege and must answer on any Linux.
  ASSERT_TRUE(h.valid);
  EXPECT_GE(h.max_error_us, 0.0);
  EXPECT_GE(h.est_error_us, 0.0);
  EXPECT_GE(h.time_state, 0);
  EXPECT_LE(h.time_state, 5);
  const std::int64_t w = clock->wall_ns();
  EXPECT_GT(w, 1'600'000'000LL * kS);  // after 2020
}
