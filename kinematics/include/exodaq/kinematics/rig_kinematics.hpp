#pragma once
// What the daemon computes every cycle from a joint vector: palm pose, elbow
// position and the shoulder's manipulability (seed 000 eq. 1-2, Fig. 18).
#include "exodaq/kinematics/chain.hpp"

namespace exodaq::kinematics {

struct RigKinematicsConfig {
  int elbow_frame = 4;      // frame whose origin is the elbow (seed 000: frame 4, at d4 = L1)
  int shoulder_joints = 4;  // J_o: angular rows of the first four joints
  // The normaliser of Fig. 18: the largest sqrt(det(J_o J_o^T)) the arm can
  // reach. (k/3)^(3/2) bounds it for any k unit-axis columns in 3-D; the model
  // file gives the arm's own value (sqrt(2) for seed 000: det = 2(s2^2 + s3^2 -
  // s2^2 s3^2), largest at home).
  double shoulder_manipulability_max = 1.5396007178390020;  // (4/3)^(3/2), a generic bound
  double singularity_threshold = 0.05;                      // on the normalised value
};

struct RigPose {
  Eigen::Vector3d palm_position = Eigen::Vector3d::Zero();
  Eigen::Matrix3d palm_rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector4d palm_quaternion_wxyz{1.0, 0.0, 0.0, 0.0};
  Eigen::Vector3d elbow_position = Eigen::Vector3d::Zero();
  double shoulder_manipulability = 0.0;             // raw sqrt(det(J_o J_o^T))
  double shoulder_manipulability_normalised = 0.0;  // divided by the maximum
  bool near_singular = false;
};

// One evaluation; no allocation.
void evaluate_rig(const Chain& chain, const RigKinematicsConfig& config, const JointVector& q,
                  RigPose& out) noexcept;

}  // namespace exodaq::kinematics
