#pragma once
// Internal to exodaq_kinematics: one pass over a chain, shared by Chain's
// evaluation functions and evaluate_rig(). No allocation, no exceptions.
#include "exodaq/kinematics/chain.hpp"

namespace exodaq::kinematics {

struct ChainAccess {
  using Rigid = Chain::Rigid;

  // What one pass should record. Every pointer may be null.
  struct Sweep {
    int joints = 0;                    // run joints 1..joints (palm needs all n)
    Eigen::Vector3d* axis = nullptr;   // [joints] world axis of joint j (z before Rz(q_j))
    Eigen::Vector3d* point = nullptr;  // [joints] world point on that axis
    int frame = -1;                    // link frame 1..n whose pose is wanted (origin only
    Rigid* frame_pose = nullptr;       // if frame_rotation is false)
    bool frame_rotation = true;
    Rigid* palm = nullptr;  // requires joints == n
  };

  static void sweep(const Chain& c, const JointVector& q, const Sweep& s) noexcept;
};

}  // namespace exodaq::kinematics
