#pragma once
// Internal to exodaq_kinematics: the numerical pieces of inverse kinematics
// (pose error, Levenberg-Marquardt, angle wrapping). No allocation, no exceptions.
#include <Eigen/Cholesky>
#include <cstdint>

#include "exodaq/kinematics/chain.hpp"

namespace exodaq::kinematics::ik_detail {

inline constexpr double kTwoPi = 6.283185307179586476925286766559;

using SquareMatrix =
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxJoints, kMaxJoints>;

// Palm position and orientation residuals of `q` against a target.
struct Residual {
  Eigen::Vector3d dp = Eigen::Vector3d::Zero();  // p_target - p(q)
  Eigen::Vector3d dr = Eigen::Vector3d::Zero();  // log(R_target R(q)^T), world frame
  double position() const noexcept { return dp.norm(); }
  double orientation() const noexcept { return dr.norm(); }
};

// log(R) as angle * axis (the rotation vector), accurate for small angles.
Eigen::Vector3d rotation_vector(const Eigen::Matrix3d& R) noexcept;

Residual residual(const Pose& palm, const Pose& target) noexcept;

struct LmSettings {
  double position_weight = 1.0;  // 1/m: the position rows are scaled by this
  int max_iterations = 100;
  unsigned active = ~0u;  // bit j: joint j may move
  // Stop once the weighted squared residual is below this (well inside the
  // caller's tolerance; below ~1e-30 is rounding noise).
  double done_cost = 1e-30;
};

struct LmWorkspace {
  Jacobian J;
  SquareMatrix A;
  Eigen::LDLT<SquareMatrix> ldlt;
};

// Minimises |W r(q)|^2 from q (modified in place); returns the final residual.
Residual levenberg_marquardt(const Chain& chain, const Pose& target, JointVector& q,
                             const LmSettings& s, LmWorkspace& w) noexcept;

// The representative of `angle` mod 2 pi within [lower, upper] (the one nearest
// `prefer` when several are); when none is, the one nearest the interval.
double wrap_into(double angle, double lower, double upper, double prefer) noexcept;

// angle mod 2 pi in (-pi, pi].
double wrap_pi(double angle) noexcept;

// Largest |a_i - b_i| with every difference taken mod 2 pi.
double angular_distance(const JointVector& a, const JointVector& b) noexcept;

// Every joint within its limits (to 1e-12 rad).
bool within_limits(const Chain& chain, const JointVector& q) noexcept;

// How far q lies outside its limits: the largest excess over the joints (rad), 0 inside.
double limit_excess(const Chain& chain, const JointVector& q) noexcept;

// Each angle wrapped into its joint's limits (nearest `prefer` when given).
void wrap_into_limits(const Chain& chain, JointVector& q, const JointVector* prefer) noexcept;

// A small deterministic generator (SplitMix64): no allocation, no state beyond 8 bytes.
struct Random {
  std::uint64_t state;
  std::uint64_t next() noexcept {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  double uniform(double lo, double hi) noexcept {
    return lo + (hi - lo) * static_cast<double>(next() >> 11) * 0x1.0p-53;
  }
};

}  // namespace exodaq::kinematics::ik_detail
