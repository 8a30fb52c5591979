#pragma once
// Shared helpers for the kinematics tests.
#include <random>
#include <string>

#include "exodaq/config/model_file.hpp"
#include "exodaq/kinematics/chain.hpp"

namespace exodaq::kin::test {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kDeg = kPi / 180.0;
// Seed 000 Table 1, macaque G, as in config/models/macaque_exo.yaml.
inline constexpr double kL1 = 0.145;
inline constexpr double kL2 = 0.152;

inline std::string model_path(const std::string& file) {
  return std::string(EXODAQ_SOURCE_DIR) + "/config/models/" + file;
}

inline const config::KinematicModel& macaque() {
  static const config::KinematicModel m = config::load_model_file(model_path("macaque_exo.yaml"));
  return m;
}

// Uniform within the chain's joint limits.
inline JointVector random_within_limits(const Chain& c, std::mt19937_64& rng) {
  JointVector q(c.joint_count());
  for (int i = 0; i < c.joint_count(); ++i) {
    const auto& l = c.joints()[static_cast<std::size_t>(i)].limits;
    q[i] = std::uniform_real_distribution<double>(l.lower, l.upper)(rng);
  }
  return q;
}

inline JointVector random_any(int n, std::mt19937_64& rng) {
  JointVector q(n);
  for (int i = 0; i < n; ++i) q[i] = std::uniform_real_distribution<double>(-kPi, kPi)(rng);
  return q;
}

}  // namespace exodaq::kin::test
