// Seed 000 rig: home posture, eq. (1), quaternion, finite-difference Jacobians.
#include <gtest/gtest.h>

#include <cmath>

#include "exodaq/kinematics/chain.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"
#include "kin_test_util.hpp"

namespace exodaq::kinematics {
namespace {

using test::kDeg;
using test::kL1;
using test::kL2;
using test::kPi;

TEST(MacaqueModel, LoadsTable3) {
  const auto& m = test::macaque();
  EXPECT_EQ(m.name, "macaque_exo");
  ASSERT_EQ(m.chain.joint_count(), 6);
  EXPECT_EQ(m.chain.convention(), Convention::kStandardDh);
  const double alpha[6] = {-90, 90, -90, 90, -90, 0};
  const double d[6] = {0, 0, 0, kL1, 0, kL2};
  const double lo[6] = {-50.5, -228.3, -98.1, -80, -88.7, -80};
  const double hi[6] = {140.5, 48.3, 98.1, 80, 8.1, 80};
  for (int i = 0; i < 6; ++i) {
    const auto& j = m.chain.joints()[static_cast<std::size_t>(i)];
    EXPECT_DOUBLE_EQ(j.dh.a, 0.0) << i;
    EXPECT_NEAR(j.dh.alpha, alpha[i] * kDeg, 1e-15) << i;
    EXPECT_DOUBLE_EQ(j.dh.d, d[i]) << i;
    EXPECT_NEAR(j.limits.lower, lo[i] * kDeg, 1e-15) << i;
    EXPECT_NEAR(j.limits.upper, hi[i] * kDeg, 1e-15) << i;
  }
  const double home[6] = {kPi / 4, -kPi / 2, kPi / 2, 0, 0, 0};
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(m.home_posture[i], home[i], 1e-15) << i;
  EXPECT_EQ(m.rig.elbow_frame, 4);
  EXPECT_EQ(m.rig.shoulder_joints, 4);
}

TEST(MacaqueModel, HomePosturePalmHangsBelowShoulder) {
  const auto& m = test::macaque();
  const Pose palm = m.chain.palm(m.home_posture);
  EXPECT_NEAR(palm.translation().x(), 0.0, 1e-15);
  EXPECT_NEAR(palm.translation().y(), 0.0, 1e-15);
  EXPECT_NEAR(palm.translation().z(), -(kL1 + kL2), 1e-15);
  // Rz(45) Rx(-90) Rz(-90) Rx(90) Rz(90) Rx(-90) Rx(90) Rx(-90) = Rz(45) Ry(180) Rz(90):
  // palm z6 points down the forearm, x6 and y6 horizontal at +-45 deg.
  const double c = std::sqrt(0.5);
  Eigen::Matrix3d expected;
  expected << -c, c, 0,  //
      c, c, 0,           //
      0, 0, -1;
  EXPECT_LT((palm.linear() - expected).cwiseAbs().maxCoeff(), 1e-15) << palm.linear();
  // A half turn about (sin 22.5, cos 22.5, 0): w = 0, first non-zero component positive.
  const Eigen::Vector4d q = quaternion_wxyz(palm.linear());
  EXPECT_NEAR(q[0], 0.0, 1e-15);
  EXPECT_NEAR(q[1], std::sin(22.5 * kDeg), 1e-15);
  EXPECT_NEAR(q[2], std::cos(22.5 * kDeg), 1e-15);
  EXPECT_NEAR(q[3], 0.0, 1e-15);
  // Elbow (origin of frame 4) at L1 below the shoulder centre.
  const Pose elbow = m.chain.frame(m.home_posture, 4);
  EXPECT_LT((elbow.translation() - Eigen::Vector3d(0, 0, -kL1)).norm(), 1e-15);

  RigPose rig;
  evaluate_rig(m.chain, m.rig, m.home_posture, rig);
  EXPECT_LT((rig.palm_position - Eigen::Vector3d(0, 0, -(kL1 + kL2))).norm(), 1e-15);
  EXPECT_LT((rig.palm_rotation - expected).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((rig.palm_quaternion_wxyz - q).norm(), 1e-15);
  EXPECT_LT((rig.elbow_position - Eigen::Vector3d(0, 0, -kL1)).norm(), 1e-15);
  // Home: theta2 = -90, theta3 = 90 -> det(J_o J_o^T) = 2 (its maximum), sqrt = sqrt(2).
  EXPECT_NEAR(rig.shoulder_manipulability, std::sqrt(2.0), 1e-14);
  EXPECT_NEAR(rig.shoulder_manipulability_normalised, 1.0, 1e-14);
  EXPECT_FALSE(rig.near_singular);
}

TEST(MacaqueModel, ZeroPostureFramesFromTable3) {
  // q = 0: frames alternate Rx(-90) / identity; the arm lies along +y0.
  const auto& m = test::macaque();
  const JointVector q = JointVector::Zero(6);
  EXPECT_LT((m.chain.frame(q, 4).translation() - Eigen::Vector3d(0, kL1, 0)).norm(), 1e-15);
  EXPECT_LT((m.chain.palm(q).translation() - Eigen::Vector3d(0, kL1 + kL2, 0)).norm(), 1e-15);
  EXPECT_TRUE(m.chain.frame(q, 0).isApprox(Pose::Identity()));
  EXPECT_TRUE(m.chain.frame(q, 7).isApprox(m.chain.palm(q)));
}

TEST(MacaqueModel, ShoulderJacobianEqualsEq1) {
  const auto& m = test::macaque();
  // One configuration by hand: theta = (0, -90, 90), s1 = 0, c1 = 1, s2 = -1, c2 = 0,
  // s3 = 1, c3 = 0 in eq. (1).
  {
    JointVector q(6);
    q << 0, -kPi / 2, kPi / 2, 0.3, -0.2, 0.1;
    Jacobian J;
    m.chain.jacobian(q, 7, J);
    Eigen::Matrix<double, 3, 4> expected;
    expected << 0, 0, -1, 0,  //
        0, 1, 0, 0,           //
        1, 0, 0, -1;
    EXPECT_LT((J.block<3, 4>(3, 0) - expected).cwiseAbs().maxCoeff(), 1e-15);
    EXPECT_LT((shoulder_orientation_jacobian_closed_form(0, -kPi / 2, kPi / 2) - expected)
                  .cwiseAbs()
                  .maxCoeff(),
              1e-15);
  }
  std::mt19937_64 rng(1);
  for (int trial = 0; trial < 2000; ++trial) {
    const JointVector q =
        trial % 2 ? test::random_within_limits(m.chain, rng) : test::random_any(6, rng);
    const auto Jo = shoulder_orientation_jacobian_closed_form(q[0], q[1], q[2]);
    for (int frame = 4; frame <= 7; ++frame) {  // angular rows do not depend on the frame
      Jacobian J;
      m.chain.jacobian(q, frame, J);
      for (int col = 0; col < 4; ++col) {
        ASSERT_LT((J.block<3, 1>(3, col) - Jo.col(col)).norm(), 1e-14)
            << "trial " << trial << " frame " << frame << " column " << col + 1;
      }
    }
    Pose palm;
    Jacobian J;
    m.chain.palm_and_jacobian(q, palm, J);
    ASSERT_LT((J.block<3, 4>(3, 0) - Jo).cwiseAbs().maxCoeff(), 1e-14) << trial;
  }
}

// Angular velocity from a rotation's central difference: vee(dR R^T).
Eigen::Vector3d omega_fd(const Eigen::Matrix3d& Rp, const Eigen::Matrix3d& Rm,
                         const Eigen::Matrix3d& R, double h) {
  const Eigen::Matrix3d W = (Rp - Rm) / (2 * h) * R.transpose();
  return Eigen::Vector3d(W(2, 1) - W(1, 2), W(0, 2) - W(2, 0), W(1, 0) - W(0, 1)) / 2;
}

void expect_jacobian_matches_fd(const Chain& chain, std::mt19937_64& rng, int trials) {
  const int n = chain.joint_count();
  const double h = 1e-6;
  double worst = 0;
  for (int t = 0; t < trials; ++t) {
    const JointVector q = test::random_any(n, rng);
    for (int f = 1; f <= n + 1; ++f) {
      Jacobian J;
      chain.jacobian(q, f, J);
      ASSERT_EQ(J.cols(), n);
      const Pose F = chain.frame(q, f);
      for (int j = 0; j < n; ++j) {
        JointVector qp = q, qm = q;
        qp[j] += h;
        qm[j] -= h;
        const Pose Fp = chain.frame(qp, f), Fm = chain.frame(qm, f);
        const Eigen::Vector3d v = (Fp.translation() - Fm.translation()) / (2 * h);
        const Eigen::Vector3d w = omega_fd(Fp.linear(), Fm.linear(), F.linear(), h);
        const double err = std::max((J.block<3, 1>(0, j) - v).cwiseAbs().maxCoeff(),
                                    (J.block<3, 1>(3, j) - w).cwiseAbs().maxCoeff());
        worst = std::max(worst, err);
        ASSERT_LT(err, 1e-7) << "frame " << f << " joint " << j + 1;
        if (j >= f) {
          ASSERT_EQ(J.col(j).norm(), 0.0) << "joint beyond the frame moves it";
        }
      }
    }
    Pose palm;
    Jacobian Jp, Jf;
    chain.palm_and_jacobian(q, palm, Jp);
    chain.jacobian(q, n + 1, Jf);
    ASSERT_LT((Jp - Jf).cwiseAbs().maxCoeff(), 1e-15);
    ASSERT_TRUE(palm.isApprox(chain.palm(q), 1e-15));
  }
  EXPECT_LT(worst, 1e-7);
}

TEST(Jacobian, EqualsCentralFiniteDifferencesOnRig) {
  std::mt19937_64 rng(2);
  const auto& m = test::macaque();
  expect_jacobian_matches_fd(m.chain, rng, 200);
  expect_jacobian_matches_fd(m.chain.to_product_of_exponentials(), rng, 100);
}

TEST(Jacobian, EqualsCentralFiniteDifferencesOnGeneralChains) {
  // Arbitrary DH tables with a != 0, offsets, a base and a tool, in all three forms.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> len(-0.4, 0.4), ang(-kPi, kPi);
  for (int trial = 0; trial < 10; ++trial) {
    std::vector<JointDescription> joints(7);
    for (auto& j : joints) j.dh = DhRow{len(rng), ang(rng), len(rng), ang(rng)};
    Pose base = Pose::Identity(), tool = Pose::Identity();
    base.rotate(Eigen::AngleAxisd(ang(rng), Eigen::Vector3d(1, 2, 3).normalized()));
    base.translation() = Eigen::Vector3d(len(rng), len(rng), len(rng));
    tool.rotate(Eigen::AngleAxisd(ang(rng), Eigen::Vector3d(-1, 0.5, 2).normalized()));
    tool.translation() = Eigen::Vector3d(len(rng), len(rng), len(rng));
    const Chain sdh(Convention::kStandardDh, joints, base, tool);
    const Chain mdh(Convention::kModifiedDh, joints, base, tool);
    expect_jacobian_matches_fd(sdh, rng, 5);
    expect_jacobian_matches_fd(mdh, rng, 5);
    expect_jacobian_matches_fd(sdh.to_product_of_exponentials(), rng, 5);
  }
}

TEST(Manipulability, RowMaskAndRelative) {
  Jacobian J(6, 3);
  J.setZero();
  J(0, 0) = 2;  // vx
  J(1, 1) = 3;  // vy
  J(5, 2) = 5;  // wz
  EXPECT_NEAR(manipulability(J, 0x01), 2.0, 1e-15);
  EXPECT_NEAR(manipulability(J, 0x03), 6.0, 1e-15);
  EXPECT_NEAR(manipulability(J, 0x23), 30.0, 1e-15);
  EXPECT_EQ(manipulability(J, kLinearRows), 0.0);  // vz row empty
  EXPECT_EQ(manipulability(J, 0x3F), 0.0);         // 6 rows, 3 columns
  EXPECT_EQ(manipulability(J, 0), 0.0);
  // Against Eigen's determinant on a random full Jacobian.
  std::mt19937_64 rng(4);
  const auto& m = test::macaque();
  for (int t = 0; t < 100; ++t) {
    const JointVector q = test::random_within_limits(m.chain, rng);
    Jacobian Jr;
    m.chain.jacobian(q, 7, Jr);
    // The four shoulder axes meet at the shoulder centre, so their twists span
    // only 3 dimensions: the 6x6 palm Jacobian always has rank 5.
    EXPECT_LT(manipulability(Jr, 0x3F), 1e-12);
    Eigen::Matrix<double, 5, 6> five = Jr.topRows<5>();
    const Eigen::Matrix<double, 5, 5> g5 = five * five.transpose();
    EXPECT_NEAR(manipulability(Jr, 0x1F), std::sqrt(g5.determinant()), 1e-12);
    const Eigen::Matrix3d lin = Jr.topRows<3>() * Jr.topRows<3>().transpose();
    EXPECT_NEAR(manipulability(Jr, kLinearRows), std::sqrt(lin.determinant()), 1e-12);
    // Seed 000 eq. (3): det^(1/m) / sqrt(sum a^2 + d^2), here sum = L1^2 + L2^2.
    EXPECT_NEAR(relative_manipulability(Jr, kLinearRows, m.chain),
                std::cbrt(lin.determinant()) / std::hypot(kL1, kL2), 1e-12);
  }
  EXPECT_NEAR(m.chain.dh_length_scale_sq(), kL1 * kL1 + kL2 * kL2, 1e-15);
  EXPECT_NEAR(m.chain.to_product_of_exponentials().dh_length_scale_sq(), kL1 * kL1 + kL2 * kL2,
              1e-15);
}

TEST(Quaternion, UnitWNonNegativeAndRoundTrips) {
  std::mt19937_64 rng(5);
  for (int t = 0; t < 1000; ++t) {
    const Eigen::Quaterniond r = Eigen::Quaterniond::UnitRandom();
    const Eigen::Matrix3d R = r.toRotationMatrix();
    const Eigen::Vector4d q = quaternion_wxyz(R);
    EXPECT_GE(q[0], 0.0);
    EXPECT_NEAR(q.norm(), 1.0, 1e-15);
    const Eigen::Quaterniond back(q[0], q[1], q[2], q[3]);
    EXPECT_LT((back.toRotationMatrix() - R).cwiseAbs().maxCoeff(), 1e-14);
  }
  // A 90 deg turn about z: (cos 45, 0, 0, sin 45).
  const Eigen::Vector4d q =
      quaternion_wxyz(Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix());
  EXPECT_NEAR(q[0], std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(q[3], std::sqrt(0.5), 1e-15);
  // A 270 deg turn is published as -90 deg (w >= 0).
  const Eigen::Vector4d q2 =
      quaternion_wxyz(Eigen::AngleAxisd(1.5 * kPi, Eigen::Vector3d::UnitZ()).toRotationMatrix());
  EXPECT_NEAR(q2[0], std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(q2[3], -std::sqrt(0.5), 1e-15);
}

TEST(Chain, WrongJointCountGivesNaNNotACrash) {
  const auto& m = test::macaque();
  const JointVector q = JointVector::Zero(5);
  EXPECT_TRUE(std::isnan(m.chain.palm(q).translation().x()));
  Jacobian J;
  m.chain.jacobian(q, 7, J);
  EXPECT_TRUE(std::isnan(J(0, 0)));
  EXPECT_TRUE(std::isnan(m.chain.frame(JointVector::Zero(6), 9).translation().x()));
  RigPose rig;
  evaluate_rig(m.chain, m.rig, q, rig);
  EXPECT_TRUE(std::isnan(rig.palm_position.x()));
  EXPECT_TRUE(rig.near_singular);
}

TEST(Chain, RejectsTooManyJointsAndZeroScrew) {
  std::vector<JointDescription> nine(kMaxJoints + 1);
  EXPECT_THROW(Chain(Convention::kStandardDh, nine, Pose::Identity(), Pose::Identity()),
               std::invalid_argument);
  std::vector<JointDescription> one(1);
  one[0].screw.omega.setZero();
  EXPECT_THROW(Chain(Convention::kProductOfExponentials, one, Pose::Identity(), Pose::Identity()),
               std::invalid_argument);
}

}  // namespace
}  // namespace exodaq::kinematics
