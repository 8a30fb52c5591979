#pragma once
// Shoulder centre of rotation from motion capture (seed 001 §II.B,
// docs/shoulder-cor.md): torso markers normalise every frame to the first one
// by a least-squares rigid transform (SVD, Umeyama 1991); frames are binned by
// humerus elevation; within a bin, random pairs of frames give the humerus'
// rotation axis each; outlying axes are dropped around a first estimate (a
// common-centre sphere fit of the humerus markers); the centre of rotation is
// then the least-squares centre of the kept pairs' motions (by default allowed
// to move linearly with elevation within the bin, reported at the bin's mean
// elevation; or seed 001's point closest to the axes), with its covariance
// from the pairs' residuals, the spread of the axes, and a flag for
// components the bin cannot determine. Pure math: no I/O.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace exodaq::calibration {

// y = rotation · x + translation.
struct RigidTransform {
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  Eigen::Vector3d apply(const Eigen::Vector3d& x) const { return rotation * x + translation; }
};

// The rigid transform (no scale) minimising Σ‖to_k − (R from_k + t)‖² (seed 001
// eq. 1). Columns are corresponding points. nullopt for fewer than three
// points or points (nearly) on one line, where the rotation is not determined.
std::optional<RigidTransform> fit_rigid_transform(const Eigen::Matrix3Xd& from,
                                                  const Eigen::Matrix3Xd& to);

// The equivalent rotation axis of a displacement (seed 001 Fig. 3): unit
// direction, angle in [0, π], the point of the axis closest to the origin, and
// the slide along the axis (0 for a pure rotation about a fixed point).
struct RotationAxis {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitZ();
  double angle_rad = 0;
  double slide_m = 0;
};
RotationAxis rotation_axis(const RigidTransform& t);  // angle 0: point and direction meaningless

double distance_to_axis(const Eigen::Vector3d& p, const RotationAxis& a);

// The point with the least sum of squared distances to the axes; nullopt
// when they do not determine one (fewer than two, or all parallel).
std::optional<Eigen::Vector3d> closest_point_to_axes(const std::vector<RotationAxis>& axes);

// Common centre of spheres: every track (the positions of one marker) keeps
// its own distance to the centre. Linear least squares on
// 2 x·c + s_m = ‖x‖² (s_m = r_m² − ‖c‖²). nullopt when ill-determined.
std::optional<Eigen::Vector3d> fit_sphere_centre(const std::vector<Eigen::Matrix3Xd>& tracks);

// One motion-capture frame: marker positions (m, camera frame), one column per
// marker in the order the analysis was given the ids; NaN columns: not seen.
struct MocapFrame {
  std::int64_t utime_us = 0;
  Eigen::Matrix3Xd torso, humerus;
};

// Columns of the markers that define the two long axes.
struct ShoulderAxes {
  int torso_cranial = 0, torso_caudal = 1;       // torso: cranial → caudal is "down"
  int humerus_proximal = 0, humerus_distal = 1;  // humerus: shoulder end → elbow end
};

struct CorOptions {
  double bin_width_rad = 20.0 * 0.017453292519943295;     // seed 001 Table II
  std::size_t pairs_per_bin = 2000;                       // K random pairs tried per bin
  double min_rotation_rad = 15.0 * 0.017453292519943295;  // smaller turns: noise dominates
  double outlier_factor = 3.0;    // axes farther than this × the median distance are dropped
  double outlier_floor_m = 2e-3;  // ... but never closer than this
  std::size_t min_axes = 10;      // fewer kept axes: no centre for the bin
  std::uint64_t seed = 1;
  // The centre may move linearly with elevation within a bin (reported at the
  // bin's mean elevation); false: seed 001's centre at rest, the point
  // closest to the axes.
  bool moving_centre = true;
  // A vertical or horizontal component (or the centre's weakest direction)
  // is flagged as poorly determined when its 95 % half-width exceeds
  // max_ci95_m, or max_condition times that of the best-determined
  // direction (axes nearly parallel: any systematic error, such as a centre
  // moving within the bin, is amplified along it).
  double max_ci95_m = 2e-3;
  double max_condition = 5.0;
};

inline constexpr double kZ95 = 1.959963984540054;  // two-sided 95 % of the normal distribution

struct CorBin {
  double elevation_lo_rad = 0, elevation_hi_rad = 0;
  double mean_elevation_rad = 0;  // of the bin's frames
  std::size_t frames = 0;
  std::size_t pairs = 0;              // tried
  std::size_t pairs_small = 0;        // rejected: rotation below min_rotation_rad
  std::size_t pairs_few_markers = 0;  // rejected: fewer than 3 humerus markers in both
  std::size_t axes = 0;               // axes kept after outlier removal
  std::size_t outliers = 0;           // axes dropped
  bool valid = false;
  std::string why;                                    // when not valid
  Eigen::Vector3d initial = Eigen::Vector3d::Zero();  // sphere-fit estimate, m
  Eigen::Vector3d centre =
      Eigen::Vector3d::Zero();  // torso frame (the first frame's camera frame), m
  double axis_rms_m = 0;        // RMS distance of the kept axes to the centre
  double vertical_m = 0;    // along cranial, relative to the first valid bin (seed 001 Table II)
  double horizontal_m = 0;  // along `horizontal_axis`, relative to the first valid bin
  // Uncertainty (docs/shoulder-cor.md §3): the centre's covariance (m²,
  // torso frame) from the kept pairs' residuals (a sandwich estimate that
  // counts pairs sharing a frame as correlated), its 95 % half-widths per axis, and
  // those of the relative motions (this bin's and the first bin's combined;
  // 0 for the first bin itself).
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  Eigen::Vector3d ci95_m = Eigen::Vector3d::Zero();
  double vertical_ci95_m = 0, horizontal_ci95_m = 0;
  // How spread the kept rotation axes are: the angle of their directions from
  // the dominant one (RMS); near 0 every axis is parallel and the centre's
  // component along them is undetermined.
  double axis_spread_rad = 0;
  Eigen::Vector3d weak_direction = Eigen::Vector3d::Zero();  // the centre's least determined
  double weak_ci95_m = 0;                                    // its 95 % half-width
  Eigen::Vector3d gradient = Eigen::Vector3d::Zero();        // centre motion per rad of elevation
  bool vertical_poor = false, horizontal_poor = false, ill_conditioned = false;
  std::string warning;  // what is poorly determined, for people
};

struct CorResult {
  std::size_t frames = 0;
  std::size_t frames_used = 0;
  std::size_t frames_torso_missing = 0;  // fewer than 3 torso markers in common with the reference
  std::size_t frames_humerus_missing = 0;  // an axis marker or 3 humerus markers not seen
  Eigen::Vector3d cranial = Eigen::Vector3d::UnitY();  // unit, torso frame
  Eigen::Vector3d horizontal_axis =
      Eigen::Vector3d::UnitX();  // ⊥ cranial, largest spread of the centres
  std::vector<CorBin> bins;      // every bin from 0 to the largest elevation seen
};

// Step 1: every frame mapped into the reference frame's torso pose (the first
// frame with all torso markers seen). Frames whose torso cannot be fitted
// come back with empty matrices and are counted in `result`.
std::vector<MocapFrame> normalise_to_torso(const std::vector<MocapFrame>& frames,
                                           CorResult& result);

// The angle between the humerus (proximal → distal) and the torso's caudal
// direction: 0 with the arm hanging along the torso. NaN when an axis marker
// was not seen.
double humerus_elevation(const MocapFrame& frame, const ShoulderAxes& axes,
                         const Eigen::Vector3d& caudal);

// Steps 1-5 of seed 001 §II.B on a recording.
CorResult analyse_shoulder_cor(const std::vector<MocapFrame>& frames, const ShoulderAxes& axes,
                               const CorOptions& options);

}  // namespace exodaq::calibration
