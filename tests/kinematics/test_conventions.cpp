// The same arm written in standard DH, modified (Craig) DH and product of
// exponentials gives the same palm pose and palm Jacobian.
#include <gtest/gtest.h>

#include "exodaq/settings/model_file.hpp"
#include "kin_test_util.hpp"

namespace exodaq::kinematics {
namespace {

using test::kPi;

void expect_same_palm(const Chain& a, const Chain& b, const JointVector& q, double tol) {
  Pose pa, pb;
  Jacobian Ja, Jb;
  a.palm_and_jacobian(q, pa, Ja);
  b.palm_and_jacobian(q, pb, Jb);
  ASSERT_LT((pa.matrix() - pb.matrix()).cwiseAbs().maxCoeff(), tol) << q.transpose();
  ASSERT_LT((Ja - Jb).cwiseAbs().maxCoeff(), tol) << q.transpose();
  ASSERT_LT((a.palm(q).matrix() - pb.matrix()).cwiseAbs().maxCoeff(), tol);
  ASSERT_LT((b.palm(q).matrix() - pa.matrix()).cwiseAbs().maxCoeff(), tol);
}

TEST(Conventions, MacaqueInThreeModelFilesAgree) {
  const auto& sdh = test::macaque();
  const auto mdh = settings::load_model_text(test::kMacaqueModifiedDh, "mdh.yaml");
  const auto poe = settings::load_model_text(test::kMacaquePoe, "poe.yaml");
  EXPECT_EQ(mdh.chain.convention(), Convention::kModifiedDh);
  EXPECT_EQ(poe.chain.convention(), Convention::kProductOfExponentials);
  const Chain converted = sdh.chain.to_product_of_exponentials();
  std::mt19937_64 rng(7);
  for (int t = 0; t < 2000; ++t) {
    const JointVector q =
        t % 2 ? test::random_within_limits(sdh.chain, rng) : test::random_any(6, rng);
    expect_same_palm(sdh.chain, mdh.chain, q, 1e-12);
    expect_same_palm(sdh.chain, poe.chain, q, 1e-12);
    expect_same_palm(sdh.chain, converted, q, 1e-12);
  }
}

TEST(Conventions, DhToPoeKeepsEveryFrameAndJacobian) {
  const auto& sdh = test::macaque();
  const Chain poe = sdh.chain.to_product_of_exponentials();
  ASSERT_EQ(poe.convention(), Convention::kProductOfExponentials);
  // The screws read off the table (see test::kMacaquePoe).
  const double L1 = test::kL1;
  const Eigen::Vector3d w[6] = {{0, 0, 1}, {0, 1, 0}, {0, 0, 1}, {0, 1, 0}, {0, 0, 1}, {0, 1, 0}};
  const Eigen::Vector3d p[6] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}, {0, 0, 0}, {0, L1, 0}, {0, L1, 0}};
  for (int i = 0; i < 6; ++i) {
    const auto& s = poe.joints()[static_cast<std::size_t>(i)].screw;
    EXPECT_LT((s.omega - w[i]).norm(), 1e-15) << i;
    // The point may sit anywhere on the axis: check the moment q x omega.
    EXPECT_LT((s.q.cross(s.omega) - p[i].cross(w[i])).norm(), 1e-15) << i;
  }
  std::mt19937_64 rng(8);
  for (int t = 0; t < 500; ++t) {
    const JointVector q = test::random_any(6, rng);
    for (int f = 0; f <= 7; ++f) {
      ASSERT_LT((sdh.chain.frame(q, f).matrix() - poe.frame(q, f).matrix()).cwiseAbs().maxCoeff(),
                1e-12)
          << "frame " << f;
      if (f == 0) continue;
      Jacobian Ja, Jb;
      sdh.chain.jacobian(q, f, Ja);
      poe.jacobian(q, f, Jb);
      ASSERT_LT((Ja - Jb).cwiseAbs().maxCoeff(), 1e-12) << "frame " << f;
    }
  }
}

TEST(Conventions, GeneralTablesWithOffsetsBaseAndTool) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> len(-0.5, 0.5), ang(-kPi, kPi);
  for (int trial = 0; trial < 50; ++trial) {
    const int n = 1 + trial % kMaxJoints;
    std::vector<JointDescription> sj(static_cast<std::size_t>(n));
    for (auto& j : sj) j.dh = DhRow{len(rng), ang(rng), len(rng), ang(rng)};
    Pose base = Pose::Identity(), tool = Pose::Identity();
    base.rotate(Eigen::AngleAxisd(ang(rng), Eigen::Vector3d(0.3, -1, 0.2).normalized()));
    base.translation() = Eigen::Vector3d(len(rng), len(rng), len(rng));
    tool.rotate(Eigen::AngleAxisd(ang(rng), Eigen::Vector3d(1, 1, 0.5).normalized()));
    tool.translation() = Eigen::Vector3d(len(rng), len(rng), len(rng));
    // Craig's form of the same arm: row i = (a_{i-1}, alpha_{i-1}, d_i, offset_i).
    std::vector<JointDescription> mj = sj;
    for (int i = 0; i < n; ++i) {
      mj[static_cast<std::size_t>(i)].dh.a = i ? sj[static_cast<std::size_t>(i - 1)].dh.a : 0.0;
      mj[static_cast<std::size_t>(i)].dh.alpha =
          i ? sj[static_cast<std::size_t>(i - 1)].dh.alpha : 0.0;
    }
    const auto& last = sj.back().dh;
    Pose mtool = Pose::Identity();
    mtool.translate(Eigen::Vector3d(last.a, 0, 0));
    mtool.rotate(Eigen::AngleAxisd(last.alpha, Eigen::Vector3d::UnitX()));
    mtool = mtool * tool;
    const Chain sdh(Convention::kStandardDh, sj, base, tool);
    const Chain mdh(Convention::kModifiedDh, mj, base, mtool);
    const Chain poe = sdh.to_product_of_exponentials();
    const Chain poe2 = mdh.to_product_of_exponentials();
    for (int t = 0; t < 40; ++t) {
      const JointVector q = test::random_any(n, rng);
      expect_same_palm(sdh, mdh, q, 1e-12);
      expect_same_palm(sdh, poe, q, 1e-12);
      expect_same_palm(sdh, poe2, q, 1e-12);
    }
  }
}

TEST(Conventions, PoeJointOffsetShiftsTheZero) {
  // offset: exp(xi (q + offset)); a planar 1R arm of length 1 about z.
  const auto m = settings::load_model_text(R"(
name: one
convention: poe
angle_unit: deg
joints:
  - {name: j, screw: {omega: [0, 0, 2], q: [0, 0, 0]}, offset: 90, limits: [-180, 180]}
home_pose: {translation: [1, 0, 0]}
)",
                                           "one.yaml");
  JointVector q(1);
  q << 0.0;
  EXPECT_LT((m.chain.palm(q).translation() - Eigen::Vector3d(0, 1, 0)).norm(), 1e-15);
  q << -kPi / 2;
  EXPECT_LT((m.chain.palm(q).translation() - Eigen::Vector3d(1, 0, 0)).norm(), 1e-15);
}

}  // namespace
}  // namespace exodaq::kinematics
