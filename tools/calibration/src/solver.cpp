// The Ceres part of the calibration: cost, solve stages, covariance. The
// identifiability analysis is in identifiability.cpp, parameters and the bounds
// file in parameters.cpp. Ceres headers compile slowly: keep them here only.
#include <ceres/ceres.h>
#include <ceres/covariance.h>
#include <ceres/manifold.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>

#include "detail.hpp"
#include "exodaq/calibration/solver.hpp"
#include "identifiability.hpp"
#include "model_point.hpp"

namespace exodaq::calibration {

using detail::fmt;
using detail::kMToMm;
using detail::kTau;

namespace {

inline double scalar(double v) {
  return v;
}
template <typename T, int N>
double scalar(const ceres::Jet<T, N>& j) {
  return j.a;
}

// θᴿ at marker time t_us + τ from the encoder stream: cubic Hermite with
// finite-difference tangents (C1 in time). Linear interpolation would put a
// kink in the cost at every encoder sample, where the solver can stall when
// the marker phases line up. `index` is the sample at or before t_us.
template <typename T>
void interpolate_theta(const std::vector<EncoderSample>& e, std::int64_t t_us, int index,
                       const T& tau, std::array<T, kJoints>& th) {
  const double target = static_cast<double>(t_us) + scalar(tau) * 1e6;
  int i = std::clamp(index, 0, static_cast<int>(e.size()) - 2);
  while (i > 0 && static_cast<double>(e[i].utime_us) > target) --i;
  while (i + 2 < static_cast<int>(e.size()) && static_cast<double>(e[i + 1].utime_us) <= target)
    ++i;
  const double dt_s = static_cast<double>(e[i + 1].utime_us - e[i].utime_us) * 1e-6;
  const T w = (T(static_cast<double>(t_us - e[i].utime_us) * 1e-6) + tau) / T(dt_s);
  const int i0 = std::max(i - 1, 0);
  const int i3 = std::min(i + 2, static_cast<int>(e.size()) - 1);
  const double span1 = static_cast<double>(e[i + 1].utime_us - e[i0].utime_us) * 1e-6;
  const double span2 = static_cast<double>(e[i3].utime_us - e[i].utime_us) * 1e-6;
  const T w2 = w * w, w3 = w2 * w;
  const T h00 = T(2.0) * w3 - T(3.0) * w2 + T(1.0);
  const T h10 = w3 - T(2.0) * w2 + w;
  const T h01 = T(-2.0) * w3 + T(3.0) * w2;
  const T h11 = w3 - w2;
  for (int j = 0; j < kJoints; ++j) {
    const double m1 = (e[i + 1].theta_r[j] - e[i0].theta_r[j]) / span1 * dt_s;
    const double m2 = (e[i3].theta_r[j] - e[i].theta_r[j]) / span2 * dt_s;
    th[j] = h00 * T(e[i].theta_r[j]) + h10 * T(m1) + h01 * T(e[i + 1].theta_r[j]) + h11 * T(m2);
  }
}

// Residual in mm: measured - predicted.
struct MarkerCost {
  const NominalModel* model;
  std::array<double, kJoints> theta_r;
  Eigen::Vector3d measured;
  MarkerSite site;
  // Time-offset estimation: the encoder stream and the marker time.
  const std::vector<EncoderSample>* enc = nullptr;
  std::int64_t t_us = 0;
  int index = 0;

  template <typename T>
  bool operator()(const T* x, const T* tau, T* r) const {
    std::array<T, kJoints> th;
    if (enc == nullptr) {
      for (int j = 0; j < kJoints; ++j) th[j] = T(theta_r[j]);
    } else {
      interpolate_theta(*enc, t_us, index, tau[0], th);
    }
    const Eigen::Matrix<T, 3, 1> p = detail::model_point(*model, x, th.data(), site);
    for (int k = 0; k < 3; ++k) r[k] = (T(measured[k]) - p[k]) * T(kMToMm);
    return true;
  }
};
using MarkerCostFunction = ceres::AutoDiffCostFunction<MarkerCost, 3, kParams, 1>;

// One progress line per iteration that moved the RMS by 0.1 % or more (an
// iteration that changes nothing visible is not news), and the stage's end.
class Progress : public ceres::IterationCallback {
 public:
  Progress(const SolveOptions& o, std::size_t residuals, std::string stage)
      : o_(o), m_(residuals), stage_(std::move(stage)) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (!o_.progress) return ceres::SOLVER_CONTINUE;
    const double rms = std::sqrt(2.0 * s.cost / static_cast<double>(m_));
    if (s.iteration == 0 || std::abs(rms - shown_) > 1e-3 * shown_) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "  [%s] iter %3d  rms %.4f mm  |step| %.2e", stage_.c_str(),
                    s.iteration, rms, s.step_norm);
      o_.progress(buf);
      shown_ = rms;
    } else {
      ++quiet_;
    }
    last_ = rms;
    iterations_ = s.iteration;
    return ceres::SOLVER_CONTINUE;
  }
  void finish() const {
    if (!o_.progress) return;
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  "  [%s] done after %d iterations (%d without a visible change), rms %.4f mm",
                  stage_.c_str(), iterations_, quiet_, last_);
    o_.progress(buf);
  }

 private:
  const SolveOptions& o_;
  std::size_t m_;
  std::string stage_;
  double shown_ = 0, last_ = 0;
  int quiet_ = 0, iterations_ = 0;
};

struct Problem {
  std::vector<std::unique_ptr<MarkerCostFunction>> costs;
  std::unique_ptr<ceres::LossFunction> loss;
};

// The solution being worked on: x (20) and τ, which parameters are free, held
// (unidentifiable) or on a bound.
struct SolveState {
  ParamVector x0{}, x{};
  double tau = 0;
  bool tau_free = false;
  detail::ColumnMask free{}, held{}, at_bound{};

  int free_count() const {
    int n = tau_free ? 1 : 0;
    for (bool f : free) n += f ? 1 : 0;
    return n;
  }
  // Estimated columns: free and not on a bound (then τ).
  std::vector<int> estimated() const {
    std::vector<int> est;
    for (int p = 0; p < kParams; ++p) {
      if (free[p] && !at_bound[p]) est.push_back(p);
    }
    if (tau_free) est.push_back(kTau);
    return est;
  }
};

std::unique_ptr<ceres::LossFunction> make_loss(const SolveOptions& o) {
  const double s = o.loss_scale_m * kMToMm;  // residuals are in mm
  switch (o.loss) {
    case RobustLoss::kHuber:
      return std::make_unique<ceres::HuberLoss>(s);
    case RobustLoss::kCauchy:
      return std::make_unique<ceres::CauchyLoss>(s);
    case RobustLoss::kNone:
      break;
  }
  return nullptr;
}

Problem make_problem(const NominalModel& model, const std::vector<AlignedSample>& points,
                     const SolveOptions& options, const EncoderSeries* encoders) {
  Problem P;
  P.loss = make_loss(options);
  for (const auto& s : points) {
    MarkerCost c{&model, s.theta_r, Eigen::Vector3d(s.marker[0], s.marker[1], s.marker[2]), s.site};
    if (options.estimate_time_offset) {
      c.enc = &encoders->samples;
      c.t_us = s.utime_us;
      c.index = s.encoder_index;
    }
    P.costs.push_back(std::make_unique<MarkerCostFunction>(new MarkerCost(c)));
  }
  return P;
}

// A ceres::Problem over x (20) and tau (1) with `free[p]` free.
std::unique_ptr<ceres::Problem> build(Problem& P, double* x, double* tau,
                                      const detail::ColumnMask& free, bool tau_free,
                                      const Bounds& b) {
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  auto problem = std::make_unique<ceres::Problem>(po);
  for (auto& c : P.costs) problem->AddResidualBlock(c.get(), P.loss.get(), x, tau);
  std::vector<int> constant;
  for (int p = 0; p < kParams; ++p) {
    if (!free[p]) constant.push_back(p);
  }
  if (static_cast<int>(constant.size()) == kParams) {
    problem->SetParameterBlockConstant(x);
  } else {
    if (!constant.empty()) problem->SetManifold(x, new ceres::SubsetManifold(kParams, constant));
    for (int p = 0; p < kParams; ++p) {
      if (!free[p]) continue;
      problem->SetParameterLowerBound(x, p, b.params[p].lower);
      problem->SetParameterUpperBound(x, p, b.params[p].upper);
    }
  }
  if (tau_free) {
    problem->SetParameterLowerBound(tau, 0, b.time_offset.lower_s);
    problem->SetParameterUpperBound(tau, 0, b.time_offset.upper_s);
  } else {
    problem->SetParameterBlockConstant(tau);
  }
  return problem;
}

ceres::Solver::Summary run(ceres::Problem& problem, const SolveOptions& o, std::size_t m,
                           const std::string& stage) {
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = o.max_iterations;
  so.function_tolerance = 1e-12;
  so.gradient_tolerance = 1e-12;
  so.parameter_tolerance = 1e-12;
  so.num_threads = 1;
  Progress cb(o, m, stage);
  so.callbacks.push_back(&cb);
  so.update_state_every_iteration = false;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  cb.finish();
  if (!summary.IsSolutionUsable()) {
    throw std::runtime_error("calibration solve failed (" + stage + "): " + summary.message);
  }
  return summary;
}

// One solve of the free parameters from the current state.
ceres::Solver::Summary solve_stage(Problem& P, SolveState& s, const Bounds& bounds,
                                   const SolveOptions& options, const std::string& stage,
                                   Report& rep) {
  auto problem = build(P, s.x.data(), &s.tau, s.free, s.tau_free, bounds);
  const auto summary = run(*problem, options, rep.residuals, stage);
  rep.iterations += static_cast<int>(summary.iterations.size());
  return summary;
}

// Dense Jacobian (3N x 21, residuals in mm, columns SI) of all parameters plus
// tau, rows weighted by sqrt(rho') of the loss (IRLS view of a robust fit).
Eigen::MatrixXd full_jacobian(Problem& P, const double* x, const double* tau,
                              Eigen::VectorXd* residuals) {
  const int n = static_cast<int>(P.costs.size());
  Eigen::MatrixXd J(3 * n, kParams + 1);
  if (residuals) residuals->resize(3 * n);
  Eigen::Matrix<double, 3, kParams, Eigen::RowMajor> jx;
  Eigen::Matrix<double, 3, 1> jt;
  double r[3] = {0.0, 0.0, 0.0};
  for (int i = 0; i < n; ++i) {
    const double* params[2] = {x, tau};
    double* jac[2] = {jx.data(), jt.data()};
    if (!P.costs[i]->Evaluate(params, r, jac)) throw std::runtime_error("cost evaluation failed");
    double w = 1.0;
    if (P.loss) {
      double rho[3];
      P.loss->Evaluate(r[0] * r[0] + r[1] * r[1] + r[2] * r[2], rho);
      w = std::sqrt(std::max(rho[1], 0.0));
    }
    J.block(3 * i, 0, 3, kParams) = w * jx;
    J.block(3 * i, kParams, 3, 1) = w * jt;
    if (residuals) residuals->segment<3>(3 * i) = Eigen::Vector3d(r[0], r[1], r[2]);
  }
  return J;
}

void check_enough_points(const std::vector<AlignedSample>& points, const Bounds& bounds,
                         const SolveOptions& options, const EncoderSeries* encoders) {
  int user_free = 0;
  for (int p = 0; p < kParams; ++p) user_free += bounds.params[p].fixed ? 0 : 1;
  const bool tau_free = options.estimate_time_offset;
  if (tau_free && encoders == nullptr) {
    throw std::invalid_argument("time-offset estimation needs the encoder stream");
  }
  const std::size_t need =
      std::max<std::size_t>(options.min_points, static_cast<std::size_t>(user_free + 1));
  if (points.size() < need) {
    throw std::runtime_error("too few calibration points: " + std::to_string(points.size()) +
                             " usable marker samples, need at least " + std::to_string(need) +
                             " for " + std::to_string(user_free + (tau_free ? 1 : 0)) +
                             " free parameters (seed 000 used 400 points moving all six joints)");
  }
}

SolveState initial_state(const Bounds& bounds, const SolveOptions& options) {
  SolveState s;
  s.x0 = initial_params(bounds);
  s.x = s.x0;
  s.tau = bounds.time_offset.initial_s;
  s.tau_free = options.estimate_time_offset;
  for (int p = 0; p < kParams; ++p) s.free[p] = !bounds.params[p].fixed;
  return s;
}

// Stage 2..: find the directions the data cannot see, hold them at their
// priors, re-solve; up to three rounds.
void hold_unobservable(Problem& P, SolveState& s, const Bounds& bounds, const SolveOptions& options,
                       Report& rep) {
  const auto& idopt = bounds.identifiability;
  for (int round = 0; round < 3; ++round) {
    Eigen::VectorXd r;
    const Eigen::MatrixXd J = full_jacobian(P, s.x.data(), &s.tau, &r);
    const double sigma_mm = std::max(
        detail::residual_sigma_mm(r, static_cast<std::size_t>(s.free_count()), P.loss != nullptr),
        idopt.noise_floor_m * kMToMm);
    const std::vector<int> newly = detail::unobservable(J, s.free, s.tau_free, sigma_mm, idopt);
    if (newly.empty()) break;
    std::string names;
    for (int p : newly) {
      names += std::string(names.empty() ? "" : ", ") + param_label(p);
      s.free[p] = false;
      s.held[p] = true;
      s.x[p] = s.x0[p];
    }
    if (options.progress) {
      options.progress("unidentifiable from these data: " + names +
                       " (held at prior values, re-solving)");
    }
    rep.termination = solve_stage(P, s, bounds, options, "gauge fixed", rep).BriefReport();
  }
  if (rep.termination.empty()) rep.termination = "converged after the first stage";
}

void mark_active_bounds(SolveState& s, const Bounds& bounds) {
  for (int p = 0; p < kParams; ++p) {
    if (!s.free[p]) continue;
    const auto& b = bounds.params[p];
    const double eps = 1e-7 * (b.upper - b.lower);
    s.at_bound[p] = s.x[p] <= b.lower + eps || s.x[p] >= b.upper - eps;
  }
}

// Final residuals from the cost functions, so an estimated time offset counts.
void final_residuals(Problem& P, SolveState& s, Report& rep) {
  Eigen::VectorXd raw;
  full_jacobian(P, s.x.data(), &s.tau, &raw);
  rep.residual_after.clear();
  for (Eigen::Index i = 0; i + 2 < raw.size(); i += 3) {
    rep.residual_after.push_back(raw.segment<3>(i) / kMToMm);
  }
  rep.after = error_stats(rep.residual_after);
}

// The covariance blocks of x (and τ) from a computed ceres::Covariance.
Eigen::MatrixXd covariance_blocks(const ceres::Covariance& covariance, SolveState& s) {
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(kParams + 1, kParams + 1);
  Eigen::Matrix<double, kParams, kParams, Eigen::RowMajor> cxx;
  covariance.GetCovarianceBlock(s.x.data(), s.x.data(), cxx.data());
  cov.topLeftCorner(kParams, kParams) = cxx;
  if (s.tau_free) {
    Eigen::Matrix<double, kParams, 1> cxt;
    double ctt = 0;
    covariance.GetCovarianceBlock(s.x.data(), &s.tau, cxt.data());
    covariance.GetCovarianceBlock(&s.tau, &s.tau, &ctt);
    cov.block(0, kParams, kParams, 1) = cxt;
    cov.block(kParams, 0, 1, kParams) = cxt.transpose();
    cov(kParams, kParams) = ctt;
  }
  return cov;
}

// Covariance of the estimated parameters with ceres::Covariance on the
// identifiable subspace (held, fixed and at-bound coordinates constant),
// scaled by the residual variance; the pseudo-inverse of JᵀJ if Ceres fails.
Eigen::MatrixXd covariance(Problem& P, SolveState& s, const Bounds& bounds,
                           const SolveOptions& options, const Eigen::MatrixXd& J,
                           const std::vector<int>& est, double sigma_mm) {
  detail::ColumnMask cov_free{};
  for (int p = 0; p < kParams; ++p) cov_free[p] = s.free[p] && !s.at_bound[p];
  auto problem = build(P, s.x.data(), &s.tau, cov_free, s.tau_free, bounds);
  ceres::Covariance::Options co;
  co.algorithm_type = ceres::DENSE_SVD;
  co.null_space_rank = -1;
  co.min_reciprocal_condition_number = 1e-14;
  ceres::Covariance covariance(co);
  std::vector<std::pair<const double*, const double*>> blocks = {{s.x.data(), s.x.data()}};
  if (s.tau_free) {
    blocks.push_back({s.x.data(), &s.tau});
    blocks.push_back({&s.tau, &s.tau});
  }
  const bool ok = std::any_of(cov_free.begin(), cov_free.end(), [](bool b) { return b; }) &&
                  covariance.Compute(blocks, problem.get());
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(kParams + 1, kParams + 1);
  if (ok) {
    cov = covariance_blocks(covariance, s);
  } else {
    const Eigen::MatrixXd K = detail::columns(J, est);
    const Eigen::MatrixXd C = (K.transpose() * K).completeOrthogonalDecomposition().pseudoInverse();
    for (std::size_t a = 0; a < est.size(); ++a) {
      for (std::size_t b = 0; b < est.size(); ++b) cov(est[a], est[b]) = C(a, b);
    }
    if (options.progress)
      options.progress("note: ceres::Covariance failed; covariance from the pseudo-inverse");
  }
  return cov * (sigma_mm * sigma_mm);  // Ceres assumes unit-variance residuals
}

void parameter_results(const SolveState& s, const Bounds& bounds, const Eigen::MatrixXd& cov,
                       Report& rep) {
  for (int p = 0; p < kParams; ++p) {
    ParamResult& pr = rep.params[p];
    pr.initial = s.x0[p];
    pr.estimate = s.x[p];
    if (bounds.params[p].fixed) {
      pr.status = ParamStatus::kFixed;
    } else if (s.held[p]) {
      pr.status = ParamStatus::kHeld;
    } else if (s.at_bound[p]) {
      pr.status = ParamStatus::kAtBound;
      pr.note =
          s.x[p] <= bounds.params[p].lower + 1e-12 ? "on its lower bound" : "on its upper bound";
    } else {
      pr.status = ParamStatus::kIdentified;
      pr.stddev = std::sqrt(std::max(cov(p, p), 0.0));
    }
  }
  if (s.tau_free) {
    rep.time_offset_s = s.tau;
    rep.time_offset_std_s = std::sqrt(std::max(cov(kParams, kParams), 0.0));
  }
}

// The offset the residuals point to when τ is not estimated (TimeOffsetHint):
// the τ column (the predicted marker's motion) projected off the estimated
// columns, against the residuals.
std::optional<TimeOffsetHint> time_offset_hint(const NominalModel& model,
                                               const std::vector<AlignedSample>& points,
                                               const EncoderSeries& enc, const SolveState& s,
                                               const Eigen::MatrixXd& J,
                                               const std::vector<int>& est,
                                               const Eigen::VectorXd& r, double sigma_mm) {
  const auto n = static_cast<Eigen::Index>(points.size());
  Eigen::VectorXd g(3 * n);
  const double tau = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const AlignedSample& p = points[static_cast<std::size_t>(i)];
    MarkerCost c{
        &model,         p.theta_r,    Eigen::Vector3d(p.marker[0], p.marker[1], p.marker[2]),
        p.site,         &enc.samples, p.utime_us,
        p.encoder_index};
    MarkerCostFunction f(new MarkerCost(c));
    const double* params[2] = {s.x.data(), &tau};
    double res[3];
    double jt[3];
    double* jac[2] = {nullptr, jt};
    if (!f.Evaluate(params, res, jac)) return std::nullopt;
    g.segment<3>(3 * i) = Eigen::Vector3d(jt[0], jt[1], jt[2]);
  }
  std::vector<int> cols;
  for (int c : est) {
    if (c != detail::kTau) cols.push_back(c);
  }
  const Eigen::MatrixXd K = detail::columns(J, cols);
  const Eigen::VectorXd g_perp =
      cols.empty() ? g : Eigen::VectorXd(g - K * K.colPivHouseholderQr().solve(g));
  const double gg = g_perp.squaredNorm(), rr = r.squaredNorm();
  if (!(gg > 0) || !(rr > 0)) return std::nullopt;
  TimeOffsetHint h;
  h.offset_s = -g_perp.dot(r) / gg;
  h.std_s = sigma_mm / std::sqrt(gg);
  h.explained = g_perp.dot(r) * g_perp.dot(r) / (gg * rr);
  return h;
}

// Every free parameter on one of its bounds, "dtheta1_deg 40.700 (bounds 20.700..40.700)".
std::string on_bounds(const SolveState& s, const Bounds& b) {
  std::string out;
  for (int p = 0; p < kParams; ++p) {
    if (b.params[p].fixed) continue;
    const auto& pr = b.params[p];
    const double eps = 1e-6 * (pr.upper - pr.lower);
    if (s.x[p] > pr.lower + eps && s.x[p] < pr.upper - eps) continue;
    out += (out.empty() ? "" : ", ") + std::string(param_key(p)) + " " +
           fmt("%.3f", to_display(p, s.x[p])) + " (bounds " + fmt("%.3f", to_display(p, pr.lower)) +
           ".." + fmt("%.3f", to_display(p, pr.upper)) + ")";
  }
  return out;
}

// Everything the report says about the final solution: noise, covariance,
// parameter statuses, singular values, degeneracies and correlations.
void describe_solution(const NominalModel& model, Problem& P, SolveState& s, const Bounds& bounds,
                       const SolveOptions& options, const std::vector<AlignedSample>& points,
                       const EncoderSeries* encoders, Report& rep) {
  const std::vector<int> est = s.estimated();
  rep.free_params = est.size();
  Eigen::VectorXd r;
  const Eigen::MatrixXd J = full_jacobian(P, s.x.data(), &s.tau, &r);
  const double sigma_mm = detail::residual_sigma_mm(r, est.size(), P.loss != nullptr);
  rep.sigma_m = sigma_mm / kMToMm;
  const Eigen::MatrixXd cov = covariance(P, s, bounds, options, J, est, sigma_mm);
  rep.singular_values = detail::scaled_singular_values(J, est, bounds.identifiability);
  parameter_results(s, bounds, cov, rep);
  detail::describe_degeneracies(J, est, s.held, sigma_mm, bounds, rep);
  rep.correlations = detail::correlations(cov, est, bounds.identifiability.correlation_threshold);
  detail::ColumnMask estimable{};
  for (int p = 0; p < kParams; ++p) estimable[p] = !bounds.params[p].fixed && !s.at_bound[p];
  rep.observation_sets = detail::observation_sets(
      J, points, estimable, s.tau_free,
      std::max(sigma_mm, bounds.identifiability.noise_floor_m * kMToMm), bounds);
  if (!s.tau_free && encoders != nullptr && encoders->samples.size() >= 2) {
    rep.time_offset_hint = time_offset_hint(model, points, *encoders, s, J, est, r, sigma_mm);
  }
}

}  // namespace

Report calibrate(const NominalModel& model, const std::vector<AlignedSample>& points,
                 const Bounds& bounds_file, const SolveOptions& options,
                 const EncoderSeries* encoders) {
  Bounds bounds = bounds_file;
  if (options.time_offset) bounds.time_offset = *options.time_offset;
  auto say = [&](const std::string& s) {
    if (options.progress) options.progress(s);
  };
  check_enough_points(points, bounds, options, encoders);
  Problem P = make_problem(model, points, options, encoders);
  SolveState s = initial_state(bounds, options);

  Report rep;
  rep.points = points.size();
  rep.residuals = 3 * points.size();
  rep.before = evaluate(model, s.x0, points, &rep.residual_before);
  say("before calibration: RMS " + fmt("%.3f", rep.before.rms_m * kMToMm) + " mm over " +
      std::to_string(points.size()) + " points");

  solve_stage(P, s, bounds, options, "all free", rep);  // stage 1: what the bounds leave free
  const ErrorStats first_fit = evaluate(model, s.x, points, nullptr);
  const std::string first_on_bounds = on_bounds(s, bounds);
  hold_unobservable(P, s, bounds, options, rep);
  // Every free parameter judged unidentifiable, or the rest ended on a
  // bound: the data do not fit the model within the bounds at all.
  const auto nothing_identified = [&] {
    const std::string bounds_note =
        first_on_bounds.empty()
            ? std::string("; ")
            : "; the fit ended on " +
                  (bounds.source.empty() ? std::string("the bounds")
                                         : "the bounds of " + bounds.source) +
                  " for " + first_on_bounds +
                  ": this rig's values may lie outside them (widen those bounds or start from "
                  "values measured on this rig); otherwise, ";
    return std::runtime_error(
        "no parameter is identifiable from these data: the best fit leaves " +
        fmt("%.1f", first_fit.rms_m * kMToMm) + " mm RMS" + bounds_note +
        "do the encoder angles and the markers belong together (the clocks, the recorded "
        "calibration, the marker ids)?");
  };
  if (s.free_count() == 0) throw nothing_identified();
  mark_active_bounds(s, bounds);
  if (s.estimated().empty()) throw nothing_identified();
  final_residuals(P, s, rep);
  const auto per_marker = residuals_per_marker(points, rep.residual_after);
  if (per_marker.size() > 1) rep.per_marker = per_marker;
  describe_solution(model, P, s, bounds, options, points, encoders, rep);
  say("after calibration: RMS " + fmt("%.3f", rep.after.rms_m * kMToMm) + " mm");
  return rep;
}

}  // namespace exodaq::calibration
