// Simulated rig: motion continuity, speed and range bounds, determinism;
// encoder counts by the floor formula, index latches, 16-bit wrap; board
// frame layout.
#include <gtest/gtest.h>

#include <cmath>

#include "exodaq/drivers/board_decoder.hpp"
#include "exodaq/drivers/sim_rig.hpp"

namespace sim = exodaq::drivers::sim;
namespace can = exodaq::drivers::can;

namespace {

constexpr double kPi = std::numbers::pi;

std::vector<double> segment_starts(const sim::SimMotion& m) {
  std::vector<double> t;
  for (const auto& s : m.homing_segments()) t.push_back(s.t0);
  for (const auto& s : m.trip_segments()) t.push_back(m.homing_end_s() + s.t0);
  t.push_back(m.homing_end_s() + m.cycle_s());  // the wrap into the next pattern
  return t;
}

TEST(SimMotion, StartsAtHomeAtRest) {
  const sim::SimMotion m;
  for (double t : {-1.0, 0.0, 0.25}) {
    const auto s = m.truth(t);
    for (int j = 0; j < 6; ++j) {
      EXPECT_EQ(s.position[static_cast<std::size_t>(j)],
                sim::kHomeRad[static_cast<std::size_t>(j)]);
      EXPECT_EQ(s.velocity[static_cast<std::size_t>(j)], 0.0);
    }
  }
  EXPECT_DOUBLE_EQ(sim::kHomeRad[0], kPi / 4);
  EXPECT_DOUBLE_EQ(sim::kHomeRad[1], -kPi / 2);
  EXPECT_DOUBLE_EQ(sim::kHomeRad[2], kPi / 2);
}

TEST(SimMotion, ContinuousPositionVelocityAccelerationAtEveryJoin) {
  const sim::SimMotion m;
  const double eps = 1e-7;
  int joins = 0;
  for (double tb : segment_starts(m)) {
    if (tb <= 0) continue;
    const auto a = m.truth(tb - eps);
    const auto b = m.truth(tb + eps);
    const auto at = m.truth(tb);
    for (std::size_t j = 0; j < 6; ++j) {
      EXPECT_NEAR(a.position[j], b.position[j], 1e-9) << "t=" << tb << " joint " << j;
      EXPECT_NEAR(a.velocity[j], b.velocity[j], 1e-6);
      EXPECT_NEAR(a.acceleration[j], b.acceleration[j], 1e-4);
      // Waypoint: zero velocity and acceleration.
      EXPECT_NEAR(at.velocity[j], 0.0, 1e-12);
      EXPECT_NEAR(at.acceleration[j], 0.0, 1e-12);
    }
    ++joins;
  }
  EXPECT_GT(joins, 12 + 16 * 7 - 1);
}

TEST(SimMotion, VelocityAndAccelerationAreDerivativesOfPosition) {
  const sim::SimMotion m;
  const double h = 1e-5;
  const double end = m.homing_end_s() + m.cycle_s();
  for (double t = 0.013; t < end; t += 0.0973) {
    const auto c = m.truth(t);
    const auto p = m.truth(t + h);
    const auto n = m.truth(t - h);
    for (std::size_t j = 0; j < 6; ++j) {
      EXPECT_NEAR((p.position[j] - n.position[j]) / (2 * h), c.velocity[j], 1e-6) << t;
      EXPECT_NEAR((p.velocity[j] - n.velocity[j]) / (2 * h), c.acceleration[j], 1e-4) << t;
    }
  }
}

TEST(SimMotion, SpeedsWithinTableIIIAndPositionsInsideLimits) {
  const sim::SimMotion m;
  const double end = m.homing_end_s() + 2 * m.cycle_s();
  sim::Vec6 vmax{};
  sim::Vec6 lo;
  sim::Vec6 hi;
  lo.fill(1e9);
  hi.fill(-1e9);
  for (double t = 0; t < end; t += 0.001) {
    const auto s = m.truth(t);
    for (std::size_t j = 0; j < 6; ++j) {
      vmax[j] = std::max(vmax[j], std::abs(s.velocity[j]));
      ASSERT_GE(s.position[j], sim::kLowerLimitRad[j]) << "joint " << j << " t " << t;
      ASSERT_LE(s.position[j], sim::kUpperLimitRad[j]) << "joint " << j << " t " << t;
      if (t >= m.homing_end_s()) {
        lo[j] = std::min(lo[j], s.position[j]);
        hi[j] = std::max(hi[j], s.position[j]);
      }
    }
  }
  // Seed 001 Table III by anatomy (ab/adduction for joints 1 and 2, flexion,
  // rotation, elbow), 3.0 rad/s for pronation/supination.
  const sim::Vec6 anatomical{0.64, 0.64, 1.06, 1.80, 5.38, 3.0};
  EXPECT_EQ(sim::kSpeedBoundRadS, anatomical);
  for (std::size_t j = 0; j < 6; ++j) {
    EXPECT_LE(vmax[j], sim::kMotionSpeedCapRadS[j] + 1e-9) << "joint " << j;
    EXPECT_LE(vmax[j], sim::kSpeedBoundRadS[j]) << "joint " << j;
    EXPECT_GT(vmax[j], 0.0);
    // Task phase: range of motion within seed 000 Table 5, and a real motion.
    EXPECT_LE(hi[j] - lo[j], sim::kTaskRomRad[j] + 1e-9) << "joint " << j;
    EXPECT_GT(hi[j] - lo[j], 0.3 * sim::kTaskRomRad[j]) << "joint " << j;
  }
}

TEST(SimMotion, HomingSweepsCrossEveryIndexAngle) {
  const sim::SimMotion m;
  for (std::size_t j = 0; j < 6; ++j) {
    EXPECT_DOUBLE_EQ(m.homing_index_rad()[j], sim::kDefaultIndexAngleRad[j]);
    const double home = sim::kHomeRad[j];
    const double idx = m.homing_index_rad()[j];
    bool crossed = false;
    for (double t = 0; t < m.homing_end_s(); t += 0.001) {
      const double p = m.truth(t).position[j];
      if ((idx > home && p > idx) || (idx < home && p < idx)) crossed = true;
    }
    EXPECT_TRUE(crossed) << "joint " << j;
  }
  const auto end = m.truth(m.homing_end_s());
  for (std::size_t j = 0; j < 6; ++j) EXPECT_NEAR(end.position[j], sim::kHomeRad[j], 1e-12);
}

TEST(SimMotion, DeterministicForASeed) {
  sim::SimMotionOptions a;
  a.seed = 7;
  sim::SimMotionOptions b = a;
  sim::SimMotionOptions c = a;
  c.seed = 8;
  const sim::SimMotion ma(a);
  const sim::SimMotion mb(b);
  const sim::SimMotion mc(c);
  bool differs = false;
  for (double t = 0; t < 200; t += 0.37) {
    const auto pa = ma.truth(t).position;
    EXPECT_EQ(pa, mb.truth(t).position);
    if (pa != mc.truth(t).position) differs = true;
  }
  EXPECT_TRUE(differs);
}

TEST(SimMotion, RejectsASweepBeyondTheLimits) {
  sim::Vec6 idx = sim::kDefaultIndexAngleRad;
  idx[2] = sim::deg(97.0);  // joint 3: 97 + 3 deg overshoot > 98.1 deg
  EXPECT_THROW(sim::SimMotion({}, idx), std::invalid_argument);
  sim::SimMotionOptions o;
  o.task_upper_rad[4] = sim::deg(10.0);  // beyond Table 3's 8.1 deg
  EXPECT_THROW(sim::SimMotion{o}, std::invalid_argument);
}

std::array<sim::SimEncoderParams, 6> odd_encoders() {
  auto e = sim::default_encoders();
  e[1].direction = -1;
  e[3].gear_ratio = 2.5;
  e[3].direction = -1;
  e[5].counts_per_rev = 2048;
  e[5].gear_ratio = 3.0;
  return e;
}

TEST(SimEncoders, CountsFollowTheFloorFormulaExactly) {
  const auto params = odd_encoders();
  sim::SimEncoders enc(params, sim::kHomeRad);
  for (std::size_t j = 0; j < 6; ++j) {
    const auto& p = params[j];
    const int ji = static_cast<int>(j);
    EXPECT_EQ(enc.count(ji), p.power_up_count);
    EXPECT_EQ(enc.count_at(ji, sim::kHomeRad[j]), p.power_up_count);
    const auto f = [&](double th) {
      return static_cast<std::int64_t>(
          std::floor((th - p.index_angle_rad) * static_cast<double>(p.counts_per_rev) *
                     p.gear_ratio / (2 * kPi)));
    };
    const std::int64_t offset = p.power_up_count - p.direction * f(sim::kHomeRad[j]);
    EXPECT_EQ(enc.offset(ji), offset);
    for (double th = -1.3; th < 1.3; th += 0.0137) {
      EXPECT_EQ(enc.count_at(ji, th), p.direction * f(th) + offset) << j << " " << th;
    }
    // One count is 2π / (cpr · gear) of joint angle.
    const double step = 2 * kPi / (static_cast<double>(p.counts_per_rev) * p.gear_ratio);
    const double base = p.index_angle_rad + 100.5 * step;
    EXPECT_EQ(enc.count_at(ji, base + step) - enc.count_at(ji, base), p.direction);
  }
}

TEST(SimEncoders, IndexLatchesExactlyAtTheCrossingBothWays) {
  const auto params = odd_encoders();
  sim::SimEncoders enc(params, sim::kHomeRad);
  sim::Vec6 th = sim::kHomeRad;
  enc.update(th);
  for (int j = 0; j < 6; ++j) EXPECT_FALSE(enc.latched(j));

  const std::size_t j = 3;  // direction −1, gear 2.5
  const int ji = 3;
  const double idx = params[j].index_angle_rad;
  const double tiny = 1e-7;
  th[j] = idx - tiny;
  enc.update(th);
  EXPECT_FALSE(enc.latched(ji));
  th[j] = idx + tiny;  // upward across n = 0
  enc.update(th);
  ASSERT_TRUE(enc.latched(ji));
  EXPECT_EQ(enc.latched_count(ji), enc.offset(ji));
  EXPECT_EQ(enc.count(ji), enc.offset(ji));  // first count at/above the index
  th[j] = idx + 2 * tiny;
  enc.update(th);
  EXPECT_FALSE(enc.latched(ji));  // latch lasts one cycle
  th[j] = idx - tiny;             // back down across the same index: same latched count
  enc.update(th);
  ASSERT_TRUE(enc.latched(ji));
  EXPECT_EQ(enc.latched_count(ji), enc.offset(ji));
  EXPECT_EQ(enc.count(ji), enc.offset(ji) - params[j].direction);

  // With gear 2.5 the next index is 2π/2.5 further: n = 1.
  const double next = idx + 2 * kPi / 2.5;
  th[j] = next - tiny;
  enc.update(th);                // crossing nothing? it jumps past no boundary below `next`
  EXPECT_TRUE(enc.latched(ji));  // jumped up across n = 0 again
  th[j] = next + tiny;
  enc.update(th);
  ASSERT_TRUE(enc.latched(ji));
  EXPECT_EQ(enc.latched_count(ji), enc.count_at_index(ji, 1));
  EXPECT_EQ(enc.count_at_index(ji, 1), -1 * 10000 + enc.offset(ji));
  EXPECT_EQ(enc.count(ji), enc.latched_count(ji));
}

TEST(SimBoard, FramesOf16BitWrappedCountsIndexAndHeartbeat) {
  sim::SimBoard board;
  sim::BoardCycle c;
  c.count = {65530, 65536 + 7, -3, 123456, 0, -70000};
  c.index_latched = (1U << 1) | (1U << 5);
  c.index_count[1] = 65536;
  c.index_count[5] = -65537;
  sim::SimBoard::Frames f{};
  const int n = board.make_cycle(300, c, f);  // 300 % 100 == 0: heartbeat
  ASSERT_EQ(n, 5);
  EXPECT_EQ(f[0].id, 0x191U);
  EXPECT_EQ(f[1].id, 0x195U);
  EXPECT_EQ(f[2].id, 0x181U);
  EXPECT_EQ(f[3].id, 0x182U);
  EXPECT_EQ(f[4].id, 0x701U);
  const auto a = can::decode(f[2]);
  EXPECT_EQ(a.counts.count16[0], 65530);
  EXPECT_EQ(a.counts.count16[1], 7);
  EXPECT_EQ(a.counts.count16[2], 65533);
  EXPECT_EQ(a.counts.index_latched, 0x02);
  EXPECT_EQ(a.counts.seq, 300 % 256);
  const auto b = can::decode(f[3]);
  EXPECT_EQ(b.counts.count16[0], 123456 & 0xFFFF);
  EXPECT_EQ(b.counts.count16[2], (-70000) & 0xFFFF);
  EXPECT_EQ(b.counts.index_latched, 0x04);
  EXPECT_EQ(can::decode(f[0]).index.count16, 0);
  EXPECT_EQ(can::decode(f[1]).index.count16, 0xFFFF);
  EXPECT_EQ(can::decode(f[4]).heartbeat.protocol_version, 1);
  EXPECT_EQ(board.make_cycle(301, c, f), 4);  // no heartbeat
}

TEST(SimRig, CountsCrossThe16BitWrapAndUnwrapToTruth) {
  sim::SimOptions o;  // joints 1 and 3 power up next to the wrap
  sim::SimRig rig(o);
  exodaq::drivers::BoardDecoder dec;
  sim::SimBoard::Frames frames{};
  std::array<std::int64_t, 6> unwrapped{};
  for (std::size_t j = 0; j < 6; ++j) unwrapped[j] = o.encoders[j].power_up_count;
  std::array<bool, 6> crossed{};
  for (std::int64_t k = 0; k < 20000; ++k) {
    const int n = rig.step(k, frames, 0, 0);
    for (int i = 0; i < n; ++i) dec.on_frame(frames[static_cast<std::size_t>(i)]);
    exodaq::drivers::EncoderSample s;
    ASSERT_TRUE(dec.poll_sample(s));
    for (std::size_t j = 0; j < 6; ++j) {
      const std::int64_t before = unwrapped[j];
      unwrapped[j] = exodaq::unwrap(unwrapped[j], s.position[j], exodaq::kCount16Modulus);
      EXPECT_EQ(unwrapped[j], rig.encoders().count(static_cast<int>(j)));
      if ((before >> 16) != (unwrapped[j] >> 16)) crossed[j] = true;
    }
  }
  EXPECT_TRUE(crossed[0]);  // 65500 up past 65535 during homing
  EXPECT_TRUE(crossed[2]);  // 10 down past 0
}

}  // namespace
