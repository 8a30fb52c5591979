#include "exodaq/kinematics/ik.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

#include "ik_impl.hpp"

namespace exodaq::kinematics {

using namespace ik_detail;

namespace {

int jacobian_rank(const Chain& chain, const JointVector& q, double wp, int skip) {
  Jacobian J;
  chain.jacobian(q, chain.joint_count() + 1, J);
  J.topRows<3>() *= wp;
  if (skip >= 0) J.col(skip).setZero();
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(J);
  const auto& s = svd.singularValues();
  int rank = 0;
  for (Eigen::Index i = 0; i < s.size(); ++i) rank += s[i] > 1e-8 * s[0] ? 1 : 0;
  return rank;
}

}  // namespace

const char* to_string(IkStatus status) noexcept {
  switch (status) {
    case IkStatus::kSolved:
      return "solved";
    case IkStatus::kOutsideLimits:
      return "outside_limits";
    case IkStatus::kUnreachable:
      return "unreachable";
  }
  return "?";
}

IkSolver::Impl::Impl(const Chain& c, const RigKinematicsConfig& r, const IkOptions& o)
    : chain(c), rig(r), opt(o), rng{o.random_seed} {
  const double scale_sq = chain.dh_length_scale_sq();
  wp = scale_sq > 0.0 ? 1.0 / std::sqrt(scale_sq) : 1.0;
  detect_redundancy();
  reach_slack = std::max(1e-3 / wp, 100.0 * opt.position_tolerance);
  if (opt.use_analytical) {
    arm = SphericalShoulderArm::detect(chain);
    if (arm) free = 0;  // the closed form is written with joint 1 given
  }
  result.solutions.reserve(kMaxIkSolutions);
  cands.reserve(kMaxIkSolutions);
  grid.reserve(kMaxIkSolutions);
  outside.reserve(kMaxIkSolutions);
  branches.reserve(kMaxIkSolutions);
}

void IkSolver::Impl::detect_redundancy() {
  const int n = chain.joint_count();
  if (n == 0) throw std::invalid_argument("inverse kinematics of a chain without joints");
  Random sample{opt.random_seed ^ 0xA5A5A5A5ULL};
  JointVector q(n);
  int rank = 0;
  int rank_without[kMaxJoints] = {};
  for (int s = 0; s < 16; ++s) {
    for (int j = 0; j < n; ++j) {
      const JointLimits& l = chain.joints()[static_cast<std::size_t>(j)].limits;
      q[j] = sample.uniform(l.lower, l.upper);
    }
    rank = std::max(rank, jacobian_rank(chain, q, wp, -1));
    for (int j = 0; j < n; ++j)
      rank_without[j] = std::max(rank_without[j], jacobian_rank(chain, q, wp, j));
  }
  redundancy = n - rank;
  if (redundancy > 1) {
    throw std::invalid_argument("inverse kinematics: the chain is redundant by " +
                                std::to_string(redundancy) + " joints (palm Jacobian rank " +
                                std::to_string(rank) + " of " + std::to_string(n) +
                                "); at most one is supported");
  }
  if (redundancy == 1) {
    for (int j = 0; j < n && free < 0; ++j) {
      if (rank_without[j] == rank) free = j;
    }
  }
}

void IkSolver::Impl::reset() noexcept {
  result.status = IkStatus::kUnreachable;
  result.solutions.clear();
  result.truncated = false;
  result.best_position_residual = std::numeric_limits<double>::infinity();
  result.best_orientation_residual = std::numeric_limits<double>::infinity();
  result.elbow_sphere_miss = kNaN;
  outside.clear();
  best_cost = std::numeric_limits<double>::infinity();
  rng.state = opt.random_seed;
}

void IkSolver::Impl::note_best(const Residual& r) noexcept {
  const double c = cost(r);
  if (c < best_cost) {
    best_cost = c;
    result.best_position_residual = r.position();
    result.best_orientation_residual = r.orientation();
  }
}

JointVector IkSolver::Impl::random_posture() noexcept {
  JointVector q(chain.joint_count());
  for (int j = 0; j < chain.joint_count(); ++j) {
    const JointLimits& l = chain.joints()[static_cast<std::size_t>(j)].limits;
    q[j] = rng.uniform(l.lower, l.upper);
  }
  return q;
}

Residual IkSolver::Impl::run_lm(const Pose& target, JointVector& q, unsigned active) noexcept {
  LmSettings s;
  s.position_weight = wp;
  s.max_iterations = opt.max_iterations;
  s.active = active;
  // A thousandth of the tolerance, at most 1e-14 (m, rad), weighted as the cost is.
  const double p = std::min(1e-3 * opt.position_tolerance, 1e-14) * wp;
  const double r = std::min(1e-3 * opt.orientation_tolerance, 1e-14);
  s.done_cost = std::max(p * p + r * r, 1e-30);
  return levenberg_marquardt(chain, target, q, s, lm);
}

bool IkSolver::Impl::add_distinct(std::vector<Candidate>& set, const Candidate& c,
                                  const Pose& target) noexcept {
  for (Candidate& o : set) {
    const double d = angular_distance(o.q, c.q);
    if (d > kMergeRadius) continue;
    bool same = d <= opt.duplicate_tolerance;
    if (!same) {
      JointVector mid = o.q;
      for (Eigen::Index i = 0; i < mid.size(); ++i) mid[i] += 0.5 * wrap_pi(c.q[i] - o.q[i]);
      same = converged(residual(chain.palm(mid), target));
    }
    if (same) {
      if (cost(c.r) < cost(o.r)) o = c;
      return true;
    }
  }
  if (set.size() >= static_cast<std::size_t>(kMaxIkSolutions)) return false;
  set.push_back(c);
  return true;
}

void IkSolver::Impl::consider(const Pose& target, JointVector q, unsigned active) noexcept {
  const Residual r = run_lm(target, q, active);
  note_best(r);
  if (!converged(r)) return;
  wrap_into_limits(chain, q, nullptr);
  Candidate c;
  c.q = q;
  c.r = r;
  c.excess = limit_excess(chain, q);
  c.in_limits = c.excess <= 1e-12;
  if (!add_distinct(cands, c, target)) result.truncated = true;
}

int IkSolver::Impl::candidates(const Pose& target, double free_value, const Candidate* seeds,
                               int n_seeds, int random_starts) noexcept {
  cands.clear();
  const bool fixed = free >= 0 && std::isfinite(free_value);
  const unsigned active = fixed ? all_joints() & ~(1u << free) : all_joints();
  if (arm && fixed) {
    SphericalCandidate out[4];
    double miss = kNaN;
    const int k = arm->solve(target, free_value, reach_slack, out, miss);
    result.elbow_sphere_miss = miss;
    for (int i = 0; i < k; ++i) consider(target, out[i].q, active);
    return static_cast<int>(cands.size());
  }
  for (int i = 0; i < n_seeds; ++i) {
    JointVector q = seeds[i].q;
    if (fixed) q[free] = free_value;
    consider(target, q, active);
  }
  // Random starts until `random_starts` in a row found nothing new (at most four
  // times as many).
  std::size_t known = cands.size();
  for (int s = 0, quiet = 0; quiet < random_starts && s < 4 * random_starts; ++s) {
    JointVector q = random_posture();
    if (fixed) q[free] = free_value;
    consider(target, q, active);
    quiet = cands.size() > known ? 0 : quiet + 1;
    known = cands.size();
  }
  return static_cast<int>(cands.size());
}

const IkSolver::Impl::Candidate* IkSolver::Impl::nearest(const JointVector& q, double gate,
                                                         bool in_limits) const noexcept {
  const Candidate* best = nullptr;
  double best_d = gate;
  for (const Candidate& c : cands) {
    if (in_limits && !c.in_limits) continue;
    const double d = angular_distance(q, c.q);
    if (d < best_d) {
      best_d = d;
      best = &c;
    }
  }
  return best;
}

void IkSolver::Impl::note_outside(const Pose& target, bool keep_one) noexcept {
  for (const Candidate& c : cands) {
    if (c.in_limits) continue;
    if (!keep_one) {
      if (!add_distinct(outside, c, target)) result.truncated = true;
    } else if (outside.empty()) {
      outside.push_back(c);
    } else if (c.excess < outside.front().excess) {
      outside.front() = c;
    }
  }
}

double IkSolver::Impl::manipulability_at(const JointVector& q) const noexcept {
  RigPose pose;
  evaluate_rig(chain, rig, q, pose);
  return pose.shoulder_manipulability;
}

IkSolution IkSolver::Impl::make_solution(const JointVector& q, const Pose& target) const noexcept {
  IkSolution s;
  s.q = q;
  RigPose pose;
  evaluate_rig(chain, rig, q, pose);
  Pose palm = Pose::Identity();
  palm.linear() = pose.palm_rotation;
  palm.translation() = pose.palm_position;
  const Residual r = residual(palm, target);
  s.position_residual = r.position();
  s.orientation_residual = r.orientation();
  s.shoulder_manipulability = pose.shoulder_manipulability;
  s.shoulder_manipulability_normalised = pose.shoulder_manipulability_normalised;
  s.within_limits = within_limits(chain, q);
  return s;
}

// The candidates of the last call into the result (a finite solution set).
void IkSolver::Impl::collect(const Pose& target) noexcept {
  for (const Candidate& c : cands) {
    if (!c.in_limits) continue;
    if (result.solutions.size() >= static_cast<std::size_t>(kMaxIkSolutions)) {
      result.truncated = true;
      break;
    }
    result.solutions.push_back(make_solution(c.q, target));
  }
  note_outside(target, false);
}

void IkSolver::Impl::finish(const Pose& target) noexcept {
  auto& sols = result.solutions;
  if (!sols.empty()) {
    result.status = IkStatus::kSolved;
    std::sort(sols.begin(), sols.end(), [](const IkSolution& a, const IkSolution& b) {
      return a.shoulder_manipulability > b.shoulder_manipulability;
    });
    return;
  }
  if (!outside.empty()) {
    result.status = IkStatus::kOutsideLimits;
    std::sort(outside.begin(), outside.end(),
              [](const Candidate& a, const Candidate& b) { return a.excess < b.excess; });
    for (const Candidate& c : outside) sols.push_back(make_solution(c.q, target));
    return;
  }
  result.status = IkStatus::kUnreachable;
  if (arm) {
    // The closed form said no without a least-squares attempt: make one, so the
    // result says by how much the pose is missed.
    for (int s = 0; s < opt.starts; ++s) {
      JointVector q = random_posture();
      note_best(run_lm(target, q, all_joints()));
    }
  }
}

IkSolver::IkSolver(const Chain& chain, const RigKinematicsConfig& rig, const IkOptions& options)
    : impl_(std::make_unique<Impl>(chain, rig, options)) {}
IkSolver::~IkSolver() = default;
IkSolver::IkSolver(IkSolver&&) noexcept = default;
IkSolver& IkSolver::operator=(IkSolver&&) noexcept = default;

const Chain& IkSolver::chain() const noexcept {
  return impl_->chain;
}
const IkOptions& IkSolver::options() const noexcept {
  return impl_->opt;
}
int IkSolver::redundancy() const noexcept {
  return impl_->redundancy;
}
int IkSolver::free_joint() const noexcept {
  return impl_->free;
}
bool IkSolver::analytical() const noexcept {
  return impl_->arm.has_value();
}

const IkResult& IkSolver::solve(const Pose& palm) noexcept {
  Impl& m = *impl_;
  m.reset();
  if (m.redundancy == 1) {
    m.sweep(palm);
  } else {
    m.candidates(palm, kNaN, nullptr, 0, m.opt.starts);
    m.collect(palm);
  }
  m.finish(palm);
  return m.result;
}

const IkResult& IkSolver::solve_fixed(const Pose& palm, double free_value) noexcept {
  Impl& m = *impl_;
  if (m.redundancy == 0) return solve(palm);
  m.reset();
  m.candidates(palm, free_value, nullptr, 0, m.opt.starts);
  m.collect(palm);
  m.finish(palm);
  return m.result;
}

bool IkSolver::solve_nearest(const Pose& palm, const JointVector& seed, IkSolution& out) noexcept {
  Impl& m = *impl_;
  const int n = m.chain.joint_count();
  if (seed.size() != n) return false;
  // Local: Levenberg-Marquardt from the seed keeps to the seed's branch.
  JointVector q = seed;
  const Residual r = m.run_lm(palm, q, m.all_joints());
  if (m.converged(r)) {
    wrap_into_limits(m.chain, q, &seed);
    if (within_limits(m.chain, q)) {
      out = m.make_solution(q, palm);
      return true;
    }
  }
  if (m.redundancy == 1) return m.nearest_by_free_joint(palm, seed, out);
  // A finite set: the nearest of all.
  const IkResult& res = solve(palm);
  if (res.status != IkStatus::kSolved) return false;
  const IkSolution* best = &res.solutions.front();
  for (const IkSolution& s : res.solutions) {
    if (angular_distance(s.q, seed) < angular_distance(best->q, seed)) best = &s;
  }
  out = *best;
  return true;
}

// The free joint stepped outward from the seed's value (alternately up and down)
// until some solution lies within the limits; of those, the nearest the seed.
bool IkSolver::Impl::nearest_by_free_joint(const Pose& target, const JointVector& seed,
                                           IkSolution& out) noexcept {
  const JointLimits& l = chain.joints()[static_cast<std::size_t>(free)].limits;
  const double t0 = std::clamp(seed[free], l.lower, l.upper);
  const double step = opt.free_joint_step;
  const int steps = static_cast<int>(std::ceil((l.upper - l.lower) / step));
  Candidate start;
  start.q = seed;
  for (int i = 0; i <= 2 * steps; ++i) {  // t0, t0 + step, t0 - step, t0 + 2 step, ...
    const double t = t0 + (i % 2 ? 1 : -1) * ((i + 1) / 2) * step;
    if (t < l.lower || t > l.upper) continue;
    candidates(target, t, &start, 1, arm ? 0 : opt.sweep_starts);
    const Candidate* best = nullptr;
    for (const Candidate& c : cands) {
      if (c.in_limits && (!best || angular_distance(c.q, seed) < angular_distance(best->q, seed))) {
        best = &c;
      }
    }
    if (best) {
      out = make_solution(best->q, target);
      return true;
    }
  }
  return false;
}

}  // namespace exodaq::kinematics
