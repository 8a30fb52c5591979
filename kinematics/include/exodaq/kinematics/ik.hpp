#pragma once
// Inverse kinematics: the joint vectors that put a chain's palm at a given pose,
// within the joint limits, each with its residual and shoulder manipulability.
// Any chain of the three conventions (numerical: Levenberg-Marquardt from many
// starts, de-duplicated); a closed form for a spherical shoulder followed by an
// elbow whose axis meets the forearm axis (seed 000), polished numerically.
// A chain whose palm Jacobian has rank n - 1 at every posture (seed 000's arm:
// four shoulder axes through one point) reaches a pose along one-parameter
// families: one joint is free; solve() then returns one solution per branch
// (an interval of the free joint) and solve_fixed() the finite set at one value.
// Explanations, tolerances and limitations: docs/kinematics.md.
// The constructor allocates (start-up); solve*() allocate nothing, throw nothing,
// and use the solver's own scratch space: one solver per thread.
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "exodaq/kinematics/chain.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"

namespace exodaq::kinematics {

struct IkOptions {
  double position_tolerance = 1e-9;     // m: a solution's palm position is this close
  double orientation_tolerance = 1e-9;  // rad: and its palm rotation this close
  int starts = 48;                      // random starts of the numerical solver (per solve)
  int sweep_starts = 6;      // random starts per free-joint value in a numerical branch sweep
  int max_iterations = 100;  // Levenberg-Marquardt iterations per start
  double duplicate_tolerance = 1e-6;  // rad: solutions closer than this (mod 2 pi) are one
  double free_joint_step = 0.0087266462599716477;  // rad (0.5 deg): branch sweep grid
  bool use_analytical = true;  // the closed form where the chain's geometry allows it
  std::uint64_t random_seed = 0x5eed000ULL;
};

enum class IkStatus {
  kSolved,         // at least one solution within the joint limits
  kOutsideLimits,  // the pose is reached, but only outside the joint limits
  kUnreachable,    // no joint vector reaches the pose within the tolerances
};

const char* to_string(IkStatus status) noexcept;

struct IkSolution {
  JointVector q;                         // radians; each angle the representative within its
                                         // limits (angles are taken mod 2 pi)
  double position_residual = 0.0;        // m: |p(q) - p_target|
  double orientation_residual = 0.0;     // rad: angle of R(q) R_target^T
  double shoulder_manipulability = 0.0;  // sqrt(det(J_o J_o^T)) at q (RigKinematicsConfig)
  double shoulder_manipulability_normalised = 0.0;
  bool within_limits = true;
  // solve() on a redundant chain: the branch's interval of the free joint (q[free]
  // lies in it; q is the posture of largest shoulder manipulability on the branch).
  // NaN otherwise.
  double free_lower = std::numeric_limits<double>::quiet_NaN();
  double free_upper = std::numeric_limits<double>::quiet_NaN();
};

struct IkResult {
  IkStatus status = IkStatus::kUnreachable;
  // kSolved: the solutions within the limits, largest shoulder manipulability first.
  // kOutsideLimits: solutions that reach the pose outside the limits (within_limits
  // false). kUnreachable: empty.
  std::vector<IkSolution> solutions;  // capacity reserved at set-up
  bool truncated = false;             // more distinct solutions than kMaxIkSolutions
  // The smallest residuals any joint vector reached (the least-squares miss when
  // unreachable).
  double best_position_residual = std::numeric_limits<double>::infinity();
  double best_orientation_residual = std::numeric_limits<double>::infinity();
  // Closed form only: distance of the elbow (fixed in the palm frame) from the
  // shoulder centre minus the upper arm's length (m). Zero to rounding when
  // reachable; its sign says whether the pose is too far or too near. NaN otherwise.
  double elbow_sphere_miss = std::numeric_limits<double>::quiet_NaN();
};

inline constexpr int kMaxIkSolutions = 64;

class IkSolver {
 public:
  // Start-up only: allocates, and throws std::invalid_argument when the chain is
  // redundant by more than one joint (rank of the palm Jacobian < n - 1).
  IkSolver(const Chain& chain, const RigKinematicsConfig& rig, const IkOptions& options = {});
  ~IkSolver();
  IkSolver(IkSolver&&) noexcept;
  IkSolver& operator=(IkSolver&&) noexcept;

  const Chain& chain() const noexcept;
  const IkOptions& options() const noexcept;
  // n minus the rank of the palm Jacobian at generic postures: 0 (finitely many
  // solutions) or 1 (one-parameter families).
  int redundancy() const noexcept;
  // The joint (0-based) that parameterises the families when redundancy() == 1,
  // else -1.
  int free_joint() const noexcept;
  // Whether the closed form (spherical shoulder, elbow, forearm) is in use.
  bool analytical() const noexcept;

  // Every distinct solution within the limits (a redundant chain: one per branch).
  // The reference stays valid until the next solve*() call.
  const IkResult& solve(const Pose& palm) noexcept;
  // Redundant chains: every distinct solution with the free joint at `free_value`
  // (also outside its limits; those solutions are flagged). A chain with
  // redundancy() == 0 ignores the value and does what solve() does.
  const IkResult& solve_fixed(const Pose& palm, double free_value) noexcept;
  // One solution within the limits near `seed` (for following a moving target):
  // Levenberg-Marquardt from the seed when that ends within the limits; else, for
  // a redundant chain, the solution nearest the seed at the free-joint value
  // closest to the seed's that has one, and for a finite set the nearest of all.
  // False when there is none.
  bool solve_nearest(const Pose& palm, const JointVector& seed, IkSolution& out) noexcept;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace exodaq::kinematics
