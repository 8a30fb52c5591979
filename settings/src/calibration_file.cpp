#include "exodaq/settings/calibration_file.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "exodaq/common/files.hpp"
#include "exodaq/common/yaml_reader.hpp"

namespace exodaq::settings {

namespace {

constexpr double kMmToM = 1e-3;

Calibration parse(const YAML::Node& root, const std::string& file) {
  MapReader top(file, root, "calibration");
  Calibration cal;

  const YAML::Node format = top.child("format");
  if (!format.IsScalar() || format.Scalar() != kCalibrationFormat) {
    top.fail(format, std::string("'format' must be '") + kCalibrationFormat + "', found '" +
                         (format.IsScalar() ? format.Scalar() : std::string("not a string")) + "'");
  }

  const auto offsets_deg = top.numbers_fixed<kCalibrationJoints>("encoder_offsets_deg");
  for (int i = 0; i < kCalibrationJoints; ++i)
    cal.encoder_offset_rad[i] = offsets_deg[i] * kDegToRad;

  {
    MapReader dh = top.map("dh_deviations_mm");
    cal.dh.d2 = dh.number("d2") * kMmToM;
    cal.dh.d3 = dh.number("d3") * kMmToM;
    cal.dh.d5 = dh.number("d5") * kMmToM;
    cal.dh.a3 = dh.number("a3") * kMmToM;
    cal.dh.a5 = dh.number("a5") * kMmToM;
    dh.finish();
  }

  const auto marker_mm = top.numbers_fixed<3>("marker_offset_mm");
  for (int i = 0; i < 3; ++i) cal.marker_offset_m[i] = marker_mm[i] * kMmToM;

  if (auto cam = top.optional_map("camera")) {
    CameraTransform c;
    const auto t_mm = cam->numbers_fixed<3>("translation_mm");
    const auto e_deg = cam->numbers_fixed<3>("euler_xyz_deg");
    for (int i = 0; i < 3; ++i) {
      c.translation_m[i] = t_mm[i] * kMmToM;
      c.euler_xyz_rad[i] = e_deg[i] * kDegToRad;
    }
    cam->finish();
    cal.camera = c;
  }

  if (auto prov = top.optional_map("provenance")) {
    CalibrationProvenance& p = cal.provenance;
    p.created_by = prov->string_or("created_by", "");
    p.date = prov->string_or("date", "");
    p.model = prov->string_or("model", "");
    p.notes = prov->string_or("notes", "");
    if (auto inputs = prov->optional_child("inputs")) {
      if (!inputs->IsSequence()) prov->fail(*inputs, "'inputs' must be a list of strings");
      for (std::size_t i = 0; i < inputs->size(); ++i) {
        p.inputs.push_back(prov->to_string((*inputs)[i], "inputs[" + std::to_string(i) + "]"));
      }
    }
    if (prov->has("rms_before_mm")) p.rms_before_m = prov->number("rms_before_mm") * kMmToM;
    if (prov->has("rms_after_mm")) p.rms_after_m = prov->number("rms_after_mm") * kMmToM;
    if (prov->has("samples")) {
      const auto n = prov->integer("samples");
      if (n < 0) prov->fail_key("samples", "'samples' must not be negative");
      if (n > std::numeric_limits<int>::max()) {
        prov->fail_key("samples", "'samples' must be at most " +
                                      std::to_string(std::numeric_limits<int>::max()));
      }
      p.samples = static_cast<int>(n);
    }
    prov->allow("rms_before_mm");
    prov->allow("rms_after_mm");
    prov->allow("samples");
    prov->finish();
  }
  top.finish();
  return cal;
}

// Shortest text that reads back as the same double.
std::string num(double v) {
  if (v == 0.0) return "0";  // also turns -0 into 0
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (const char ch : s) {
    switch (ch) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\t':
        out += "\\t";
        break;
      case '\r':
        out += "\\r";
        break;
      default:
        if (static_cast<unsigned char>(ch) < 0x20) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\x%02x", static_cast<unsigned>(ch));
          out += buf;
        } else {
          out += ch;
        }
    }
  }
  return out + "\"";
}

template <std::size_t N>
std::string list(const std::array<double, N>& v, double scale) {
  std::string s = "[";
  for (std::size_t i = 0; i < N; ++i) s += (i ? ", " : "") + num(v[i] * scale);
  return s + "]";
}

}  // namespace

Calibration load_calibration_text(const std::string& text, const std::string& name) {
  return parse(load_yaml_text(text, name), name);
}

Calibration load_calibration_file(const std::string& path) {
  return parse(load_yaml_file(path), path);
}

std::string calibration_to_yaml(const Calibration& cal) {
  constexpr double kRadToDeg = 1.0 / kDegToRad;
  constexpr double kMToMm = 1e3;
  std::ostringstream o;
  o << "# exodaq kinematic calibration (docs/calibration.md). Angles in degrees, lengths in mm.\n"
       "# theta = encoder_offset + theta_R (seed 000 eq. 4); DH deviations add to the model's\n"
       "# d/a of joints 2, 3, 5 (1-based); marker_offset is in frame 6 and adds to the tool.\n";
  o << "format: " << kCalibrationFormat << "\n";
  o << "encoder_offsets_deg: " << list(cal.encoder_offset_rad, kRadToDeg) << "\n";
  o << "dh_deviations_mm:\n";
  o << "  d2: " << num(cal.dh.d2 * kMToMm) << "\n";
  o << "  d3: " << num(cal.dh.d3 * kMToMm) << "\n";
  o << "  d5: " << num(cal.dh.d5 * kMToMm) << "\n";
  o << "  a3: " << num(cal.dh.a3 * kMToMm) << "\n";
  o << "  a5: " << num(cal.dh.a5 * kMToMm) << "\n";
  o << "marker_offset_mm: " << list(cal.marker_offset_m, kMToMm) << "\n";
  if (cal.camera) {
    o << "# p_cam = translation + Rx(x) Ry(y) Rz(z) p_exo (intrinsic x-y'-z''); not used by the "
         "daemon.\n";
    o << "camera:\n";
    o << "  translation_mm: " << list(cal.camera->translation_m, kMToMm) << "\n";
    o << "  euler_xyz_deg: " << list(cal.camera->euler_xyz_rad, kRadToDeg) << "\n";
  }
  const CalibrationProvenance& p = cal.provenance;
  o << "provenance:\n";
  o << "  created_by: " << quoted(p.created_by) << "\n";
  o << "  date: " << quoted(p.date) << "\n";
  o << "  model: " << quoted(p.model) << "\n";
  o << "  inputs: [";
  for (std::size_t i = 0; i < p.inputs.size(); ++i) o << (i ? ", " : "") << quoted(p.inputs[i]);
  o << "]\n";
  if (p.rms_before_m) o << "  rms_before_mm: " << num(*p.rms_before_m * kMToMm) << "\n";
  if (p.rms_after_m) o << "  rms_after_mm: " << num(*p.rms_after_m * kMToMm) << "\n";
  if (p.samples) o << "  samples: " << *p.samples << "\n";
  o << "  notes: " << quoted(p.notes) << "\n";
  return o.str();
}

void write_calibration_file(const std::string& path, const Calibration& cal,
                            const std::vector<std::string>& inputs) {
  files::OutputOptions o;
  o.inputs = inputs;
  try {
    files::write_output(path, calibration_to_yaml(cal), o);
  } catch (const files::FileError& e) {
    throw ConfigError(path, 0, e.reason());
  }
}

kinematics::Chain apply_calibration(const kinematics::Chain& nominal, const Calibration& cal) {
  if (nominal.convention() != kinematics::Convention::kStandardDh) {
    throw std::invalid_argument(
        "apply_calibration: the calibration's DH deviations (seed 000 Δζ) are defined for a "
        "standard-DH chain; this model uses another convention");
  }
  if (nominal.joint_count() != kCalibrationJoints) {
    throw std::invalid_argument(
        "apply_calibration: the calibration is for a " + std::to_string(kCalibrationJoints) +
        "-joint chain, the model has " + std::to_string(nominal.joint_count()) + " joints");
  }
  std::vector<kinematics::JointDescription> joints = nominal.joints();
  joints[1].dh.d += cal.dh.d2;
  joints[2].dh.d += cal.dh.d3;
  joints[4].dh.d += cal.dh.d5;
  joints[2].dh.a += cal.dh.a3;
  joints[4].dh.a += cal.dh.a5;
  kinematics::Pose tool = nominal.tool();
  tool.translation() +=
      Eigen::Vector3d(cal.marker_offset_m[0], cal.marker_offset_m[1], cal.marker_offset_m[2]);
  return kinematics::Chain(kinematics::Convention::kStandardDh, std::move(joints), nominal.base(),
                           tool);
}

}  // namespace exodaq::settings
