// Inverse kinematics (exodaq/kinematics/ik.hpp) on the shipped models: FK o IK
// round trips, solution counts at known postures, the closed form against the
// numerical solver, singular and unreachable poses.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <vector>

#include "alloc_counter.hpp"
#include "exodaq/kinematics/ik.hpp"
#include "exodaq/settings/model_file.hpp"
#include "kin_test_util.hpp"

namespace exodaq::kinematics {
namespace {

using test::kDeg;
using test::kPi;

constexpr double kTol = 1e-9;  // m and rad: the round-trip bound

double rotation_angle(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a * b.transpose()).angle();
}

// FK of the solution (recomputed here, not taken from the solver) reaches the target.
void expect_reaches(const Chain& chain, const IkSolution& s, const Pose& target) {
  const Pose p = chain.palm(s.q);
  const double dp = (p.translation() - target.translation()).norm();
  const double dr = rotation_angle(p.linear(), target.linear());
  ASSERT_LE(dp, kTol) << s.q.transpose();
  ASSERT_LE(dr, kTol) << s.q.transpose();
  EXPECT_NEAR(s.position_residual, dp, 1e-15);
  EXPECT_NEAR(s.orientation_residual, dr, 1e-14);
}

double angular_distance(const JointVector& a, const JointVector& b) {
  double d = 0.0;
  for (Eigen::Index i = 0; i < a.size(); ++i) {
    d = std::max(d, std::abs(std::remainder(a[i] - b[i], 2.0 * kPi)));
  }
  return d;
}

bool within(const Chain& c, const JointVector& q, double slack = 1e-12) {
  for (int i = 0; i < c.joint_count(); ++i) {
    const auto& l = c.joints()[static_cast<std::size_t>(i)].limits;
    if (q[i] < l.lower - slack || q[i] > l.upper + slack) return false;
  }
  return true;
}

JointVector deg(std::initializer_list<double> v) {
  JointVector q(static_cast<Eigen::Index>(v.size()));
  Eigen::Index i = 0;
  for (const double x : v) q[i++] = x * kDeg;
  return q;
}

// The macaque with every joint limited to [-pi, pi]: every solution counts.
Chain widened(const Chain& c) {
  std::vector<JointDescription> joints = c.joints();
  for (auto& j : joints) j.limits = {-kPi, kPi};
  return Chain(c.convention(), joints, c.base(), c.tool());
}

TEST(IkSetup, StructureOfTheModels) {
  const auto& m = test::macaque();
  const auto mdh = settings::load_model_text(test::kMacaqueModifiedDh, "mdh.yaml");
  const auto poe = settings::load_model_text(test::kMacaquePoe, "poe.yaml");
  for (const Chain* c : {&m.chain, &mdh.chain, &poe.chain}) {
    const IkSolver ik(*c, m.rig);
    EXPECT_EQ(ik.redundancy(), 1);  // four shoulder axes through one point
    EXPECT_EQ(ik.free_joint(), 0);
    EXPECT_TRUE(ik.analytical());
  }
  IkOptions numerical;
  numerical.use_analytical = false;
  const IkSolver ikn(m.chain, m.rig, numerical);
  EXPECT_EQ(ikn.redundancy(), 1);
  EXPECT_EQ(ikn.free_joint(), 0);
  EXPECT_FALSE(ikn.analytical());

  const auto planar = settings::load_model_file(test::model_path("seed004_planar.yaml"));
  const IkSolver ikp(planar.chain, planar.rig);
  EXPECT_EQ(ikp.redundancy(), 0);
  EXPECT_EQ(ikp.free_joint(), -1);
  EXPECT_FALSE(ikp.analytical());

  const auto puma = settings::load_model_text(test::kPuma560, "puma.yaml");
  const IkSolver ikr(puma.chain, puma.rig);
  EXPECT_EQ(ikr.redundancy(), 0);
  EXPECT_FALSE(ikr.analytical());  // no spherical shoulder
}

TEST(IkSetup, RedundantByTwoIsRefused) {
  // Five parallel axes in a plane: rank 3, redundant by two.
  std::vector<JointDescription> joints(5);
  for (int i = 0; i < 5; ++i) joints[static_cast<std::size_t>(i)].dh.a = 0.1;
  const Chain c(Convention::kStandardDh, joints, Pose::Identity(), Pose::Identity());
  EXPECT_THROW(IkSolver(c, RigKinematicsConfig{}), std::invalid_argument);
}

// Seed 000's arm: with joint 1 given, within Table 3's limits exactly one
// solution (docs/kinematics.md: the other three need joint 4 or 6 turned by pi).
void macaque_round_trips(const Chain& chain, const RigKinematicsConfig& rig, int postures,
                         std::uint64_t seed) {
  IkSolver ik(chain, rig);
  std::mt19937_64 rng(seed);
  int recovered = 0;
  for (int t = 0; t < postures; ++t) {
    const JointVector q = test::random_within_limits(chain, rng);
    const Pose target = chain.palm(q);
    const IkResult& r = ik.solve_fixed(target, q[0]);
    ASSERT_EQ(r.status, IkStatus::kSolved) << q.transpose();
    ASSERT_EQ(r.solutions.size(), 1u) << q.transpose();
    const IkSolution& s = r.solutions[0];
    expect_reaches(chain, s, target);
    EXPECT_TRUE(s.within_limits);
    EXPECT_TRUE(within(chain, s.q));
    recovered += angular_distance(s.q, q) <= 1e-7 ? 1 : 0;
  }
  EXPECT_EQ(recovered, postures);  // the one solution is the posture itself
}

TEST(IkMacaque, RoundTrip10000PosturesStandardDh) {
  macaque_round_trips(test::macaque().chain, test::macaque().rig, 10000, 1);
}

TEST(IkMacaque, RoundTripModifiedDhAndPoe) {
  const auto mdh = settings::load_model_text(test::kMacaqueModifiedDh, "mdh.yaml");
  const auto poe = settings::load_model_text(test::kMacaquePoe, "poe.yaml");
  macaque_round_trips(mdh.chain, mdh.rig, 2000, 2);
  macaque_round_trips(poe.chain, poe.rig, 2000, 3);
  const Chain converted = test::macaque().chain.to_product_of_exponentials();
  macaque_round_trips(converted, test::macaque().rig, 2000, 4);
}

TEST(IkMacaque, ClosedFormMatchesNumerical) {
  // Wide limits: all four solutions at a given joint 1 count, and both solvers
  // must find the same four.
  const auto& m = test::macaque();
  const Chain wide = widened(m.chain);
  IkSolver closed(wide, m.rig);
  IkOptions o;
  o.use_analytical = false;
  IkSolver numerical(wide, m.rig, o);
  ASSERT_TRUE(closed.analytical());
  ASSERT_FALSE(numerical.analytical());
  std::mt19937_64 rng(5);
  for (int t = 0; t < 200; ++t) {
    const JointVector q = test::random_within_limits(m.chain, rng);
    const Pose target = wide.palm(q);
    const std::vector<IkSolution> a = closed.solve_fixed(target, q[0]).solutions;
    const std::vector<IkSolution> b = numerical.solve_fixed(target, q[0]).solutions;
    ASSERT_EQ(a.size(), 4u) << q.transpose();
    ASSERT_EQ(b.size(), 4u) << q.transpose();
    for (const IkSolution& s : a) {
      expect_reaches(wide, s, target);
      double nearest = 1e9;
      for (const IkSolution& u : b) nearest = std::min(nearest, angular_distance(s.q, u.q));
      ASSERT_LE(nearest, 1e-7) << q.transpose();
    }
  }
}

TEST(IkMacaque, BranchSweepClosedFormMatchesNumerical) {
  const auto& m = test::macaque();
  IkSolver closed(m.chain, m.rig);
  IkOptions o;
  o.use_analytical = false;
  IkSolver numerical(m.chain, m.rig, o);
  std::mt19937_64 rng(6);
  for (int t = 0; t < 4; ++t) {
    const JointVector q = test::random_within_limits(m.chain, rng);
    const Pose target = m.chain.palm(q);
    const std::vector<IkSolution> a = closed.solve(target).solutions;
    const std::vector<IkSolution> b = numerical.solve(target).solutions;
    ASSERT_EQ(a.size(), b.size()) << q.transpose();
    ASSERT_FALSE(a.empty());
    for (const IkSolution& s : a) {
      bool matched = false;
      for (const IkSolution& u : b) {
        matched = matched || (std::abs(s.free_lower - u.free_lower) < 1e-6 &&
                              std::abs(s.free_upper - u.free_upper) < 1e-6);
      }
      EXPECT_TRUE(matched) << "branch [" << s.free_lower << ", " << s.free_upper << "]";
    }
  }
}

// solve() on the macaque: one solution per branch; the branches are the
// intervals of joint 1 where the (unique) solution lies within the limits.
TEST(IkMacaque, BranchesCoverExactlyTheFeasibleAzimuths) {
  const auto& m = test::macaque();
  IkSolver ik(m.chain, m.rig);
  IkSolver probe(m.chain, m.rig);
  const auto& l1 = m.chain.joints()[0].limits;
  std::mt19937_64 rng(7);
  for (int t = 0; t < 300; ++t) {
    const JointVector q = test::random_within_limits(m.chain, rng);
    const Pose target = m.chain.palm(q);
    const std::vector<IkSolution> branches = ik.solve(target).solutions;
    ASSERT_FALSE(branches.empty());
    int containing = 0;
    for (std::size_t i = 0; i < branches.size(); ++i) {
      const IkSolution& b = branches[i];
      expect_reaches(m.chain, b, target);
      EXPECT_TRUE(within(m.chain, b.q));
      EXPECT_LE(b.free_lower, b.free_upper);
      EXPECT_GE(b.q[0], b.free_lower - 1e-12);
      EXPECT_LE(b.q[0], b.free_upper + 1e-12);
      containing += q[0] >= b.free_lower - 1e-9 && q[0] <= b.free_upper + 1e-9 ? 1 : 0;
      for (std::size_t k = 0; k < i; ++k) {  // disjoint: one solution per azimuth
        EXPECT_TRUE(b.free_upper < branches[k].free_lower || b.free_lower > branches[k].free_upper);
      }
      // Each end is the azimuth's own limit or where another joint meets its limit.
      for (const double end : {b.free_lower, b.free_upper}) {
        if (end == l1.lower || end == l1.upper) continue;
        const IkResult& r = probe.solve_fixed(target, end);
        ASSERT_EQ(r.status, IkStatus::kSolved) << end;
        double closest = 1e9;
        for (int j = 1; j < 6; ++j) {
          const auto& l = m.chain.joints()[static_cast<std::size_t>(j)].limits;
          const double v = r.solutions[0].q[j];
          closest = std::min({closest, std::abs(v - l.lower), std::abs(v - l.upper)});
        }
        EXPECT_LE(closest, 1e-8) << "branch end " << end;
      }
    }
    EXPECT_EQ(containing, 1) << q.transpose();
  }
}

TEST(IkMacaque, DenseAzimuthScanFindsNoOtherBranch) {
  const auto& m = test::macaque();
  IkSolver ik(m.chain, m.rig);
  IkSolver probe(m.chain, m.rig);
  const auto& l1 = m.chain.joints()[0].limits;
  std::mt19937_64 rng(8);
  for (int t = 0; t < 12; ++t) {
    const Pose target = m.chain.palm(test::random_within_limits(m.chain, rng));
    const std::vector<IkSolution> branches = ik.solve(target).solutions;
    for (double a = l1.lower; a <= l1.upper; a += 0.05 * kDeg) {
      bool inside = false, near_end = false;
      for (const IkSolution& b : branches) {
        inside = inside || (a >= b.free_lower && a <= b.free_upper);
        near_end =
            near_end || std::min(std::abs(a - b.free_lower), std::abs(a - b.free_upper)) < 1e-6;
      }
      if (near_end) continue;
      const bool solved = probe.solve_fixed(target, a).status == IkStatus::kSolved;
      ASSERT_EQ(solved, inside) << "azimuth " << a / kDeg << " deg";
    }
  }
}

TEST(IkMacaque, HomePosture) {
  // Arm straight down: axes 4 and 6 lie on one line, so only theta4 + theta6 =
  // theta1 - 45 deg is fixed and the solver centres the two (theta4 = theta6);
  // |theta1 - 45| <= 160 deg keeps both within +-80, so the one branch is the
  // whole azimuth range [-50.5, 140.5] deg. Its representative is the home
  // posture itself (the middle of a plateau of normalised manipulability 1).
  const auto& m = test::macaque();
  IkSolver ik(m.chain, m.rig);
  const Pose target = m.chain.palm(m.home_posture);
  const IkResult& r = ik.solve(target);
  ASSERT_EQ(r.status, IkStatus::kSolved);
  ASSERT_EQ(r.solutions.size(), 1u);
  const IkSolution& s = r.solutions[0];
  expect_reaches(m.chain, s, target);
  EXPECT_NEAR(s.free_lower, -50.5 * kDeg, 1e-12);
  EXPECT_NEAR(s.free_upper, 140.5 * kDeg, 1e-12);
  EXPECT_LE(angular_distance(s.q, m.home_posture), 1e-9) << s.q.transpose() / kDeg;
  EXPECT_NEAR(s.shoulder_manipulability, std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(s.shoulder_manipulability_normalised, 1.0, 1e-12);
  // With joint 1 at 0, joints 4 and 6 share -45 deg.
  const IkResult& f = ik.solve_fixed(target, 0.0);
  ASSERT_EQ(f.solutions.size(), 1u);
  EXPECT_LE(angular_distance(f.solutions[0].q, deg({0, -90, 90, -22.5, 0, -22.5})), 1e-9);
}

TEST(IkMacaque, SingularPosturesRoundTrip) {
  const auto& m = test::macaque();
  IkSolver ik(m.chain, m.rig);
  const std::vector<JointVector> postures = {
      deg({30, -180, 0, 10, -40, 20}),  // seed 000's shoulder singularity
      deg({30, 0, 0, 10, -40, 20}),     // the other one (docs/kinematics.md)
      deg({-20, -180 + 1e-7, 1e-7, -30, -60, 5}),
      deg({100, 1e-6, -1e-6, 70, -20, -70}),
      deg({30, -70, 40, 10, 0, 20}),      // elbow straight
      deg({30, -70, 40, 10, -1e-7, 20}),  // nearly
      deg({30, -70, 40, 10, -1e-3, 20}),
      deg({0, -180, 0, 0, 0, 0}),  // both
  };
  for (const JointVector& q : postures) {
    const Pose target = m.chain.palm(q);
    const IkResult& f = ik.solve_fixed(target, q[0]);
    ASSERT_EQ(f.status, IkStatus::kSolved) << q.transpose() / kDeg;
    for (const IkSolution& s : f.solutions) expect_reaches(m.chain, s, target);
    const IkResult& r = ik.solve(target);
    ASSERT_EQ(r.status, IkStatus::kSolved) << q.transpose() / kDeg;
    bool contains = false;
    for (const IkSolution& s : r.solutions) {
      expect_reaches(m.chain, s, target);
      contains = contains || (q[0] >= s.free_lower - 1e-9 && q[0] <= s.free_upper + 1e-9);
    }
    EXPECT_TRUE(contains) << q.transpose() / kDeg;
  }
}

TEST(IkMacaque, UnreachablePosesAreAnsweredClearly) {
  const auto& m = test::macaque();
  IkSolver ik(m.chain, m.rig);
  const Pose home = m.chain.palm(m.home_posture);
  // The palm 1 mm further along the forearm: the elbow leaves its sphere.
  for (const double shift : {1e-3, -1e-3}) {
    Pose target = home;
    target.translation() += shift * home.linear().col(2);
    const IkResult& r = ik.solve(target);
    EXPECT_EQ(r.status, IkStatus::kUnreachable);
    EXPECT_TRUE(r.solutions.empty());
    EXPECT_NEAR(r.elbow_sphere_miss, shift, 1e-12);
    EXPECT_GT(r.best_position_residual, 0.5e-3);
    EXPECT_LE(r.best_position_residual, 1e-3 + 1e-9);
  }
  // Far away.
  Pose far = home;
  far.translation() = Eigen::Vector3d(1.0, 0.0, 0.0);
  const IkResult& r = ik.solve(far);
  EXPECT_EQ(r.status, IkStatus::kUnreachable);
  const Eigen::Vector3d elbow = far.translation() - test::kL2 * far.linear().col(2);
  EXPECT_NEAR(r.elbow_sphere_miss, elbow.norm() - test::kL1, 1e-12);
  EXPECT_GT(r.best_position_residual, 0.5);
  EXPECT_STREQ(to_string(r.status), "unreachable");
}

TEST(IkMacaque, ElbowBeyondItsLimitsIsOutsideLimits) {
  // The forearm at 100 deg to the upper arm: Table 3 allows elbow flexion down to
  // -88.7 deg and +8.1 deg the other way, so no posture within the limits.
  const auto& m = test::macaque();
  IkSolver ik(m.chain, m.rig);
  const Pose target = m.chain.palm(deg({30, -70, 40, 10, -100, 20}));
  const IkResult& r = ik.solve(target);
  ASSERT_EQ(r.status, IkStatus::kOutsideLimits);
  ASSERT_FALSE(r.solutions.empty());
  for (const IkSolution& s : r.solutions) {
    EXPECT_FALSE(s.within_limits);
    expect_reaches(m.chain, s, target);
    EXPECT_NEAR(std::abs(s.q[4]), 100.0 * kDeg, 1e-9);
  }
  EXPECT_STREQ(to_string(r.status), "outside_limits");
}

TEST(IkMacaque, NearestFollowsASmoothPath) {
  const auto& m = test::macaque();
  IkSolver ik(m.chain, m.rig);
  const JointVector a = deg({10, -100, 60, -20, -50, 10});
  const JointVector b = deg({80, -60, 20, 30, -10, -40});
  JointVector seed = a;
  for (int k = 1; k <= 200; ++k) {
    const JointVector q = a + (b - a) * (k / 200.0);
    const Pose target = m.chain.palm(q);
    IkSolution s;
    ASSERT_TRUE(ik.solve_nearest(target, seed, s)) << k;
    expect_reaches(m.chain, s, target);
    EXPECT_TRUE(s.within_limits);
    EXPECT_LE(angular_distance(s.q, seed), 0.05) << k;  // steps of <= 0.35 deg per joint
    seed = s.q;
  }
  // From a far seed: still a solution within the limits.
  IkSolution s;
  const Pose target = m.chain.palm(b);
  ASSERT_TRUE(ik.solve_nearest(target, m.home_posture, s));
  expect_reaches(m.chain, s, target);
  EXPECT_TRUE(within(m.chain, s.q));
  // Unreachable: false.
  Pose far = target;
  far.translation() = Eigen::Vector3d(1.0, 0.0, 0.0);
  EXPECT_FALSE(ik.solve_nearest(far, m.home_posture, s));
}

// Seed 004's planar 3R arm (numerical solver): two solutions (elbow up and down)
// except with the arm straight or folded, where they meet.
TEST(IkSeed004, RoundTrip10000Postures) {
  const auto planar = settings::load_model_file(test::model_path("seed004_planar.yaml"));
  const Chain& c = planar.chain;
  IkSolver ik(c, planar.rig);
  std::mt19937_64 rng(9);
  int recovered = 0;
  const int postures = 10000;
  for (int t = 0; t < postures; ++t) {
    const JointVector q = test::random_within_limits(c, rng);
    const Pose target = c.palm(q);
    const IkResult& r = ik.solve(target);
    ASSERT_EQ(r.status, IkStatus::kSolved) << q.transpose();
    if (std::abs(std::sin(q[1])) > 1e-3) {
      ASSERT_EQ(r.solutions.size(), 2u) << q.transpose();
    }
    bool found = false;
    for (const IkSolution& s : r.solutions) {
      expect_reaches(c, s, target);
      found = found || angular_distance(s.q, q) <= 1e-7;
    }
    recovered += found ? 1 : 0;
  }
  EXPECT_EQ(recovered, postures);
}

TEST(IkSeed004, KnownPostureCounts) {
  const auto planar = settings::load_model_file(test::model_path("seed004_planar.yaml"));
  const Chain& c = planar.chain;
  IkSolver ik(c, planar.rig);
  struct Case {
    JointVector q;
    std::size_t count;
  };
  const std::vector<Case> cases = {
      {deg({0, 0, 0}), 1},       // straight along +y (the home pose M)
      {deg({40, 0, -30}), 1},    // straight, turned
      {deg({10, 180, 20}), 1},   // folded back (l2 > l1: reaches)
      {deg({30, 60, -45}), 2},   // elbow one way
      {deg({90, -60, -45}), 2},  // and the other
  };
  for (const Case& k : cases) {
    const Pose target = c.palm(k.q);
    const IkResult& r = ik.solve(target);
    ASSERT_EQ(r.status, IkStatus::kSolved);
    EXPECT_EQ(r.solutions.size(), k.count) << k.q.transpose() / kDeg;
    for (const IkSolution& s : r.solutions) expect_reaches(c, s, target);
  }
  // Off the arm's plane: unreachable, missed by the offset.
  Pose off = c.palm(deg({30, 60, -45}));
  off.translation().z() += 0.01;
  const IkResult& r = ik.solve(off);
  EXPECT_EQ(r.status, IkStatus::kUnreachable);
  EXPECT_NEAR(r.best_position_residual, 0.01, 1e-9);
}

// PUMA 560: eight solutions at a generic posture (Craig sec. 4.7: shoulder left /
// right, elbow up / down, wrist flipped or not), in all three conventions.
TEST(IkPuma560, EightSolutionsInEachConvention) {
  const auto sdh = settings::load_model_text(test::kPuma560, "puma.yaml");
  const auto mdh = settings::load_model_text(test::kPuma560ModifiedDh, "puma_mdh.yaml");
  const Chain poe = sdh.chain.to_product_of_exponentials();
  const std::vector<JointVector> postures = {
      deg({10, -40, 30, 50, -60, 70}),
      deg({-120, 20, -50, 160, 45, -10}),
      deg({75, 135, 10, -80, -120, 100}),
  };
  for (const Chain* c : {&sdh.chain, &mdh.chain, &poe}) {
    IkSolver ik(*c, sdh.rig);
    for (const JointVector& q : postures) {
      const Pose target = c->palm(q);
      const IkResult& r = ik.solve(target);
      ASSERT_EQ(r.status, IkStatus::kSolved);
      EXPECT_EQ(r.solutions.size(), 8u) << q.transpose() / kDeg;
      bool found = false;
      for (const IkSolution& s : r.solutions) {
        expect_reaches(*c, s, target);
        found = found || angular_distance(s.q, q) <= 1e-7;
      }
      EXPECT_TRUE(found) << q.transpose() / kDeg;
    }
  }
}

TEST(IkPuma560, MultiStartFindsAllEightAtMostRandomPostures) {
  // The numerical solver's miss rate (docs/kinematics.md): every solution it
  // returns reaches the pose; all eight at >= 99 % of random postures.
  const auto m = settings::load_model_text(test::kPuma560, "puma.yaml");
  IkSolver ik(m.chain, m.rig);
  std::mt19937_64 rng(11);
  int all_eight = 0;
  const int postures = 1000;
  for (int t = 0; t < postures; ++t) {
    const Pose target = m.chain.palm(test::random_within_limits(m.chain, rng));
    const IkResult& r = ik.solve(target);
    ASSERT_EQ(r.status, IkStatus::kSolved);
    ASSERT_LE(r.solutions.size(), 8u);
    for (const IkSolution& s : r.solutions) expect_reaches(m.chain, s, target);
    all_eight += r.solutions.size() == 8u ? 1 : 0;
  }
  RecordProperty("all_eight", all_eight);
  std::printf("PUMA 560: all eight solutions at %d of %d random postures\n", all_eight, postures);
  EXPECT_GE(all_eight, 990);
}

TEST(IkPuma560, JointLimitsLeaveTheSolutionsWithin) {
  // Joint 2 limited to [-90, 90] deg: the shoulder-flipped solutions drop out.
  auto m = settings::load_model_text(test::kPuma560, "puma.yaml");
  std::vector<JointDescription> joints = m.chain.joints();
  joints[1].limits = {-kPi / 2, kPi / 2};
  const Chain limited(m.chain.convention(), joints, m.chain.base(), m.chain.tool());
  IkSolver all(m.chain, m.rig);
  IkSolver some(limited, m.rig);
  const JointVector q = deg({10, -40, 30, 50, -60, 70});
  const Pose target = m.chain.palm(q);
  const std::vector<IkSolution> every = all.solve(target).solutions;
  const IkResult& r = some.solve(target);
  ASSERT_EQ(r.status, IkStatus::kSolved);
  std::size_t expected = 0;
  for (const IkSolution& s : every) expected += within(limited, s.q) ? 1 : 0;
  EXPECT_EQ(r.solutions.size(), expected);
  EXPECT_LT(expected, 8u);
  for (const IkSolution& s : r.solutions) EXPECT_TRUE(within(limited, s.q));
}

TEST(IkAllocation, SolvingAllocatesNothingAfterSetUp) {
  const auto& m = test::macaque();
  const auto planar = settings::load_model_file(test::model_path("seed004_planar.yaml"));
  IkSolver closed(m.chain, m.rig);
  IkOptions o;
  o.use_analytical = false;
  o.free_joint_step = 5.0 * kDeg;  // a coarse numerical sweep keeps the test short
  IkSolver numerical(m.chain, m.rig, o);
  IkSolver flat(planar.chain, planar.rig);
  std::mt19937_64 rng(10);
  std::vector<Pose> targets;
  std::vector<Pose> flat_targets;
  for (int i = 0; i < 20; ++i) {
    targets.push_back(m.chain.palm(test::random_within_limits(m.chain, rng)));
    flat_targets.push_back(planar.chain.palm(test::random_within_limits(planar.chain, rng)));
  }
  Pose far = targets[0];
  far.translation() = Eigen::Vector3d(1.0, 0.0, 0.0);
  targets.push_back(far);
  IkSolution s;
  std::size_t solutions = 0;
  exodaq::test::AllocationScope scope;
  for (const Pose& t : targets) {
    solutions += closed.solve(t).solutions.size();
    solutions += closed.solve_fixed(t, 0.3).solutions.size();
    solutions += closed.solve_nearest(t, m.home_posture, s) ? 1 : 0;
    solutions += numerical.solve_fixed(t, 0.3).solutions.size();
    solutions += numerical.solve_nearest(t, m.home_posture, s) ? 1 : 0;
  }
  solutions += numerical.solve(targets[1]).solutions.size();
  for (const Pose& t : flat_targets) {
    solutions += flat.solve(t).solutions.size();
    solutions += flat.solve_nearest(t, planar.home_posture, s) ? 1 : 0;
  }
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_GT(solutions, 40u);
}

}  // namespace
}  // namespace exodaq::kinematics
