// The Ceres part of the calibration: cost, solve, identifiability, covariance.
// One translation unit on purpose (Ceres headers compile slowly).
#include "exodaq/calibration/solver.hpp"

#include <ceres/ceres.h>
#include <ceres/covariance.h>
#include <ceres/manifold.h>

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "exodaq/config/yaml_reader.hpp"

namespace exodaq::calibration {

namespace {
constexpr double kRadToDeg = 57.29577951308232;
constexpr double kDegToRad = 0.017453292519943295;
constexpr double kMToMm = 1e3;
constexpr int kTau = kParams;  // column index of the time offset in full Jacobians

struct ParamInfo {
  const char* key;
  const char* label;
  bool angle;
};
constexpr std::array<ParamInfo, kParams> kInfo{{
    {"dtheta1_deg", "Δθ1⁰", true}, {"dtheta2_deg", "Δθ2⁰", true}, {"dtheta3_deg", "Δθ3⁰", true},
    {"dtheta4_deg", "Δθ4⁰", true}, {"dtheta5_deg", "Δθ5⁰", true}, {"dtheta6_deg", "Δθ6⁰", true},
    {"dd2_mm", "Δd2", false},      {"dd3_mm", "Δd3", false},      {"dd5_mm", "Δd5", false},
    {"da3_mm", "Δa3", false},      {"da5_mm", "Δa5", false},      {"dpx_mm", "Δpᴹx", false},
    {"dpy_mm", "Δpᴹy", false},     {"dpz_mm", "Δpᴹz", false},     {"dx_mm", "dx", false},
    {"dy_mm", "dy", false},        {"dz_mm", "dz", false},        {"phix_deg", "φx", true},
    {"phiy_deg", "φy", true},      {"phiz_deg", "φz", true},
}};

inline double scalar(double v) {
  return v;
}
template <typename T, int N>
double scalar(const ceres::Jet<T, N>& j) {
  return j.a;
}

// Marker in the camera frame (seed 000 Fig. 12). `theta` is θᴿ (joint reading
// relative to the index); x holds the 20 parameters.
template <typename T>
Eigen::Matrix<T, 3, 1> model_point(const NominalModel& m, const T* x, const T* theta) {
  using std::cos;
  using std::sin;
  const Eigen::Vector3d t6 = m.tool.translation();
  T px = T(t6.x()) + x[kPx];
  T py = T(t6.y()) + x[kPy];
  T pz = T(t6.z()) + x[kPz];
  for (int i = 5; i >= 0; --i) {
    const kin::DhRow& r = m.dh[i];
    T a = T(r.a);
    T d = T(r.d);
    if (i == 1) d += x[kDd2];
    if (i == 2) {
      d += x[kDd3];
      a += x[kDa3];
    }
    if (i == 4) {
      d += x[kDd5];
      a += x[kDa5];
    }
    // T_i = Rz(θ) Tz(d) Tx(a) Rx(α), applied to the point from the right.
    const double ca = std::cos(r.alpha), sa = std::sin(r.alpha);
    const T y1 = ca * py - sa * pz;
    const T z1 = sa * py + ca * pz + d;
    const T x1 = px + a;
    const T th = theta[i] + x[kTheta1 + i] + T(r.theta_offset);
    const T c = cos(th), s = sin(th);
    px = c * x1 - s * y1;
    py = s * x1 + c * y1;
    pz = z1;
  }
  // World (base) frame.
  const Eigen::Matrix3d Rb = m.base.linear();
  const Eigen::Vector3d tb = m.base.translation();
  T wx = T(Rb(0, 0)) * px + T(Rb(0, 1)) * py + T(Rb(0, 2)) * pz + T(tb.x());
  T wy = T(Rb(1, 0)) * px + T(Rb(1, 1)) * py + T(Rb(1, 2)) * pz + T(tb.y());
  T wz = T(Rb(2, 0)) * px + T(Rb(2, 1)) * py + T(Rb(2, 2)) * pz + T(tb.z());
  // Camera: d + Rx(φx) Ry(φy) Rz(φz) p.
  {
    const T c = cos(x[kPhiZ]), s = sin(x[kPhiZ]);
    const T nx = c * wx - s * wy;
    wy = s * wx + c * wy;
    wx = nx;
  }
  {
    const T c = cos(x[kPhiY]), s = sin(x[kPhiY]);
    const T nx = c * wx + s * wz;
    wz = -s * wx + c * wz;
    wx = nx;
  }
  {
    const T c = cos(x[kPhiX]), s = sin(x[kPhiX]);
    const T ny = c * wy - s * wz;
    wz = s * wy + c * wz;
    wy = ny;
  }
  return Eigen::Matrix<T, 3, 1>(wx + x[kDx], wy + x[kDy], wz + x[kDz]);
}

// Residual in mm: measured - predicted.
struct MarkerCost {
  const NominalModel* model;
  std::array<double, kJoints> theta_r;
  Eigen::Vector3d measured;
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
      const auto& e = *enc;
      const double shift_us = scalar(tau[0]) * 1e6;
      const double target = static_cast<double>(t_us) + shift_us;
      int i = std::clamp(index, 0, static_cast<int>(e.size()) - 2);
      while (i > 0 && static_cast<double>(e[i].utime_us) > target) --i;
      while (i + 2 < static_cast<int>(e.size()) && static_cast<double>(e[i + 1].utime_us) <= target)
        ++i;
      const double dt_s = static_cast<double>(e[i + 1].utime_us - e[i].utime_us) * 1e-6;
      const T w = (T(static_cast<double>(t_us - e[i].utime_us) * 1e-6) + tau[0]) / T(dt_s);
      // Cubic Hermite with finite-difference tangents (C1 in time): linear
      // interpolation would put a kink in the cost at every encoder sample,
      // where the solver can stall when the marker phases line up.
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
    const Eigen::Matrix<T, 3, 1> p = model_point(*model, x, th.data());
    for (int k = 0; k < 3; ++k) r[k] = (T(measured[k]) - p[k]) * T(kMToMm);
    return true;
  }
};
using MarkerCostFunction = ceres::AutoDiffCostFunction<MarkerCost, 3, kParams, 1>;

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

ParamPrior read_prior(config::MapReader& parent, int p) {
  config::MapReader m = parent.map(kInfo[p].key);
  ParamPrior pr;
  pr.fixed = m.boolean_or("fixed", false);
  const double init = m.number("initial");
  double lo = init, hi = init;
  if (!pr.fixed || m.has("lower") || m.has("upper")) {
    lo = m.number("lower");
    hi = m.number("upper");
  }
  if (!(lo <= init && init <= hi)) {
    m.fail(m.node()["initial"],
           std::string("'") + kInfo[p].key + "': initial must lie within [lower, upper], found " +
               fmt("%g", init) + " not in [" + fmt("%g", lo) + ", " + fmt("%g", hi) + "]");
  }
  if (!pr.fixed && !(lo < hi)) {
    m.fail(m.node()["lower"],
           std::string("'") + kInfo[p].key + "': lower must be below upper (or set fixed: true)");
  }
  m.finish();
  pr.initial = from_display(p, init);
  pr.lower = from_display(p, lo);
  pr.upper = from_display(p, hi);
  return pr;
}

Bounds parse_bounds(const YAML::Node& root, const std::string& file) {
  config::MapReader top(file, root, "bounds");
  Bounds b;
  b.source = file;
  const YAML::Node format = top.child("format");
  if (!format.IsScalar() || format.Scalar() != "exodaq-calibration-bounds-1") {
    top.fail(format, "'format' must be 'exodaq-calibration-bounds-1'");
  }
  config::MapReader params = top.map("parameters");
  for (int p = 0; p < kParams; ++p) b.params[p] = read_prior(params, p);
  params.finish();
  if (auto t = top.optional_map("time_offset_ms")) {
    b.time_offset.initial_s = t->number("initial") * 1e-3;
    b.time_offset.lower_s = t->number("lower") * 1e-3;
    b.time_offset.upper_s = t->number("upper") * 1e-3;
    if (!(b.time_offset.lower_s <= b.time_offset.initial_s &&
          b.time_offset.initial_s <= b.time_offset.upper_s &&
          b.time_offset.lower_s < b.time_offset.upper_s)) {
      t->fail(t->node(), "time_offset_ms: need lower <= initial <= upper and lower < upper");
    }
    t->finish();
  }
  if (auto id = top.optional_map("identifiability")) {
    auto& o = b.identifiability;
    o.max_std_angle_rad = id->number_or("max_std_deg", o.max_std_angle_rad * kRadToDeg) * kDegToRad;
    o.max_std_length_m = id->number_or("max_std_mm", o.max_std_length_m * kMToMm) / kMToMm;
    o.noise_floor_m = id->number_or("noise_floor_mm", o.noise_floor_m * kMToMm) / kMToMm;
    o.correlation_threshold = id->number_or("correlation_threshold", o.correlation_threshold);
    o.gauge_probe_fraction = id->number_or("gauge_probe_fraction", o.gauge_probe_fraction);
    if (o.max_std_angle_rad <= 0 || o.max_std_length_m <= 0 || o.noise_floor_m < 0) {
      id->fail(id->node(), "identifiability: max_std_* must be positive, noise_floor_mm >= 0");
    }
    id->finish();
  }
  top.finish();
  return b;
}

// ---------------------------------------------------------------------------
// The solve.

class Progress : public ceres::IterationCallback {
 public:
  Progress(const SolveOptions& o, std::size_t residuals, std::string stage)
      : o_(o), m_(residuals), stage_(std::move(stage)) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (o_.progress) {
      char buf[200];
      std::snprintf(buf, sizeof buf, "  [%s] iter %3d  rms %.4f mm  |step| %.2e  %s",
                    stage_.c_str(), s.iteration, std::sqrt(2.0 * s.cost / static_cast<double>(m_)),
                    s.step_norm, s.step_is_successful ? "" : "(rejected)");
      o_.progress(buf);
    }
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const SolveOptions& o_;
  std::size_t m_;
  std::string stage_;
};

struct Problem {
  std::vector<std::unique_ptr<MarkerCostFunction>> costs;
  std::unique_ptr<ceres::LossFunction> loss;
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

// Builds a ceres::Problem over x (20) and tau (1) with `free[p]` free.
std::unique_ptr<ceres::Problem> build(Problem& P, double* x, double* tau,
                                      const std::array<bool, kParams>& free, bool tau_free,
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
  if (!summary.IsSolutionUsable()) {
    throw std::runtime_error("calibration solve failed (" + stage + "): " + summary.message);
  }
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

// Per-axis residual std (mm): from the sum of squares, or with a robust loss
// from the median absolute residual (outliers would inflate the former).
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

}  // namespace

// ---------------------------------------------------------------------------

bool is_angle(int p) noexcept {
  return p >= 0 && p < kParams && kInfo[p].angle;
}
const char* param_key(int p) noexcept {
  return kInfo[p].key;
}
const char* param_label(int p) noexcept {
  return p == kTau ? "τ" : kInfo[p].label;
}
double to_display(int p, double si) noexcept {
  return is_angle(p) ? si * kRadToDeg : si * kMToMm;
}
double from_display(int p, double v) noexcept {
  return is_angle(p) ? v * kDegToRad : v / kMToMm;
}
const char* display_unit(int p) noexcept {
  return is_angle(p) ? "deg" : "mm";
}

const char* status_name(ParamStatus s) noexcept {
  switch (s) {
    case ParamStatus::kIdentified:
      return "identified";
    case ParamStatus::kGaugeDependent:
      return "gauge-dependent";
    case ParamStatus::kHeld:
      return "HELD (unidentifiable)";
    case ParamStatus::kAtBound:
      return "AT BOUND";
    case ParamStatus::kFixed:
      return "fixed";
  }
  return "?";
}

NominalModel nominal_from_chain(const kin::Chain& chain) {
  if (chain.convention() != kin::Convention::kStandardDh || chain.joint_count() != 6) {
    throw std::invalid_argument(
        "calibration needs a six-joint standard-DH model (seed 000 Table 3); the deviations "
        "Δd2, Δd3, Δd5, Δa3, Δa5 are defined on that table");
  }
  NominalModel m;
  for (int i = 0; i < 6; ++i) m.dh[i] = chain.joints()[i].dh;
  m.base = chain.base();
  m.tool = chain.tool();
  return m;
}

Eigen::Vector3d predict_marker(const NominalModel& model, const ParamVector& x,
                               const std::array<double, kJoints>& theta_r) {
  return model_point(model, x.data(), theta_r.data());
}

Bounds load_bounds_file(const std::string& path) {
  return parse_bounds(config::load_yaml_file(path), path);
}
Bounds load_bounds_text(const std::string& text, const std::string& name) {
  return parse_bounds(config::load_yaml_text(text, name), name);
}

ParamVector initial_params(const Bounds& b) {
  ParamVector x{};
  for (int p = 0; p < kParams; ++p) x[p] = b.params[p].initial;
  return x;
}

ParamVector estimates(const Report& r) {
  ParamVector x{};
  for (int p = 0; p < kParams; ++p) x[p] = r.params[p].estimate;
  return x;
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
                  predict_marker(model, x, p.theta_r));
  }
  ErrorStats s = error_stats(res);
  if (out) *out = std::move(res);
  return s;
}

config::Calibration to_calibration(const ParamVector& x) {
  config::Calibration c;
  for (int j = 0; j < 6; ++j) c.encoder_offset_rad[j] = x[kTheta1 + j];
  c.dh = {x[kDd2], x[kDd3], x[kDd5], x[kDa3], x[kDa5]};
  c.marker_offset_m = {x[kPx], x[kPy], x[kPz]};
  config::CameraTransform cam;
  cam.translation_m = {x[kDx], x[kDy], x[kDz]};
  cam.euler_xyz_rad = {x[kPhiX], x[kPhiY], x[kPhiZ]};
  c.camera = cam;
  return c;
}

ParamVector from_calibration(const config::Calibration& c) {
  ParamVector x{};
  for (int j = 0; j < 6; ++j) x[kTheta1 + j] = c.encoder_offset_rad[j];
  x[kDd2] = c.dh.d2;
  x[kDd3] = c.dh.d3;
  x[kDd5] = c.dh.d5;
  x[kDa3] = c.dh.a3;
  x[kDa5] = c.dh.a5;
  for (int k = 0; k < 3; ++k) {
    x[kPx + k] = c.marker_offset_m[k];
    if (c.camera) {
      x[kDx + k] = c.camera->translation_m[k];
      x[kPhiX + k] = c.camera->euler_xyz_rad[k];
    }
  }
  return x;
}

std::string Degeneracy::describe() const {
  std::ostringstream o;
  o << param_label(held) << (exact ? " is exactly" : " is nearly") << " unobservable";
  if (!partners.empty()) {
    o << ": its effect is reproduced by";
    for (std::size_t k = 0; k < partners.size(); ++k) {
      const auto& p = partners[k];
      // slope in display units per display unit of the held parameter
      const double s = to_display(p.param, p.slope) / to_display(held, 1.0);
      o << (k ? "," : "") << " " << param_label(p.param) << " (" << fmt("%+.4g", s) << " "
        << display_unit(p.param) << "/" << display_unit(held) << ", share " << fmt("%.2f", p.share)
        << ")";
    }
  } else {
    o << ": it has no effect on the marker";
  }
  o << "; explained " << fmt("%.6f", explained);
  if (!exact && std::isfinite(stddev_if_free)) {
    o << ", std if estimated " << fmt("%.3g", to_display(held, stddev_if_free)) << " "
      << display_unit(held);
  }
  return o.str();
}

Report calibrate(const NominalModel& model, const std::vector<AlignedSample>& points,
                 const Bounds& bounds, const SolveOptions& options, const EncoderSeries* encoders) {
  auto say = [&](const std::string& s) {
    if (options.progress) options.progress(s);
  };
  const auto& idopt = bounds.identifiability;
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

  Problem P;
  P.loss = make_loss(options);
  for (const auto& s : points) {
    MarkerCost c{&model, s.theta_r, Eigen::Vector3d(s.marker[0], s.marker[1], s.marker[2])};
    if (tau_free) {
      c.enc = &encoders->samples;
      c.t_us = s.utime_us;
      c.index = s.encoder_index;
    }
    P.costs.push_back(std::make_unique<MarkerCostFunction>(new MarkerCost(c)));
  }

  Report rep;
  rep.points = points.size();
  rep.residuals = 3 * points.size();
  ParamVector x0 = initial_params(bounds);
  ParamVector x = x0;
  double tau = bounds.time_offset.initial_s;

  rep.before = evaluate(model, x0, points, &rep.residual_before);
  say("before calibration: RMS " + fmt("%.3f", rep.before.rms_m * kMToMm) + " mm over " +
      std::to_string(points.size()) + " points");

  std::array<bool, kParams> free{};
  for (int p = 0; p < kParams; ++p) free[p] = !bounds.params[p].fixed;
  std::array<bool, kParams> held{};

  // Stage 1: everything the bounds file leaves free.
  {
    auto problem = build(P, x.data(), &tau, free, tau_free, bounds);
    const auto s = run(*problem, options, rep.residuals, "all free");
    rep.iterations += static_cast<int>(s.iterations.size());
  }

  // Stage 2..: find the directions the data cannot see, hold them, re-solve.
  // Columns are added to the kept set from the end of eq. (6) to the front
  // (camera, marker, DH deviations, then encoder offsets), so where two
  // parameters cannot be told apart the encoder offset is the one held.
  for (int round = 0; round < 3; ++round) {
    Eigen::VectorXd r;
    const Eigen::MatrixXd J = full_jacobian(P, x.data(), &tau, &r);
    int nfree = tau_free ? 1 : 0;
    for (int p = 0; p < kParams; ++p) nfree += free[p] ? 1 : 0;
    const double sigma_mm =
        std::max(residual_sigma_mm(r, static_cast<std::size_t>(nfree), P.loss != nullptr),
                 idopt.noise_floor_m * kMToMm);
    std::vector<int> kept;
    if (tau_free) kept.push_back(kTau);
    std::vector<int> newly;
    for (int p = kParams - 1; p >= 0; --p) {
      if (!free[p]) continue;
      const double sd = std_given(J, kept, p, sigma_mm);
      if (sd > tolerance(idopt, p)) {
        newly.push_back(p);
      } else {
        kept.push_back(p);
      }
    }
    // Fallback: the whole kept set must be well conditioned too.
    for (;;) {
      const Eigen::MatrixXd K = columns(J, kept);
      Eigen::MatrixXd Ks = K;
      for (Eigen::Index k = 0; k < Ks.cols(); ++k) Ks.col(k) *= tolerance(idopt, kept[k]);
      Eigen::JacobiSVD<Eigen::MatrixXd> svd(Ks, Eigen::ComputeThinV);
      const auto& sv = svd.singularValues();
      const Eigen::Index last = sv.size() - 1;
      if (last < 0 || sigma_mm / std::max(sv[last], 1e-300) <= 1.0) break;
      const Eigen::VectorXd v = svd.matrixV().col(last);
      const double vmax = v.cwiseAbs().maxCoeff();
      int pick = -1;  // earliest in eq. (6) order with a significant share
      for (Eigen::Index k = 0; k < v.size(); ++k) {
        if (kept[k] != kTau && std::abs(v[k]) >= 0.3 * vmax && (pick < 0 || kept[k] < pick)) {
          pick = kept[k];
        }
      }
      if (pick < 0) break;
      newly.push_back(pick);
      kept.erase(std::find(kept.begin(), kept.end(), pick));
    }
    if (newly.empty()) break;
    std::string names;
    for (int p : newly) {
      names += std::string(names.empty() ? "" : ", ") + param_label(p);
      free[p] = false;
      held[p] = true;
      x[p] = x0[p];
    }
    say("unidentifiable from these data: " + names + " (held at prior values, re-solving)");
    auto problem = build(P, x.data(), &tau, free, tau_free, bounds);
    const auto s = run(*problem, options, rep.residuals, "gauge fixed");
    rep.iterations += static_cast<int>(s.iterations.size());
    rep.termination = s.BriefReport();
  }
  if (rep.termination.empty()) rep.termination = "converged after the first stage";

  // Active bounds.
  std::array<bool, kParams> at_bound{};
  for (int p = 0; p < kParams; ++p) {
    if (!free[p]) continue;
    const auto& b = bounds.params[p];
    const double eps = 1e-7 * (b.upper - b.lower);
    at_bound[p] = x[p] <= b.lower + eps || x[p] >= b.upper - eps;
  }

  // Final statistics (from the cost functions, so an estimated time offset counts).
  {
    Eigen::VectorXd raw;
    full_jacobian(P, x.data(), &tau, &raw);
    rep.residual_after.clear();
    for (Eigen::Index i = 0; i + 2 < raw.size(); i += 3) {
      rep.residual_after.push_back(raw.segment<3>(i) / kMToMm);
    }
    rep.after = error_stats(rep.residual_after);
  }
  std::vector<int> est;  // estimated columns: free and not on a bound
  for (int p = 0; p < kParams; ++p) {
    if (free[p] && !at_bound[p]) est.push_back(p);
  }
  if (tau_free) est.push_back(kTau);
  rep.free_params = est.size();
  Eigen::VectorXd r;
  const Eigen::MatrixXd J = full_jacobian(P, x.data(), &tau, &r);
  const double sigma_mm = residual_sigma_mm(r, est.size(), P.loss != nullptr);
  rep.sigma_m = sigma_mm / kMToMm;

  // Covariance of the estimated parameters with ceres::Covariance on the
  // identifiable subspace (held, fixed and at-bound coordinates constant).
  Eigen::MatrixXd cov = Eigen::MatrixXd::Zero(kParams + 1, kParams + 1);
  {
    std::array<bool, kParams> cov_free{};
    for (int p = 0; p < kParams; ++p) cov_free[p] = free[p] && !at_bound[p];
    auto problem = build(P, x.data(), &tau, cov_free, tau_free, bounds);
    ceres::Covariance::Options co;
    co.algorithm_type = ceres::DENSE_SVD;
    co.null_space_rank = -1;
    co.min_reciprocal_condition_number = 1e-14;
    ceres::Covariance covariance(co);
    std::vector<std::pair<const double*, const double*>> blocks = {{x.data(), x.data()}};
    if (tau_free) {
      blocks.push_back({x.data(), &tau});
      blocks.push_back({&tau, &tau});
    }
    bool ok = std::any_of(cov_free.begin(), cov_free.end(), [](bool b) { return b; }) &&
              covariance.Compute(blocks, problem.get());
    if (ok) {
      Eigen::Matrix<double, kParams, kParams, Eigen::RowMajor> cxx;
      covariance.GetCovarianceBlock(x.data(), x.data(), cxx.data());
      cov.topLeftCorner(kParams, kParams) = cxx;
      if (tau_free) {
        Eigen::Matrix<double, kParams, 1> cxt;
        double ctt = 0;
        covariance.GetCovarianceBlock(x.data(), &tau, cxt.data());
        covariance.GetCovarianceBlock(&tau, &tau, &ctt);
        cov.block(0, kParams, kParams, 1) = cxt;
        cov.block(kParams, 0, 1, kParams) = cxt.transpose();
        cov(kParams, kParams) = ctt;
      }
    } else {
      // Dense fallback on the same columns.
      const Eigen::MatrixXd K = columns(J, est);
      const Eigen::MatrixXd C =
          (K.transpose() * K).completeOrthogonalDecomposition().pseudoInverse();
      for (std::size_t a = 0; a < est.size(); ++a) {
        for (std::size_t b = 0; b < est.size(); ++b) cov(est[a], est[b]) = C(a, b);
      }
      say("note: ceres::Covariance failed; covariance from the pseudo-inverse");
    }
    cov *= sigma_mm * sigma_mm;  // Ceres assumes unit-variance residuals
  }

  {
    Eigen::MatrixXd K = columns(J, est);
    for (Eigen::Index k = 0; k < K.cols(); ++k) K.col(k) *= tolerance(idopt, est[k]);
    Eigen::JacobiSVD<Eigen::MatrixXd> svd(K);
    rep.singular_values.assign(svd.singularValues().data(),
                               svd.singularValues().data() + svd.singularValues().size());
  }

  for (int p = 0; p < kParams; ++p) {
    ParamResult& pr = rep.params[p];
    pr.initial = x0[p];
    pr.estimate = x[p];
    if (bounds.params[p].fixed) {
      pr.status = ParamStatus::kFixed;
    } else if (held[p]) {
      pr.status = ParamStatus::kHeld;
    } else if (at_bound[p]) {
      pr.status = ParamStatus::kAtBound;
      pr.note =
          x[p] <= bounds.params[p].lower + 1e-12 ? "on its lower bound" : "on its upper bound";
    } else {
      pr.status = ParamStatus::kIdentified;
      pr.stddev = std::sqrt(std::max(cov(p, p), 0.0));
    }
  }
  if (tau_free) {
    rep.time_offset_s = tau;
    rep.time_offset_std_s = std::sqrt(std::max(cov(kParams, kParams), 0.0));
  }

  // Degeneracies: what the estimated parameters make of each held one.
  {
    const Eigen::MatrixXd K = columns(J, est);
    const auto qr = K.colPivHouseholderQr();
    for (int h = 0; h < kParams; ++h) {
      if (!held[h]) continue;
      Degeneracy d;
      d.held = h;
      const Eigen::VectorXd c = J.col(h);
      const double cn = c.norm();
      Eigen::VectorXd beta = Eigen::VectorXd::Zero(K.cols());
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
      // Free parameters whose estimate follows the held prior.
      const double probe =
          idopt.gauge_probe_fraction * (bounds.params[h].upper - bounds.params[h].lower);
      for (Eigen::Index k = 0; k < K.cols(); ++k) {
        const int j = est[k];
        if (j == kTau || cn == 0) continue;
        ParamResult& pr = rep.params[j];
        const double shift = std::abs(beta[k]) * probe;  // SI
        if (pr.stddev > 0 && shift > pr.stddev) {
          pr.status = ParamStatus::kGaugeDependent;
          const double s = to_display(j, -beta[k]) / to_display(h, 1.0);
          pr.note += std::string(pr.note.empty() ? "" : "; ") + "follows held " + param_label(h) +
                     " (" + fmt("%+.4g", s) + " " + display_unit(j) + "/" + display_unit(h) + ")";
        }
      }
      rep.params[h].note = d.exact ? "exactly unobservable" : "nearly unobservable";
      if (!d.exact && std::isfinite(d.stddev_if_free)) {
        rep.params[h].note += ", std if estimated " + fmt("%.3g", to_display(h, d.stddev_if_free)) +
                              " " + display_unit(h);
      }
      rep.degeneracies.push_back(d);
    }
  }

  // Correlations among estimated parameters.
  for (std::size_t a = 0; a < est.size(); ++a) {
    for (std::size_t b = a + 1; b < est.size(); ++b) {
      const double va = cov(est[a], est[a]), vb = cov(est[b], est[b]);
      if (va <= 0 || vb <= 0) continue;
      const double rr = cov(est[a], est[b]) / std::sqrt(va * vb);
      if (std::abs(rr) > idopt.correlation_threshold)
        rep.correlations.push_back({est[a], est[b], rr});
    }
  }
  say("after calibration: RMS " + fmt("%.3f", rep.after.rms_m * kMToMm) + " mm");
  return rep;
}

}  // namespace exodaq::calibration
