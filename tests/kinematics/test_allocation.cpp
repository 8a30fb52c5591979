// The hot path allocates nothing (counting operator new from exodaq_test_alloc).
#include <gtest/gtest.h>

#include <memory>
#include <vector>

#include "alloc_counter.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"
#include "kin_test_util.hpp"

namespace exodaq::kinematics {
namespace {

TEST(Allocation, CounterSeesAnAllocation) {
  // The counter works: a vector's growth is counted.
  exodaq::test::AllocationScope scope;
  auto v = std::make_unique<std::vector<int>>(100);
  EXPECT_GE(scope.count(), 2u);
}

void run_hot_path(const Chain& chain, const RigKinematicsConfig& cfg, int reps) {
  std::mt19937_64 rng(11);
  // Inputs and outputs prepared before counting.
  std::vector<JointVector> qs;
  for (int i = 0; i < reps; ++i) qs.push_back(test::random_within_limits(chain, rng));
  Pose palm;
  Jacobian J;
  RigPose rig;
  double sink = 0;
  exodaq::test::AllocationScope scope;
  for (const auto& q : qs) {
    palm = chain.palm(q);
    sink += palm.translation().x();
    for (int f = 0; f <= chain.joint_count() + 1; ++f) {
      sink += chain.frame(q, f).translation().y();
      chain.jacobian(q, f, J);
      sink += J(5, 0);
    }
    chain.palm_and_jacobian(q, palm, J);
    sink += manipulability(J, kLinearRows) + manipulability(J, kAngularRows) +
            manipulability(J, 0x3F) + relative_manipulability(J, kLinearRows, chain);
    evaluate_rig(chain, cfg, q, rig);
    sink += rig.shoulder_manipulability + quaternion_wxyz(rig.palm_rotation)[0];
    sink += shoulder_orientation_jacobian_closed_form(q[0], q[0], q[0])(0, 1);
  }
  EXPECT_EQ(scope.count(), 0u);
  EXPECT_TRUE(std::isfinite(sink));
}

TEST(Allocation, HotPathAllocatesNothing) {
  const auto& m = test::macaque();
  run_hot_path(m.chain, m.rig, 200);
  const Chain poe = m.chain.to_product_of_exponentials();
  run_hot_path(poe, m.rig, 200);
  const auto planar = settings::load_model_file(test::model_path("seed004_planar.yaml"));
  run_hot_path(planar.chain, planar.rig, 200);
}

}  // namespace
}  // namespace exodaq::kinematics
