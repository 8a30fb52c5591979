// Seed 001 §II.B: shoulder centre of rotation per humerus-elevation bin.
#include "exodaq/calibration/shoulder_cor.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <random>
#include <stdexcept>

namespace exodaq::calibration {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

bool seen(const Eigen::Matrix3Xd& m, Eigen::Index k) {
  return k < m.cols() && m.col(k).allFinite();
}

// Columns seen in both matrices.
std::vector<Eigen::Index> common_columns(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b) {
  std::vector<Eigen::Index> out;
  for (Eigen::Index k = 0; k < std::min(a.cols(), b.cols()); ++k) {
    if (seen(a, k) && seen(b, k)) out.push_back(k);
  }
  return out;
}

std::optional<RigidTransform> fit_columns(const Eigen::Matrix3Xd& from, const Eigen::Matrix3Xd& to,
                                          const std::vector<Eigen::Index>& cols) {
  return fit_rigid_transform(from(Eigen::all, cols), to(Eigen::all, cols));
}

Eigen::Matrix3Xd transformed(const RigidTransform& t, const Eigen::Matrix3Xd& m) {
  Eigen::Matrix3Xd out = m;
  for (Eigen::Index k = 0; k < m.cols(); ++k) {
    if (seen(m, k)) out.col(k) = t.apply(m.col(k));
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// A frame of a bin with its humerus elevation.
struct BinFrame {
  const MocapFrame* frame;
  double elevation;
};

// One pair of a bin's frames: the humerus' motion from frame a to frame b,
// its rotation axis, and the two frames' elevations and indices.
struct PairMotion {
  RigidTransform motion;
  RotationAxis axis;
  double ea = 0, eb = 0;
  std::size_t a = 0, b = 0;
};

// Step 2-3: the motions of up to K random pairs of the bin's frames.
std::vector<PairMotion> pair_motions(const std::vector<BinFrame>& frames, const CorOptions& o,
                                     std::uint64_t seed, CorBin& bin) {
  std::vector<PairMotion> pairs;
  const std::size_t n = frames.size();
  if (n < 2) return pairs;
  auto try_pair = [&](std::size_t i, std::size_t j) {
    ++bin.pairs;
    const Eigen::Matrix3Xd& a = frames[i].frame->humerus;
    const Eigen::Matrix3Xd& b = frames[j].frame->humerus;
    const auto cols = common_columns(a, b);
    const auto t = cols.size() >= 3 ? fit_columns(a, b, cols) : std::nullopt;
    if (!t) {
      ++bin.pairs_few_markers;
      return;
    }
    const RotationAxis axis = rotation_axis(*t);
    if (axis.angle_rad < o.min_rotation_rad) {
      ++bin.pairs_small;
      return;
    }
    pairs.push_back({*t, axis, frames[i].elevation, frames[j].elevation, i, j});
  };
  if (n * (n - 1) / 2 <= o.pairs_per_bin) {  // few frames: every pair once
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t j = i + 1; j < n; ++j) try_pair(i, j);
    }
    return pairs;
  }
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  for (std::size_t k = 0; k < o.pairs_per_bin; ++k) {
    const std::size_t i = pick(rng);
    std::size_t j = pick(rng);
    while (j == i) j = pick(rng);
    try_pair(i, j);
  }
  return pairs;
}

// Step 4 (first half): the initial estimate from the humerus markers' tracks.
std::optional<Eigen::Vector3d> initial_centre(const std::vector<BinFrame>& frames) {
  const Eigen::Index markers = frames.front().frame->humerus.cols();
  std::vector<Eigen::Matrix3Xd> tracks;
  for (Eigen::Index k = 0; k < markers; ++k) {
    std::vector<Eigen::Vector3d> pts;
    for (const BinFrame& f : frames) {
      if (seen(f.frame->humerus, k)) pts.push_back(f.frame->humerus.col(k));
    }
    Eigen::Matrix3Xd t(3, static_cast<Eigen::Index>(pts.size()));
    for (std::size_t i = 0; i < pts.size(); ++i) t.col(static_cast<Eigen::Index>(i)) = pts[i];
    tracks.push_back(std::move(t));
  }
  return fit_sphere_centre(tracks);
}

// The pairs whose axes lie within max(factor × median, floor) of `centre`.
std::vector<PairMotion> near_pairs(const std::vector<PairMotion>& pairs,
                                   const Eigen::Vector3d& centre, const CorOptions& o) {
  std::vector<double> d;
  for (const auto& p : pairs) d.push_back(distance_to_axis(centre, p.axis));
  const double limit = std::max(o.outlier_factor * median(d), o.outlier_floor_m);
  std::vector<PairMotion> kept;
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    if (d[k] <= limit) kept.push_back(pairs[k]);
  }
  return kept;
}

std::vector<RotationAxis> axes_of(const std::vector<PairMotion>& pairs) {
  std::vector<RotationAxis> axes;
  for (const auto& p : pairs) axes.push_back(p.axis);
  return axes;
}

// A linear least-squares problem in blocks of three rows, one per pair of
// frames: A_i x = y_i. The covariance of x is the dyadic-robust sandwich:
// every block's score A_iᵀ r_i goes to both of its frames, so pairs sharing
// a frame (whose errors are correlated through that frame's noise) count as
// correlated, whatever the noise is (Fafchamps & Gubert 2007; Cameron,
// Gelbach & Miller 2011).
// Ascending eigenvalues of a symmetric matrix.
Eigen::VectorXd eigenvalues(const Eigen::MatrixXd& m) {
  return Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(m, Eigen::EigenvaluesOnly).eigenvalues();
}

template <int N>
struct BlockLeastSquares {
  using Mat = Eigen::Matrix<double, N, N>;
  using Vec = Eigen::Matrix<double, N, 1>;
  std::vector<Eigen::Matrix<double, 3, N>> A;
  std::vector<Eigen::Vector3d> y;
  std::vector<std::array<std::size_t, 2>> frames;

  std::optional<Vec> solve(Mat* covariance) const {
    Mat AtA = Mat::Zero();
    Vec Aty = Vec::Zero();
    for (std::size_t i = 0; i < A.size(); ++i) {
      AtA += A[i].transpose() * A[i];
      Aty += A[i].transpose() * y[i];
    }
    // Dynamic-size solvers: one instantiation for both sizes (a fixed 6x6
    // one alone cost seconds of every build).
    const Eigen::VectorXd ev = eigenvalues(AtA);
    if (!(ev(0) > 1e-12 * ev(N - 1))) return std::nullopt;
    const Mat inv = AtA.inverse();
    const Vec x = inv * Aty;
    std::map<std::size_t, Vec> by_frame;
    Mat self = Mat::Zero();
    for (std::size_t i = 0; i < A.size(); ++i) {
      const Vec g = A[i].transpose() * (A[i] * x - y[i]);
      self += g * g.transpose();
      for (std::size_t f : frames[i]) {
        auto [it, fresh] = by_frame.try_emplace(f, Vec::Zero());
        it->second += g;
      }
    }
    Mat meat = -self;  // each pair's own term was added twice, once per frame
    for (const auto& [f, g] : by_frame) meat += g * g.transpose();
    // Never below the independent-pairs estimate.
    if (eigenvalues(meat - self)(0) < 0) meat = self;
    const double n = 3.0 * static_cast<double>(A.size());
    *covariance = inv * meat * inv * (n / std::max(1.0, n - N));
    return x;
  }
};

// Step 5: the centre from the kept pairs. Moving centre: c(e) = c0 + (e - ē) g,
// each pair's motion x_b = R x_a + t carrying c(e_a) to c(e_b), i.e.
// t = (I - R) c0 + ((e_b - ē) I - (e_a - ē) R) g; c0 is the centre at the
// bin's mean elevation ē, solved for as an offset from a point `near` it.
// At rest (or when the bin's elevations cannot tell g): the point closest to
// the axes. Returns the covariance of c0.
std::optional<Eigen::Vector3d> centre_of(const std::vector<PairMotion>& kept, double mean_e,
                                         const Eigen::Vector3d& near, const CorOptions& o,
                                         Eigen::Matrix3d& cov, Eigen::Vector3d& gradient) {
  gradient.setZero();
  if (o.moving_centre) {
    BlockLeastSquares<6> ls;
    for (const auto& p : kept) {
      Eigen::Matrix<double, 3, 6> a;
      const Eigen::Matrix3d& R = p.motion.rotation;
      a.leftCols<3>() = Eigen::Matrix3d::Identity() - R;
      a.rightCols<3>() = (p.eb - mean_e) * Eigen::Matrix3d::Identity() - (p.ea - mean_e) * R;
      ls.A.push_back(a);
      ls.frames.push_back({p.a, p.b});
      // Solved for c0 - near: a noisy R multiplying a centre a metre from
      // the origin would bias it towards the origin (errors in variables).
      ls.y.push_back(p.motion.translation - (Eigen::Matrix3d::Identity() - R) * near);
    }
    Eigen::Matrix<double, 6, 6> c6;
    if (const auto x = ls.solve(&c6)) {
      cov = c6.topLeftCorner<3, 3>();
      gradient = x->tail<3>();
      return Eigen::Vector3d(near + x->head<3>());
    }
  }
  // Seed 001: the point closest to the axes, sum of |P_i (c - p_i)|².
  BlockLeastSquares<3> ls;
  for (const auto& p : kept) {
    const Eigen::Matrix3d P =
        Eigen::Matrix3d::Identity() - p.axis.direction * p.axis.direction.transpose();
    ls.A.push_back(P);
    ls.y.push_back(P * p.axis.point);
    ls.frames.push_back({p.a, p.b});
  }
  return ls.solve(&cov);
}

// The RMS angle of the axes from their dominant direction.
double axis_spread(const std::vector<PairMotion>& kept) {
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (const auto& p : kept) S += p.axis.direction * p.axis.direction.transpose();
  S /= static_cast<double>(std::max<std::size_t>(kept.size(), 1));
  const double a1 = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(S).eigenvalues()(2);
  return std::asin(std::sqrt(std::clamp(1.0 - a1, 0.0, 1.0)));
}

// Steps 4-5: drop outlying axes around the initial estimate, then the centre
// of the rest; the outlier test once more around that centre.
void estimate_centre(const std::vector<PairMotion>& pairs, const CorOptions& o, CorBin& bin) {
  std::optional<Eigen::Vector3d> c = bin.initial;
  std::vector<PairMotion> kept = pairs;
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
  for (int pass = 0; pass < 2 && c; ++pass) {
    kept = near_pairs(pairs, *c, o);
    c = kept.size() >= o.min_axes ? centre_of(kept, bin.mean_elevation_rad, *c, o, cov, gradient)
                                  : std::nullopt;
  }
  bin.axes = kept.size();
  bin.outliers = pairs.size() - kept.size();
  if (!c) {
    bin.why = "only " + std::to_string(kept.size()) + " usable rotation axes (need " +
              std::to_string(o.min_axes) + ")";
    return;
  }
  bin.centre = *c;
  bin.gradient = gradient;
  bin.covariance = cov;
  bin.ci95_m = kZ95 * bin.covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(bin.covariance);
  bin.weak_direction = eig.eigenvectors().col(2);
  bin.weak_ci95_m = kZ95 * std::sqrt(std::max(eig.eigenvalues()(2), 0.0));
  bin.axis_spread_rad = axis_spread(kept);
  double sq = 0;
  for (const auto& p : kept) sq += std::pow(distance_to_axis(*c, p.axis), 2);
  bin.axis_rms_m = std::sqrt(sq / static_cast<double>(kept.size()));
  bin.valid = true;
}

void analyse_bin(const std::vector<BinFrame>& frames, const CorOptions& o, std::uint64_t seed,
                 CorBin& bin) {
  bin.frames = frames.size();
  for (const BinFrame& f : frames)
    bin.mean_elevation_rad += f.elevation / static_cast<double>(frames.size());
  if (frames.size() < 2) {
    bin.why = frames.empty() ? "no frames" : "one frame";
    return;
  }
  const std::vector<PairMotion> pairs = pair_motions(frames, o, seed, bin);
  if (pairs.size() < o.min_axes) {
    bin.why = "only " + std::to_string(pairs.size()) +
              " pairs turned by at least the minimum "
              "rotation (need " +
              std::to_string(o.min_axes) + ")";
    return;
  }
  const auto init = initial_centre(frames);
  bin.initial =
      init ? *init : closest_point_to_axes(axes_of(pairs)).value_or(Eigen::Vector3d::Zero());
  estimate_centre(pairs, o, bin);
}

std::string mm_text(double m) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f", m * 1e3);
  return buf;
}

// The flags and warning of a bin from its own 95 % half-widths.
void flag(CorBin& b, double vertical, double horizontal, const CorOptions& o) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(b.covariance);
  const double best = kZ95 * std::sqrt(std::max(eig.eigenvalues()(0), 0.0));
  const double limit = std::min(o.max_ci95_m, o.max_condition * best);
  b.vertical_poor = vertical > limit;
  b.horizontal_poor = horizontal > limit;
  b.ill_conditioned = b.weak_ci95_m > limit;
  std::string w;
  if (b.vertical_poor) w += "vertical ±" + mm_text(vertical) + " mm";
  if (b.horizontal_poor) {
    w += (w.empty() ? "" : ", ") + ("horizontal ±" + mm_text(horizontal) + " mm");
  }
  if (b.ill_conditioned && w.empty()) w = "weakest direction ±" + mm_text(b.weak_ci95_m) + " mm";
  if (w.empty()) return;
  char text[200];
  std::snprintf(text, sizeof text,
                " (%.0f times the best-determined direction's ±%.2f mm; rotation axes spread "
                "%.0f deg): a systematic error is amplified along it",
                b.weak_ci95_m / std::max(best, 1e-12), best * 1e3,
                b.axis_spread_rad * 57.29577951308232);
  b.warning = "poorly determined: " + w + text;
}

// Vertical and horizontal motion of the centres relative to the first valid
// bin, their combined uncertainty, and the flags.
void describe_motion(CorResult& r, const CorOptions& o) {
  const auto first =
      std::find_if(r.bins.begin(), r.bins.end(), [](const CorBin& b) { return b.valid; });
  if (first == r.bins.end()) return;
  const Eigen::Vector3d c0 = first->centre;
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& b : r.bins) {
    if (!b.valid) continue;
    const Eigen::Vector3d d = b.centre - c0;
    const Eigen::Vector3d h = d - d.dot(r.cranial) * r.cranial;
    scatter += h * h.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(scatter);
  Eigen::Vector3d axis = eig.eigenvectors().col(2);
  if (eig.eigenvalues()(2) <= 0) axis = r.cranial.unitOrthogonal();
  double sum = 0;
  for (const auto& b : r.bins) sum += b.valid ? (b.centre - c0).dot(axis) : 0.0;
  r.horizontal_axis = sum < 0 ? Eigen::Vector3d(-axis) : axis;
  const Eigen::Matrix3d C0 = first->covariance;
  const auto half_width = [](const Eigen::Matrix3d& C, const Eigen::Vector3d& u) {
    return kZ95 * std::sqrt(std::max(u.dot(C * u), 0.0));
  };
  for (auto& b : r.bins) {
    if (!b.valid) continue;
    b.vertical_m = (b.centre - c0).dot(r.cranial);
    b.horizontal_m = (b.centre - c0).dot(r.horizontal_axis);
    const bool reference = &b == &*first;
    b.vertical_ci95_m = reference ? 0.0 : half_width(b.covariance + C0, r.cranial);
    b.horizontal_ci95_m = reference ? 0.0 : half_width(b.covariance + C0, r.horizontal_axis);
    flag(b, half_width(b.covariance, r.cranial), half_width(b.covariance, r.horizontal_axis), o);
  }
}

}  // namespace

std::optional<RigidTransform> fit_rigid_transform(const Eigen::Matrix3Xd& from,
                                                  const Eigen::Matrix3Xd& to) {
  if (from.cols() < 3 || from.cols() != to.cols() || !from.allFinite() || !to.allFinite()) {
    return std::nullopt;
  }
  const Eigen::Matrix3Xd centred = from.colwise() - from.rowwise().mean();
  // The scatter's eigenvalues are the squared singular values of `centred`
  // (ascending): the middle one against the largest says whether the points
  // span a plane. On one line, a rotation about it is free.
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(
                                 centred * centred.transpose(), Eigen::EigenvaluesOnly)
                                 .eigenvalues();
  if (!(ev(1) > 1e-12 * ev(2))) return std::nullopt;
  const Eigen::Matrix4d T = Eigen::umeyama(from, to, false);
  RigidTransform t;
  t.rotation = T.topLeftCorner<3, 3>();
  t.translation = T.topRightCorner<3, 1>();
  return t;
}

RotationAxis rotation_axis(const RigidTransform& t) {
  const Eigen::AngleAxisd aa(t.rotation);
  RotationAxis a;
  a.angle_rad = aa.angle();
  if (!(a.angle_rad > 1e-12)) {
    a.slide_m = t.translation.norm();
    return a;
  }
  a.direction = aa.axis().normalized();
  a.slide_m = a.direction.dot(t.translation);
  const Eigen::Vector3d t_perp = t.translation - a.slide_m * a.direction;
  // (I − R) c = t⊥ with c ⊥ v: (I − R + v vᵀ) c = t⊥ (I − R keeps the plane ⊥ v).
  const Eigen::Matrix3d A =
      Eigen::Matrix3d::Identity() - t.rotation + a.direction * a.direction.transpose();
  a.point = A.colPivHouseholderQr().solve(t_perp);
  return a;
}

double distance_to_axis(const Eigen::Vector3d& p, const RotationAxis& a) {
  const Eigen::Vector3d d = p - a.point;
  return (d - d.dot(a.direction) * a.direction).norm();
}

std::optional<Eigen::Vector3d> closest_point_to_axes(const std::vector<RotationAxis>& axes) {
  if (axes.size() < 2) return std::nullopt;
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  for (const auto& a : axes) {
    const Eigen::Matrix3d P = Eigen::Matrix3d::Identity() - a.direction * a.direction.transpose();
    M += P;
    b += P * a.point;
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(M);
  if (!(eig.eigenvalues()(0) > 1e-9 * eig.eigenvalues()(2))) return std::nullopt;  // parallel
  return Eigen::Vector3d(M.ldlt().solve(b));
}

std::optional<Eigen::Vector3d> fit_sphere_centre(const std::vector<Eigen::Matrix3Xd>& tracks) {
  Eigen::Index rows = 0, m = 0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& t : tracks) {
    if (t.cols() < 2) continue;
    rows += t.cols();
    ++m;
    mean += t.rowwise().sum();
  }
  if (rows < 3 + m + 1) return std::nullopt;
  mean /= static_cast<double>(rows);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(rows, 3 + m);
  Eigen::VectorXd y(rows);
  Eigen::Index r = 0, k = 0;
  for (const auto& t : tracks) {
    if (t.cols() < 2) continue;
    for (Eigen::Index i = 0; i < t.cols(); ++i, ++r) {
      const Eigen::Vector3d x = t.col(i) - mean;  // centred for conditioning
      A.block<1, 3>(r, 0) = 2.0 * x.transpose();
      A(r, 3 + k) = 1.0;
      y(r) = x.squaredNorm();
    }
    ++k;
  }
  const auto qr = A.colPivHouseholderQr();
  if (qr.rank() < A.cols()) return std::nullopt;
  return Eigen::Vector3d(qr.solve(y).head<3>() + mean);
}

std::vector<MocapFrame> normalise_to_torso(const std::vector<MocapFrame>& frames,
                                           CorResult& result) {
  const auto ref = std::find_if(frames.begin(), frames.end(),
                                [](const MocapFrame& f) { return f.torso.allFinite(); });
  if (ref == frames.end() || ref->torso.cols() < 3) {
    throw std::invalid_argument(
        "no frame shows all torso markers (at least 3 needed to hold the torso still)");
  }
  std::vector<MocapFrame> out;
  out.reserve(frames.size());
  for (const MocapFrame& f : frames) {
    MocapFrame n;
    n.utime_us = f.utime_us;
    const auto cols = common_columns(f.torso, ref->torso);
    const auto t = cols.size() >= 3 ? fit_columns(f.torso, ref->torso, cols) : std::nullopt;
    if (t) {
      n.torso = transformed(*t, f.torso);
      n.humerus = transformed(*t, f.humerus);
    } else {
      ++result.frames_torso_missing;
    }
    out.push_back(std::move(n));
  }
  return out;
}

double humerus_elevation(const MocapFrame& frame, const ShoulderAxes& axes,
                         const Eigen::Vector3d& caudal) {
  if (!seen(frame.humerus, axes.humerus_proximal) || !seen(frame.humerus, axes.humerus_distal)) {
    return kNaN;
  }
  const Eigen::Vector3d d =
      (frame.humerus.col(axes.humerus_distal) - frame.humerus.col(axes.humerus_proximal))
          .normalized();
  return std::acos(std::clamp(d.dot(caudal), -1.0, 1.0));
}

CorResult analyse_shoulder_cor(const std::vector<MocapFrame>& frames, const ShoulderAxes& axes,
                               const CorOptions& options) {
  CorResult r;
  r.frames = frames.size();
  const std::vector<MocapFrame> norm = normalise_to_torso(frames, r);
  const MocapFrame& ref = *std::find_if(norm.begin(), norm.end(), [](const MocapFrame& f) {
    return f.torso.cols() > 0 && f.torso.allFinite();
  });
  const Eigen::Vector3d caudal =
      (ref.torso.col(axes.torso_caudal) - ref.torso.col(axes.torso_cranial)).normalized();
  r.cranial = -caudal;
  std::vector<std::vector<BinFrame>> by_bin;
  for (const MocapFrame& f : norm) {
    if (f.torso.cols() == 0) continue;
    const double e = humerus_elevation(f, axes, caudal);
    if (!std::isfinite(e) || common_columns(f.humerus, f.humerus).size() < 3) {
      ++r.frames_humerus_missing;
      continue;
    }
    const auto k = static_cast<std::size_t>(e / options.bin_width_rad);
    if (by_bin.size() <= k) by_bin.resize(k + 1);
    by_bin[k].push_back({&f, e});
    ++r.frames_used;
  }
  r.bins.resize(by_bin.size());
  for (std::size_t k = 0; k < by_bin.size(); ++k) {
    r.bins[k].elevation_lo_rad = static_cast<double>(k) * options.bin_width_rad;
    r.bins[k].elevation_hi_rad = static_cast<double>(k + 1) * options.bin_width_rad;
    analyse_bin(by_bin[k], options, options.seed + 7919 * k, r.bins[k]);
  }
  describe_motion(r, options);
  return r;
}

}  // namespace exodaq::calibration
