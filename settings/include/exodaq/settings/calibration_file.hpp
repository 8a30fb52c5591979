#pragma once
// The calibration file: what `exodaq calibrate` writes and the daemon reads
// (docs/calibration.md). Seed 000 §4: encoder offsets Δθ⁰ (eq. 4), the DH
// deviations Δζ = (Δd2, Δd3, Δd5, Δa3, Δa5), the marker offset Δpᴹ in frame 6
// and, for the record, the camera-to-exoskeleton transform (d, φ).
//
// In memory everything is SI (rad, m); in the file angles are degrees and
// lengths millimetres, and every key says its unit.
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "exodaq/kinematics/chain.hpp"
#include "exodaq/wire_constants.hpp"

namespace exodaq::settings {

// The calibration is one encoder offset per joint of the published messages.
inline constexpr int kCalibrationJoints = wire::kJointCount;
inline constexpr const char* kCalibrationFormat = "exodaq-calibration-1";

// Deviations of the nominal DH table (seed 000 Δζ), metres. Joint numbers are
// 1-based as in the paper: d2 is joint 2's d, a3 joint 3's a, ...
struct DhDeviations {
  double d2 = 0.0;
  double d3 = 0.0;
  double d5 = 0.0;
  double a3 = 0.0;
  double a5 = 0.0;
};

// Camera (motion-capture) frame from the exoskeleton base frame O0:
//   p_cam = translation + R(euler) * p_exo,  R = Rx(φx) · Ry(φy) · Rz(φz)
// i.e. intrinsic rotations x, then y', then z'' (equivalently extrinsic z, y, x).
// With seed 000 Table 4 (φ = (-89.01, -0.10, -135.52) deg) this puts z0 (joint
// 1's axis, up) along the camera's +y (the usual "Y up" of motion capture) and
// O0 at 849 mm above the camera origin. Not used by the daemon.
struct CameraTransform {
  std::array<double, 3> translation_m{};  // d
  std::array<double, 3> euler_xyz_rad{};  // φ = (φx, φy, φz)
};

struct CalibrationProvenance {
  std::string created_by;           // tool and version
  std::string date;                 // ISO 8601
  std::string model;                // model file the calibration was made against
  std::vector<std::string> inputs;  // encoder log(s), mocap file(s)
  std::optional<double> rms_before_m;
  std::optional<double> rms_after_m;
  std::optional<int> samples;
  std::string notes;  // free text: held (unidentifiable) parameters, robust loss, ...
};

struct Calibration {
  // Δθ⁰: the joint angle at the encoder's index, θ = Δθ⁰ + θᴿ (seed 000 eq. 4). rad.
  std::array<double, kCalibrationJoints> encoder_offset_rad{};
  DhDeviations dh;                          // m
  std::array<double, 3> marker_offset_m{};  // Δpᴹ in frame 6 (added to the tool translation)
  std::optional<CameraTransform> camera;
  CalibrationProvenance provenance;
};

// Strict readers: every error is a ConfigError "file:line: what" (unknown key,
// missing field, wrong list length, non-finite number, wrong format tag).
Calibration load_calibration_file(const std::string& path);
Calibration load_calibration_text(const std::string& text, const std::string& name);

// The exact text load_calibration_text() reads back (numbers with enough digits
// to round-trip doubles).
std::string calibration_to_yaml(const Calibration& cal);
// Writes calibration_to_yaml() to `path` as a files::OutputFile (a temporary
// file beside it, fsync'ed and renamed: a running daemon never sees half a
// file; a symlink is followed; `inputs` are never replaced). Throws
// ConfigError "path: what" with errno's reason when it cannot.
void write_calibration_file(const std::string& path, const Calibration& cal,
                            const std::vector<std::string>& inputs = {});

// The nominal chain with Δζ and Δpᴹ applied: joints 2, 3, 5 (1-based) get
// Δd2, Δd3, Δd5 added to dh.d, joints 3 and 5 Δa3, Δa5 added to dh.a, and the
// tool translation gets Δpᴹ (frame 6 coordinates). Standard DH, six joints
// only; throws std::invalid_argument otherwise. Encoder offsets are not part
// of the chain: the daemon's homing applies them.
kinematics::Chain apply_calibration(const kinematics::Chain& nominal, const Calibration& cal);

}  // namespace exodaq::settings
