// JointTracker: unwrap, homing (seed 000 eq. 4), faults, velocity.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "exodaq/core/joint_tracker.hpp"

using exodaq::core::HomingState;
using exodaq::core::JointEvent;
using exodaq::core::JointInput;
using exodaq::core::JointTracker;
using exodaq::core::JointTrackerConfig;
namespace jf = exodaq::core::joint_flag;

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr std::int64_t kMs = 1'000'000;

JointTrackerConfig base_config() {
  JointTrackerConfig c;
  c.channel = 0;
  c.direction = 1;
  c.counts_per_rev = 10000;
  c.gear_ratio = 1.0;
  c.offset_rad = 30.0 * kPi / 180.0;
  c.home_rad = 45.0 * kPi / 180.0;
  c.lower_rad = -50.5 * kPi / 180.0;
  c.upper_rad = 140.5 * kPi / 180.0;
  c.limit_margin_rad = 2.0 * kPi / 180.0;
  c.max_speed_rad_s = 0.64 * 1.5;
  c.index_tolerance_counts = 2;
  c.stale_ns = 20 * kMs;
  c.fault_hold_ns = 100 * kMs;
  return c;
}

// Protocol v1's input: 16-bit positions, 8-bit sequence (-1: none).
JointInput v1_input(std::int64_t t_ns, int board_seq, bool fresh, std::int64_t count,
                    bool index = false, std::int64_t index_count = 0) {
  JointInput in;
  in.mono_ns = t_ns;
  in.seq = board_seq;
  in.seq_modulus = 256;
  in.fresh = fresh;
  in.position = count & 0xFFFF;
  in.modulus = 65536;
  in.index_valid = index;
  in.index_position = index_count & 0xFFFF;
  return in;
}

// Feeds `count` (unwrapped, any int64) as its low 16 bits.
JointEvent feed(JointTracker& t, std::int64_t ms, std::int64_t count, bool index = false,
                std::int64_t index_count = 0) {
  return t.update(v1_input(ms * kMs, -1, true, count, index, index_count));
}
}  // namespace

TEST(JointTracker, UnhomedAngleIsHomePosturePlusTravelSincePowerUp) {
  JointTracker t(base_config());
  feed(t, 0, 1000);
  EXPECT_FALSE(t.reading().homed);
  EXPECT_TRUE(t.reading().flags & jf::kUnhomed);
  EXPECT_DOUBLE_EQ(t.reading().position_rad, 45.0 * kPi / 180.0);
  feed(t, 1, 1001);
  EXPECT_NEAR(t.reading().position_rad, 45.0 * kPi / 180.0 + 2 * kPi / 10000, 1e-15);
  EXPECT_EQ(t.reading().count, 1001);
}

TEST(JointTracker, UnwrapsAcrossThe16BitBoundaryBothWays) {
  auto c = base_config();
  c.max_speed_rad_s = 100.0;  // no glitch for the big steps below
  JointTracker t(c);
  feed(t, 0, 65530);
  feed(t, 1, 65540);  // sent as 4
  EXPECT_EQ(t.reading().count, 65540);
  feed(t, 2, 65530);
  feed(t, 3, 65520);
  EXPECT_EQ(t.reading().count, 65520);
  // a step of 32767 counts is still unwrapped forwards
  feed(t, 100, 65520 + 32767);
  EXPECT_EQ(t.reading().count, 65520 + 32767);
}

TEST(JointTracker, HomesOnIndexWithDeltaTheta0PlusThetaR) {
  JointTracker t(base_config());
  feed(t, 0, 5000);
  // The joint moves down by 15 deg (4166.67 counts) to the index at 30 deg.
  const std::int64_t index_count = 5000 - 4167;
  EXPECT_EQ(feed(t, 1, index_count - 3, true, index_count), JointEvent::kHomed);
  EXPECT_TRUE(t.reading().homed);
  EXPECT_EQ(t.reading().homing, HomingState::kHomed);
  EXPECT_EQ(t.reading().flags & jf::kUnhomed, 0u);
  // theta = delta_theta0 + theta_R: 3 counts below the index.
  EXPECT_NEAR(t.reading().position_rad, 30.0 * kPi / 180.0 - 3 * 2 * kPi / 10000, 1e-12);
  feed(t, 2, index_count + 100);
  EXPECT_NEAR(t.reading().position_rad, 30.0 * kPi / 180.0 + 100 * 2 * kPi / 10000, 1e-12);
  EXPECT_EQ(t.counters().homings, 1);
}

TEST(JointTracker, NegativeDirectionInvertsThetaR) {
  auto c = base_config();
  c.direction = -1;
  JointTracker t(c);
  feed(t, 0, 0);
  feed(t, 1, 10, true, 10);
  feed(t, 2, 0);
  EXPECT_NEAR(t.reading().position_rad, 30.0 * kPi / 180.0 + 10 * 2 * kPi / 10000, 1e-12);
}

TEST(JointTracker, GearRatioPicksTheCrossingNearestTheEstimate) {
  // Belt joint: 2.5 encoder revolutions per joint revolution, the index every 144 deg.
  auto c = base_config();
  c.gear_ratio = 2.5;
  c.offset_rad = 0.0;
  c.home_rad = 150.0 * kPi / 180.0;  // power-up near the crossing at 144 deg
  c.lower_rad = -160.0 * kPi / 180.0;
  c.upper_rad = 160.0 * kPi / 180.0;
  JointTracker t(c);
  feed(t, 0, 0);
  // 6 deg down at the joint = 6/360 * 25000 counts = 416.67 counts.
  feed(t, 1, -417, true, -417);
  ASSERT_TRUE(t.reading().homed);
  EXPECT_NEAR(t.reading().position_rad, 144.0 * kPi / 180.0, 1e-12);
  // One encoder revolution further down is the crossing at 0 deg.
  auto cfg2 = c;
  JointTracker t2(cfg2);
  feed(t2, 0, 0);
  feed(t2, 1, -417, true, -417);
  feed(t2, 2, -417 - 10000);
  EXPECT_NEAR(t2.reading().position_rad, 0.0, 1e-9);
}

TEST(JointTracker, RejectsAHomingOutsideTheLimits) {
  auto c = base_config();
  c.offset_rad = 170.0 * kPi / 180.0;  // index beyond the 140.5 deg limit + margin
  c.home_rad = 170.0 * kPi / 180.0;
  JointTracker t(c);
  feed(t, 0, 0);
  EXPECT_EQ(feed(t, 1, 0, true, 0), JointEvent::kHomingRejected);
  EXPECT_FALSE(t.reading().homed);
  EXPECT_EQ(t.reading().homing, HomingState::kRejected);
  EXPECT_TRUE(t.reading().flags & jf::kHomingRejected);
  EXPECT_EQ(t.counters().rejected_homings, 1);
}

TEST(JointTracker, IndexDriftBeyondToleranceIsLostCountsAndReHomes) {
  auto c = base_config();
  c.max_speed_rad_s = 10000.0;
  JointTracker t(c);
  feed(t, 0, 0, true, 0);  // homed at count 0 = 30 deg
  ASSERT_TRUE(t.reading().homed);
  // One revolution later the index shows up 5 counts early: 5 counts lost.
  std::int64_t ms = 1;
  for (std::int64_t k = 1; k <= 10; ++k) feed(t, ms++, k * 999);
  EXPECT_EQ(feed(t, ms++, 9995, true, 9995), JointEvent::kLostCounts);
  EXPECT_EQ(t.counters().lost_count_events, 1);
  EXPECT_EQ(t.counters().last_index_drift_counts, -5);
  EXPECT_TRUE(t.reading().flags & jf::kLostCounts);
  // Re-homed on that index: it is the crossing at 30 deg + 360 deg.
  EXPECT_NEAR(t.reading().position_rad, (30.0 + 360.0) * kPi / 180.0, 1e-9);
  // Within tolerance (2 counts) is no event.
  feed(t, ms++, 9995 + 10000 - 2);
  EXPECT_EQ(feed(t, ms++, 9995 + 10000 + 2, true, 9995 + 10000 + 2), JointEvent::kNone);
  EXPECT_EQ(t.counters().lost_count_events, 1);
  // The flag clears after fault_hold (100 ms).
  feed(t, ms + 150, 9995 + 10000 + 2);
  EXPECT_EQ(t.reading().flags & jf::kLostCounts, 0u);
}

TEST(JointTracker, GlitchIsFlaggedUntilTheNextIndexVerifies) {
  JointTracker t(base_config());
  feed(t, 0, 0, true, 0);
  feed(t, 1, 1);
  // 1000 counts in 1 ms is 628 rad/s: a glitch.
  EXPECT_EQ(feed(t, 2, 1001), JointEvent::kGlitch);
  EXPECT_EQ(t.counters().glitches, 1);
  for (int ms = 3; ms < 500; ++ms) {
    feed(t, ms, 1001);
    ASSERT_TRUE(t.reading().flags & jf::kGlitch) << "cleared at " << ms;
  }
  // The index arrives where the glitched count says it should not: corrected.
  EXPECT_EQ(feed(t, 500, 1001, true, 1000), JointEvent::kLostCounts);
  EXPECT_EQ(t.reading().flags & jf::kGlitch, 0u);
}

TEST(JointTracker, MaxPlausibleSpeedIsNotAGlitch) {
  JointTracker t(base_config());
  feed(t, 0, 0);
  // 0.96 rad/s x 1 ms = 1.53 counts per ms: 2 counts pass (quantisation), 3 do not.
  EXPECT_EQ(feed(t, 1, 2), JointEvent::kNone);
  EXPECT_EQ(feed(t, 2, 5), JointEvent::kGlitch);
}

namespace {
// A board that stalled and then sent its queued cycles back to back: the
// receive stamps are 50 us apart, the board's cycles 1 ms. The joint moves at
// 0.9 of its bound throughout (1.38 counts per board cycle).
struct Burst {
  std::int64_t received_ns;
  int board_seq;
  std::int64_t count;
};
std::vector<Burst> stalled_then_burst() {
  std::vector<Burst> b;
  for (int k = 0; k < 40; ++k) {
    const std::int64_t rx = k < 20 ? k * kMs : 30 * kMs + (k - 20) * 50'000;
    b.push_back({rx, (250 + k) % 256, std::llround(k * 1.38)});  // wraps 255 -> 0
  }
  return b;
}

// A fresh count (no index, no board error) received at `received_ns`.
JointEvent count_at(JointTracker& t, std::int64_t received_ns, int board_seq, std::int64_t count) {
  return t.update(v1_input(received_ns, board_seq, true, count));
}

JointTrackerConfig board_config(std::int64_t board_period_ns = kMs) {
  auto c = base_config();
  c.board_period_ns = board_period_ns;
  return c;
}
}  // namespace

TEST(JointTracker, ABoardsQueuedCyclesArrivingTogetherAreNoGlitch) {
  JointTracker t(board_config());
  for (const Burst& s : stalled_then_burst()) {
    count_at(t, s.received_ns, s.board_seq, s.count);
    ASSERT_EQ(t.reading().flags & jf::kGlitch, 0u) << "board cycle " << s.board_seq;
  }
  EXPECT_EQ(t.counters().glitches, 0);
  // Without the board's cycles (period unknown) the same stream is judged by
  // its receive stamps alone: the burst looks 20x too fast.
  JointTracker by_stamps(board_config(0));
  for (const Burst& s : stalled_then_burst())
    count_at(by_stamps, s.received_ns, s.board_seq, s.count);
  EXPECT_GT(by_stamps.counters().glitches, 0);
}

TEST(JointTracker, ABoardCycleGivesNoMoreTimeThanItsPeriod) {
  JointTracker t(board_config());
  count_at(t, 0, 10, 0);
  // Next board cycle, stamped 1 ms later: 1000 counts is still a glitch.
  EXPECT_EQ(count_at(t, kMs, 11, 1000), JointEvent::kGlitch);
}

TEST(JointTracker, AnOlderOrRepeatedBoardCycleGivesOnlyTheReceiveInterval) {
  for (const int seq : {10, 9, 138}) {  // same, older, 128 ahead (= 128 behind)
    JointTracker t(board_config());
    count_at(t, 0, 10, 0);
    // 0.96 rad/s over the 1 ms receive interval: 2 counts pass, 3 do not.
    EXPECT_EQ(count_at(t, kMs, seq, 2), JointEvent::kNone) << seq;
    EXPECT_EQ(count_at(t, 2 * kMs, seq, 5), JointEvent::kGlitch) << seq;
  }
}

TEST(JointTracker, ALongBoardGapAllowsTheTravelOfItsCycles) {
  JointTracker t(board_config());
  count_at(t, 0, 0, 0);
  // 100 board cycles later (frames lost), received 1 ms after the last one:
  // 100 ms at 0.96 rad/s is 152.8 counts.
  EXPECT_EQ(count_at(t, kMs, 100, 150), JointEvent::kNone);
  EXPECT_EQ(count_at(t, 2 * kMs, 200, 150 + 160), JointEvent::kGlitch);
}

TEST(JointTracker, StaleAfterConfiguredTimeWithoutAFreshCount) {
  JointTracker t(base_config());
  feed(t, 0, 0);
  for (int ms = 1; ms <= 20; ++ms) {
    EXPECT_EQ(t.update(v1_input(ms * kMs, -1, false, 0)), JointEvent::kNone);
    EXPECT_TRUE(t.reading().flags & jf::kHeld);
    EXPECT_EQ(t.reading().flags & jf::kStale, 0u);
  }
  EXPECT_EQ(t.update(v1_input(21 * kMs, -1, false, 0)), JointEvent::kStale);
  EXPECT_TRUE(t.reading().flags & jf::kStale);
  EXPECT_EQ(t.counters().stale_events, 1);
  feed(t, 22, 0);
  EXPECT_EQ(t.reading().flags & (jf::kStale | jf::kHeld), 0u);
}

TEST(JointTracker, OutOfRangeBeyondLimitPlusMargin) {
  auto c = base_config();
  c.max_speed_rad_s = 1000.0;
  JointTracker t(c);
  feed(t, 0, 0, true, 0);  // 30 deg
  // 140.5 + 2 = 142.5 deg limit: 112.5 deg above the index is 3125 counts.
  feed(t, 1, 3124);
  EXPECT_EQ(t.reading().flags & jf::kOutOfRange, 0u);
  EXPECT_EQ(feed(t, 2, 3127), JointEvent::kOutOfRange);
  EXPECT_TRUE(t.reading().flags & jf::kOutOfRange);
  feed(t, 3, 3130);
  EXPECT_EQ(t.counters().out_of_range_events, 1);
  feed(t, 4, 3000);
  EXPECT_EQ(t.reading().flags & jf::kOutOfRange, 0u);
}

TEST(JointTracker, VelocityFitOfAConstantSpeedIsExactToQuantisation) {
  auto c = base_config();
  c.velocity_window = 21;
  JointTracker t(c);
  const double speed = 0.5;  // rad/s
  const double counts_per_rad = 10000 / (2 * kPi);
  for (int ms = 0; ms < 100; ++ms) {
    const auto count = static_cast<std::int64_t>(std::floor(speed * ms * 1e-3 * counts_per_rad));
    feed(t, ms, count);
  }
  // Quantisation noise of a 21-sample fit: q / (dt sqrt(N(N^2-1))) = 6.5e-3 rad/s.
  EXPECT_NEAR(t.reading().velocity_rad_s, speed, 0.02);
}

TEST(JointTracker, ReconfigureKeepsHomingAndAppliesNewOffset) {
  JointTracker t(base_config());
  feed(t, 0, 0, true, 0);
  auto c = base_config();
  c.offset_rad = 31.85 * kPi / 180.0;
  t.reconfigure(c);
  feed(t, 1, 0);
  EXPECT_TRUE(t.reading().homed);
  EXPECT_NEAR(t.reading().position_rad, 31.85 * kPi / 180.0, 1e-12);
}

namespace {
// The velocity fit as it was computed before the running sums (two passes in
// double over the window, relative to the newest sample): the reference the
// exact integer fit is held to.
double two_pass_slope(const std::vector<std::int64_t>& t, const std::vector<std::int64_t>& c) {
  const std::int64_t tn = t.back();
  const std::int64_t cn = c.back();
  double st = 0.0;
  double sc = 0.0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    st += static_cast<double>(t[i] - tn) * 1e-9;
    sc += static_cast<double>(c[i] - cn);
  }
  const double n = static_cast<double>(t.size());
  double stt = 0.0;
  double stc = 0.0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    const double dt = static_cast<double>(t[i] - tn) * 1e-9 - st / n;
    const double dc = static_cast<double>(c[i] - cn) - sc / n;
    stt += dt * dt;
    stc += dt * dc;
  }
  return stt > 0.0 ? stc / stt : 0.0;
}
}  // namespace

// The running integer sums give the two-pass fit's velocity to within a few
// ulp over a long jittered, accelerating run (window full, anchors far behind).
TEST(JointTracker, VelocityFromRunningSumsMatchesTheTwoPassFit) {
  auto c = base_config();
  c.velocity_window = 21;
  c.max_speed_rad_s = 100.0;
  JointTracker t(c);
  const double rad_per_count = 2 * kPi / 10000;
  std::vector<std::int64_t> ts, cs;
  std::uint64_t rng = 12345;
  double worst = 0.0;
  for (int k = 0; k < 20'000; ++k) {
    rng = rng * 6364136223846793005ULL + 1442695040888963407ULL;
    const std::int64_t jitter = static_cast<std::int64_t>((rng >> 33) % 200'000) - 100'000;
    const std::int64_t tk = 5'000'000'000'000LL + k * kMs + jitter;  // ~83 min after boot
    const double s = k * 1e-3;
    const auto count =
        static_cast<std::int64_t>(std::floor(3000.0 * std::sin(0.7 * s) + 40.0 * s * s));
    t.update(v1_input(tk, -1, true, count));
    ts.push_back(tk);
    cs.push_back(count);
    if (ts.size() > 21) {
      ts.erase(ts.begin());
      cs.erase(cs.begin());
    }
    if (ts.size() < 2) continue;
    const double expected = two_pass_slope(ts, cs) * rad_per_count;
    const double got = t.reading().velocity_rad_s;
    const double err = std::abs(got - expected) / std::max(1.0, std::abs(expected));
    worst = std::max(worst, err);
  }
  EXPECT_LT(worst, 1e-12);
}

// Exact data give the exact slope: 3 counts per ms is 3000 counts/s.
TEST(JointTracker, VelocityOfAnExactLineIsExact) {
  auto c = base_config();
  c.max_speed_rad_s = 100.0;
  JointTracker t(c);
  for (int ms = 0; ms < 50; ++ms) feed(t, ms, 3 * ms);
  EXPECT_EQ(t.reading().velocity_rad_s, 3000.0 * (2 * kPi / 10000));
}

// A reload that shrinks the window keeps the newest samples: the same
// velocity as a tracker that only ever saw those.
TEST(JointTracker, ShrinkingTheVelocityWindowKeepsTheNewestSamples) {
  auto c = base_config();
  c.max_speed_rad_s = 100.0;
  c.velocity_window = 21;
  JointTracker a(c);
  auto counts = [](int ms) { return static_cast<std::int64_t>(ms * ms / 7); };
  for (int ms = 0; ms < 40; ++ms) feed(a, ms, counts(ms));
  c.velocity_window = 5;
  a.reconfigure(c);
  feed(a, 40, counts(40));
  JointTracker b(c);
  for (int ms = 0; ms <= 40; ++ms) feed(b, ms, counts(ms));
  EXPECT_EQ(a.reading().velocity_rad_s, b.reading().velocity_rad_s);
  c.velocity_window = 9;  // and growing keeps all it has
  a.reconfigure(c);
  b.reconfigure(c);
  for (int ms = 41; ms < 45; ++ms) {
    feed(a, ms, counts(ms));
    feed(b, ms, counts(ms));
  }
  EXPECT_EQ(a.reading().velocity_rad_s, b.reading().velocity_rad_s);
  EXPECT_NE(a.reading().velocity_rad_s, 0.0);
}

namespace {
// A fresh position of a channel that wraps at `modulus` (0: never).
JointInput wrapped_input(std::int64_t ms, std::int64_t position, std::int64_t modulus,
                         bool absolute = false) {
  JointInput in;
  in.mono_ns = ms * kMs;
  in.fresh = true;
  in.position = position;
  in.modulus = modulus;
  in.absolute = absolute;
  return in;
}
constexpr double kRadPerCount = 2 * kPi / 10000;
}  // namespace

TEST(JointTracker, UnwrapsAtTheSourcesStatedModulus) {
  constexpr std::int64_t k32 = std::int64_t{1} << 32;
  JointTracker t(base_config());
  t.update(wrapped_input(0, k32 - 1, k32));
  EXPECT_EQ(t.reading().count, k32 - 1);
  t.update(wrapped_input(1, 0, k32));  // one count forwards across the 32-bit wrap
  EXPECT_EQ(t.reading().count, k32);
  t.update(wrapped_input(2, k32 - 1, k32));
  EXPECT_EQ(t.reading().count, k32 - 1);
  EXPECT_EQ(t.reading().flags & jf::kGlitch, 0u);

  JointTracker whole(base_config());  // modulus 0: the position is the count
  whole.update(wrapped_input(0, -70000, 0));
  whole.update(wrapped_input(1, -69999, 0));
  EXPECT_EQ(whole.reading().count, -69999);
}

TEST(JointTracker, AnUnwrapIsAmbiguousOnceHalfTheModulusCouldHavePassed) {
  // 0.96 rad/s is 1528 counts/s: 1.4 s without a count could be 2139 counts,
  // more than half of a 12-bit modulus, far less than half of 16 bits.
  JointTracker small(base_config());
  small.update(wrapped_input(0, 100, 4096));
  EXPECT_EQ(small.update(wrapped_input(1400, 110, 4096)), JointEvent::kUnwrapAmbiguous);
  EXPECT_NE(small.reading().flags & jf::kGlitch, 0u);

  JointTracker wide(base_config());
  wide.update(wrapped_input(0, 100, 65536));
  EXPECT_EQ(wide.update(wrapped_input(1400, 110, 65536)), JointEvent::kNone);
  EXPECT_EQ(wide.reading().flags & jf::kGlitch, 0u);

  JointTracker whole(base_config());  // never wraps: a step is never ambiguous, only a glitch
  whole.update(wrapped_input(0, 100, 0));
  EXPECT_EQ(whole.update(wrapped_input(1400, 30000, 0)), JointEvent::kGlitch);
}

TEST(JointTracker, AnAbsoluteEncoderIsHomedAtItsFirstPosition) {
  // Single-turn, 10000 counts: offset 30 deg is the angle at the encoder's zero.
  JointTracker t(base_config());
  EXPECT_EQ(t.update(wrapped_input(0, 417, 10000, true)), JointEvent::kHomed);
  EXPECT_TRUE(t.reading().homed);
  EXPECT_EQ(t.reading().flags & jf::kFaults, 0u);
  EXPECT_NEAR(t.reading().position_rad, 30.0 * kPi / 180.0 + 417 * kRadPerCount, 1e-12);
  // Down across the encoder's zero, one count a millisecond: the angle goes on.
  for (std::int64_t k = 1; k <= 420; ++k) {
    t.update(wrapped_input(k, (417 - k + 10000) % 10000, 10000, true));
  }
  EXPECT_EQ(t.reading().count, -3);
  EXPECT_NEAR(t.reading().position_rad, 30.0 * kPi / 180.0 - 3 * kRadPerCount, 1e-12);
  // An index latch means nothing to an absolute channel.
  JointInput in = wrapped_input(421, 9996, 10000, true);
  in.index_valid = true;
  in.index_position = 5000;
  EXPECT_EQ(t.update(in), JointEvent::kNone);
  EXPECT_NEAR(t.reading().position_rad, 30.0 * kPi / 180.0 - 4 * kRadPerCount, 1e-12);
  EXPECT_EQ(t.counters().homings, 1);
}

TEST(JointTracker, AnAbsoluteEncoderTakesTheTurnNearestTheHomePosture) {
  // Zero at 200 deg: 5694 counts (204.98 deg) on is 404.98 deg, i.e. 44.98
  // deg, next to the 45 deg home posture; direction -1 counts the other way.
  auto c = base_config();
  c.offset_rad = 200.0 * kPi / 180.0;
  JointTracker t(c);
  t.update(wrapped_input(0, 5694, 10000, true));
  EXPECT_NEAR(t.reading().position_rad, (200.0 - 360.0) * kPi / 180.0 + 5694 * kRadPerCount, 1e-12);
  c.direction = -1;
  c.offset_rad = -110.0 * kPi / 180.0;
  JointTracker down(c);
  down.update(wrapped_input(0, 5694, 10000, true));
  EXPECT_NEAR(down.reading().position_rad, (-110.0 + 360.0) * kPi / 180.0 - 5694 * kRadPerCount,
              1e-12);
}
