#pragma once
// Synthetic motion capture for the shoulder centre-of-rotation analysis (seed
// 001 §II.B): 5 torso and 7 humerus markers (as on seed 001's macaque), a
// torso that sways, and a humerus turning about a centre that rises with arm
// elevation as in seed 001 Table II. 0.3 mm noise per axis.
#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "exodaq/calibration/shoulder_cor.hpp"

namespace exodaq::calibration::shoulder_synth {

inline constexpr double kDeg = 0.017453292519943295;
// Seed 001 Table II: CoR vertical motion (mm) for humerus elevation 0-20, ..., 100-120°.
inline constexpr std::array<double, 6> kTable2Mm = {0, 4, 13, 27, 43, 62};

struct Options {
  unsigned seed = 1;
  double duration_s = 120.0;
  double rate_hz = 100.0;
  double noise_m = 0.3e-3;
  // true: the centre is constant within each 20° bin (the analysis' own
  // assumption); false: it moves continuously (Table II at the bin centres,
  // linearly interpolated).
  bool piecewise = true;
  // > 0: instead, the centre rises linearly with elevation at this rate (and
  // moves forward by a third of that): the moving-centre model exactly.
  double linear_mm_per_deg = 0.0;
  double occluded_fraction = 0.0;  // humerus marker samples not seen
  double swapped_fraction = 0.0;   // frames with one humerus marker 20 mm off (a camera swap)
  double elevation_lo_deg = 5.0, elevation_hi_deg = 115.0;  // the arm's range
};

// Torso-local frame: x lateral (right), y cranial, z ventral.
inline const std::array<Eigen::Vector3d, 5> kTorso = {
    Eigen::Vector3d(0.0, 0.05, 0.02), Eigen::Vector3d(0.0, -0.10, 0.02),  // cranial, caudal
    Eigen::Vector3d(0.06, 0.0, 0.03), Eigen::Vector3d(-0.06, 0.0, 0.03),
    Eigen::Vector3d(0.03, -0.05, 0.05)};
// Humerus-local frame: origin at the centre of rotation, the arm along -y.
inline const std::array<Eigen::Vector3d, 7> kHumerus = {
    Eigen::Vector3d(0.0, -0.020, 0.012),
    Eigen::Vector3d(0.0, -0.110, 0.012),  // proximal, distal
    Eigen::Vector3d(0.015, -0.040, 0.0),
    Eigen::Vector3d(-0.015, -0.060, 0.010),
    Eigen::Vector3d(0.012, -0.080, -0.012),
    Eigen::Vector3d(-0.010, -0.095, -0.010),
    Eigen::Vector3d(0.0, -0.050, -0.016)};
inline const Eigen::Vector3d kCentreAtRest(0.07, 0.0, 0.0);

// Vertical centre motion (m) at elevation e.
inline double vertical_m(double e, bool piecewise) {
  const double bin = e / (20.0 * kDeg);
  if (piecewise) return kTable2Mm[std::min<std::size_t>(5, static_cast<std::size_t>(bin))] * 1e-3;
  const double x = std::clamp(bin - 0.5, 0.0, 5.0);  // Table II values at the bin centres
  const auto i = std::min<std::size_t>(4, static_cast<std::size_t>(x));
  return (kTable2Mm[i] + (x - i) * (kTable2Mm[i + 1] - kTable2Mm[i])) * 1e-3;
}

// Centre of rotation in torso coordinates: up with Table II (or linearly),
// a third as much forward.
inline Eigen::Vector3d centre_local(double e, bool piecewise, double linear_mm_per_deg = 0.0) {
  const double v =
      linear_mm_per_deg > 0 ? linear_mm_per_deg * 1e-3 * e / kDeg : vertical_m(e, piecewise);
  return kCentreAtRest + Eigen::Vector3d(0.0, v, v / 3.0);
}

// 5°..115° and back, twice in 120 s (or between other limits).
inline double elevation_at(double t, double lo_deg = 5.0, double hi_deg = 115.0) {
  return (lo_deg + (hi_deg - lo_deg) * (0.5 - 0.5 * std::cos(2 * M_PI * t / 60.0))) * kDeg;
}

// Humerus orientation: plane of elevation ψ about the vertical, elevation ε,
// axial rotation ρ; the angle between the arm and "down" is exactly ε.
inline Eigen::Matrix3d humerus_rotation(double t, double lo_deg = 5.0, double hi_deg = 115.0) {
  const double psi = 35.0 * kDeg * std::sin(2 * M_PI * t / 7.3);
  const double rho = 40.0 * kDeg * std::sin(2 * M_PI * t / 5.1 + 1.0);
  return (Eigen::AngleAxisd(psi, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(elevation_at(t, lo_deg, hi_deg), Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rho, Eigen::Vector3d::UnitY()))
      .toRotationMatrix();
}

// The torso in the camera frame (camera y up): it sways by up to 8° and 15 mm.
inline Eigen::Isometry3d torso_pose(double t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() =
      Eigen::Vector3d(0.30, 0.90, 0.50) +
      0.015 * Eigen::Vector3d(std::sin(2 * M_PI * t / 11.0), std::sin(2 * M_PI * t / 13.0 + 0.5),
                              std::sin(2 * M_PI * t / 17.0 + 1.0));
  const Eigen::Vector3d w(std::sin(2 * M_PI * t / 9.0), std::cos(2 * M_PI * t / 14.0), 0.5);
  T.linear() = (Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(8.0 * kDeg * std::sin(2 * M_PI * t / 12.0), w.normalized()))
                   .toRotationMatrix();
  return T;
}

// The true centre of rotation of elevation bin k in the analysis' torso frame
// (the first frame's camera frame), for the piecewise-constant centre.
inline Eigen::Vector3d true_centre(std::size_t bin) {
  return torso_pose(0.0) * centre_local((20.0 * static_cast<double>(bin) + 10.0) * kDeg, true);
}

inline std::vector<MocapFrame> make_frames(const Options& o) {
  std::mt19937_64 rng(77 + o.seed);
  std::normal_distribution<double> noise(0.0, o.noise_m);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto n = static_cast<std::size_t>(o.duration_s * o.rate_hz);
  std::vector<MocapFrame> frames(n);
  for (std::size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) / o.rate_hz;
    const Eigen::Isometry3d T = torso_pose(t);
    const double e = elevation_at(t, o.elevation_lo_deg, o.elevation_hi_deg);
    const Eigen::Vector3d c = centre_local(e, o.piecewise, o.linear_mm_per_deg);
    const Eigen::Matrix3d R = humerus_rotation(t, o.elevation_lo_deg, o.elevation_hi_deg);
    MocapFrame& f = frames[k];
    f.utime_us = 1'700'000'000'000'000LL + static_cast<std::int64_t>(k) * 10'000;
    f.torso.resize(3, 5);
    f.humerus.resize(3, 7);
    for (int m = 0; m < 5; ++m) {
      f.torso.col(m) = T * kTorso[m] + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    }
    for (int m = 0; m < 7; ++m) {
      f.humerus.col(m) =
          T * (c + R * kHumerus[m]) + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
      if (k > 0 && m >= 2 && u(rng) < o.occluded_fraction) f.humerus.col(m).setConstant(NAN);
    }
    if (k > 0 && u(rng) < o.swapped_fraction) f.humerus.col(4) += Eigen::Vector3d(0.02, 0, 0);
  }
  return frames;
}

// The long CSV of `exodaq calibrate` and `exodaq shoulder-cor`: torso markers
// ids 1-5, humerus markers ids 11-17.
inline void write_csv(const std::string& path, const std::vector<MocapFrame>& frames) {
  std::ofstream out(path);
  out << "utime_us,x_mm,y_mm,z_mm,marker_id\n";
  out.precision(10);
  auto row = [&](std::int64_t t, const Eigen::Vector3d& p, int id) {
    out << t << ",";
    if (p.allFinite()) {
      out << p.x() * 1e3 << "," << p.y() * 1e3 << "," << p.z() * 1e3;
    } else {
      out << ",,";
    }
    out << "," << id << "\n";
  };
  for (const auto& f : frames) {
    for (int m = 0; m < 5; ++m) row(f.utime_us, f.torso.col(m), 1 + m);
    for (int m = 0; m < 7; ++m) row(f.utime_us, f.humerus.col(m), 11 + m);
  }
}

}  // namespace exodaq::calibration::shoulder_synth
