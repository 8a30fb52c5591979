#pragma once
// The measurement model of seed 000 Fig. 12, templated for Ceres' automatic
// differentiation: marker position in the camera frame from the joint readings
// θᴿ and the 20 parameters.
#include <Eigen/Core>
#include <cmath>

#include "exodaq/calibration/solver.hpp"

namespace exodaq::calibration::detail {

// Point given in DH frame 6 carried to the world (base) frame through joints
// 6..1 with the deviated DH rows and offsets of x. theta is θᴿ.
template <typename T>
Eigen::Matrix<T, 3, 1> frame6_to_world(const NominalModel& m, const T* x, const T* theta, T px,
                                       T py, T pz) {
  using std::cos;
  using std::sin;
  for (int i = 5; i >= 0; --i) {
    const kinematics::DhRow& r = m.dh[i];
    T a = T(r.a);
    T d = T(r.d);
    if (i == 1) d += x[kDd2];
    if (i == 2) {
      d += x[kDd3];
      a += x[kDa3];
    }
    if (i == 4) {
      d += x[kDd5];
      a += x[kDa5];
    }
    // T_i = Rz(θ) Tz(d) Tx(a) Rx(α), applied to the point from the right.
    const double ca = std::cos(r.alpha), sa = std::sin(r.alpha);
    const T y1 = ca * py - sa * pz;
    const T z1 = sa * py + ca * pz + d;
    const T x1 = px + a;
    const T th = theta[i] + x[kTheta1 + i] + T(r.theta_offset);
    const T c = cos(th), s = sin(th);
    px = c * x1 - s * y1;
    py = s * x1 + c * y1;
    pz = z1;
  }
  const Eigen::Matrix3d Rb = m.base.linear();
  const Eigen::Vector3d tb = m.base.translation();
  return Eigen::Matrix<T, 3, 1>(T(Rb(0, 0)) * px + T(Rb(0, 1)) * py + T(Rb(0, 2)) * pz + T(tb.x()),
                                T(Rb(1, 0)) * px + T(Rb(1, 1)) * py + T(Rb(1, 2)) * pz + T(tb.y()),
                                T(Rb(2, 0)) * px + T(Rb(2, 1)) * py + T(Rb(2, 2)) * pz + T(tb.z()));
}

// Camera: d + Rx(φx) Ry(φy) Rz(φz) p.
template <typename T>
Eigen::Matrix<T, 3, 1> world_to_camera(const T* x, const Eigen::Matrix<T, 3, 1>& p) {
  using std::cos;
  using std::sin;
  T wx = p[0], wy = p[1], wz = p[2];
  {
    const T c = cos(x[kPhiZ]), s = sin(x[kPhiZ]);
    const T nx = c * wx - s * wy;
    wy = s * wx + c * wy;
    wx = nx;
  }
  {
    const T c = cos(x[kPhiY]), s = sin(x[kPhiY]);
    const T nx = c * wx + s * wz;
    wz = -s * wx + c * wz;
    wx = nx;
  }
  {
    const T c = cos(x[kPhiX]), s = sin(x[kPhiX]);
    const T ny = c * wy - s * wz;
    wz = s * wy + c * wz;
    wy = ny;
  }
  return Eigen::Matrix<T, 3, 1>(wx + x[kDx], wy + x[kDy], wz + x[kDz]);
}

// Marker in the camera frame (seed 000 Fig. 12). A hand marker sits at the
// tool point + its layout position + Δpᴹ in frame 6 (seed 000's one marker:
// position 0); a base marker at its layout position in the world frame.
template <typename T>
Eigen::Matrix<T, 3, 1> model_point(const NominalModel& m, const T* x, const T* theta,
                                   const MarkerSite& site) {
  const auto& q = site.position;
  if (site.mount == MarkerMount::kBase) {
    return world_to_camera(x, Eigen::Matrix<T, 3, 1>(T(q[0]), T(q[1]), T(q[2])));
  }
  const Eigen::Vector3d t6 = m.tool.translation();
  const T px = T(t6.x() + q[0]) + x[kPx];
  const T py = T(t6.y() + q[1]) + x[kPy];
  const T pz = T(t6.z() + q[2]) + x[kPz];
  return world_to_camera(x, frame6_to_world(m, x, theta, px, py, pz));
}

}  // namespace exodaq::calibration::detail
