// Predictions and error statistics with a given parameter set (no solver).
#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include "exodaq/calibration/solver.hpp"
#include "model_point.hpp"

namespace exodaq::calibration {

Eigen::Vector3d predict_marker(const NominalModel& model, const ParamVector& x,
                               const std::array<double, kJoints>& theta_r) {
  return detail::model_point(model, x.data(), theta_r.data(), MarkerSite{});
}

Eigen::Vector3d predict_marker(const NominalModel& model, const ParamVector& x,
                               const std::array<double, kJoints>& theta_r, const MarkerSite& site) {
  return detail::model_point(model, x.data(), theta_r.data(), site);
}

ErrorStats error_stats(const std::vector<Eigen::Vector3d>& res) {
  ErrorStats s;
  s.n = res.size();
  if (res.empty()) return s;
  std::vector<double> e;
  e.reserve(res.size());
  double sq = 0;
  for (const auto& r : res) {
    e.push_back(r.norm());
    sq += r.squaredNorm();
    s.mean_xyz_m += r;
    s.rms_xyz_m += r.cwiseAbs2();
  }
  const double n = static_cast<double>(res.size());
  s.mean_xyz_m /= n;
  s.rms_xyz_m = (s.rms_xyz_m / n).cwiseSqrt();
  s.rms_m = std::sqrt(sq / n);
  s.mean_m = std::accumulate(e.begin(), e.end(), 0.0) / n;
  double v = 0;
  for (double x : e) v += (x - s.mean_m) * (x - s.mean_m);
  s.std_m = res.size() > 1 ? std::sqrt(v / (n - 1)) : 0.0;
  std::sort(e.begin(), e.end());
  s.max_m = e.back();
  s.median_m = e[e.size() / 2];
  s.p95_m = e[std::min(e.size() - 1, static_cast<std::size_t>(std::ceil(0.95 * n)) - 1)];
  return s;
}

ErrorStats evaluate(const NominalModel& model, const ParamVector& x,
                    const std::vector<AlignedSample>& points, std::vector<Eigen::Vector3d>* out) {
  std::vector<Eigen::Vector3d> res;
  res.reserve(points.size());
  for (const auto& p : points) {
    res.push_back(Eigen::Vector3d(p.marker[0], p.marker[1], p.marker[2]) -
                  predict_marker(model, x, p.theta_r, p.site));
  }
  ErrorStats s = error_stats(res);
  if (out) *out = std::move(res);
  return s;
}

std::vector<MarkerResiduals> residuals_per_marker(const std::vector<AlignedSample>& points,
                                                  const std::vector<Eigen::Vector3d>& residuals) {
  std::map<int, std::vector<Eigen::Vector3d>> by_id;
  std::map<int, MarkerSite> sites;
  for (std::size_t i = 0; i < points.size() && i < residuals.size(); ++i) {
    by_id[points[i].site.id].push_back(residuals[i]);
    sites[points[i].site.id] = points[i].site;
  }
  std::vector<MarkerResiduals> out;
  for (const auto& [id, res] : by_id) out.push_back({sites[id], error_stats(res)});
  return out;
}

}  // namespace exodaq::calibration
