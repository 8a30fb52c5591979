#include "exodaq/kinematics/rig_kinematics.hpp"

#include <cmath>
#include <limits>

#include "chain_access.hpp"

namespace exodaq::kinematics {

void evaluate_rig(const Chain& chain, const RigKinematicsConfig& config, const JointVector& q,
                  RigPose& out) noexcept {
  const int n = chain.joint_count();
  const int k = config.shoulder_joints;
  const int e = config.elbow_frame;
  if (q.size() != n || k < 0 || k > n || e < 0 || e > n + 1) {
    constexpr double nan = std::numeric_limits<double>::quiet_NaN();
    out.palm_position.setConstant(nan);
    out.palm_rotation.setConstant(nan);
    out.palm_quaternion_wxyz.setConstant(nan);
    out.elbow_position.setConstant(nan);
    out.shoulder_manipulability = nan;
    out.shoulder_manipulability_normalised = nan;
    out.near_singular = true;
    return;
  }
  Eigen::Vector3d axis[kMaxJoints];
  ChainAccess::Rigid palm;
  ChainAccess::Rigid elbow;
  ChainAccess::Sweep s;
  s.joints = n;
  s.axis = axis;
  s.frame = e;
  s.frame_pose = &elbow;
  s.frame_rotation = false;
  s.palm = &palm;
  ChainAccess::sweep(chain, q, s);

  out.palm_position = palm.p;
  out.palm_rotation = palm.R;
  out.palm_quaternion_wxyz = quaternion_wxyz(palm.R);
  if (e == 0) {
    out.elbow_position = chain.base().translation();
  } else if (e == n + 1) {
    out.elbow_position = palm.p;
  } else {
    out.elbow_position = elbow.p;
  }
  // det(J_o J_o^T) by Cauchy-Binet: the sum of the squared 3x3 minors, each a
  // triple product of three joint axes. Exact to rounding at a singularity
  // (det of the 3x3 Gram matrix would leave sqrt(eps) ~ 1e-8 there).
  double det = 0.0;
  for (int a = 0; a + 2 < k; ++a) {
    for (int b = a + 1; b + 1 < k; ++b) {
      const Eigen::Vector3d ab = axis[a].cross(axis[b]);
      for (int c = b + 1; c < k; ++c) {
        const double minor = ab.dot(axis[c]);
        det += minor * minor;
      }
    }
  }
  const double w = std::sqrt(det);
  out.shoulder_manipulability = w;
  out.shoulder_manipulability_normalised =
      config.shoulder_manipulability_max > 0.0 ? w / config.shoulder_manipulability_max : 0.0;
  out.near_singular = !(out.shoulder_manipulability_normalised >= config.singularity_threshold);
}

}  // namespace exodaq::kinematics
