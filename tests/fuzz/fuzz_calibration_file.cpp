// Fuzz target calibration_file: load_calibration_text() on any text.
// Documented behaviour (calibration_file.hpp, docs/calibration.md): a
// Calibration or a ConfigError "file:line: what". What it accepts survives
// calibration_to_yaml() and back (to an ulp:
// the file is in degrees and millimetres), and applies to the nominal chain.
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>

#include "exodaq/settings/calibration_file.hpp"
#include "exodaq/settings/model_file.hpp"
#include "fuzz_input.hpp"

namespace settings = exodaq::settings;

namespace {

// The file holds degrees and millimetres with 17 significant digits, memory
// radians and metres: the unit conversion each way may move a value by an ulp.
bool close(double x, double y) {
  const double scale = std::max(std::fabs(x), std::fabs(y));
  return std::fabs(x - y) <= 4 * std::numeric_limits<double>::epsilon() * scale + 1e-300;
}

bool same(const settings::Calibration& a, const settings::Calibration& b) {
  const auto eq = [](double x, double y) { return close(x, y); };
  const auto eq_opt = [](const std::optional<double>& x, const std::optional<double>& y) {
    return x.has_value() == y.has_value() && (!x || close(*x, *y));
  };
  for (std::size_t i = 0; i < a.encoder_offset_rad.size(); ++i) {
    if (!eq(a.encoder_offset_rad[i], b.encoder_offset_rad[i])) return false;
  }
  for (std::size_t i = 0; i < 3; ++i) {
    if (!eq(a.marker_offset_m[i], b.marker_offset_m[i])) return false;
  }
  if (!eq(a.dh.d2, b.dh.d2) || !eq(a.dh.d3, b.dh.d3) || !eq(a.dh.d5, b.dh.d5) ||
      !eq(a.dh.a3, b.dh.a3) || !eq(a.dh.a5, b.dh.a5)) {
    return false;
  }
  if (a.camera.has_value() != b.camera.has_value()) return false;
  if (a.camera) {
    for (std::size_t i = 0; i < 3; ++i) {
      if (!eq(a.camera->translation_m[i], b.camera->translation_m[i]) ||
          !eq(a.camera->euler_xyz_rad[i], b.camera->euler_xyz_rad[i])) {
        return false;
      }
    }
  }
  return a.provenance.created_by == b.provenance.created_by &&
         a.provenance.date == b.provenance.date && a.provenance.model == b.provenance.model &&
         a.provenance.inputs == b.provenance.inputs && a.provenance.notes == b.provenance.notes &&
         a.provenance.samples == b.provenance.samples &&
         eq_opt(a.provenance.rms_before_m, b.provenance.rms_before_m) &&
         eq_opt(a.provenance.rms_after_m, b.provenance.rms_after_m);
}

const exodaq::kinematics::Chain& nominal() {
  static const settings::KinematicModel m =
      settings::load_model_file(std::string(EXODAQ_SOURCE_DIR) + "/config/models/macaque_exo.yaml");
  return m.chain;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 16384) return 0;
  settings::Calibration cal;
  try {
    cal = settings::load_calibration_text(exodaq::fuzz::as_text(data, size), "fuzz.yaml");
  } catch (const exodaq::ConfigError& e) {
    FUZZ_CHECK(e.file() == "fuzz.yaml");
    FUZZ_CHECK(e.line() >= 0);
    return 0;
  }
  const std::string text = settings::calibration_to_yaml(cal);
  settings::Calibration again;
  try {
    again = settings::load_calibration_text(text, "written.yaml");
  } catch (const exodaq::ConfigError& e) {
    std::fprintf(stderr, "calibration_to_yaml() wrote what the loader rejects: %s\n---\n%s---\n",
                 e.what(), text.c_str());
    FUZZ_CHECK(false);
  }
  FUZZ_CHECK(same(cal, again));
  (void)settings::apply_calibration(nominal(), cal);
  return 0;
}
