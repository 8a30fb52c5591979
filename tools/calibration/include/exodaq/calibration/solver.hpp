#pragma once
// Offline kinematic calibration (seed 000 §4, eq. 4-6) by bounded nonlinear
// least squares with Ceres, with an identifiability analysis that finds the
// directions one marker cannot observe and holds them at their priors.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "exodaq/calibration/inputs.hpp"
#include "exodaq/kinematics/chain.hpp"
#include "exodaq/settings/calibration_file.hpp"

namespace exodaq::calibration {

// The 20 parameters of seed 000 eq. (6), in the paper's order. SI inside (rad, m).
//   x = [Δθ⁰1..6, Δd2, Δd3, Δd5, Δa3, Δa5, Δpᴹx,y,z, dx,y,z, φx,y,z]
// Camera model: p_cam = d + Rx(φx) Ry(φy) Rz(φz) p_exo (intrinsic x-y'-z'').
inline constexpr int kParams = 20;
enum Param : int {
  kTheta1 = 0,
  kTheta2,
  kTheta3,
  kTheta4,
  kTheta5,
  kTheta6,
  kDd2,
  kDd3,
  kDd5,
  kDa3,
  kDa5,
  kPx,
  kPy,
  kPz,
  kDx,
  kDy,
  kDz,
  kPhiX,
  kPhiY,
  kPhiZ,
};
using ParamVector = std::array<double, kParams>;

bool is_angle(int p) noexcept;                 // rad inside, degrees in files and reports
const char* param_key(int p) noexcept;         // bounds-file key, e.g. "dtheta1_deg", "dd2_mm"
const char* param_label(int p) noexcept;       // report label, e.g. "Δθ1⁰", "Δd2", "φz"
double to_display(int p, double si) noexcept;  // rad -> deg, m -> mm
double from_display(int p, double v) noexcept;
const char* display_unit(int p) noexcept;  // "deg" or "mm"

// The nominal standard-DH model the deviations apply to (from a kinematics::Chain).
struct NominalModel {
  std::array<kinematics::DhRow, 6> dh{};
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
};
NominalModel nominal_from_chain(const kinematics::Chain& chain);  // throws std::invalid_argument

// Marker position in the camera frame for joint readings θᴿ and parameters x
// (seed 000 Fig. 12). Plain-double twin of the Ceres cost. Without a site: seed
// 000's one marker at the tool point (+ Δpᴹ).
Eigen::Vector3d predict_marker(const NominalModel& model, const ParamVector& x,
                               const std::array<double, kJoints>& theta_r);
Eigen::Vector3d predict_marker(const NominalModel& model, const ParamVector& x,
                               const std::array<double, kJoints>& theta_r, const MarkerSite& site);

// Per-parameter prior: initial guess, bounds, optionally fixed.
struct ParamPrior {
  double initial = 0, lower = 0, upper = 0;  // SI
  bool fixed = false;
};

struct TimeOffsetPrior {
  double initial_s = 0, lower_s = -0.05, upper_s = 0.05;
};

struct IdentifiabilityOptions {
  // A direction in parameter space is unidentifiable when the standard deviation
  // along it exceeds these (the resolution the calibration is meant to reach).
  double max_std_angle_rad = 0.5 * 0.017453292519943295;
  double max_std_length_m = 1.0e-3;
  // Lower bound on the noise used to judge (noise-free synthetic data would
  // otherwise call every non-exact direction identifiable).
  double noise_floor_m = 0.05e-3;
  double correlation_threshold = 0.9;
  // A free parameter depends on a held one ("gauge-dependent") when moving the
  // held one across this fraction of its bounds' range moves the free one by
  // more than its own standard deviation.
  double gauge_probe_fraction = 0.25;
};

struct Bounds {
  std::array<ParamPrior, kParams> params{};
  TimeOffsetPrior time_offset;
  IdentifiabilityOptions identifiability;
  std::string source;
};

// Strict YAML (docs/calibration.md, config/calibration/bounds_seed000.yaml).
Bounds load_bounds_file(const std::string& path);
Bounds load_bounds_text(const std::string& text, const std::string& name);

enum class RobustLoss { kNone, kHuber, kCauchy };

struct SolveOptions {
  RobustLoss loss = RobustLoss::kNone;
  double loss_scale_m = 1.0e-3;  // residual (per axis) where the loss bends
  bool estimate_time_offset = false;
  std::optional<TimeOffsetPrior> time_offset;  // τ's range (default: the bounds file's)
  int max_iterations = 200;
  // Called with progress lines (solver iterations, stages); may be empty.
  std::function<void(const std::string&)> progress;
  std::size_t min_points = 30;
};

struct ErrorStats {
  std::size_t n = 0;
  double rms_m = 0, mean_m = 0, std_m = 0, max_m = 0, median_m = 0, p95_m = 0;
  Eigen::Vector3d mean_xyz_m = Eigen::Vector3d::Zero();  // bias per axis
  Eigen::Vector3d rms_xyz_m = Eigen::Vector3d::Zero();
};

enum class ParamStatus {
  kIdentified,      // free, estimated, std from the covariance
  kGaugeDependent,  // free, but its value follows a held parameter's prior
  kHeld,            // unidentifiable: held at its prior (gauge fixed)
  kAtBound,         // free but ended on a bound
  kFixed,           // fixed by the bounds file
};
const char* status_name(ParamStatus s) noexcept;

struct ParamResult {
  double initial = 0, estimate = 0, stddev = 0;  // SI; stddev 0 when not estimated
  ParamStatus status = ParamStatus::kIdentified;
  std::string note;  // e.g. "follows held Δθ1⁰ (-1.000 deg/deg)"
};

// A direction the data cannot (or can barely) see, found at the solution.
struct Degeneracy {
  int held = -1;  // the parameter held at its prior to fix the gauge
  // How much of the held parameter's effect on the residuals the other free
  // parameters reproduce: 1 - ||(I - P) J_h|| / ||J_h||. 1 means exact.
  double explained = 0;
  bool exact = false;         // explained > 1 - 1e-6 (or the column is zero)
  double stddev_if_free = 0;  // SI; inf for exact
  // Other parameters that reproduce it, with d(x_j)/d(x_held) and their share.
  struct Partner {
    int param;
    double slope;  // SI per SI
    double share;  // fraction of the held column reproduced by this parameter
  };
  std::vector<Partner> partners;
  std::string describe() const;
};

struct Correlation {
  int a, b;
  double r;
};

// Residuals of one marker (several markers: docs/calibration.md §3.5).
struct MarkerResiduals {
  MarkerSite site;
  ErrorStats after;
};

// What one set of observations identifies, judged on the Jacobian at the
// solution: seed 000's one hand marker with a free camera first, then each
// addition (more hand markers, base markers, a fixed camera), then all.
struct ObservationSet {
  std::string name;
  std::vector<int> unidentifiable;      // parameters these observations cannot determine
  std::vector<int> newly_identifiable;  // unidentifiable in the first set, identified here
};

// What the residuals say about a clock offset that was not estimated: the
// offset τ (encoder = marker + τ) that would best explain them given the
// estimated parameters, its standard deviation, and the share of the residual
// sum of squares it explains.
struct TimeOffsetHint {
  double offset_s = 0, std_s = 0, explained = 0;
  // τ stands out of the noise and explains a noticeable share of the residuals.
  bool significant() const noexcept { return std::abs(offset_s) > 5 * std_s && explained > 0.05; }
};

struct Report {
  std::size_t points = 0;
  std::size_t residuals = 0;
  std::size_t free_params = 0;
  ErrorStats before, after;
  std::array<ParamResult, kParams> params{};
  std::optional<double> time_offset_s, time_offset_std_s;
  std::optional<TimeOffsetHint> time_offset_hint;  // when τ was not estimated
  std::vector<Degeneracy> degeneracies;
  std::vector<Correlation> correlations;  // |r| > threshold among estimated parameters
  double sigma_m = 0;                     // per-axis residual std estimate
  std::vector<double> singular_values;    // of the scaled Jacobian at the final solution
  int iterations = 0;
  std::string termination;
  std::vector<Eigen::Vector3d> residual_before, residual_after;  // measured - predicted, m
  std::vector<MarkerResiduals> per_marker;                       // with more than one marker id
  std::vector<ObservationSet> observation_sets;  // with several markers or a fixed camera
};

ParamVector initial_params(const Bounds& bounds);
ParamVector estimates(const Report& report);

// Solves eq. (6) for the aligned points. Throws std::runtime_error with a
// clear message for too few points or a failed solve.
Report calibrate(const NominalModel& model, const std::vector<AlignedSample>& points,
                 const Bounds& bounds, const SolveOptions& options,
                 const EncoderSeries* encoders = nullptr);

// Errors of a parameter set on other data (cross-validation, seed 000 §4.3.2).
ErrorStats evaluate(const NominalModel& model, const ParamVector& x,
                    const std::vector<AlignedSample>& points,
                    std::vector<Eigen::Vector3d>* residuals = nullptr);
ErrorStats error_stats(const std::vector<Eigen::Vector3d>& residuals);
// Statistics per marker id (points[i] <-> residuals[i]), ids ascending.
std::vector<MarkerResiduals> residuals_per_marker(const std::vector<AlignedSample>& points,
                                                  const std::vector<Eigen::Vector3d>& residuals);

// The calibration the daemon reads (camera transform included for the record).
settings::Calibration to_calibration(const ParamVector& x);
ParamVector from_calibration(const settings::Calibration& cal);  // no camera: zeros

}  // namespace exodaq::calibration
