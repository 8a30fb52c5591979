#pragma once
// Shared helpers for the kinematics tests.
#include <random>
#include <string>

#include "exodaq/kinematics/chain.hpp"
#include "exodaq/settings/model_file.hpp"

namespace exodaq::kinematics::test {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kDeg = kPi / 180.0;
// Seed 000 Table 1, macaque G, as in config/models/macaque_exo.yaml.
inline constexpr double kL1 = 0.145;
inline constexpr double kL2 = 0.152;

inline std::string model_path(const std::string& file) {
  return std::string(EXODAQ_SOURCE_DIR) + "/config/models/" + file;
}

inline const settings::KinematicModel& macaque() {
  static const settings::KinematicModel m =
      settings::load_model_file(model_path("macaque_exo.yaml"));
  return m;
}

// Seed 000's arm in Craig's form. Regrouping the standard product
//   Rz(t1) Tz(d1) [Tx(a1) Rx(al1)] Rz(t2) Tz(d2) [Tx(a2) Rx(al2)] ... [Tx(a6) Rx(al6)]
// row i of the modified table is (a_{i-1}, alpha_{i-1}, d_i), and the last
// [Tx(a6) Rx(al6)] (identity here, alpha6 = a6 = 0) becomes the tool.
inline constexpr const char* kMacaqueModifiedDh = R"(
name: macaque_exo_mdh
convention: modified_dh
angle_unit: deg
joints:
  - {name: j1, dh: {a: 0, alpha: 0, d: 0}, limits: [-50.5, 140.5]}
  - {name: j2, dh: {a: 0, alpha: -90, d: 0}, limits: [-228.3, 48.3]}
  - {name: j3, dh: {a: 0, alpha: 90, d: 0}, limits: [-98.1, 98.1]}
  - {name: j4, dh: {a: 0, alpha: -90, d: 0.145}, limits: [-80, 80]}
  - {name: j5, dh: {a: 0, alpha: 90, d: 0}, limits: [-88.7, 8.1]}
  - {name: j6, dh: {a: 0, alpha: -90, d: 0.152}, limits: [-80, 80]}
home_posture: [45, -90, 90, 0, 0, 0]
)";

// The same arm as screws, read off Table 3 at q = 0: joint axes alternate
// z0 / y0 through the shoulder centre (joints 1-4) and the elbow (0, L1, 0)
// (joints 5-6); at q = 0 the palm is at (0, L1 + L2, 0) with R = Rx(-90).
inline constexpr const char* kMacaquePoe = R"(
name: macaque_exo_poe
convention: poe
angle_unit: deg
joints:
  - {name: j1, screw: {omega: [0, 0, 1], q: [0, 0, 0]}, limits: [-50.5, 140.5]}
  - {name: j2, screw: {omega: [0, 1, 0], q: [0, 0, 0]}, limits: [-228.3, 48.3]}
  - {name: j3, screw: {omega: [0, 0, 1], q: [0, 0, 0]}, limits: [-98.1, 98.1]}
  - {name: j4, screw: {omega: [0, 1, 0], q: [0, 0, 0]}, limits: [-80, 80]}
  - {name: j5, screw: {omega: [0, 0, 1], q: [0, 0.145, 0]}, limits: [-88.7, 8.1]}
  - {name: j6, screw: {omega: [0, 1, 0], q: [0, 0.145, 0]}, limits: [-80, 80]}
home_pose: {translation: [0, 0.297, 0], rpy: [-90, 0, 0]}
home_posture: [45, -90, 90, 0, 0, 0]
elbow_frame: 4
)";

// PUMA 560 (Corke's standard DH table, metres), every joint limited to
// [-180, 180] deg: a 6R arm with up to eight inverse-kinematics solutions
// (Craig, Introduction to Robotics, sec. 4.7). Test-only, not a shipped model.
inline constexpr const char* kPuma560 = R"(
name: puma560
convention: standard_dh
angle_unit: deg
joints:
  - {name: j1, dh: {a: 0, alpha: 90, d: 0}, limits: [-180, 180]}
  - {name: j2, dh: {a: 0.4318, alpha: 0, d: 0}, limits: [-180, 180]}
  - {name: j3, dh: {a: 0.0203, alpha: -90, d: 0.15005}, limits: [-180, 180]}
  - {name: j4, dh: {a: 0, alpha: 90, d: 0.4318}, limits: [-180, 180]}
  - {name: j5, dh: {a: 0, alpha: -90, d: 0}, limits: [-180, 180]}
  - {name: j6, dh: {a: 0, alpha: 0, d: 0}, limits: [-180, 180]}
)";

// The same PUMA in Craig's modified DH (row i: a_{i-1}, alpha_{i-1}, d_i).
inline constexpr const char* kPuma560ModifiedDh = R"(
name: puma560_mdh
convention: modified_dh
angle_unit: deg
joints:
  - {name: j1, dh: {a: 0, alpha: 0, d: 0}, limits: [-180, 180]}
  - {name: j2, dh: {a: 0, alpha: 90, d: 0}, limits: [-180, 180]}
  - {name: j3, dh: {a: 0.4318, alpha: 0, d: 0.15005}, limits: [-180, 180]}
  - {name: j4, dh: {a: 0.0203, alpha: -90, d: 0.4318}, limits: [-180, 180]}
  - {name: j5, dh: {a: 0, alpha: 90, d: 0}, limits: [-180, 180]}
  - {name: j6, dh: {a: 0, alpha: -90, d: 0}, limits: [-180, 180]}
)";

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

}  // namespace exodaq::kinematics::test
