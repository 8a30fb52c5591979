// KDL (ChainFkSolverPos_recursive, ChainJntToJacSolver) and exodaq agree on the
// seed-000 chain. KDL is a test/bench-only dependency.
#include <gtest/gtest.h>

#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainjnttojacsolver.hpp>
#include <kdl/jacobian.hpp>
#include <kdl/jntarray.hpp>

#include "kin_test_util.hpp"

namespace exodaq::kinematics {
namespace {

// One KDL segment per standard DH row: RotZ joint, then Frame::DH(a, alpha, d, offset).
KDL::Chain to_kdl(const Chain& c) {
  KDL::Chain k;
  for (const auto& j : c.joints()) {
    k.addSegment(KDL::Segment(j.name, KDL::Joint(KDL::Joint::RotZ),
                              KDL::Frame::DH(j.dh.a, j.dh.alpha, j.dh.d, j.dh.theta_offset)));
  }
  return k;
}

TEST(Kdl, AgreesWithExodaqOnSeed000Chain) {
  const auto& m = test::macaque();
  const KDL::Chain k = to_kdl(m.chain);
  ASSERT_EQ(k.getNrOfJoints(), 6u);
  KDL::ChainFkSolverPos_recursive fk(k);
  KDL::ChainJntToJacSolver jac(k);
  KDL::JntArray q_kdl(6);
  KDL::Jacobian J_kdl(6);
  std::mt19937_64 rng(12);
  for (int t = 0; t < 2000; ++t) {
    const JointVector q = t == 0 ? m.home_posture : test::random_any(6, rng);
    for (int i = 0; i < 6; ++i) q_kdl(i) = q[i];
    KDL::Frame f;
    ASSERT_GE(fk.JntToCart(q_kdl, f), 0);
    ASSERT_GE(jac.JntToJac(q_kdl, J_kdl), 0);
    Pose palm;
    Jacobian J;
    m.chain.palm_and_jacobian(q, palm, J);
    for (int r = 0; r < 3; ++r) {
      ASSERT_NEAR(palm.translation()[r], f.p(r), 1e-12);
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(palm.linear()(r, c), f.M(r, c), 1e-12);
    }
    // KDL's Jacobian: reference point = end effector, expressed in the base: the
    // same geometric Jacobian (rows vx vy vz wx wy wz).
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) ASSERT_NEAR(J(r, c), J_kdl(r, c), 1e-12) << r << "," << c;
    }
    // Link frames too (KDL segment i = frame i).
    for (int s = 1; s <= 6; ++s) {
      ASSERT_GE(fk.JntToCart(q_kdl, f, s), 0);
      const Pose F = m.chain.frame(q, s);
      for (int r = 0; r < 3; ++r) ASSERT_NEAR(F.translation()[r], f.p(r), 1e-12);
    }
  }
}

}  // namespace
}  // namespace exodaq::kinematics
