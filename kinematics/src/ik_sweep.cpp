// The branch sweep of a chain redundant by one joint: the free joint steps over
// its limits; each open branch is followed to the next value by continuation
// (steps halved until no joint moves more than kStepGate), solutions no branch
// reaches open new branches, a branch's ends are refined by bisection and its
// posture of largest shoulder manipulability by golden-section search.
// docs/kinematics.md, "Inverse kinematics".
#include <algorithm>
#include <cmath>

#include "ik_impl.hpp"

namespace exodaq::kinematics {

using namespace ik_detail;

void IkSolver::Impl::sweep(const Pose& target) noexcept {
  branches.clear();
  grid.clear();
  const JointLimits& l = chain.joints()[static_cast<std::size_t>(free)].limits;
  const double span = l.upper - l.lower;
  const int values = std::max(2, static_cast<int>(std::ceil(span / opt.free_joint_step)) + 1);
  sweep_step = span / (values - 1);
  for (int k = 0; k < values; ++k) {
    const double t = k + 1 == values ? l.upper : l.lower + k * sweep_step;
    sweep_grid_value(target, t, t - sweep_step, k == 0);
  }
  for (Branch& b : branches) {  // open to the upper limit
    b.t_end = b.t_last;
    emit(target, b);
  }
  branches.clear();
}

void IkSolver::Impl::sweep_grid_value(const Pose& target, double t, double t_prev,
                                      bool first) noexcept {
  const int starts = arm ? 0 : (first ? opt.starts : opt.sweep_starts);
  candidates(target, t, grid.data(), static_cast<int>(grid.size()), starts);
  note_outside(target, true);
  grid = cands;  // within the reserved capacity: no allocation
  bool used[kMaxIkSolutions] = {};
  const auto n_grid = grid.size();
  // Follow each open branch to t; close it where it leaves the limits.
  for (std::size_t bi = 0; bi < branches.size();) {
    Branch& b = branches[bi];
    JointVector q;
    if (follow(target, b.t_last, b.q_last, t, q) && within_limits(chain, q)) {
      for (std::size_t j = 0; j < n_grid; ++j) {  // the grid's solution it became
        if (grid[j].in_limits && !used[j] && angular_distance(q, grid[j].q) < kStepGate) {
          used[j] = true;
          break;
        }
      }
      note_grid_posture(b, t, q);
      ++bi;
    } else {
      JointVector q_end = b.q_last;
      b.t_end = refine_boundary(target, b.t_last, q_end, t);
      emit(target, b);
      branches.erase(branches.begin() + static_cast<std::ptrdiff_t>(bi));
    }
  }
  // Solutions no branch took open new ones.
  for (std::size_t j = 0; j < n_grid; ++j) {
    if (!grid[j].in_limits || used[j]) continue;
    if (branches.size() >= static_cast<std::size_t>(kMaxIkSolutions)) {
      result.truncated = true;
      break;
    }
    Branch b;
    b.t_first = t;
    note_grid_posture(b, t, grid[j].q);
    JointVector q_start = b.q_last;
    b.t_start = first ? t : refine_boundary(target, t, q_start, t_prev);
    branches.push_back(b);
  }
}

// One more grid posture on a branch: keeps the largest shoulder manipulability
// and the unbroken run of grid values that share it (a plateau).
void IkSolver::Impl::note_grid_posture(Branch& b, double t, const JointVector& q) noexcept {
  b.t_last = t;
  b.q_last = q;
  const double w = manipulability_at(q);
  const double tie = 1e-9 * std::max(1.0, b.w_best);
  if (w > b.w_best + tie) {
    b.w_best = w;
    b.t_best = t;
    b.q_best = q;
    b.t_plateau_end = t;
    b.plateau_open = true;
  } else if (b.plateau_open && w >= b.w_best - tie) {
    b.t_plateau_end = t;
  } else {
    b.plateau_open = false;
  }
}

// Follows a branch from (t_from, q_from) to t_to by continuation, limits
// ignored. False when the branch is lost (no solution near within 1e-12 rad).
bool IkSolver::Impl::follow(const Pose& target, double t_from, const JointVector& q_from,
                            double t_to, JointVector& q_to) noexcept {
  q_to = q_from;
  double t = t_from;
  double dt = t_to - t_from;
  for (int guard = 0; t != t_to && guard < 400; ++guard) {
    const double t_next = std::abs(t_to - t) <= std::abs(dt) ? t_to : t + dt;
    Candidate seed;
    seed.q = q_to;
    candidates(target, t_next, &seed, 1, 0);
    const Candidate* c = nearest(q_to, kStepGate, false);
    if (c) {
      t = t_next;
      q_to = c->q;
      dt *= 2.0;
    } else {
      dt *= 0.5;
      if (std::abs(dt) < 1e-12) return false;
    }
  }
  return t == t_to;
}

// The last value of the free joint, between t_good (branch within the limits,
// posture q_good) and t_bad (not), where the branch is still within the limits.
double IkSolver::Impl::refine_boundary(const Pose& target, double t_good, JointVector& q_good,
                                       double t_bad) noexcept {
  for (int it = 0; it < 64 && std::abs(t_bad - t_good) > 1e-12; ++it) {
    const double t = 0.5 * (t_good + t_bad);
    JointVector q;
    if (follow(target, t_good, q_good, t, q) && within_limits(chain, q)) {
      t_good = t;
      q_good = q;
    } else {
      t_bad = t;
    }
  }
  return t_good;
}

// The branch's representative: the middle of a plateau of largest shoulder
// manipulability, else a golden-section search for the largest within one grid
// step either side of the best grid value.
void IkSolver::Impl::refine_best(const Pose& target, Branch& b) noexcept {
  if (b.t_plateau_end > b.t_best + 0.5 * sweep_step) {
    const double lo = b.t_best == b.t_first ? b.t_start : b.t_best;
    const double hi = b.t_plateau_end == b.t_last ? b.t_end : b.t_plateau_end;
    JointVector q;
    if (follow(target, b.t_best, b.q_best, 0.5 * (lo + hi), q) && within_limits(chain, q)) {
      b.t_best = 0.5 * (lo + hi);
      b.q_best = q;
    }
    return;
  }
  double lo = std::max(b.t_start, b.t_best - sweep_step);
  double hi = std::min(b.t_end, b.t_best + sweep_step);
  if (!(hi - lo > 1e-12)) return;
  auto value = [&](double t, JointVector& q) {
    if (!follow(target, b.t_best, b.q_best, t, q) || !within_limits(chain, q)) return -1.0;
    return manipulability_at(q);
  };
  constexpr double kInvPhi = 0.6180339887498949;
  JointVector q1, q2;
  double x1 = hi - kInvPhi * (hi - lo), x2 = lo + kInvPhi * (hi - lo);
  double f1 = value(x1, q1), f2 = value(x2, q2);
  for (int it = 0; it < 40 && hi - lo > 1e-10; ++it) {
    if (f1 >= f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      q2 = q1;
      x1 = hi - kInvPhi * (hi - lo);
      f1 = value(x1, q1);
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      q1 = q2;
      x2 = lo + kInvPhi * (hi - lo);
      f2 = value(x2, q2);
    }
  }
  if (f1 > b.w_best) {
    b.w_best = f1;
    b.t_best = x1;
    b.q_best = q1;
  }
  if (f2 > b.w_best) {
    b.w_best = f2;
    b.t_best = x2;
    b.q_best = q2;
  }
}

void IkSolver::Impl::emit(const Pose& target, Branch& b) noexcept {
  refine_best(target, b);
  if (result.solutions.size() >= static_cast<std::size_t>(kMaxIkSolutions)) {
    result.truncated = true;
    return;
  }
  IkSolution s = make_solution(b.q_best, target);
  s.free_lower = b.t_start;
  s.free_upper = b.t_end;
  result.solutions.push_back(s);
}

}  // namespace exodaq::kinematics
