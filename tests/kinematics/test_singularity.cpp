// Seed 000 section 3.2: where sqrt(det(J_o J_o^T)) vanishes within Table 3's limits.
//
// From eq. (1) (Cauchy-Binet over the four 3x3 minors, which are -s2, c2 s3, s2 c3
// and -s3): det(J_o J_o^T) = 2 (sin^2 t2 + sin^2 t3 - sin^2 t2 sin^2 t3), independent
// of t1 and t4. It is zero only where sin t2 = sin t3 = 0; inside the limits
// (t2 in [-228.3, 48.3] deg, t3 in [-98.1, 98.1] deg) that is t3 = 0 with t2 = -180 deg
// (the paper's singularity, axis 1 || axis 3 and axis 2 || axis 4) or t2 = 0 (axis 3
// lines up with axis 1 again; the paper does not name this one). Its maximum is 2.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "exodaq/kinematics/rig_kinematics.hpp"
#include "kin_test_util.hpp"

namespace exodaq::kinematics {
namespace {

using test::kDeg;
using test::kPi;

double shoulder_w(const settings::KinematicModel& m, const JointVector& q) {
  RigPose out;
  evaluate_rig(m.chain, m.rig, q, out);
  return out.shoulder_manipulability;
}

double closed_form_w(double t2, double t3) {
  const double a = std::sin(t2) * std::sin(t2), b = std::sin(t3) * std::sin(t3);
  return std::sqrt(2.0 * (a + b - a * b));
}

bool is_singular_point(double t2, double t3) {
  return t3 == 0.0 && (t2 == 0.0 || t2 == -kPi);
}

TEST(ShoulderSingularity, VanishesExactlyAtTheTwoPointsOnAGrid) {
  const auto& m = test::macaque();
  const auto& J = m.chain.joints();
  // theta2 grid: every 2 deg from -228 to 48 plus -180 exactly (in radians),
  // theta3: every 2 deg from -98 to 98 (contains 0), theta1, theta4 spread over their limits.
  std::vector<double> t2s, t3s;
  for (int d = -228; d <= 48; d += 2) t2s.push_back(d == -180 ? -kPi : d * kDeg);
  t2s.push_back(J[1].limits.lower);
  t2s.push_back(J[1].limits.upper);
  for (int d = -98; d <= 98; d += 2) t3s.push_back(d * kDeg);
  const double t1s[] = {J[0].limits.lower, -0.3, 0.0, 1.0, J[0].limits.upper};
  const double t4s[] = {J[3].limits.lower, 0.0, 0.7, J[3].limits.upper};
  int singular = 0;
  double smallest_regular = 1e9;
  for (double t1 : t1s) {
    for (double t2 : t2s) {
      for (double t3 : t3s) {
        for (double t4 : t4s) {
          JointVector q(6);
          q << t1, t2, t3, t4, -0.4, 0.2;
          const double w = shoulder_w(m, q);
          ASSERT_NEAR(w, closed_form_w(t2, t3), 1e-12);
          if (is_singular_point(t2, t3)) {
            ++singular;
            ASSERT_LT(w, 1e-12) << "t1 " << t1 << " t2 " << t2 << " t4 " << t4;
          } else {
            smallest_regular = std::min(smallest_regular, w);
            // 2 deg from a singular point: w >= sin(2 deg) = 0.0349.
            ASSERT_GT(w, 0.034) << "t2 " << t2 / kDeg << " t3 " << t3 / kDeg;
          }
        }
      }
    }
  }
  EXPECT_EQ(singular, 5 * 2 * 4);  // two (t2, t3) points for every t1, t4
  EXPECT_NEAR(smallest_regular, std::sqrt(2.0) * std::sin(2 * kDeg), 1e-3);
}

TEST(ShoulderSingularity, SmallestValuesOfADenseSampleLieNextToThePoints) {
  const auto& m = test::macaque();
  std::mt19937_64 rng(6);
  struct Sample {
    double w, t2, t3;
  };
  std::vector<Sample> s;
  const int count = 400000;
  s.reserve(count);
  double largest = 0;
  for (int i = 0; i < count; ++i) {
    const JointVector q = test::random_within_limits(m.chain, rng);
    const double w = shoulder_w(m, q);
    largest = std::max(largest, w);
    s.push_back({w, q[1], q[2]});
  }
  std::partial_sort(s.begin(), s.begin() + 50, s.end(),
                    [](const Sample& a, const Sample& b) { return a.w < b.w; });
  int near_paper = 0, near_zero = 0;
  for (int i = 0; i < 50; ++i) {
    // w^2 >= sin^2 t2 + sin^2 t3, so a small w pins both angles.
    const double d_paper =
        std::hypot(s[static_cast<std::size_t>(i)].t2 + kPi, s[static_cast<std::size_t>(i)].t3);
    const double d_zero =
        std::hypot(s[static_cast<std::size_t>(i)].t2, s[static_cast<std::size_t>(i)].t3);
    ASSERT_LT(std::min(d_paper, d_zero), 0.1)
        << "sample " << i << ": w " << s[static_cast<std::size_t>(i)].w << " at t2 "
        << s[static_cast<std::size_t>(i)].t2 / kDeg << " t3 "
        << s[static_cast<std::size_t>(i)].t3 / kDeg;
    (d_paper < d_zero ? near_paper : near_zero)++;
  }
  EXPECT_GT(near_paper, 0);  // both points show up in the sample
  EXPECT_GT(near_zero, 0);
  // And the sample's maximum approaches sqrt(2), never above.
  EXPECT_LE(largest, std::sqrt(2.0) + 1e-12);
  EXPECT_GT(largest, std::sqrt(2.0) - 1e-3);
}

TEST(ShoulderSingularity, AxesLineUpAtBothPoints) {
  const auto& m = test::macaque();
  for (double t2 : {0.0, -kPi}) {
    JointVector q(6);
    q << 0.8, t2, 0.0, -0.5, -0.3, 0.4;
    Jacobian J;
    m.chain.jacobian(q, 7, J);
    const Eigen::Vector3d z0 = J.block<3, 1>(3, 0), z1 = J.block<3, 1>(3, 1);
    const Eigen::Vector3d z2 = J.block<3, 1>(3, 2), z3 = J.block<3, 1>(3, 3);
    EXPECT_NEAR(std::abs(z0.dot(z2)), 1.0, 1e-15) << "axis 3 || axis 1 at t2 = " << t2;
    EXPECT_NEAR(std::abs(z1.dot(z3)), 1.0, 1e-15) << "axis 4 || axis 2 at t2 = " << t2;
    RigPose out;
    evaluate_rig(m.chain, m.rig, q, out);
    EXPECT_LT(out.shoulder_manipulability, 1e-12);
    EXPECT_TRUE(out.near_singular);
  }
  // Just off the point: small but not zero, and flagged by the threshold.
  JointVector q(6);
  q << 0.8, -kPi + 0.01, 0.0, -0.5, -0.3, 0.4;
  RigPose out;
  evaluate_rig(m.chain, m.rig, q, out);
  EXPECT_NEAR(out.shoulder_manipulability, std::sqrt(2.0) * std::sin(0.01), 1e-12);
  EXPECT_TRUE(out.near_singular);
  EXPECT_NEAR(out.shoulder_manipulability_normalised, std::sin(0.01), 1e-12);
}

}  // namespace
}  // namespace exodaq::kinematics
