// Joint trajectories (exodaq/kinematics/trajectory.hpp): via points, bounds,
// continuity, time scaling, errors, allocation-free sampling, and IK feeding a
// trajectory (palm targets -> joint via points -> motion).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "alloc_counter.hpp"
#include "exodaq/kinematics/ik.hpp"
#include "exodaq/kinematics/trajectory.hpp"
#include "kin_test_util.hpp"

namespace exodaq::kinematics {
namespace {

using test::kDeg;

// Seed 001 Table III for joints 1-4 (0.64, 1.06, 1.80, 5.38 rad/s); the elbow
// and pronation bounds the project's configs use for joints 5-6 (5.38, 3.0).
JointBounds table3_bounds(double acceleration) {
  JointBounds b;
  b.max_speed.resize(6);
  b.max_speed << 0.64, 1.06, 1.80, 5.38, 5.38, 3.0;
  b.max_acceleration = JointVector::Constant(6, acceleration);
  return b;
}

std::vector<JointVector> random_via_points(const Chain& c, int count, std::mt19937_64& rng) {
  std::vector<JointVector> via;
  for (int k = 0; k < count; ++k) via.push_back(test::random_within_limits(c, rng));
  return via;
}

const SegmentShape kShapes[] = {SegmentShape::kCubic, SegmentShape::kQuintic};

TEST(Trajectory, PassesThroughTheViaPointsFromRestToRest) {
  const Chain& c = test::macaque().chain;
  std::mt19937_64 rng(1);
  for (const SegmentShape shape : kShapes) {
    for (int trial = 0; trial < 50; ++trial) {
      const auto via = random_via_points(c, 2 + trial % 8, rng);
      TrajectoryOptions o;
      o.shape = shape;
      const JointTrajectory traj(via, table3_bounds(4.0), o);
      ASSERT_EQ(traj.segment_count(), static_cast<int>(via.size()) - 1);
      ASSERT_EQ(traj.joint_count(), 6);
      EXPECT_EQ(traj.via_time(0), 0.0);
      EXPECT_EQ(traj.via_time(traj.segment_count()), traj.duration());
      for (int k = 0; k <= traj.segment_count(); ++k) {
        const TrajectorySample s = traj.sample(traj.via_time(k));
        EXPECT_LE((s.q - via[static_cast<std::size_t>(k)]).cwiseAbs().maxCoeff(), 1e-12) << k;
      }
      for (const double t : {0.0, traj.duration()}) {
        const TrajectorySample s = traj.sample(t);
        EXPECT_LE(s.qd.cwiseAbs().maxCoeff(), 1e-12);
        if (shape == SegmentShape::kQuintic) {
          EXPECT_LE(s.qdd.cwiseAbs().maxCoeff(), 1e-9);
        }
      }
    }
  }
}

TEST(Trajectory, KeepsTheSpeedAndAccelerationBounds) {
  const Chain& c = test::macaque().chain;
  std::mt19937_64 rng(2);
  for (const SegmentShape shape : kShapes) {
    for (const double acceleration : {2.0, 10.0, 1e9}) {
      for (int trial = 0; trial < 20; ++trial) {
        const auto via = random_via_points(c, 6, rng);
        const JointBounds b = table3_bounds(acceleration);
        TrajectoryOptions o;
        o.shape = shape;
        const JointTrajectory traj(via, b, o);
        JointVector seen_v = JointVector::Zero(6), seen_a = JointVector::Zero(6);
        TrajectorySample s;
        for (double t = 0.0; t <= traj.duration(); t += 5e-4) {
          traj.sample(t, s);
          seen_v = seen_v.cwiseMax(s.qd.cwiseAbs());
          seen_a = seen_a.cwiseMax(s.qdd.cwiseAbs());
        }
        for (int j = 0; j < 6; ++j) {
          EXPECT_LE(seen_v[j], b.max_speed[j] * (1 + 1e-9)) << j;
          EXPECT_LE(seen_a[j], b.max_acceleration[j] * (1 + 1e-9)) << j;
          EXPECT_LE(traj.peak_speed()[j], b.max_speed[j] * (1 + 1e-9)) << j;
          EXPECT_LE(traj.peak_acceleration()[j], b.max_acceleration[j] * (1 + 1e-9)) << j;
          // The reported peaks are the extrema the samples approach.
          EXPECT_GE(traj.peak_speed()[j], seen_v[j] - 1e-12);
          EXPECT_LE(traj.peak_speed()[j], seen_v[j] + 5e-4 * traj.peak_acceleration()[j] + 1e-12);
        }
        // Time-scaled: as short as the bounds allow, so some joint reaches one.
        double worst = 0.0;
        for (int j = 0; j < 6; ++j) {
          worst = std::max({worst, traj.peak_speed()[j] / b.max_speed[j],
                            std::sqrt(traj.peak_acceleration()[j] / b.max_acceleration[j])});
        }
        EXPECT_NEAR(worst, 1.0, 1e-9);
      }
    }
  }
}

TEST(Trajectory, OneSegmentTakesTheClosedFormMinimumTime) {
  // Rest to rest over h: the cubic peaks at 1.5 h/T (speed) and 6 h/T^2
  // (acceleration), the quintic at 15 h/(8 T) and 10 h/(sqrt(3) T^2).
  JointBounds b;
  b.max_speed = JointVector::Constant(1, 0.64);
  b.max_acceleration = JointVector::Constant(1, 2.0);
  for (const double h : {0.01, 0.3, 2.0}) {
    const std::vector<JointVector> via = {JointVector::Constant(1, 0.1),
                                          JointVector::Constant(1, 0.1 + h)};
    TrajectoryOptions o;
    o.shape = SegmentShape::kCubic;
    const JointTrajectory cubic(via, b, o);
    EXPECT_NEAR(cubic.duration(), std::max(1.5 * h / 0.64, std::sqrt(6.0 * h / 2.0)),
                1e-9 * cubic.duration());
    o.shape = SegmentShape::kQuintic;
    const JointTrajectory quintic(via, b, o);
    EXPECT_NEAR(quintic.duration(),
                std::max(15.0 * h / (8.0 * 0.64), std::sqrt(10.0 * h / (std::sqrt(3.0) * 2.0))),
                1e-9 * quintic.duration());
  }
}

TEST(Trajectory, ContinuousAtTheViaPointsAndConsistentDerivatives) {
  const Chain& c = test::macaque().chain;
  std::mt19937_64 rng(3);
  for (const SegmentShape shape : kShapes) {
    TrajectoryOptions o;
    o.shape = shape;
    const JointTrajectory traj(random_via_points(c, 8, rng), table3_bounds(5.0), o);
    constexpr double e = 1e-7;
    for (int k = 1; k < traj.segment_count(); ++k) {
      const TrajectorySample a = traj.sample(traj.via_time(k) - e);
      const TrajectorySample b = traj.sample(traj.via_time(k) + e);
      EXPECT_LE((a.q - b.q).cwiseAbs().maxCoeff(), 1e-6);
      EXPECT_LE((a.qd - b.qd).cwiseAbs().maxCoeff(), 1e-5);
      if (shape == SegmentShape::kQuintic) {
        EXPECT_LE((a.qdd - b.qdd).cwiseAbs().maxCoeff(), 1e-4);
      }
    }
    // Central differences of q and qd match qd and qdd.
    for (double t = 0.01; t < traj.duration() - 0.01; t += traj.duration() / 97.0) {
      const double h = 1e-5;
      const TrajectorySample m = traj.sample(t), lo = traj.sample(t - h), hi = traj.sample(t + h);
      EXPECT_LE(((hi.q - lo.q) / (2 * h) - m.qd).cwiseAbs().maxCoeff(), 1e-6) << t;
      EXPECT_LE(((hi.qd - lo.qd) / (2 * h) - m.qdd).cwiseAbs().maxCoeff(), 1e-4) << t;
    }
  }
}

TEST(Trajectory, NoSegmentOvershootsItsViaPoints) {
  // So a path through via points within the joint limits stays within them.
  const Chain& c = test::macaque().chain;
  std::mt19937_64 rng(4);
  for (const SegmentShape shape : kShapes) {
    TrajectoryOptions o;
    o.shape = shape;
    for (int trial = 0; trial < 30; ++trial) {
      const auto via = random_via_points(c, 7, rng);
      const JointTrajectory traj(via, table3_bounds(3.0), o);
      TrajectorySample s;
      for (int k = 0; k < traj.segment_count(); ++k) {
        const auto& a = via[static_cast<std::size_t>(k)];
        const auto& b = via[static_cast<std::size_t>(k) + 1];
        for (int i = 0; i <= 200; ++i) {
          traj.sample(traj.via_time(k) + (traj.via_time(k + 1) - traj.via_time(k)) * i / 200.0, s);
          for (int j = 0; j < 6; ++j) {
            ASSERT_GE(s.q[j], std::min(a[j], b[j]) - 1e-12);
            ASSERT_LE(s.q[j], std::max(a[j], b[j]) + 1e-12);
          }
        }
      }
    }
  }
}

TEST(Trajectory, RestsOutsideItsTimeAndDwellsOnRepeatedPoints) {
  const JointVector a = test::macaque().home_posture;
  const JointVector b = a + 0.5 * JointVector::Unit(6, 0);
  TrajectoryOptions o;
  o.min_segment_duration = 0.25;
  const JointTrajectory traj({a, b, b, a}, table3_bounds(4.0), o);
  EXPECT_NEAR(traj.via_time(2) - traj.via_time(1), 0.25, 1e-12);  // the dwell
  const TrajectorySample mid = traj.sample(0.5 * (traj.via_time(1) + traj.via_time(2)));
  EXPECT_LE((mid.q - b).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LE(mid.qd.cwiseAbs().maxCoeff(), 1e-15);
  const TrajectorySample before = traj.sample(-1.0), after = traj.sample(traj.duration() + 1.0);
  EXPECT_LE((before.q - a).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LE((after.q - a).cwiseAbs().maxCoeff(), 1e-12);
  EXPECT_LE(after.qd.cwiseAbs().maxCoeff(), 1e-12);
  // Joint 1 alone moves: 0.5 rad at 0.64 rad/s at best.
  EXPECT_GE(traj.via_time(1), 0.5 / 0.64);
}

TEST(Trajectory, BadInputIsRefusedWithTheReason) {
  const JointVector a = test::macaque().home_posture;
  const JointBounds b = table3_bounds(4.0);
  auto message = [](auto&& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no exception");
  };
  EXPECT_EQ(message([&] { JointTrajectory({a}, b); }),
            "a trajectory needs at least two via points");
  EXPECT_EQ(message([&] {
              JointTrajectory({a, JointVector::Zero(5)}, b);
            }),
            "via point 1 has 5 joints, via point 0 has 6");
  JointVector nan = a;
  nan[2] = std::nan("");
  EXPECT_EQ(message([&] { JointTrajectory({a, nan}, b); }), "via point 1 is not finite");
  JointBounds slow = b;
  slow.max_speed[3] = 0.0;
  EXPECT_EQ(message([&] { JointTrajectory({a, a}, slow); }), "max_speed of joint 4 must be > 0");
  JointBounds short_b = b;
  short_b.max_acceleration = JointVector::Constant(3, 1.0);
  EXPECT_EQ(message([&] {
              JointTrajectory({a, a}, short_b);
            }),
            "max_acceleration has 3 values, the via points 6 joints");
  JointBounds no_acc = b;
  no_acc.max_acceleration.resize(0);  // no acceleration bound: fine
  EXPECT_EQ(message([&] { JointTrajectory({a, a}, no_acc); }), "no exception");
}

TEST(Trajectory, SamplingAllocatesNothing) {
  const Chain& c = test::macaque().chain;
  std::mt19937_64 rng(5);
  const JointTrajectory traj(random_via_points(c, 20, rng), table3_bounds(4.0));
  TrajectorySample s;
  double sink = 0.0;
  exodaq::test::AllocationScope scope;
  for (double t = -0.1; t < traj.duration() + 0.1; t += 1e-3) {
    traj.sample(t, s);
    sink += s.q[0] + s.qd[1] + s.qdd[2] + traj.sample(t).q[3];
  }
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_TRUE(std::isfinite(sink));
}

TEST(Trajectory, PalmTargetsThroughIkBecomeJointMotion) {
  // What the task-driven simulated rig does: palm targets -> IK (nearest the
  // previous posture) -> a time-scaled trajectory whose via points put the palm
  // on the targets.
  const auto& m = test::macaque();
  IkSolver ik(m.chain, m.rig);
  std::mt19937_64 rng(6);
  std::vector<Pose> targets;
  for (int k = 0; k < 6; ++k)
    targets.push_back(m.chain.palm(test::random_within_limits(m.chain, rng)));
  std::vector<JointVector> via = {m.home_posture};
  for (const Pose& t : targets) {
    IkSolution s;
    ASSERT_TRUE(ik.solve_nearest(t, via.back(), s));
    via.push_back(s.q);
  }
  const JointTrajectory traj(via, table3_bounds(4.0));
  for (std::size_t k = 0; k < targets.size(); ++k) {
    const Pose p = m.chain.palm(traj.sample(traj.via_time(static_cast<int>(k) + 1)).q);
    EXPECT_LE((p.translation() - targets[k].translation()).norm(), 1e-9);
    EXPECT_LE(Eigen::AngleAxisd(p.linear() * targets[k].linear().transpose()).angle(), 1e-9);
  }
  // Every sample within the joint limits (no overshoot past the via points).
  TrajectorySample s;
  for (double t = 0.0; t <= traj.duration(); t += 1e-3) {
    traj.sample(t, s);
    for (int j = 0; j < 6; ++j) {
      const auto& l = m.chain.joints()[static_cast<std::size_t>(j)].limits;
      ASSERT_GE(s.q[j], l.lower - 1e-12);
      ASSERT_LE(s.q[j], l.upper + 1e-12);
    }
  }
}

}  // namespace
}  // namespace exodaq::kinematics
