#pragma once
// The kinematic model file (config/models/*.yaml): one serial chain in
// standard DH, modified DH or product-of-exponentials form, its joint limits,
// home posture and the rig quantities the daemon publishes. Format:
// docs/kinematics.md. Start-up code only: throws ConfigError ("file:line: what")
// for every problem and never crashes on any input.
#include <string>

#include "exodaq/common/config_error.hpp"
#include "exodaq/kinematics/chain.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"

namespace exodaq::settings {

struct KinematicModel {
  std::string name;
  std::string description;
  std::string file;         // where it was read from (or the name given to load_model_text)
  kinematics::Chain chain;  // lengths in metres, angles in radians
  kinematics::JointVector home_posture;  // radians, within the joint limits
  kinematics::RigKinematicsConfig rig;   // elbow_frame, shoulder_joints, normaliser, threshold
};

KinematicModel load_model_file(const std::string& path);
// Same from text in memory (tests, fuzzing); `name` stands in for the file name.
KinematicModel load_model_text(const std::string& text, const std::string& name);

// The model file used when none is given: the source tree's
// config/models/macaque_exo.yaml when that exists (a build tree), else the
// installed /etc/exodaq/models/macaque_exo.yaml.
std::string default_model_path();

}  // namespace exodaq::settings
