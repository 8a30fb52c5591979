// Seed 004's three planar examples (eqs. 13-15), from the PoE model file
// config/models/seed004_planar.yaml (lengths in mm, l1 = 397, l2 = 450, l3 = 212).
//
// The paper prints the palm poses but not the joint angles. We recovered them
// from each printed matrix with the closed form of eq. (11): the palm angle
// phi = t1 + t2 + t3 = atan2(R10, R00) from the printed first column, then the
// 2R inverse kinematics of the wrist point p - l3 (-sin phi, cos phi) (two
// elbow branches; we keep the one nearest round numbers):
//   example 1 (eq. 13): t = (-0.52320574011699850, 1.0457434259492702, 0.78604449121438358) rad
//                         = (-29.978, 59.917, 45.037) deg, close to (-30, 60, 45)
//   example 2 (eq. 14): t = (2.0923025016654750, -2.3561971204052456, -0.87241939158092796) rad
//                         = (119.880, -135.000, -49.986) deg, close to (120, -135, -50)
//   example 3 (eq. 15): t = (pi/4, pi/4, -pi/4) exactly.
// Printed digits: positions are reproduced to half a unit of the last printed
// digit. Rotation entries to one unit of the last printed digit: example 1's
// printed 0.259 / 0.965 cannot both be rounded values of one angle (cos 74.96 deg
// rounds to 0.259 but sin needs <= 74.90 deg to round to 0.965), so the paper
// truncates at least one of them. Its R11 = 0.2596 is a typo: a planar rotation
// has R11 = R00 = 0.259 (0.2592 here).
#include <gtest/gtest.h>

#include <cmath>

#include "exodaq/settings/model_file.hpp"
#include "kin_test_util.hpp"

namespace exodaq::kinematics {
namespace {

struct Example {
  const char* name;
  double t[3];
  double R[2][2];  // printed upper-left 2x2 (R02 = R12 = R20 = R21 = 0, R22 = 1)
  double unit_R[2][2];
  double p[2];  // printed x, y in mm (z = 0)
  double unit_p[2];
};

const Example kExamples[] = {
    {"eq. 13",
     {-0.52320574011699850, 1.0457434259492702, 0.78604449121438358},
     {{0.259, -0.965}, {0.965, 0.259 /* printed 0.2596: typo */}},
     {{1e-3, 1e-3}, {1e-3, 1e-3}},
     {-230.975, 788.7946},
     {1e-3, 1e-4}},
    {"eq. 14",
     {2.0923025016654750, -2.3561971204052456, -0.87241939158092796},
     {{0.4209, 0.907}, {-0.907, 0.4209}},
     {{1e-4, 1e-3}, {1e-3, 1e-4}},
     {-34.545, 325.881},
     {1e-3, 1e-3}},
    {"eq. 15",
     {M_PI / 4, M_PI / 4, -M_PI / 4},
     {{0.7071, -0.7071}, {0.7071, 0.7071}},
     {{1e-4, 1e-4}, {1e-4, 1e-4}},
     {-880.628, 430.628},
     {1e-3, 1e-3}},
};

TEST(Seed004, PlanarExamplesFromPoeModelFile) {
  const auto m = settings::load_model_file(test::model_path("seed004_planar.yaml"));
  ASSERT_EQ(m.chain.joint_count(), 3);
  ASSERT_EQ(m.chain.convention(), Convention::kProductOfExponentials);
  // g_st(0) of eq. (11) at q = 0: palm at (0, l1 + l2 + l3, 0) mm = 1.059 m.
  EXPECT_LT((m.chain.home_pose().translation() - Eigen::Vector3d(0, 1.059, 0)).norm(), 1e-15);
  for (const Example& ex : kExamples) {
    SCOPED_TRACE(ex.name);
    JointVector q(3);
    q << ex.t[0], ex.t[1], ex.t[2];
    const Pose g = m.chain.palm(q);
    const Eigen::Vector3d p_mm = g.translation() * 1000.0;  // the model is loaded in metres
    for (int i = 0; i < 2; ++i) {
      EXPECT_NEAR(p_mm[i], ex.p[i], 0.5 * ex.unit_p[i]) << "p[" << i << "]";
      for (int j = 0; j < 2; ++j) {
        EXPECT_NEAR(g.linear()(i, j), ex.R[i][j], ex.unit_R[i][j]) << "R(" << i << "," << j << ")";
      }
    }
    EXPECT_NEAR(p_mm.z(), 0.0, 1e-9);
    EXPECT_NEAR(g.linear()(2, 2), 1.0, 1e-15);
    EXPECT_NEAR(g.linear()(0, 2), 0.0, 1e-15);
    EXPECT_NEAR(g.linear()(2, 0), 0.0, 1e-15);
    // And eq. (11) written out.
    const double l1 = 0.397, l2 = 0.450, l3 = 0.212;
    const double s1 = std::sin(q[0]), c1 = std::cos(q[0]);
    const double s12 = std::sin(q[0] + q[1]), c12 = std::cos(q[0] + q[1]);
    const double s123 = std::sin(q.sum()), c123 = std::cos(q.sum());
    EXPECT_NEAR(g.translation().x(), -l3 * s123 - l2 * s12 - l1 * s1, 1e-15);
    EXPECT_NEAR(g.translation().y(), l3 * c123 + l2 * c12 + l1 * c1, 1e-15);
    EXPECT_NEAR(g.linear()(0, 0), c123, 1e-15);
    EXPECT_NEAR(g.linear()(1, 0), s123, 1e-15);
  }
  // Example 3 exactly: (-(l1 + l3) sqrt(1/2) - l2, (l1 + l3) sqrt(1/2)).
  JointVector q(3);
  q << M_PI / 4, M_PI / 4, -M_PI / 4;
  const Eigen::Vector3d p = m.chain.palm(q).translation() * 1000.0;
  EXPECT_NEAR(p.x(), -609.0 * std::sqrt(0.5) - 450.0, 1e-9);
  EXPECT_NEAR(p.y(), 609.0 * std::sqrt(0.5), 1e-9);
}

TEST(Seed004, PrintedHomePoseSignWouldNotReproduceTheExamples) {
  // The paper's eq. (4) puts the palm at y = -(l1 + l2 + l3) at q = 0; with that
  // M example 3 lands elsewhere, which is why the model file follows eq. (11).
  const auto m = settings::load_model_text(R"(
name: seed004_eq4
convention: poe
angle_unit: deg
length_unit: mm
joints:
  - {name: a, screw: {omega: [0, 0, 1], q: [0, 0, 0]}, limits: [-180, 180]}
  - {name: b, screw: {omega: [0, 0, 1], q: [0, 397, 0]}, limits: [-180, 180]}
  - {name: c, screw: {omega: [0, 0, 1], q: [0, 847, 1]}, limits: [-180, 180]}
home_pose: {translation: [0, -1059, 0]}
)",
                                           "eq4.yaml");
  JointVector q(3);
  q << M_PI / 4, M_PI / 4, -M_PI / 4;
  const Eigen::Vector3d p = m.chain.palm(q).translation() * 1000.0;
  EXPECT_GT(std::abs(p.x() - -880.628), 100.0);
}

}  // namespace
}  // namespace exodaq::kinematics
