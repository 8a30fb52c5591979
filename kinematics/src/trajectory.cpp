#include "exodaq/kinematics/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace exodaq::kinematics {

namespace {

constexpr int kMaxDegree = 5;

double horner(const double* p, int deg, double x) noexcept {
  double y = p[deg];
  for (int k = deg - 1; k >= 0; --k) y = y * x + p[k];
  return y;
}

// Real roots of the polynomial p (degree <= 4) strictly inside (lo, hi), by
// splitting the interval at the roots of the derivative (recursively) and
// bisecting every piece whose ends differ in sign. Returns how many.
int roots_in(const double* p, int deg, double lo, double hi, double* out) noexcept {
  while (deg > 0 && p[deg] == 0.0) --deg;
  if (deg == 0) return 0;
  if (deg == 1) {
    const double r = -p[0] / p[1];
    if (r > lo && r < hi) {
      out[0] = r;
      return 1;
    }
    return 0;
  }
  if (deg == 2) {  // closed form, in the form that avoids cancellation
    const double disc = p[1] * p[1] - 4.0 * p[2] * p[0];
    if (disc < 0.0) return 0;
    const double qq = -0.5 * (p[1] + std::copysign(std::sqrt(disc), p[1]));
    int count = 0;
    for (const double r : {qq / p[2], qq != 0.0 ? p[0] / qq : qq / p[2]}) {
      if (r > lo && r < hi && (count == 0 || r != out[0])) out[count++] = r;
    }
    return count;
  }
  double d[kMaxDegree];
  for (int k = 1; k <= deg; ++k) d[k - 1] = k * p[k];
  double cuts[kMaxDegree + 1];
  int n_cuts = 0;
  cuts[n_cuts++] = lo;
  n_cuts += roots_in(d, deg - 1, lo, hi, cuts + 1);
  for (int i = 2; i < n_cuts; ++i) {  // insertion sort of at most three roots
    for (int k = i; k > 1 && cuts[k] < cuts[k - 1]; --k) std::swap(cuts[k], cuts[k - 1]);
  }
  cuts[n_cuts++] = hi;
  int count = 0;
  for (int i = 0; i + 1 < n_cuts; ++i) {
    double a = cuts[i], b = cuts[i + 1];
    double fa = horner(p, deg, a), fb = horner(p, deg, b);
    if (i > 0 && fa == 0.0) {
      out[count++] = a;
      continue;
    }
    if ((fa < 0.0) == (fb < 0.0) || fb == 0.0) continue;
    for (int it = 0; it < 200 && b - a > 0.0; ++it) {
      const double m = 0.5 * (a + b);
      if (m <= a || m >= b) break;
      const double fm = horner(p, deg, m);
      if ((fm < 0.0) == (fa < 0.0)) {
        a = m;
        fa = fm;
      } else {
        b = m;
      }
    }
    out[count++] = 0.5 * (a + b);
  }
  return count;
}

// Largest |p(x)| for x in [0, T]: at an end or where p' = 0.
double max_abs(const double* p, int deg, double T) noexcept {
  double best = std::max(std::abs(horner(p, deg, 0.0)), std::abs(horner(p, deg, T)));
  if (deg < 2) return best;
  double d[kMaxDegree];
  for (int k = 1; k <= deg; ++k) d[k - 1] = k * p[k];
  double r[kMaxDegree];
  const int n = roots_in(d, deg - 1, 0.0, T, r);
  for (int i = 0; i < n; ++i) best = std::max(best, std::abs(horner(p, deg, r[i])));
  return best;
}

// Coefficients of one joint's segment from its boundary conditions.
void segment_coefficients(SegmentShape shape, double q0, double q1, double v0, double v1, double T,
                          double c[6]) noexcept {
  const double h = q1 - q0;
  c[0] = q0;
  c[1] = v0;
  if (shape == SegmentShape::kCubic) {
    c[2] = (3.0 * h / T - 2.0 * v0 - v1) / T;
    c[3] = (-2.0 * h / T + v0 + v1) / (T * T);
    c[4] = c[5] = 0.0;
    return;
  }
  // Quintic with zero acceleration at both ends.
  const double T2 = T * T, T3 = T2 * T;
  c[2] = 0.0;
  c[3] = (20.0 * h - (8.0 * v1 + 12.0 * v0) * T) / (2.0 * T3);
  c[4] = (-30.0 * h + (14.0 * v1 + 16.0 * v0) * T) / (2.0 * T3 * T);
  c[5] = (12.0 * h - 6.0 * (v1 + v0) * T) / (2.0 * T3 * T2);
}

// Peak |qd| and |qdd| of one joint's segment.
void segment_peaks(const double c[6], double T, double& speed, double& acceleration) noexcept {
  const double v[5] = {c[1], 2.0 * c[2], 3.0 * c[3], 4.0 * c[4], 5.0 * c[5]};
  const double a[4] = {2.0 * c[2], 6.0 * c[3], 12.0 * c[4], 20.0 * c[5]};
  speed = max_abs(v, 4, T);
  acceleration = max_abs(a, 3, T);
}

// Shortest rest-to-rest duration of one joint's move h (the starting guess).
double rest_to_rest(SegmentShape shape, double h, double v_max, double a_max) noexcept {
  h = std::abs(h);
  if (shape == SegmentShape::kCubic) {
    return std::max(1.5 * h / v_max, std::sqrt(6.0 * h / a_max));
  }
  return std::max(1.875 * h / v_max, std::sqrt(5.773502691896258 * h / a_max));
}

void check_bounds(const JointVector& b, int n, const char* what, bool allow_empty) {
  if (allow_empty && b.size() == 0) return;
  if (b.size() != n) {
    throw std::invalid_argument(std::string(what) + " has " + std::to_string(b.size()) +
                                " values, the via points " + std::to_string(n) + " joints");
  }
  for (int j = 0; j < n; ++j) {
    if (!(b[j] > 0.0)) {
      throw std::invalid_argument(std::string(what) + " of joint " + std::to_string(j + 1) +
                                  " must be > 0");
    }
  }
}

void check_via_points(const std::vector<JointVector>& via) {
  if (via.size() < 2) throw std::invalid_argument("a trajectory needs at least two via points");
  const auto n = via.front().size();
  if (n == 0) throw std::invalid_argument("via points have no joints");
  for (std::size_t k = 0; k < via.size(); ++k) {
    if (via[k].size() != n) {
      throw std::invalid_argument("via point " + std::to_string(k) + " has " +
                                  std::to_string(via[k].size()) + " joints, via point 0 has " +
                                  std::to_string(n));
    }
    if (!via[k].allFinite()) {
      throw std::invalid_argument("via point " + std::to_string(k) + " is not finite");
    }
  }
}

// The segment durations for one set of via points and bounds.
class DurationPlanner {
 public:
  DurationPlanner(const std::vector<JointVector>& via, const JointBounds& bounds,
                  const TrajectoryOptions& options)
      : via_(via),
        bounds_(bounds),
        shape_(options.shape),
        floor_(options.min_segment_duration),
        m_(static_cast<int>(via.size()) - 1),
        n_(static_cast<int>(via.front().size())),
        T_(static_cast<std::size_t>(m_)),
        vel_(static_cast<std::size_t>((m_ + 1) * n_)),
        ratio_(static_cast<std::size_t>(m_)) {}

  // Each segment starts at its rest-to-rest minimum and is rescaled by its own
  // ratio; the best total so far, made tight by one uniform stretch (every ratio
  // scales exactly with it), is kept.
  void plan() {
    for (int k = 0; k < m_; ++k) {
      T_[k] = floor_;
      for (int j = 0; j < n_; ++j) {
        T_[k] = std::max(T_[k], rest_to_rest(shape_, via_[k + 1][j] - via_[k][j],
                                             bounds_.max_speed[j], a_max(j)));
      }
    }
    std::vector<double> best = T_;
    double best_total = std::numeric_limits<double>::infinity();
    for (int iter = 0; iter < 60; ++iter) {
      const double worst = ratios();
      if (!(worst > 0.0)) break;  // nothing moves
      double total = 0.0;
      for (const double d : T_) total += std::max(floor_, d * worst);
      if (total < best_total) {
        best_total = total;
        for (int k = 0; k < m_; ++k) best[k] = std::max(floor_, T_[k] * worst * (1.0 + 1e-12));
      }
      bool settled = true;  // every segment at a bound or at the floor
      for (int k = 0; k < m_; ++k) {
        const double next = std::max(floor_, T_[k] * ratio_[k]);
        settled = settled && std::abs(next - T_[k]) <= 1e-12 * T_[k];
        T_[k] = next;
      }
      if (settled) break;
    }
    // A floor raised above the uniform stretch changes neighbouring via speeds:
    // stretch once more if that pushed any segment over its bounds.
    T_ = best;
    const double worst = ratios();
    if (worst > 1.0) {
      for (double& d : T_) d *= worst * (1.0 + 1e-12);
    }
    velocities();
  }

  const std::vector<double>& durations() const { return T_; }
  // Coefficients of joint j's polynomial on segment k (after plan()).
  void coefficients(int k, int j, double c[6]) const noexcept {
    segment_coefficients(shape_, via_[k][j], via_[k + 1][j], vel_[k * n_ + j],
                         vel_[(k + 1) * n_ + j], T_[k], c);
  }

 private:
  double a_max(int j) const noexcept {
    return bounds_.max_acceleration.size() ? bounds_.max_acceleration[j]
                                           : std::numeric_limits<double>::infinity();
  }
  // Speeds at the via points (Fritsch-Butland: the harmonic mean of the two
  // neighbouring slopes when they agree in sign, else 0): no segment overshoots.
  void velocities() noexcept {
    std::fill(vel_.begin(), vel_.end(), 0.0);
    for (int k = 1; k < m_; ++k) {
      for (int j = 0; j < n_; ++j) {
        const double s1 = (via_[k][j] - via_[k - 1][j]) / T_[k - 1];
        const double s2 = (via_[k + 1][j] - via_[k][j]) / T_[k];
        if (s1 * s2 > 0.0) vel_[k * n_ + j] = 2.0 * s1 * s2 / (s1 + s2);
      }
    }
  }
  // How far each segment is from its bounds (1 = exactly at one); the worst.
  double ratios() noexcept {
    velocities();
    double worst = 0.0;
    for (int k = 0; k < m_; ++k) {
      double r = 0.0;
      for (int j = 0; j < n_; ++j) {
        double c[6], speed, acc;
        coefficients(k, j, c);
        segment_peaks(c, T_[k], speed, acc);
        r = std::max({r, speed / bounds_.max_speed[j], std::sqrt(acc / a_max(j))});
      }
      ratio_[k] = r;
      worst = std::max(worst, r);
    }
    return worst;
  }

  const std::vector<JointVector>& via_;
  const JointBounds& bounds_;
  SegmentShape shape_;
  double floor_;
  int m_, n_;
  std::vector<double> T_;
  std::vector<double> vel_;  // (m + 1) x n, row k = via point k
  std::vector<double> ratio_;
};

}  // namespace

JointTrajectory::JointTrajectory(const std::vector<JointVector>& via, const JointBounds& bounds,
                                 const TrajectoryOptions& options)
    : shape_(options.shape) {
  check_via_points(via);
  joints_ = static_cast<int>(via.front().size());
  check_bounds(bounds.max_speed, joints_, "max_speed", false);
  check_bounds(bounds.max_acceleration, joints_, "max_acceleration", true);
  if (!(options.min_segment_duration > 0.0) || !std::isfinite(options.min_segment_duration)) {
    throw std::invalid_argument("min_segment_duration must be > 0");
  }
  DurationPlanner planner(via, bounds, options);
  planner.plan();
  const int m = static_cast<int>(via.size()) - 1;
  const int n = joints_;
  durations_ = planner.durations();
  times_.assign(static_cast<std::size_t>(m + 1), 0.0);
  segments_.resize(static_cast<std::size_t>(m));
  peak_speed_ = JointVector::Zero(n);
  peak_acceleration_ = JointVector::Zero(n);
  for (int k = 0; k < m; ++k) {
    times_[k + 1] = times_[k] + durations_[k];
    Segment& s = segments_[k];
    for (auto& c : s.c) c.resize(n);
    for (int j = 0; j < n; ++j) {
      double c[6], speed, acc;
      planner.coefficients(k, j, c);
      for (int i = 0; i < 6; ++i) s.c[i][j] = c[i];
      segment_peaks(c, durations_[k], speed, acc);
      peak_speed_[j] = std::max(peak_speed_[j], speed);
      peak_acceleration_[j] = std::max(peak_acceleration_[j], acc);
    }
  }
}

void JointTrajectory::sample(double t, TrajectorySample& out) const noexcept {
  out.q.resize(joints_);
  out.qd.resize(joints_);
  out.qdd.resize(joints_);
  if (segments_.empty()) return;
  t = std::clamp(t, 0.0, duration());
  // The segment whose [start, end) holds t (the last one holds its end too).
  const auto it = std::upper_bound(times_.begin() + 1, times_.end() - 1, t);
  const auto k = static_cast<std::size_t>(it - (times_.begin() + 1));
  const double tau = t - times_[k];
  const Segment& s = segments_[k];
  for (int j = 0; j < joints_; ++j) {
    const double c1 = s.c[1][j], c2 = s.c[2][j], c3 = s.c[3][j], c4 = s.c[4][j], c5 = s.c[5][j];
    out.q[j] = s.c[0][j] + tau * (c1 + tau * (c2 + tau * (c3 + tau * (c4 + tau * c5))));
    out.qd[j] = c1 + tau * (2.0 * c2 + tau * (3.0 * c3 + tau * (4.0 * c4 + tau * 5.0 * c5)));
    out.qdd[j] = 2.0 * c2 + tau * (6.0 * c3 + tau * (12.0 * c4 + tau * 20.0 * c5));
  }
}

TrajectorySample JointTrajectory::sample(double t) const noexcept {
  TrajectorySample s;
  sample(t, s);
  return s;
}

}  // namespace exodaq::kinematics
