#include "exodaq/kinematics/chain.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

#include "chain_access.hpp"

namespace exodaq::kinematics {

namespace {

using Rigid = ChainAccess::Rigid;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

Rigid from_pose(const Pose& p) {
  Rigid r;
  r.R = p.linear();
  r.p = p.translation();
  return r;
}

Pose to_pose(const Rigid& r) noexcept {
  Pose p = Pose::Identity();
  p.linear() = r.R;
  p.translation() = r.p;
  return p;
}

Rigid compose(const Rigid& a, const Rigid& b) {
  Rigid r;
  r.R = a.R * b.R;
  r.p = a.p + a.R * b.p;
  return r;
}

Rigid inverse(const Rigid& a) {
  Rigid r;
  r.R = a.R.transpose();
  r.p = -(r.R * a.p);
  return r;
}

Rigid rot_x(double angle) {
  Rigid r;
  r.R = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitX()).toRotationMatrix();
  return r;
}

Rigid trans(double x, double y, double z) {
  Rigid r;
  r.p = Eigen::Vector3d(x, y, z);
  return r;
}

// A frame whose z axis is `omega` (unit) and whose origin is `q`.
Rigid axis_frame(const Eigen::Vector3d& omega, const Eigen::Vector3d& q) {
  // Pick the world axis least aligned with omega to complete the basis.
  Eigen::Index k = 0;
  omega.cwiseAbs().minCoeff(&k);
  const Eigen::Vector3d x = Eigen::Vector3d::Unit(k).cross(omega).normalized();
  Rigid r;
  r.R.col(0) = x;
  r.R.col(1) = omega.cross(x);
  r.R.col(2) = omega;
  r.p = q;
  return r;
}

// The joint's rotated x and y axes: columns of R Rz(angle).
inline void rotate_xy(const Eigen::Matrix3d& R, double angle, Eigen::Vector3d& x,
                      Eigen::Vector3d& y) noexcept {
  const double c = std::cos(angle), s = std::sin(angle);  // one sincos call
  x = c * R.col(0) + s * R.col(1);
  y = c * R.col(1) - s * R.col(0);
}

// T <- T Rz(angle) C, given the rotated axes x, y from rotate_xy (z and p of T
// are unchanged by Rz).
inline void advance(Rigid& T, const Eigen::Vector3d& x, const Eigen::Vector3d& y,
                    const Rigid& C) noexcept {
  const Eigen::Vector3d z = T.R.col(2);
  T.p += C.p.x() * x + C.p.y() * y + C.p.z() * z;
  if (C.rx) {
    T.R.col(0) = x;
    T.R.col(1) = C.cb * y + C.sb * z;
    T.R.col(2) = C.cb * z - C.sb * y;
  } else {
    for (int k = 0; k < 3; ++k) {
      T.R.col(k) = C.R(0, k) * x + C.R(1, k) * y + C.R(2, k) * z;
    }
  }
}

void fill_nan(Pose& p) noexcept {
  p.linear().setConstant(kNaN);
  p.translation().setConstant(kNaN);
}

}  // namespace

Chain::Chain(Convention convention, std::vector<JointDescription> joints, const Pose& base,
             const Pose& tool)
    : convention_(convention), joints_(std::move(joints)), base_(base), tool_(tool) {
  compile(nullptr);
}

Chain::Chain(Convention convention, std::vector<JointDescription> joints, const Pose& base,
             const Pose& tool, const std::vector<Pose>& link_homes)
    : convention_(convention), joints_(std::move(joints)), base_(base), tool_(tool) {
  if (convention_ != Convention::kProductOfExponentials) {
    throw std::invalid_argument("link frames at q = 0 are given only for a PoE chain");
  }
  if (static_cast<int>(link_homes.size()) != joint_count()) {
    throw std::invalid_argument("one link frame per joint is needed");
  }
  compile(&link_homes);
}

namespace {

// Each joint's fixed transforms before (A_i) and after (B_i) its Rz(q_i), the
// palm in the last joint's frame, and the squared length scale of the chain.
struct JointSteps {
  std::array<Rigid, kMaxJoints> A{};
  std::array<Rigid, kMaxJoints> B{};
  Rigid palm_from_n;
  double scale = 0.0;
};

// A DH chain: standard Rz(q + off) Tz(d) Tx(a) Rx(alpha), modified
// Rx(alpha) Tx(a) Rz(q + off) Tz(d).
JointSteps dh_steps(Convention convention, const std::vector<JointDescription>& joints,
                    const Pose& tool) {
  JointSteps out;
  out.palm_from_n = from_pose(tool);
  for (std::size_t i = 0; i < joints.size(); ++i) {
    const DhRow& dh = joints[i].dh;
    out.scale += dh.a * dh.a + dh.d * dh.d;
    if (convention == Convention::kStandardDh) {
      out.B[i] = compose(trans(dh.a, 0.0, dh.d), rot_x(dh.alpha));
    } else {
      out.A[i] = compose(rot_x(dh.alpha), trans(dh.a, 0.0, 0.0));
      out.B[i] = trans(0.0, 0.0, dh.d);
    }
  }
  return out;
}

// The link frames of a PoE chain at q = 0: given, or at the next joint's axis
// point (the palm for the last).
std::vector<Pose> poe_link_homes(const std::vector<JointDescription>& joints, const Pose& tool,
                                 const std::vector<Pose>* given) {
  if (given) return *given;
  const std::size_t n = joints.size();
  std::vector<Pose> homes(n, Pose::Identity());
  for (std::size_t i = 0; i < n; ++i) {
    if (i + 1 < n) {
      homes[i].translation() = joints[i + 1].screw.q;
    } else {
      homes[i] = tool;
    }
  }
  return homes;
}

// A product-of-exponentials chain (normalises each screw axis in place).
// exp([xi] (q + off)) = G Rz(q + off) G^-1, so the product of exponentials is
// G_1 Rz(q_1 + off_1) G_1^-1 G_2 Rz(q_2 + off_2) G_2^-1 ... M. Link frame i is
// that product up to joint i times L_i: B_i = G_i^-1 L_i, and A_i is then taken
// from link frame i - 1: A_i = L_{i-1}^-1 G_i (L_0 = I).
JointSteps poe_steps(std::vector<JointDescription>& joints, const Pose& tool,
                     const std::vector<Pose>& homes) {
  JointSteps out;
  out.palm_from_n = from_pose(tool);
  const std::size_t n = joints.size();
  Eigen::Vector3d last_point = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    ScrewAxis& s = joints[i].screw;
    const double norm = s.omega.norm();
    if (!(norm > 1e-9) || !std::isfinite(norm)) {
      throw std::invalid_argument("joint " + std::to_string(i + 1) +
                                  ": screw axis omega has zero length");
    }
    s.omega /= norm;
    const Rigid G = axis_frame(s.omega, s.q);
    const Rigid prev = i == 0 ? Rigid{} : inverse(from_pose(homes[i - 1]));
    out.A[i] = compose(prev, G);
    out.B[i] = compose(inverse(G), from_pose(homes[i]));
    out.scale += (s.q - last_point).squaredNorm();
    last_point = s.q;
  }
  out.scale += (tool.translation() - last_point).squaredNorm();
  // The palm is M; frame n is L_n (the palm itself unless link frames are given).
  if (n > 0) out.palm_from_n = compose(inverse(from_pose(homes[n - 1])), from_pose(tool));
  return out;
}

}  // namespace

void Chain::compile(const std::vector<Pose>* link_homes) {
  const int n = joint_count();
  if (n > kMaxJoints) {
    throw std::invalid_argument("a chain has at most " + std::to_string(kMaxJoints) +
                                " joints, got " + std::to_string(n));
  }
  home_ = Pose::Identity();
  link_homes_.clear();
  JointSteps js = dh_steps(convention_, joints_, tool_);
  if (convention_ == Convention::kProductOfExponentials) {
    // A PoE chain that also carries DH lengths keeps their scale.
    const double dh_scale = js.scale;
    home_ = tool_;
    link_homes_ = poe_link_homes(joints_, tool_, link_homes);
    js = poe_steps(joints_, tool_, link_homes_);
    if (dh_scale > 0.0) js.scale = dh_scale;
  }
  length_scale_sq_ = js.scale;
  link_ = {};
  step_ = {};
  const Rigid base = from_pose(base_);
  if (n == 0) {
    step_[0] = compose(base, js.palm_from_n);
    return;
  }
  step_[0] = compose(base, js.A[0]);
  offset_ = {};
  for (int i = 0; i < n; ++i) {
    offset_[i] = joints_[i].dh.theta_offset;
    link_[i] = js.B[i];
    Rigid& C = step_[i + 1];
    C = compose(js.B[i], i + 1 < n ? js.A[i + 1] : js.palm_from_n);
    C.rx = C.R(0, 0) == 1.0 && C.R(1, 0) == 0.0 && C.R(2, 0) == 0.0 && C.R(0, 1) == 0.0 &&
           C.R(0, 2) == 0.0 && C.R(1, 1) == C.R(2, 2) && C.R(2, 1) == -C.R(1, 2);
    C.cb = C.R(1, 1);
    C.sb = C.R(2, 1);
  }
}

void ChainAccess::sweep(const Chain& c, const JointVector& q, const Sweep& s) noexcept {
  Rigid T = c.step_[0];
  for (int j = 0; j < s.joints; ++j) {
    if (s.axis) s.axis[j] = T.R.col(2);
    if (s.point) s.point[j] = T.p;
    Eigen::Vector3d x, y;
    rotate_xy(T.R, q[j] + c.offset_[j], x, y);
    if (j + 1 == s.frame && s.frame_pose) {
      const Rigid& B = c.link_[j];
      const Eigen::Vector3d& z = T.R.col(2);
      s.frame_pose->p = T.p + B.p.x() * x + B.p.y() * y + B.p.z() * z;
      if (s.frame_rotation) {
        for (int k = 0; k < 3; ++k) {
          s.frame_pose->R.col(k) = B.R(0, k) * x + B.R(1, k) * y + B.R(2, k) * z;
        }
      }
    }
    advance(T, x, y, c.step_[j + 1]);
  }
  if (s.palm) *s.palm = T;
}

Pose Chain::palm(const JointVector& q) const noexcept {
  const int n = joint_count();
  Pose out;
  if (q.size() != n) {
    fill_nan(out);
    return out;
  }
  Rigid T = step_[0];
  for (int j = 0; j < n; ++j) {
    Eigen::Vector3d x, y;
    rotate_xy(T.R, q[j] + offset_[j], x, y);
    advance(T, x, y, step_[j + 1]);
  }
  return to_pose(T);
}

Pose Chain::frame(const JointVector& q, int i) const noexcept {
  const int n = joint_count();
  Pose out;
  if (q.size() != n || i < 0 || i > n + 1) {
    fill_nan(out);
    return out;
  }
  if (i == 0) return base_;
  if (i == n + 1) return palm(q);
  Rigid F;
  ChainAccess::Sweep s;
  s.joints = i;
  s.frame = i;
  s.frame_pose = &F;
  ChainAccess::sweep(*this, q, s);
  return to_pose(F);
}

void Chain::jacobian(const JointVector& q, int i, Jacobian& J) const noexcept {
  const int n = joint_count();
  J.setZero(6, n);
  if (q.size() != n || i < 0 || i > n + 1) {
    J.setConstant(kNaN);
    return;
  }
  if (i == 0) return;
  Eigen::Vector3d axis[kMaxJoints];
  Eigen::Vector3d point[kMaxJoints];
  Rigid F;
  ChainAccess::Sweep s;
  s.axis = axis;
  s.point = point;
  if (i == n + 1) {
    s.joints = n;
    s.palm = &F;
  } else {
    s.joints = i;
    s.frame = i;
    s.frame_pose = &F;
    s.frame_rotation = false;
  }
  ChainAccess::sweep(*this, q, s);
  for (int j = 0; j < s.joints; ++j) {
    J.template block<3, 1>(0, j) = axis[j].cross(F.p - point[j]);
    J.template block<3, 1>(3, j) = axis[j];
  }
}

void Chain::palm_and_jacobian(const JointVector& q, Pose& palm, Jacobian& J) const noexcept {
  const int n = joint_count();
  J.setZero(6, n);
  if (q.size() != n) {
    J.setConstant(kNaN);
    fill_nan(palm);
    return;
  }
  Eigen::Vector3d axis[kMaxJoints];
  Eigen::Vector3d point[kMaxJoints];
  Rigid T = step_[0];
  for (int j = 0; j < n; ++j) {
    axis[j] = T.R.col(2);
    point[j] = T.p;
    Eigen::Vector3d x, y;
    rotate_xy(T.R, q[j] + offset_[j], x, y);
    advance(T, x, y, step_[j + 1]);
  }
  for (int j = 0; j < n; ++j) {
    J.template block<3, 1>(0, j) = axis[j].cross(T.p - point[j]);
    J.template block<3, 1>(3, j) = axis[j];
  }
  palm = to_pose(T);
}

Chain Chain::to_product_of_exponentials() const {
  if (convention_ == Convention::kProductOfExponentials) return *this;
  const int n = joint_count();
  // Everything in O0 (the base is kept as the chain's base), at q = 0.
  Chain local(convention_, joints_, Pose::Identity(), tool_);
  const JointVector zero = JointVector::Zero(n);
  Eigen::Vector3d axis[kMaxJoints];
  Eigen::Vector3d point[kMaxJoints];
  Rigid palm0;
  ChainAccess::Sweep s;
  s.joints = n;
  s.axis = axis;
  s.point = point;
  s.palm = &palm0;
  ChainAccess::sweep(local, zero, s);
  std::vector<JointDescription> joints = joints_;
  std::vector<Pose> homes;
  homes.reserve(n);
  for (int i = 0; i < n; ++i) {
    joints[i].screw.omega = axis[i];
    joints[i].screw.q = point[i];
    joints[i].dh.theta_offset = 0.0;  // already in the q = 0 frames
    homes.push_back(local.frame(zero, i + 1));
  }
  Chain out(Convention::kProductOfExponentials, std::move(joints), base_, to_pose(palm0), homes);
  // Keep the DH length scale of seed 000 eq. (3).
  out.length_scale_sq_ = length_scale_sq_;
  return out;
}

double Chain::dh_length_scale_sq() const noexcept {
  return length_scale_sq_;
}

double manipulability(const Jacobian& J, unsigned rows) noexcept {
  // sqrt(det(J_S J_S^T)) = |det R| of J_S^T = Q R: the product of the norms of the
  // selected rows after Gram-Schmidt (two passes). Unlike det of the Gram matrix
  // this keeps full accuracy near a singularity (no square root of rounding noise).
  const int n = static_cast<int>(J.cols());
  double V[6][kMaxJoints];
  int m = 0;
  for (int r = 0; r < 6; ++r) {
    if (!(rows & (1u << r))) continue;
    for (int k = 0; k < n; ++k) V[m][k] = J(r, k);
    ++m;
  }
  if (m == 0 || m > n) return 0.0;
  double w = 1.0;
  for (int a = 0; a < m; ++a) {
    for (int pass = 0; pass < 2; ++pass) {
      for (int b = 0; b < a; ++b) {
        double d = 0.0;
        for (int k = 0; k < n; ++k) d += V[a][k] * V[b][k];
        for (int k = 0; k < n; ++k) V[a][k] -= d * V[b][k];
      }
    }
    double norm_sq = 0.0;
    for (int k = 0; k < n; ++k) norm_sq += V[a][k] * V[a][k];
    const double norm = std::sqrt(norm_sq);
    if (norm == 0.0) return 0.0;
    w *= norm;
    for (int k = 0; k < n; ++k) V[a][k] /= norm;
  }
  return w;
}

double relative_manipulability(const Jacobian& J, unsigned rows, const Chain& chain) noexcept {
  int m = 0;
  for (int r = 0; r < 6; ++r) m += (rows >> r) & 1u;
  const double scale_sq = chain.dh_length_scale_sq();
  if (m == 0 || !(scale_sq > 0.0)) return 0.0;
  const double w = manipulability(J, rows);
  return std::pow(w * w, 1.0 / m) / std::sqrt(scale_sq);
}

Eigen::Matrix<double, 3, 4> shoulder_orientation_jacobian_closed_form(double t1, double t2,
                                                                      double t3) noexcept {
  const double s1 = std::sin(t1), c1 = std::cos(t1);
  const double s2 = std::sin(t2), c2 = std::cos(t2);
  const double s3 = std::sin(t3), c3 = std::cos(t3);
  Eigen::Matrix<double, 3, 4> Jo;
  Jo << 0.0, -s1, c1 * s2, -c1 * c2 * s3 - s1 * c3,  //
      0.0, c1, s1 * s2, -s1 * c2 * s3 + c1 * c3,     //
      1.0, 0.0, c2, s2 * s3;
  return Jo;
}

Eigen::Vector4d quaternion_wxyz(const Eigen::Matrix3d& R) noexcept {
  Eigen::Quaterniond q(R);
  q.normalize();
  Eigen::Vector4d out(q.w(), q.x(), q.y(), q.z());
  // q and -q are the same rotation: publish w >= 0. For a half turn (w = 0 up to
  // rounding) the first non-zero of x, y, z is made positive instead, so the
  // sign does not depend on rounding noise in w.
  constexpr double kTie = 1e-12;
  if (std::abs(out[0]) <= kTie) {
    for (int i = 1; i < 4; ++i) {
      if (std::abs(out[i]) > kTie) {
        if (out[i] < 0.0) out = -out;
        break;
      }
    }
    out[0] = std::abs(out[0]);
  } else if (out[0] < 0.0) {
    out = -out;
  }
  return out;
}

}  // namespace exodaq::kinematics
