#pragma once
// Synthetic calibration data (issue 8 point 6): a trajectory moving all six
// joints, the marker computed with the seed 000 Table 4 "Results" as truth,
// 0.3 mm isotropic marker noise, encoders quantised at 10 000 counts/rev.
#include <cmath>
#include <cstdint>
#include <fstream>
#include <random>
#include <string>

#include "exodaq/calibration/inputs.hpp"
#include "exodaq/calibration/solver.hpp"

namespace exodaq::calibration::synth {

inline constexpr double kDeg = 0.017453292519943295;
inline constexpr double kMm = 1e-3;
inline constexpr std::int64_t kEpochUs = 1'700'000'000'000'000LL;

// Seed 000 Table 3 with L1 = 0.145 m, L2 = 0.152 m (config/models/macaque_exo.yaml).
inline NominalModel rig_model() {
  NominalModel m;
  const double alpha[6] = {-90, 90, -90, 90, -90, 0};
  for (int i = 0; i < 6; ++i) m.dh[i] = kinematics::DhRow{0.0, alpha[i] * kDeg, 0.0, 0.0};
  m.dh[3].d = 0.145;
  m.dh[5].d = 0.152;
  return m;
}

// Seed 000 Table 4.
inline ParamVector table4_results() {
  const double deg[6] = {31.85, -17.60, -13.45, -17.19, -22.11, -2.39};
  ParamVector x{};
  for (int j = 0; j < 6; ++j) x[kTheta1 + j] = deg[j] * kDeg;
  x[kDd2] = -1.79 * kMm;
  x[kDd3] = -0.48 * kMm;
  x[kDd5] = 2.80 * kMm;
  x[kDa3] = -4.01 * kMm;
  x[kDa5] = 0.03 * kMm;
  x[kPx] = -0.10 * kMm;
  x[kPy] = -0.16 * kMm;
  x[kPz] = -8.46 * kMm;
  x[kDx] = 203.29 * kMm;
  x[kDy] = 849.31 * kMm;
  x[kDz] = 224.30 * kMm;
  x[kPhiX] = -89.01 * kDeg;
  x[kPhiY] = -0.10 * kDeg;
  x[kPhiZ] = -135.52 * kDeg;
  return x;
}

inline ParamVector table4_guess() {
  const double deg[6] = {30.7, -16.3, -15.2, -17.1, -25.5, -2.3};
  ParamVector x{};
  for (int j = 0; j < 6; ++j) x[kTheta1 + j] = deg[j] * kDeg;
  x[kDx] = 203.2 * kMm;
  x[kDy] = 852.1 * kMm;
  x[kDz] = 216.8 * kMm;
  x[kPhiX] = -90.0 * kDeg;
  x[kPhiZ] = -135.0 * kDeg;
  return x;
}

struct TrajectoryOptions {
  unsigned seed = 1;
  double duration_s = 40.5;
  double marker_rate_hz = 10.0;    // 400 points over 40 s
  double marker_noise_m = 0.3e-3;  // per axis
  double counts_per_rev = 10000.0;
  int frozen_joint = -1;             // 0-based joint that never moves
  double marker_clock_offset_s = 0;  // marker utime = true time + offset
  // Markers seen at every marker time (empty: seed 000's one marker at the
  // tool point, written with marker_id 3).
  MarkerLayout layout;
};

struct SyntheticData {
  EncoderSeries encoders;
  MarkerSeries markers;
};

// Joint angle (true, rad) of joint j at time t: two incommensurate sines per
// joint covering much of each joint's range (Table 3 limits), away from the
// shoulder singularity (θ2, θ3) = (-180°, 0).
inline double joint_angle(int j, double t, unsigned seed, int frozen) {
  const double centre[6] = {45, -90, 20, 0, -40, 0};
  const double amp[6] = {75, 60, 65, 65, 42, 65};
  const double f1[6] = {0.031, 0.043, 0.057, 0.071, 0.089, 0.103};
  const double f2[6] = {0.113, 0.127, 0.149, 0.163, 0.181, 0.197};
  const double ph = 0.7 * seed + 1.3 * j;
  if (j == frozen) return (centre[j] + 0.3 * amp[j]) * kDeg;
  const double s = seed * 0.013;
  const double v = 0.65 * std::sin(2 * M_PI * (f1[j] + s) * t + ph) +
                   0.35 * std::sin(2 * M_PI * (f2[j] + 0.5 * s) * t + 2.1 * ph);
  return (centre[j] + amp[j] * v) * kDeg;
}

inline SyntheticData make_data(const TrajectoryOptions& o,
                               const ParamVector& truth = table4_results(),
                               const NominalModel& model = rig_model()) {
  SyntheticData d;
  d.encoders.source = "synthetic-encoders";
  d.markers.source = "synthetic-markers";
  const double q = 2 * M_PI / o.counts_per_rev;
  const int n_enc = static_cast<int>(o.duration_s * 1000.0) + 1;
  d.encoders.samples.reserve(n_enc);
  for (int k = 0; k < n_enc; ++k) {
    const double t = k * 1e-3;
    EncoderSample s;
    s.utime_us = kEpochUs + k * 1000;
    for (int j = 0; j < 6; ++j) {
      const double theta_r = joint_angle(j, t, o.seed, o.frozen_joint) - truth[kTheta1 + j];
      s.theta_r[j] = std::round(theta_r / q) * q;
    }
    d.encoders.samples.push_back(s);
  }
  std::mt19937_64 rng(1000 + o.seed);
  std::normal_distribution<double> noise(0.0, o.marker_noise_m);
  const std::vector<MarkerSite> sites =
      o.layout.sites.empty() ? std::vector<MarkerSite>{MarkerSite{}} : o.layout.sites;
  const double first = 0.25;  // s: markers start after the encoders
  const int n_mk = static_cast<int>((o.duration_s - 2 * first) * o.marker_rate_hz);
  for (int k = 0; k < n_mk; ++k) {
    const double t = first + k / o.marker_rate_hz + 0.000377;
    std::array<double, 6> theta_r{};
    for (int j = 0; j < 6; ++j) {
      theta_r[j] = joint_angle(j, t, o.seed, o.frozen_joint) - truth[kTheta1 + j];
    }
    for (const MarkerSite& site : sites) {
      const Eigen::Vector3d p = predict_marker(model, truth, theta_r, site);
      MarkerSample m;
      m.utime_us =
          kEpochUs + static_cast<std::int64_t>(std::llround((t + o.marker_clock_offset_s) * 1e6));
      m.present = true;
      m.marker_id = site.id;
      m.x = p.x() + noise(rng);
      m.y = p.y() + noise(rng);
      m.z = p.z() + noise(rng);
      d.markers.samples.push_back(m);
    }
  }
  return d;
}

// Seed 000's hand marker at the palm (id 3), a second hand marker 70 mm up
// the forearm and 20 mm off its axis (id 4), and three markers on the base
// (ids 10-12), as in config/calibration/markers_example.yaml (with its labels).
inline MarkerLayout rig_layout(bool second_hand, bool base) {
  MarkerLayout l;
  l.source = "synthetic-layout";
  l.sites.push_back({3, MarkerMount::kHand, {0.0, 0.0, 0.0}, "palm"});
  if (second_hand) l.sites.push_back({4, MarkerMount::kHand, {0.020, 0.0, -0.070}, "forearm"});
  if (base) {
    l.sites.push_back({10, MarkerMount::kBase, {-0.120, 0.080, -0.060}, "base1"});
    l.sites.push_back({11, MarkerMount::kBase, {-0.120, -0.080, -0.060}, "base2"});
    l.sites.push_back({12, MarkerMount::kBase, {-0.180, 0.0, 0.050}, "base3"});
  }
  return l;
}

// Bounds around Table 4 "Guess" (config/calibration/bounds_seed000.yaml).
inline Bounds guess_bounds() {
  Bounds b;
  const ParamVector g = table4_guess();
  for (int p = 0; p < kParams; ++p) {
    const double half = is_angle(p) ? (p >= kPhiX ? 10.0 * kDeg : 10.0 * kDeg)
                        : p >= kDx  ? 100.0 * kMm
                                    : 20.0 * kMm;
    b.params[p] = ParamPrior{g[p], g[p] - half, g[p] + half, false};
  }
  return b;
}

inline void write_encoder_csv(const std::string& path, const EncoderSeries& e) {
  std::ofstream o(path);
  o << "# synthetic encoders: theta_R in rad relative to the index\n";
  o << "utime_us,j1_rad,j2_rad,j3_rad,j4_rad,j5_rad,j6_rad,homed_mask,fault_mask\n";
  o.precision(17);
  for (const auto& s : e.samples) {
    o << s.utime_us;
    for (double v : s.theta_r) o << "," << v;
    o << "," << int(s.homed_mask) << "," << int(s.fault_mask) << "\n";
  }
}

inline void write_marker_csv(const std::string& path, const MarkerSeries& m) {
  std::ofstream o(path);
  o << "utime_us,x_mm,y_mm,z_mm,marker_id\n";
  o.precision(10);
  for (const auto& s : m.samples) {
    o << s.utime_us << ",";
    if (s.present) {
      o << s.x * 1e3 << "," << s.y * 1e3 << "," << s.z * 1e3;
    } else {
      o << ",,";
    }
    o << "," << (s.marker_id < 0 ? 3 : s.marker_id) << "\n";
  }
}

}  // namespace exodaq::calibration::synth
