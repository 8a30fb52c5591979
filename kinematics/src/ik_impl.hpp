#pragma once
// Internal to exodaq_kinematics: the state of an IkSolver (ik.cpp: set-up,
// candidates, results; ik_sweep.cpp: the branch sweep of a redundant chain).
#include <optional>
#include <vector>

#include "exodaq/kinematics/ik.hpp"
#include "ik_numeric.hpp"
#include "ik_spherical.hpp"

namespace exodaq::kinematics {

namespace ik_detail {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Following a branch, one step may move no joint further than this (rad); the
// step is halved until it does. Distinct solutions at one free-joint value differ
// by more (seed 000's arm: by pi in some joint).
constexpr double kStepGate = 0.2;
// Solutions closer than this (rad) are one when the posture half-way is one too
// (a double root that two starts approach from either side).
constexpr double kMergeRadius = 1e-2;

struct Candidate {
  JointVector q;
  Residual r;
  bool in_limits = false;
  double excess = 0.0;
};

// An open branch of a one-parameter family during the sweep.
struct Branch {
  double t_start = 0.0;  // refined lower end of the free joint's interval
  double t_first = 0.0;  // first grid value on the branch
  double t_last = 0.0;   // last grid value on the branch
  double t_end = 0.0;    // refined upper end of the interval (set when it closes)
  JointVector q_last;
  double t_best = 0.0;  // largest shoulder manipulability so far
  JointVector q_best;
  double w_best = -1.0;
  double t_plateau_end = 0.0;  // last grid value of an unbroken run at w_best
  bool plateau_open = false;
};

}  // namespace ik_detail

struct IkSolver::Impl {
  using Candidate = ik_detail::Candidate;
  using Branch = ik_detail::Branch;
  using Residual = ik_detail::Residual;

  Chain chain;
  RigKinematicsConfig rig;
  IkOptions opt;
  int redundancy = 0;
  int free = -1;
  std::optional<ik_detail::SphericalShoulderArm> arm;
  double wp = 1.0;           // position weight (1/m): 1 / the chain's length scale
  double reach_slack = 0.0;  // m: the closed form's candidates are polished within this
  IkResult result;
  ik_detail::LmWorkspace lm;
  ik_detail::Random rng{0};
  std::vector<Candidate> cands;    // the last candidates() call
  std::vector<Candidate> grid;     // the sweep's current grid value
  std::vector<Candidate> outside;  // solutions outside the limits
  std::vector<Branch> branches;    // the sweep's open branches
  double sweep_step = 0.0;         // rad: the sweep's grid spacing
  double best_cost = 0.0;

  Impl(const Chain& c, const RigKinematicsConfig& r, const IkOptions& o);
  void detect_redundancy();
  bool converged(const Residual& r) const noexcept {
    return r.position() <= opt.position_tolerance && r.orientation() <= opt.orientation_tolerance;
  }
  double cost(const Residual& r) const noexcept {
    return wp * wp * r.dp.squaredNorm() + r.dr.squaredNorm();
  }
  unsigned all_joints() const noexcept { return (1u << chain.joint_count()) - 1u; }

  // ik.cpp
  void reset() noexcept;
  void note_best(const Residual& r) noexcept;
  Residual run_lm(const Pose& target, JointVector& q, unsigned active) noexcept;
  bool add_distinct(std::vector<Candidate>& set, const Candidate& c, const Pose& target) noexcept;
  void consider(const Pose& target, JointVector q, unsigned active) noexcept;
  int candidates(const Pose& target, double free_value, const Candidate* seeds, int n_seeds,
                 int random_starts) noexcept;
  const Candidate* nearest(const JointVector& q, double gate, bool in_limits) const noexcept;
  void note_outside(const Pose& target, bool keep_one) noexcept;
  IkSolution make_solution(const JointVector& q, const Pose& target) const noexcept;
  void collect(const Pose& target) noexcept;
  void finish(const Pose& target) noexcept;
  double manipulability_at(const JointVector& q) const noexcept;
  JointVector random_posture() noexcept;
  bool nearest_by_free_joint(const Pose& target, const JointVector& seed, IkSolution& out) noexcept;

  // ik_sweep.cpp: the branches of a one-parameter family (redundancy 1).
  void sweep(const Pose& target) noexcept;
  void sweep_grid_value(const Pose& target, double t, double t_prev, bool first) noexcept;
  double refine_boundary(const Pose& target, double t_good, JointVector& q_good,
                         double t_bad) noexcept;
  void note_grid_posture(Branch& b, double t, const JointVector& q) noexcept;
  void refine_best(const Pose& target, Branch& b) noexcept;
  bool follow(const Pose& target, double t_from, const JointVector& q_from, double t_to,
              JointVector& q_to) noexcept;
  void emit(const Pose& target, Branch& b) noexcept;
};

}  // namespace exodaq::kinematics
