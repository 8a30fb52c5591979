#include "identifiability.hpp"

#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>

#include "detail.hpp"

namespace exodaq::calibration {

namespace detail {

namespace {

// Standard deviation (same units as the column) of parameter `col` if it were
// added to the `kept` set: sigma / ||(I - P_kept) J_col||.
double std_given(const Eigen::MatrixXd& J, const std::vector<int>& kept, int col, double sigma_mm) {
  Eigen::VectorXd c = J.col(col);
  if (!kept.empty()) {
    const Eigen::MatrixXd K = columns(J, kept);
    const Eigen::VectorXd beta = K.colPivHouseholderQr().solve(c);
    c -= K * beta;
  }
  const double n = c.norm();
  return n > 0 ? sigma_mm / n : std::numeric_limits<double>::infinity();
}

// The kept column to drop when the kept set is ill-conditioned as a whole
// (-1: it is not): the earliest in eq. (6) order with a significant share of
// the weakest singular direction.
int weakest_kept(const Eigen::MatrixXd& J, const std::vector<int>& kept, double sigma_mm,
                 const IdentifiabilityOptions& o) {
  if (kept.empty()) return -1;  // an SVD of no columns is undefined in Eigen
  Eigen::MatrixXd Ks = columns(J, kept);
  for (Eigen::Index k = 0; k < Ks.cols(); ++k) Ks.col(k) *= tolerance(o, kept[k]);
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(Ks, Eigen::ComputeThinV);
  const auto& sv = svd.singularValues();
  const Eigen::Index last = sv.size() - 1;
  if (last < 0 || sigma_mm / std::max(sv[last], 1e-300) <= 1.0) return -1;
  const Eigen::VectorXd v = svd.matrixV().col(last);
  const double vmax = v.cwiseAbs().maxCoeff();
  int pick = -1;
  for (Eigen::Index k = 0; k < v.size(); ++k) {
    if (kept[k] != kTau && std::abs(v[k]) >= 0.3 * vmax && (pick < 0 || kept[k] < pick)) {
      pick = kept[k];
    }
  }
  return pick;
}

Degeneracy degeneracy_of(const Eigen::MatrixXd& J, const std::vector<int>& est,
                         const Eigen::MatrixXd& K,
                         const Eigen::ColPivHouseholderQR<Eigen::MatrixXd>& qr, int h,
                         double sigma_mm, Eigen::VectorXd& beta) {
  Degeneracy d;
  d.held = h;
  const Eigen::VectorXd c = J.col(h);
  const double cn = c.norm();
  beta = Eigen::VectorXd::Zero(K.cols());
  if (cn > 0 && K.cols() > 0) beta = qr.solve(c);
  const double rn = (c - K * beta).norm();
  d.explained = cn > 0 ? 1.0 - rn / cn : 1.0;
  d.exact = cn == 0 || d.explained > 1.0 - 1e-6;
  d.stddev_if_free = rn > 0 ? (sigma_mm / rn) : std::numeric_limits<double>::infinity();
  for (Eigen::Index k = 0; k < K.cols(); ++k) {
    if (est[k] == kTau || cn == 0) continue;
    const double share = std::abs(beta[k]) * K.col(k).norm() / cn;
    if (share < 0.05) continue;
    // Keeping the residuals unchanged when x_h moves by δ needs x_j to move by -β_j δ.
    d.partners.push_back({est[k], -beta[k], share});
  }
  std::sort(d.partners.begin(), d.partners.end(),
            [](const auto& a, const auto& b) { return a.share > b.share; });
  return d;
}

// Free parameters whose estimate follows the held prior h.
void mark_followers(const std::vector<int>& est, const Eigen::VectorXd& beta, int h, double cn,
                    const Bounds& bounds, Report& rep) {
  const double probe = bounds.identifiability.gauge_probe_fraction *
                       (bounds.params[h].upper - bounds.params[h].lower);
  for (std::size_t k = 0; k < est.size(); ++k) {
    const int j = est[k];
    if (j == kTau || cn == 0) continue;
    ParamResult& pr = rep.params[j];
    const auto kk = static_cast<Eigen::Index>(k);
    const double shift = std::abs(beta[kk]) * probe;  // SI
    if (pr.stddev > 0 && shift > pr.stddev) {
      pr.status = ParamStatus::kGaugeDependent;
      const double s = to_display(j, -beta[kk]) / to_display(h, 1.0);
      pr.note += std::string(pr.note.empty() ? "" : "; ") + "follows held " + param_label(h) +
                 " (" + fmt("%+.4g", s) + " " + display_unit(j) + "/" + display_unit(h) + ")";
    }
  }
}

// The markers of a calibration by mount, with their point counts.
struct MarkerCensus {
  std::map<int, std::size_t> hand, base;
  int primary = -1;  // the hand marker with the most points (ties: lowest id; -1: no id column)
  bool has_primary = false;

  explicit MarkerCensus(const std::vector<AlignedSample>& points) {
    for (const auto& p : points) ++(p.site.mount == MarkerMount::kHand ? hand : base)[p.site.id];
    std::size_t most = 0;
    for (const auto& [id, n] : hand) {
      if (n > most) {
        most = n;
        primary = id;
        has_primary = true;
      }
    }
  }
};

std::string id_list(const std::map<int, std::size_t>& ids, int except) {
  std::string out;
  for (const auto& [id, n] : ids) {
    if (id != except) out += (out.empty() ? "" : ", ") + std::to_string(id);
  }
  return out;
}

// J's rows (3 per point) of the points whose marker passes `keep`.
template <typename Keep>
Eigen::MatrixXd rows_of(const Eigen::MatrixXd& J, const std::vector<AlignedSample>& points,
                        Keep keep) {
  std::vector<Eigen::Index> rows;
  for (std::size_t i = 0; i < points.size(); ++i) {
    if (!keep(points[i].site)) continue;
    for (Eigen::Index k = 0; k < 3; ++k) rows.push_back(static_cast<Eigen::Index>(3 * i) + k);
  }
  return J(rows, Eigen::all);
}

bool is_camera(int p) {
  return p >= kDx && p <= kPhiZ;
}

}  // namespace

Eigen::MatrixXd columns(const Eigen::MatrixXd& J, const std::vector<int>& cols) {
  Eigen::MatrixXd out(J.rows(), static_cast<Eigen::Index>(cols.size()));
  for (std::size_t k = 0; k < cols.size(); ++k)
    out.col(static_cast<Eigen::Index>(k)) = J.col(cols[k]);
  return out;
}

double tolerance(const IdentifiabilityOptions& o, int col) {
  if (col == kTau) return 1e-3;  // 1 ms
  return is_angle(col) ? o.max_std_angle_rad : o.max_std_length_m;
}

double residual_sigma_mm(const Eigen::VectorXd& r, std::size_t nfree, bool robust) {
  if (robust && r.size() > 0) {
    std::vector<double> a(r.data(), r.data() + r.size());
    for (double& v : a) v = std::abs(v);
    std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(a.size() / 2), a.end());
    return 1.4826 * a[a.size() / 2];
  }
  const double dof = std::max(1.0, static_cast<double>(r.size()) - static_cast<double>(nfree));
  return std::sqrt(r.squaredNorm() / dof);
}

std::vector<int> unobservable(const Eigen::MatrixXd& J, const ColumnMask& candidate, bool with_tau,
                              double sigma_mm, const IdentifiabilityOptions& o) {
  std::vector<int> kept;
  if (with_tau) kept.push_back(kTau);
  std::vector<int> out;
  for (int p = kParams - 1; p >= 0; --p) {
    if (!candidate[p]) continue;
    if (std_given(J, kept, p, sigma_mm) > tolerance(o, p)) {
      out.push_back(p);
    } else {
      kept.push_back(p);
    }
  }
  for (int pick = weakest_kept(J, kept, sigma_mm, o); pick >= 0;
       pick = weakest_kept(J, kept, sigma_mm, o)) {
    out.push_back(pick);
    kept.erase(std::find(kept.begin(), kept.end(), pick));
  }
  return out;
}

std::vector<double> scaled_singular_values(const Eigen::MatrixXd& J, const std::vector<int>& est,
                                           const IdentifiabilityOptions& o) {
  if (est.empty()) return {};
  Eigen::MatrixXd K = columns(J, est);
  for (Eigen::Index k = 0; k < K.cols(); ++k) K.col(k) *= tolerance(o, est[k]);
  Eigen::JacobiSVD<Eigen::MatrixXd> svd(K);
  return {svd.singularValues().data(), svd.singularValues().data() + svd.singularValues().size()};
}

void describe_degeneracies(const Eigen::MatrixXd& J, const std::vector<int>& est,
                           const ColumnMask& held, double sigma_mm, const Bounds& bounds,
                           Report& rep) {
  const Eigen::MatrixXd K = columns(J, est);
  const auto qr = K.colPivHouseholderQr();
  for (int h = 0; h < kParams; ++h) {
    if (!held[h]) continue;
    Eigen::VectorXd beta;
    const Degeneracy d = degeneracy_of(J, est, K, qr, h, sigma_mm, beta);
    mark_followers(est, beta, h, J.col(h).norm(), bounds, rep);
    rep.params[h].note = d.exact ? "exactly unobservable" : "nearly unobservable";
    if (!d.exact && std::isfinite(d.stddev_if_free)) {
      rep.params[h].note += ", std if estimated " + fmt("%.3g", to_display(h, d.stddev_if_free)) +
                            " " + display_unit(h);
    }
    rep.degeneracies.push_back(d);
  }
}

std::vector<Correlation> correlations(const Eigen::MatrixXd& cov, const std::vector<int>& est,
                                      double threshold) {
  std::vector<Correlation> out;
  for (std::size_t a = 0; a < est.size(); ++a) {
    for (std::size_t b = a + 1; b < est.size(); ++b) {
      const double va = cov(est[a], est[a]), vb = cov(est[b], est[b]);
      if (va <= 0 || vb <= 0) continue;
      const double rr = cov(est[a], est[b]) / std::sqrt(va * vb);
      if (std::abs(rr) > threshold) out.push_back({est[a], est[b], rr});
    }
  }
  return out;
}

std::vector<ObservationSet> observation_sets(const Eigen::MatrixXd& J,
                                             const std::vector<AlignedSample>& points,
                                             const ColumnMask& estimable, bool with_tau,
                                             double sigma_mm, const Bounds& bounds) {
  const MarkerCensus census(points);
  bool camera_fixed = false;
  for (int p = kDx; p <= kPhiZ; ++p) camera_fixed = camera_fixed || bounds.params[p].fixed;
  if (!census.has_primary || (census.hand.size() == 1 && census.base.empty() && !camera_fixed)) {
    return {};
  }
  ColumnMask camera_free = estimable;
  for (int p = 0; p < kParams; ++p) camera_free[p] = camera_free[p] || is_camera(p);
  const auto& o = bounds.identifiability;
  auto analyse = [&](std::string name, const Eigen::MatrixXd& Jr, const ColumnMask& cols) {
    ObservationSet set{std::move(name), unobservable(Jr, cols, with_tau, sigma_mm, o), {}};
    std::sort(set.unidentifiable.begin(), set.unidentifiable.end());
    return set;
  };
  const int primary = census.primary;
  const auto is_primary = [primary](const MarkerSite& m) {
    return m.mount == MarkerMount::kHand && m.id == primary;
  };
  const Eigen::MatrixXd J1 = rows_of(J, points, is_primary);
  std::vector<ObservationSet> sets;
  const std::string which = primary < 0 ? "" : " (id " + std::to_string(primary) + ")";
  sets.push_back(analyse("one hand marker" + which + ", camera free (seed 000)", J1, camera_free));
  if (census.hand.size() > 1) {
    sets.push_back(analyse(
        "+ hand markers " + id_list(census.hand, primary),
        rows_of(J, points, [](const MarkerSite& m) { return m.mount == MarkerMount::kHand; }),
        camera_free));
  }
  if (!census.base.empty()) {
    sets.push_back(analyse("+ base markers " + id_list(census.base, -1),
                           rows_of(J, points,
                                   [&](const MarkerSite& m) {
                                     return is_primary(m) || m.mount == MarkerMount::kBase;
                                   }),
                           camera_free));
  }
  if (camera_fixed) sets.push_back(analyse("camera transform fixed (bounds file)", J1, estimable));
  sets.push_back(analyse("all observations (this calibration)", J, estimable));
  for (auto& set : sets) {
    for (int p : sets.front().unidentifiable) {
      const auto& u = set.unidentifiable;
      if (estimable[p] && std::find(u.begin(), u.end(), p) == u.end()) {
        set.newly_identifiable.push_back(p);
      }
    }
  }
  return sets;
}

}  // namespace detail

std::string Degeneracy::describe() const {
  std::ostringstream o;
  o << param_label(held) << (exact ? " is exactly" : " is nearly") << " unobservable";
  if (!partners.empty()) {
    o << ": its effect is reproduced by";
    for (std::size_t k = 0; k < partners.size(); ++k) {
      const auto& p = partners[k];
      // slope in display units per display unit of the held parameter
      const double s = to_display(p.param, p.slope) / to_display(held, 1.0);
      o << (k ? "," : "") << " " << param_label(p.param) << " (" << detail::fmt("%+.4g", s) << " "
        << display_unit(p.param) << "/" << display_unit(held) << ", share "
        << detail::fmt("%.2f", p.share) << ")";
    }
  } else {
    o << ": it has no effect on the marker";
  }
  o << "; explained " << detail::fmt("%.6f", explained);
  if (!exact && std::isfinite(stddev_if_free)) {
    o << ", std if estimated " << detail::fmt("%.3g", to_display(held, stddev_if_free)) << " "
      << display_unit(held);
  }
  return o.str();
}

}  // namespace exodaq::calibration
