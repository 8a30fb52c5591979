// The 20 parameters of seed 000 eq. (6): names, units, the bounds file, and
// the conversions to and from the calibration file the daemon reads.
#include <stdexcept>

#include "detail.hpp"
#include "exodaq/calibration/solver.hpp"
#include "exodaq/common/yaml_reader.hpp"

namespace exodaq::calibration {

using detail::fmt;
using detail::kDegToRad;
using detail::kMToMm;
using detail::kRadToDeg;

namespace {

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

// lower/upper may be omitted for a fixed parameter.
void read_range(exodaq::MapReader& m, int p, bool fixed, double init, double& lo, double& hi) {
  lo = init;
  hi = init;
  if (!fixed || m.has("lower") || m.has("upper")) {
    lo = m.number("lower");
    hi = m.number("upper");
  }
  if (!(lo <= init && init <= hi)) {
    m.fail(m.node()["initial"],
           std::string("'") + kInfo[p].key + "': initial must lie within [lower, upper], found " +
               fmt("%g", init) + " not in [" + fmt("%g", lo) + ", " + fmt("%g", hi) + "]");
  }
  if (!fixed && !(lo < hi)) {
    m.fail(m.node()["lower"],
           std::string("'") + kInfo[p].key + "': lower must be below upper (or set fixed: true)");
  }
}

ParamPrior read_prior(exodaq::MapReader& parent, int p) {
  exodaq::MapReader m = parent.map(kInfo[p].key);
  ParamPrior pr;
  pr.fixed = m.boolean_or("fixed", false);
  const double init = m.number("initial");
  double lo = 0, hi = 0;
  read_range(m, p, pr.fixed, init, lo, hi);
  m.finish();
  pr.initial = from_display(p, init);
  pr.lower = from_display(p, lo);
  pr.upper = from_display(p, hi);
  return pr;
}

void read_time_offset(exodaq::MapReader& t, TimeOffsetPrior& o) {
  o.initial_s = t.number("initial") * 1e-3;
  o.lower_s = t.number("lower") * 1e-3;
  o.upper_s = t.number("upper") * 1e-3;
  if (!(o.lower_s <= o.initial_s && o.initial_s <= o.upper_s && o.lower_s < o.upper_s)) {
    t.fail(t.node(), "time_offset_ms: need lower <= initial <= upper and lower < upper");
  }
  t.finish();
}

void read_identifiability(exodaq::MapReader& id, IdentifiabilityOptions& o) {
  o.max_std_angle_rad = id.number_or("max_std_deg", o.max_std_angle_rad * kRadToDeg) * kDegToRad;
  o.max_std_length_m = id.number_or("max_std_mm", o.max_std_length_m * kMToMm) / kMToMm;
  o.noise_floor_m = id.number_or("noise_floor_mm", o.noise_floor_m * kMToMm) / kMToMm;
  o.correlation_threshold = id.number_or("correlation_threshold", o.correlation_threshold);
  o.gauge_probe_fraction = id.number_or("gauge_probe_fraction", o.gauge_probe_fraction);
  if (o.max_std_angle_rad <= 0 || o.max_std_length_m <= 0 || o.noise_floor_m < 0) {
    id.fail(id.node(), "identifiability: max_std_* must be positive, noise_floor_mm >= 0");
  }
  id.finish();
}

Bounds parse_bounds(const YAML::Node& root, const std::string& file) {
  exodaq::MapReader top(file, root, "bounds");
  Bounds b;
  b.source = file;
  const YAML::Node format = top.child("format");
  if (!format.IsScalar() || format.Scalar() != "exodaq-calibration-bounds-1") {
    top.fail(format, "'format' must be 'exodaq-calibration-bounds-1'");
  }
  exodaq::MapReader params = top.map("parameters");
  for (int p = 0; p < kParams; ++p) b.params[p] = read_prior(params, p);
  params.finish();
  if (auto t = top.optional_map("time_offset_ms")) read_time_offset(*t, b.time_offset);
  if (auto id = top.optional_map("identifiability")) read_identifiability(*id, b.identifiability);
  top.finish();
  return b;
}

}  // namespace

bool is_angle(int p) noexcept {
  return p >= 0 && p < kParams && kInfo[p].angle;
}
const char* param_key(int p) noexcept {
  return kInfo[p].key;
}
const char* param_label(int p) noexcept {
  return p == detail::kTau ? "τ" : kInfo[p].label;
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

NominalModel nominal_from_chain(const kinematics::Chain& chain) {
  if (chain.convention() != kinematics::Convention::kStandardDh || chain.joint_count() != 6) {
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

Bounds load_bounds_file(const std::string& path) {
  return parse_bounds(exodaq::load_yaml_file(path), path);
}
Bounds load_bounds_text(const std::string& text, const std::string& name) {
  return parse_bounds(exodaq::load_yaml_text(text, name), name);
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

settings::Calibration to_calibration(const ParamVector& x) {
  settings::Calibration c;
  for (int j = 0; j < 6; ++j) c.encoder_offset_rad[j] = x[kTheta1 + j];
  c.dh = {x[kDd2], x[kDd3], x[kDd5], x[kDa3], x[kDa5]};
  c.marker_offset_m = {x[kPx], x[kPy], x[kPz]};
  settings::CameraTransform cam;
  cam.translation_m = {x[kDx], x[kDy], x[kDz]};
  cam.euler_xyz_rad = {x[kPhiX], x[kPhiY], x[kPhiZ]};
  c.camera = cam;
  return c;
}

ParamVector from_calibration(const settings::Calibration& c) {
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

}  // namespace exodaq::calibration
