#pragma once
// A serial chain of revolute joints, written in standard DH, modified (Craig)
// DH or product-of-exponentials form. Eigen only: no I/O, no exceptions and no
// heap allocation in the evaluation functions (the hot path).
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <string>
#include <vector>

namespace exodaq::kinematics {

inline constexpr int kMaxJoints = 8;

// Joint-space vectors and Jacobians: dynamic size up to kMaxJoints, stored
// inline (no heap allocation).
using JointVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxJoints, 1>;
using Jacobian = Eigen::Matrix<double, 6, Eigen::Dynamic, 0, 6, kMaxJoints>;
using Pose = Eigen::Isometry3d;

enum class Convention { kStandardDh, kModifiedDh, kProductOfExponentials };

// Standard DH (seed 000 Table 3): T_i = Rz(theta_i + offset) Tz(d) Tx(a) Rx(alpha).
// Modified DH (Craig): T_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i + offset) Tz(d_i);
// the same four numbers per row, read in Craig's order.
struct DhRow {
  double a = 0.0;
  double alpha = 0.0;
  double d = 0.0;
  double theta_offset = 0.0;
};

// Product of exponentials (seed 004): a revolute joint's unit axis omega through
// point q, both in the base frame at the zero configuration.
struct ScrewAxis {
  Eigen::Vector3d omega = Eigen::Vector3d::UnitZ();
  Eigen::Vector3d q = Eigen::Vector3d::Zero();
};

struct JointLimits {
  double lower = -M_PI;
  double upper = M_PI;
};

struct JointDescription {
  std::string name;
  JointLimits limits;
  DhRow dh;         // used for the DH conventions
  ScrewAxis screw;  // used for product of exponentials
};

// One chain. Frames are numbered as in DH: frame 0 is the base frame O0,
// frame i is attached to link i (i = 1..n), and the palm (tool) frame is
// frame n followed by `tool`. `base` maps the world into O0 (identity for
// the rig: O0 is the world).
class Chain {
 public:
  Chain() = default;
  // For the DH conventions `tool` maps frame n to the palm. For product of
  // exponentials `tool` is M: the palm pose in O0 at q = 0 (home_pose()), and the
  // link frames at q = 0 default to the world-aligned frame at the next joint's
  // axis point q_{i+1} (frame n = palm). Throws std::invalid_argument for more
  // than kMaxJoints joints or a zero-length screw axis (start-up code only).
  Chain(Convention convention, std::vector<JointDescription> joints, const Pose& base,
        const Pose& tool);
  // PoE only: also give the pose of every link frame 1..n in O0 at q = 0
  // (`link_homes.size()` == n). Used by to_product_of_exponentials() so that
  // every frame's pose and Jacobian are kept.
  Chain(Convention convention, std::vector<JointDescription> joints, const Pose& base,
        const Pose& tool, const std::vector<Pose>& link_homes);

  Convention convention() const noexcept { return convention_; }
  int joint_count() const noexcept { return static_cast<int>(joints_.size()); }
  const std::vector<JointDescription>& joints() const noexcept { return joints_; }
  const Pose& base() const noexcept { return base_; }
  const Pose& tool() const noexcept { return tool_; }
  // PoE only: the palm pose at q = 0 (M in Lynch & Park, g_st(0) in seed 004).
  const Pose& home_pose() const noexcept { return home_; }

  // Palm pose in the world frame. q.size() must equal joint_count().
  Pose palm(const JointVector& q) const noexcept;

  // Pose of frame i (0 = base O0, n = last link, n + 1 = palm) in the world frame.
  Pose frame(const JointVector& q, int i) const noexcept;

  // Geometric Jacobian (rows 0-2 linear velocity of the frame origin, rows 3-5
  // angular velocity, both in the world frame) of frame i (1..n+1); columns of
  // joints beyond the frame are zero. J is resized to 6 x n.
  void jacobian(const JointVector& q, int i, Jacobian& J) const noexcept;

  // Palm pose and palm Jacobian together, sharing the frame computation.
  void palm_and_jacobian(const JointVector& q, Pose& palm, Jacobian& J) const noexcept;

  // The equivalent PoE chain (same palm pose and Jacobians for every q).
  Chain to_product_of_exponentials() const;

  // sum(a_i^2 + d_i^2) over DH rows (seed 000 eq. 3's denominator, squared).
  double dh_length_scale_sq() const noexcept;

 private:
  Convention convention_ = Convention::kStandardDh;
  std::vector<JointDescription> joints_;
  Pose base_ = Pose::Identity();
  Pose tool_ = Pose::Identity();
  Pose home_ = Pose::Identity();

  // Every convention is compiled into one form: world <- frame i is
  //   X_1 Rz(q_1) B_1                                   (i = 1)
  //   X_1 Rz(q_1) C_1 Rz(q_2) C_2 ... Rz(q_i) B_i       (i > 1)
  // with constant 3x4 transforms; X_1 contains the base and A_1, C_i = B_i A_{i+1},
  // C_n maps onto the palm; joint offsets are added to q. Filled by the constructors.
  struct Rigid {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    Eigen::Vector3d p = Eigen::Vector3d::Zero();
    // R == Rx(beta) exactly (every DH step): cb = cos(beta), sb = sin(beta); the
    // evaluation then skips the general 3x3 product.
    bool rx = false;
    double cb = 1.0;
    double sb = 0.0;
  };
  std::array<Rigid, kMaxJoints + 1> step_{};  // step_[0] = X_1, step_[i] = C_i
  std::array<Rigid, kMaxJoints> link_{};      // link_[i - 1] = B_i
  std::array<double, kMaxJoints> offset_{};   // joint i turns by Rz(q_i + offset_i)
  std::vector<Pose> link_homes_;              // PoE link frames at q = 0 (may be empty)
  double length_scale_sq_ = 0.0;
  void compile(const std::vector<Pose>* link_homes);
  friend struct ChainAccess;  // kinematics/src internals (evaluate_rig)
};

// sqrt(det(J_S J_S^T)) over the selected rows of J (seed 000 eq. 2). `rows` is
// a bit mask over the 6 rows (bit 0 = vx ... bit 5 = wz).
double manipulability(const Jacobian& J, unsigned rows) noexcept;

// Seed 000 eq. 3: det(J_S J_S^T)^(1/m) / sqrt(sum(a_i^2 + d_i^2)), m = number of rows.
double relative_manipulability(const Jacobian& J, unsigned rows, const Chain& chain) noexcept;

inline constexpr unsigned kLinearRows = 0x07;
inline constexpr unsigned kAngularRows = 0x38;

// Seed 000 eq. (1), written out in closed form: the angular rows of the first
// four joints' Jacobian for the rig's DH table. Used as a golden reference.
Eigen::Matrix<double, 3, 4> shoulder_orientation_jacobian_closed_form(double t1, double t2,
                                                                      double t3) noexcept;

// Quaternion (w, x, y, z) with w >= 0, so a pose has one published form.
Eigen::Vector4d quaternion_wxyz(const Eigen::Matrix3d& R) noexcept;

}  // namespace exodaq::kinematics
