#include "ik_numeric.hpp"

#include <algorithm>
#include <cmath>

namespace exodaq::kinematics::ik_detail {

Eigen::Vector3d rotation_vector(const Eigen::Matrix3d& R) noexcept {
  Eigen::Quaterniond q(R);
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  const Eigen::Vector3d v = q.vec();
  const double s = v.norm();
  if (s < 1e-300) return 2.0 * v;
  return v * (2.0 * std::atan2(s, q.w()) / s);
}

Residual residual(const Pose& palm, const Pose& target) noexcept {
  Residual r;
  r.dp = target.translation() - palm.translation();
  r.dr = rotation_vector(target.linear() * palm.linear().transpose());
  return r;
}

namespace {

double weighted_cost(const Residual& r, double wp) noexcept {
  return wp * wp * r.dp.squaredNorm() + r.dr.squaredNorm();
}

}  // namespace

Residual levenberg_marquardt(const Chain& chain, const Pose& target, JointVector& q,
                             const LmSettings& s, LmWorkspace& w) noexcept {
  const int n = chain.joint_count();
  const double wp = s.position_weight;
  Pose palm;
  chain.palm_and_jacobian(q, palm, w.J);
  Residual r = residual(palm, target);
  double cost = weighted_cost(r, wp);
  double lambda = 1e-3;
  Jacobian J_trial;
  JointVector delta(n), g(n), q_trial(n);
  Eigen::Matrix<double, 6, 1> e;
  int creeping = 0;  // accepted steps in a row that gained less than 1 %
  for (int it = 0; it < s.max_iterations && cost > s.done_cost && creeping < 6; ++it) {
    for (int j = 0; j < n; ++j) {
      if (!(s.active & (1u << j))) w.J.col(j).setZero();
    }
    w.J.topRows<3>() *= wp;
    e << wp * r.dp, r.dr;
    g.noalias() = w.J.transpose() * e;
    w.A.noalias() = w.J.transpose() * w.J;
    const double dmax = std::max(w.A.diagonal().maxCoeff(), 1e-300);
    bool accepted = false;
    // Near rounding noise a rejected step means done: do not raise the damping for long.
    const int max_tries = cost < 1e-20 ? 2 : 16;
    for (int tries = 0; tries < max_tries && !accepted; ++tries) {
      SquareMatrix M = w.A;
      for (int j = 0; j < n; ++j) {
        M(j, j) = (s.active & (1u << j)) ? M(j, j) + lambda * (w.A(j, j) + 1e-6 * dmax) : 1.0;
      }
      w.ldlt.compute(M);
      delta = w.ldlt.solve(g);
      q_trial = q + delta;
      Pose palm_trial;
      chain.palm_and_jacobian(q_trial, palm_trial, J_trial);
      const Residual r_trial = residual(palm_trial, target);
      const double cost_trial = weighted_cost(r_trial, wp);
      if (cost_trial < cost) {
        creeping = cost_trial > 0.99 * cost ? creeping + 1 : 0;
        q = q_trial;
        r = r_trial;
        cost = cost_trial;
        w.J = J_trial;
        lambda = std::max(lambda * 0.1, 1e-10);
        accepted = true;
      } else {
        lambda *= 10.0;
      }
    }
    if (!accepted || delta.cwiseAbs().maxCoeff() < 1e-16) break;
  }
  return r;
}

double wrap_pi(double angle) noexcept {
  return angle - kTwoPi * std::nearbyint(angle / kTwoPi);  // std::remainder is exact but slow
}

double wrap_into(double angle, double lower, double upper, double prefer) noexcept {
  constexpr double kSlack = 1e-12;
  const double base =
      angle - kTwoPi * std::floor((angle - lower) / kTwoPi);  // [lower, lower + 2 pi)
  if (base <= upper + kSlack) {
    const double room = std::max(0.0, std::floor((upper + kSlack - base) / kTwoPi));
    const double k = std::clamp(std::round((prefer - base) / kTwoPi), 0.0, room);
    return base + kTwoPi * k;
  }
  // Outside: the representative nearest the interval.
  return base - upper <= lower + kTwoPi - base ? base : base - kTwoPi;
}

double angular_distance(const JointVector& a, const JointVector& b) noexcept {
  double d = 0.0;
  for (Eigen::Index i = 0; i < a.size(); ++i) d = std::max(d, std::abs(wrap_pi(a[i] - b[i])));
  return d;
}

bool within_limits(const Chain& chain, const JointVector& q) noexcept {
  return limit_excess(chain, q) <= 1e-12;
}

double limit_excess(const Chain& chain, const JointVector& q) noexcept {
  double excess = 0.0;
  for (int i = 0; i < chain.joint_count(); ++i) {
    const JointLimits& l = chain.joints()[static_cast<std::size_t>(i)].limits;
    excess = std::max({excess, l.lower - q[i], q[i] - l.upper});
  }
  return excess;
}

void wrap_into_limits(const Chain& chain, JointVector& q, const JointVector* prefer) noexcept {
  for (int i = 0; i < chain.joint_count(); ++i) {
    const JointLimits& l = chain.joints()[static_cast<std::size_t>(i)].limits;
    const double p = prefer ? (*prefer)[i] : 0.5 * (l.lower + l.upper);
    q[i] = wrap_into(q[i], l.lower, l.upper, p);
  }
}

}  // namespace exodaq::kinematics::ik_detail
