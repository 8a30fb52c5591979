#include "exodaq/calibration/time_alignment.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace exodaq::calibration {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// Speeds are taken over this baseline: long enough that 0.3 mm of marker
// noise is 1 % of a slow arm's speed, short against its movements.
constexpr double kBaselineS = 0.05;
// Encoder positions are predicted at this spacing (the speed needs no more).
constexpr double kEncoderStepS = 0.01;
// The broad scan's budget of (marker bin × offset) pairs.
constexpr double kScanBudget = 1.5e8;

// A speed at a time (s, relative to the stream's first sample).
struct Speed {
  double t, v;
};

// Speeds over kBaselineS between samples of one point track (times
// ascending); pairs across a gap longer than 2 baselines are skipped.
std::vector<Speed> speeds(const std::vector<double>& t, const std::vector<Eigen::Vector3d>& p) {
  std::vector<Speed> out;
  std::size_t j = 0;
  for (std::size_t i = 0; i < t.size(); ++i) {
    j = std::max(j, i + 1);
    while (j < t.size() && t[j] - t[i] < kBaselineS) ++j;
    if (j >= t.size()) break;
    const double dt = t[j] - t[i];
    if (dt > 2 * kBaselineS) continue;
    out.push_back({0.5 * (t[i] + t[j]), (p[j] - p[i]).norm() / dt});
  }
  return out;
}

std::vector<Speed> marker_speeds(const MarkerSeries& m, int id, std::int64_t t0) {
  std::vector<double> t;
  std::vector<Eigen::Vector3d> p;
  for (const MarkerSample& s : m.samples) {
    if ((id >= 0 && s.marker_id != id) || !s.present) continue;
    t.push_back(static_cast<double>(s.utime_us - t0) * 1e-6);
    p.emplace_back(s.x, s.y, s.z);
  }
  return speeds(t, p);
}

std::vector<Speed> model_speeds(const NominalModel& model, const ParamVector& x,
                                const EncoderSeries& e, const MarkerSite& site, std::int64_t t0) {
  std::vector<double> t;
  std::vector<Eigen::Vector3d> p;
  double next = -1e300;
  for (const EncoderSample& s : e.samples) {
    const double ts = static_cast<double>(s.utime_us - t0) * 1e-6;
    if (ts < next || !s.valid()) continue;
    next = ts + kEncoderStepS;
    t.push_back(ts);
    p.push_back(predict_marker(model, x, s.theta_r, site));
  }
  return speeds(t, p);
}

// Mean speed per bin of width h from `t0` (NaN: no sample in the bin).
std::vector<double> binned(const std::vector<Speed>& s, double t0, double h, std::size_t n) {
  std::vector<double> sum(n, 0.0), count(n, 0.0);
  for (const Speed& v : s) {
    const double k = std::floor((v.t - t0) / h);
    if (k < 0 || k >= static_cast<double>(n)) continue;
    sum[static_cast<std::size_t>(k)] += v.v;
    count[static_cast<std::size_t>(k)] += 1;
  }
  for (std::size_t k = 0; k < n; ++k) sum[k] = count[k] > 0 ? sum[k] / count[k] : kNaN;
  return sum;
}

// Pearson correlation of pairs, accumulated.
struct Pearson {
  double n = 0, sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
  void add(double a, double b) {
    n += 1;
    sa += a;
    sb += b;
    saa += a * a;
    sbb += b * b;
    sab += a * b;
  }
  double r(double min_n) const {
    if (n < min_n) return kNaN;
    const double va = saa - sa * sa / n, vb = sbb - sb * sb / n;
    if (!(va > 0 && vb > 0)) return kNaN;
    return (sab - sa * sb / n) / std::sqrt(va * vb);
  }
};

// Linear interpolation of speeds at t (NaN outside or across a gap).
double speed_at(const std::vector<Speed>& s, double t) {
  const auto it =
      std::lower_bound(s.begin(), s.end(), t, [](const Speed& a, double b) { return a.t < b; });
  if (it == s.begin() || it == s.end()) return kNaN;
  const Speed& b = *it;
  const Speed& a = *(it - 1);
  if (b.t - a.t > 4 * kBaselineS) return kNaN;
  const double w = (t - a.t) / (b.t - a.t);
  return (1 - w) * a.v + w * b.v;
}

// Correlation of the marker speeds with the encoder speeds at offset o
// (encoder t = marker t + o, both relative to their own t0).
double correlation_at(const std::vector<Speed>& mk, const std::vector<Speed>& enc, double o,
                      double min_n) {
  Pearson p;
  for (const Speed& m : mk) {
    const double e = speed_at(enc, m.t + o);
    if (std::isfinite(e)) p.add(m.v, e);
  }
  return p.r(min_n);
}

}  // namespace

std::string CoarseOffset::describe() const {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "%+.3f s (speed cross-correlation r = %.3f over %.0f s, in %.0f ms steps; next "
                "best r = %.3f at %+.1f s)",
                offset_s, correlation, overlap_s, step_s * 1e3, runner_up, runner_up_at_s);
  return buf;
}

CoarseOffset coarse_time_offset(const NominalModel& model, const ParamVector& x,
                                const EncoderSeries& encoders, const MarkerSeries& markers,
                                const MarkerSite& site, const CoarseOffsetOptions& o) {
  if (encoders.samples.size() < 2 || markers.samples.empty()) {
    throw std::runtime_error("time alignment: no samples to align");
  }
  const std::int64_t e0 = encoders.samples.front().utime_us;
  const std::int64_t m0 = markers.samples.front().utime_us;
  const std::vector<Speed> enc = model_speeds(model, x, encoders, site, e0);
  const std::vector<Speed> mk = marker_speeds(markers, site.id, m0);
  if (enc.size() < 10 || mk.size() < 10) {
    throw std::runtime_error("time alignment: too few marker or encoder samples of marker " +
                             site.name() + " to compare their speeds");
  }
  const double te = enc.back().t, tm = mk.back().t;
  const double min_overlap = std::max(std::min(o.min_overlap_s, 0.5 * std::min(te, tm)),
                                      o.min_overlap_fraction * std::min(te, tm));
  // Broad scan: binned profiles, every offset on the grid.
  const double h = std::max(0.05, std::sqrt(tm * (te + tm) / kScanBudget));
  const auto ne = static_cast<std::size_t>(te / h) + 1, nm = static_cast<std::size_t>(tm / h) + 1;
  const std::vector<double> E = binned(enc, 0.0, h, ne), M = binned(mk, 0.0, h, nm);
  const double min_bins = std::max(10.0, 0.5 * min_overlap / h);
  const auto lag_lo = -static_cast<long>(nm), lag_hi = static_cast<long>(ne);
  std::vector<std::pair<double, double>> scan;  // (offset, r)
  for (long lag = lag_lo; lag <= lag_hi; ++lag) {
    Pearson p;
    for (std::size_t j = 0; j < nm; ++j) {
      const long i = static_cast<long>(j) + lag;
      if (i < 0 || i >= static_cast<long>(ne) || !std::isfinite(M[j])) continue;
      if (std::isfinite(E[static_cast<std::size_t>(i)]))
        p.add(M[j], E[static_cast<std::size_t>(i)]);
    }
    if (p.n * h < min_overlap) continue;
    const double r = p.r(min_bins);
    if (std::isfinite(r)) scan.emplace_back(static_cast<double>(lag) * h, r);
  }
  if (scan.empty()) {
    throw std::runtime_error("time alignment: the marker and encoder streams never overlap by " +
                             std::to_string(static_cast<int>(min_overlap)) + " s");
  }
  const auto best = std::max_element(
      scan.begin(), scan.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
  CoarseOffset c;
  c.runner_up = -1;
  for (const auto& [off, r] : scan) {
    if (std::abs(off - best->first) >= 2.0 && r > c.runner_up) {
      c.runner_up = r;
      c.runner_up_at_s = off;
    }
  }
  // Refinement: the marker speeds against the encoder speeds interpolated
  // at each offset, in ever finer steps around the best.
  double off = best->first, step = h;
  double r_best = best->second;
  while (step > o.finest_step_s) {
    const double span = 2 * step;
    step = std::max(o.finest_step_s, step / 5);
    double r_here = -2;
    double at = off;
    for (double d = -span; d <= span + 1e-12; d += step) {
      const double r = correlation_at(mk, enc, off + d, 10);
      if (std::isfinite(r) && r > r_here) {
        r_here = r;
        at = off + d;
      }
    }
    off = at;
    r_best = r_here;
  }
  c.step_s = step;
  c.correlation = r_best;
  c.offset_s = off + static_cast<double>(e0 - m0) * 1e-6;
  c.runner_up_at_s += static_cast<double>(e0 - m0) * 1e-6;
  c.overlap_s = std::max(0.0, std::min(te, tm + off) - std::max(0.0, off));
  return c;
}

bool needs_time_alignment(const EncoderSeries& encoders, const MarkerSeries& markers) {
  if (!markers.info.epoch_times) return true;
  if (encoders.samples.empty()) return false;
  const std::int64_t lo = encoders.samples.front().utime_us;
  const std::int64_t hi = encoders.samples.back().utime_us;
  std::size_t inside = 0;
  for (const MarkerSample& s : markers.samples) inside += s.utime_us >= lo && s.utime_us <= hi;
  return 2 * inside < markers.samples.size();
}

MarkerSeries shifted_markers(MarkerSeries m, double offset_s) {
  const auto d = static_cast<std::int64_t>(std::llround(offset_s * 1e6));
  for (MarkerSample& s : m.samples) s.utime_us += d;
  return m;
}

}  // namespace exodaq::calibration
