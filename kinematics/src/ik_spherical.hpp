#pragma once
// Internal to exodaq_kinematics: closed-form inverse kinematics of a six-joint
// arm with a spherical shoulder (axes 1-4 through one point S) and an elbow
// (axes 5 and 6 meet at a point E), seed 000's structure, in product-of-
// exponentials form. Joint 1 is the free joint; with it given, the solutions are
// Paden-Kahan subproblems (docs/kinematics.md, "Inverse kinematics").
// No allocation, no exceptions after detect().
#include <optional>

#include "exodaq/kinematics/chain.hpp"

namespace exodaq::kinematics::ik_detail {

struct SphericalCandidate {
  JointVector q;                // joint angles (offsets removed), not yet wrapped or polished
  bool straight_arm = false;    // elbow axis undetermined: joint 6 set to mid-range
  bool shoulder_triad = false;  // joints 2 and 4 aligned: joint 2 set to mid-range
};

class SphericalShoulderArm {
 public:
  // The closed form for `chain` when its geometry allows it (checked on the
  // chain's PoE form, to 1e-9 m / 1e-9 rad), else nullopt. Start-up only.
  static std::optional<SphericalShoulderArm> detect(const Chain& chain);

  // Up to four candidates with joint 1 at `q1`; returns how many were written
  // (0 when the pose is out of reach: the elbow off its sphere by more than
  // `reach_slack` m, or the forearm at an angle the elbow cannot make).
  // `elbow_sphere_miss` receives |E - S| - L1.
  int solve(const Pose& target, double q1, double reach_slack, SphericalCandidate out[4],
            double& elbow_sphere_miss) const noexcept;

 private:
  struct ShoulderTriad {
    double phi2 = 0.0, phi3 = 0.0, phi4 = 0.0;
    bool aligned = false;  // axes 2 and 4 in line
  };
  void shoulder_triad(const Eigen::Matrix3d& N, ShoulderTriad out[2]) const noexcept;
  void centre_singular_pairs(SphericalCandidate& c, const Eigen::Vector3d& forearm) const noexcept;
  void centre_pair(JointVector& q, int i, int j, double sigma) const noexcept;

  Pose base_inverse_ = Pose::Identity();
  Eigen::Vector3d s_ = Eigen::Vector3d::Zero();  // shoulder centre (O0)
  Eigen::Vector3d w_[6];                         // joint axes at q = 0 (O0)
  double offset_[6] = {};                        // joint i turns by q_i + offset_i
  double lower_[6] = {};                         // joint limits
  double upper_[6] = {};
  double mid_[6] = {};                                           // middle of each joint's limits
  Eigen::Vector3d u0_ = Eigen::Vector3d::Zero();                 // S -> E at q = 0, unit
  double upper_arm_ = 0.0;                                       // |E - S|
  Eigen::Vector3d elbow_in_palm_ = Eigen::Vector3d::Zero();      // E in palm coordinates
  Eigen::Vector3d axis6_in_palm_ = Eigen::Vector3d::Zero();      // axis 6 in palm coordinates
  Eigen::Matrix3d home_rotation_ = Eigen::Matrix3d::Identity();  // rotation of M
  // angle(u, f) equation: a cos(phi5) + b sin(phi5) + c = u . f
  double a_ = 0.0, b_ = 0.0, c_ = 0.0;
};

}  // namespace exodaq::kinematics::ik_detail
