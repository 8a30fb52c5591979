#include "ik_spherical.hpp"

#include "ik_numeric.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

namespace exodaq::kinematics::ik_detail {

namespace {

Eigen::Matrix3d rot(const Eigen::Vector3d& axis, double angle) noexcept {
  return Eigen::AngleAxisd(angle, axis).toRotationMatrix();
}

// Paden-Kahan subproblem 1: the angle about unit `w` that turns p onto q (their
// components normal to w). Returns false when p has none (any angle will do).
bool turn_angle(const Eigen::Vector3d& w, const Eigen::Vector3d& p, const Eigen::Vector3d& q,
                double& angle) noexcept {
  const Eigen::Vector3d pp = p - w * w.dot(p);
  const Eigen::Vector3d qq = q - w * w.dot(q);
  if (pp.norm() < 1e-12 || qq.norm() < 1e-12) return false;
  angle = std::atan2(w.dot(pp.cross(qq)), pp.dot(qq));
  return true;
}

// The angle of a rotation X about unit w (exact when X is one).
double angle_about(const Eigen::Vector3d& w, const Eigen::Matrix3d& X) noexcept {
  Eigen::Index k = 0;
  w.cwiseAbs().minCoeff(&k);
  const Eigen::Vector3d v = Eigen::Vector3d::Unit(k).cross(w).normalized();
  double angle = 0.0;
  turn_angle(w, v, X * v, angle);
  return angle;
}

// Orthonormal frame [a, n, a x n] with n the unit part of b normal to a.
Eigen::Matrix3d frame_of(const Eigen::Vector3d& a, const Eigen::Vector3d& b) noexcept {
  const Eigen::Vector3d n = (b - a * a.dot(b)).normalized();
  Eigen::Matrix3d F;
  F.col(0) = a;
  F.col(1) = n;
  F.col(2) = a.cross(n);
  return F;
}

constexpr double kGeometryTol = 1e-9;

}  // namespace

std::optional<SphericalShoulderArm> SphericalShoulderArm::detect(const Chain& chain) {
  if (chain.joint_count() != 6) return std::nullopt;
  const Chain poe = chain.to_product_of_exponentials();
  SphericalShoulderArm a;
  a.base_inverse_ = poe.base().inverse();
  Eigen::Vector3d point[6];
  for (int i = 0; i < 6; ++i) {
    const JointDescription& j = poe.joints()[static_cast<std::size_t>(i)];
    a.w_[i] = j.screw.omega.normalized();
    point[i] = j.screw.q;
    a.offset_[i] = j.dh.theta_offset;
    a.lower_[i] = j.limits.lower;
    a.upper_[i] = j.limits.upper;
    a.mid_[i] = 0.5 * (j.limits.lower + j.limits.upper);
  }
  // Shoulder centre: the point nearest axes 1-4 (least squares), on all of them.
  Eigen::Matrix3d P_sum = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b_sum = Eigen::Vector3d::Zero();
  for (int i = 0; i < 4; ++i) {
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - a.w_[i] * a.w_[i].transpose();
    P_sum += P;
    b_sum += P * point[i];
  }
  if (Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(P_sum).eigenvalues().minCoeff() < 1e-6) {
    return std::nullopt;  // axes 1-4 all parallel
  }
  a.s_ = P_sum.ldlt().solve(b_sum);
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d d = a.s_ - point[i];
    if ((d - a.w_[i] * a.w_[i].dot(d)).norm() > kGeometryTol) return std::nullopt;
  }
  // Elbow: where axes 5 and 6 meet.
  const double c56 = a.w_[4].dot(a.w_[5]);
  const double den = 1.0 - c56 * c56;
  if (den < 1e-12) return std::nullopt;
  const Eigen::Vector3d d = point[5] - point[4];
  const double t5 = (a.w_[4].dot(d) - c56 * a.w_[5].dot(d)) / den;
  const double t6 = (c56 * a.w_[4].dot(d) - a.w_[5].dot(d)) / den;
  const Eigen::Vector3d e5 = point[4] + t5 * a.w_[4];
  const Eigen::Vector3d e6 = point[5] + t6 * a.w_[5];
  if ((e5 - e6).norm() > kGeometryTol) return std::nullopt;
  const Eigen::Vector3d elbow = 0.5 * (e5 + e6);
  a.upper_arm_ = (elbow - a.s_).norm();
  if (a.upper_arm_ < kGeometryTol) return std::nullopt;
  a.u0_ = (elbow - a.s_) / a.upper_arm_;
  // Joints 2-4 as two rotations of axis 4 (subproblem 2) need 2 x 3 and 3 x 4.
  if (a.w_[1].cross(a.w_[2]).norm() < 1e-6 || a.w_[2].cross(a.w_[3]).norm() < 1e-6) {
    return std::nullopt;
  }
  const Pose& M = poe.home_pose();
  a.home_rotation_ = M.linear();
  a.elbow_in_palm_ = M.inverse() * elbow;
  a.axis6_in_palm_ = M.linear().transpose() * a.w_[5];
  // u0 . Rot(w5, phi) w6 = a cos(phi) + b sin(phi) + c (Rodrigues).
  a.c_ = a.w_[4].dot(a.u0_) * a.w_[4].dot(a.w_[5]);
  a.a_ = a.u0_.dot(a.w_[5]) - a.c_;
  a.b_ = a.u0_.dot(a.w_[4].cross(a.w_[5]));
  if (std::hypot(a.a_, a.b_) < 1e-6) return std::nullopt;  // the elbow cannot bend
  return a;
}

// Joints i and j turn about one line (a singular posture): q_i + t, q_j - sigma t
// is the same pose for every t. Picks the t in the middle of the range that keeps
// both within their limits (no change when no t does).
void SphericalShoulderArm::centre_pair(JointVector& q, int i, int j, double sigma) const noexcept {
  const double qi = wrap_into(q[i], lower_[i], upper_[i], mid_[i]);
  const double qj = wrap_into(q[j], lower_[j], upper_[j], mid_[j]);
  const double lo_i = lower_[i] - qi, hi_i = upper_[i] - qi;
  double best_lo = 0.0, best_hi = -1.0;
  for (int m = -1; m <= 1; ++m) {
    const double shift = kTwoPi * m;
    // q_j - sigma t in [lower_j, upper_j] + shift
    double lo_j = sigma > 0 ? qj - upper_[j] - shift : lower_[j] + shift - qj;
    double hi_j = sigma > 0 ? qj - lower_[j] - shift : upper_[j] + shift - qj;
    const double lo = std::max(lo_i, lo_j), hi = std::min(hi_i, hi_j);
    if (hi - lo > best_hi - best_lo) {
      best_lo = lo;
      best_hi = hi;
    }
  }
  if (best_hi < best_lo) return;
  const double t = 0.5 * (best_lo + best_hi);
  q[i] = qi + t;
  q[j] = qj - sigma * t;
}

// Paden-Kahan subproblem 2 on axis 4 (two roots) for joints 2 and 3, then
// subproblem 1 for joint 4.
void SphericalShoulderArm::shoulder_triad(const Eigen::Matrix3d& N,
                                          ShoulderTriad out[2]) const noexcept {
  const Eigen::Vector3d& p = w_[3];
  const Eigen::Vector3d qv = N * p;
  const double c23 = w_[1].dot(w_[2]);
  const double den = c23 * c23 - 1.0;
  const double alpha = (c23 * w_[2].dot(p) - w_[1].dot(qv)) / den;
  const double beta = (c23 * w_[1].dot(qv) - w_[2].dot(p)) / den;
  const Eigen::Vector3d w23 = w_[1].cross(w_[2]);
  const double gamma_sq =
      (p.squaredNorm() - alpha * alpha - beta * beta - 2.0 * alpha * beta * c23) /
      w23.squaredNorm();
  const double gamma = std::sqrt(std::max(gamma_sq, 0.0));
  for (int k = 0; k < 2; ++k) {
    ShoulderTriad& t = out[k];
    const Eigen::Vector3d z = alpha * w_[1] + beta * w_[2] + (k ? -gamma : gamma) * w23;
    t.phi3 = 0.0;
    turn_angle(w_[2], p, z, t.phi3);
    t.phi2 = mid_[1] + offset_[1];
    t.aligned = !turn_angle(w_[1], z, qv, t.phi2);  // axes 2 and 4 in line: phi2 free
    const Eigen::Matrix3d Y = rot(w_[2], t.phi3).transpose() * rot(w_[1], t.phi2).transpose() * N;
    t.phi4 = angle_about(w_[3], Y);
  }
}

// At a singular posture two joints turn about one line: centre the pair.
void SphericalShoulderArm::centre_singular_pairs(SphericalCandidate& c,
                                                 const Eigen::Vector3d& forearm) const noexcept {
  const double phi3 = c.q[2] + offset_[2];
  if (c.shoulder_triad) {  // axes 2 and 4 in line: only phi2 + sigma phi4 is fixed
    centre_pair(c.q, 1, 3, w_[1].dot(rot(w_[2], phi3) * w_[3]) > 0.0 ? 1.0 : -1.0);
  }
  if (c.straight_arm) {  // axes 4 and 6 in line, when the upper arm turns about axis 4
    const Eigen::Vector3d a4 = rot(w_[0], c.q[0] + offset_[0]) * rot(w_[1], c.q[1] + offset_[1]) *
                               rot(w_[2], phi3) * w_[3];
    const double d = a4.dot(forearm);
    if (std::abs(d) > 1.0 - 1e-9) centre_pair(c.q, 3, 5, d > 0.0 ? 1.0 : -1.0);
  }
}

int SphericalShoulderArm::solve(const Pose& target, double q1, double reach_slack,
                                SphericalCandidate out[4],
                                double& elbow_sphere_miss) const noexcept {
  const Pose T = base_inverse_ * target;
  const Eigen::Matrix3d& Rg = T.linear();
  const Eigen::Vector3d elbow = Rg * elbow_in_palm_ + T.translation();
  const Eigen::Vector3d f = Rg * axis6_in_palm_;
  const double dist = (elbow - s_).norm();
  elbow_sphere_miss = dist - upper_arm_;
  if (!(std::abs(elbow_sphere_miss) <= reach_slack) || dist < kGeometryTol) return 0;
  const Eigen::Vector3d u = (elbow - s_) / dist;
  // The elbow angle: angle(u0, Rot(w5, phi5) w6) must equal angle(u, f).
  const double r = std::hypot(a_, b_);
  const double ratio = (u.dot(f) - c_) / r;
  if (!(std::abs(ratio) <= 1.0 + 1e-3)) return 0;
  const double base5 = std::atan2(b_, a_);
  const double delta5 = std::acos(std::clamp(ratio, -1.0, 1.0));
  const Eigen::Matrix3d palm_from_home = Rg * home_rotation_.transpose();
  const double phi1 = q1 + offset_[0];
  int count = 0;
  for (const double phi5 : {base5 + delta5, base5 - delta5}) {
    const Eigen::Matrix3d R5 = rot(w_[4], phi5);
    const Eigen::Vector3d w = R5 * w_[5];
    bool straight = u0_.cross(w).norm() < kGeometryTol;
    double phi6 = mid_[5] + offset_[5];
    Eigen::Matrix3d Rsh;
    if (!straight) {
      Rsh = frame_of(u, f) * frame_of(u0_, w).transpose();
      phi6 = angle_about(w_[5], R5.transpose() * Rsh.transpose() * palm_from_home);
    } else {
      // Upper arm and forearm in line: only the sum of the rotations about them
      // is fixed; joint 6 takes the middle of its range.
      Rsh = palm_from_home * rot(w_[5], phi6).transpose() * R5.transpose();
    }
    // Joints 2-4: Rot(w2, phi2) Rot(w3, phi3) Rot(w4, phi4) = N.
    ShoulderTriad triads[2];
    shoulder_triad(rot(w_[0], phi1).transpose() * Rsh, triads);
    for (const ShoulderTriad& t : triads) {
      SphericalCandidate& c = out[count++];
      c.q.resize(6);
      const double phi[6] = {phi1, t.phi2, t.phi3, t.phi4, phi5, phi6};
      for (int i = 0; i < 6; ++i) c.q[i] = phi[i] - offset_[i];
      c.straight_arm = straight;
      c.shoulder_triad = t.aligned;
      centre_singular_pairs(c, f);
    }
  }
  return count;
}

}  // namespace exodaq::kinematics::ik_detail
