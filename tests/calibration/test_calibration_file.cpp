// The calibration file: round trip, exact error messages, shipped files,
// apply_calibration.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/settings/calibration_file.hpp"

namespace {

using exodaq::ConfigError;
using exodaq::settings::Calibration;
using exodaq::settings::load_calibration_text;
namespace kinematics = exodaq::kinematics;

constexpr double kDeg = 0.017453292519943295;

const std::string kGood =
    "format: exodaq-calibration-1\n"                                         // 1
    "encoder_offsets_deg: [31.85, -17.60, -13.45, -17.19, -22.11, -2.39]\n"  // 2
    "dh_deviations_mm:\n"                                                    // 3
    "  d2: -1.79\n"                                                          // 4
    "  d3: -0.48\n"                                                          // 5
    "  d5: 2.80\n"                                                           // 6
    "  a3: -4.01\n"                                                          // 7
    "  a5: 0.03\n"                                                           // 8
    "marker_offset_mm: [-0.10, -0.16, -8.46]\n";                             // 9

std::string error_of(const std::string& text) {
  try {
    load_calibration_text(text, "cal.yaml");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "no error";
}

std::string replace(std::string s, const std::string& a, const std::string& b) {
  const auto p = s.find(a);
  EXPECT_NE(p, std::string::npos) << a;
  return s.replace(p, a.size(), b);
}

TEST(CalibrationFile, ReadsUnitsIntoSi) {
  const Calibration c = load_calibration_text(kGood, "cal.yaml");
  EXPECT_NEAR(c.encoder_offset_rad[0], 31.85 * kDeg, 1e-15);
  EXPECT_NEAR(c.encoder_offset_rad[5], -2.39 * kDeg, 1e-15);
  EXPECT_NEAR(c.dh.d2, -1.79e-3, 1e-15);
  EXPECT_NEAR(c.dh.a3, -4.01e-3, 1e-15);
  EXPECT_NEAR(c.dh.a5, 0.03e-3, 1e-15);
  EXPECT_NEAR(c.marker_offset_m[2], -8.46e-3, 1e-15);
  EXPECT_FALSE(c.camera.has_value());
}

TEST(CalibrationFile, RoundTrip) {
  Calibration c;
  for (int i = 0; i < 6; ++i) c.encoder_offset_rad[i] = 0.1 * i - 0.234567891234;
  c.dh = {1e-3, -2.5e-4, 3.3e-3, -4.01e-3, 1.2345678e-5};
  c.marker_offset_m = {-1e-4, 2e-4, -8.46e-3};
  c.camera = exodaq::settings::CameraTransform{{0.20329, 0.84931, 0.2243}, {-1.5, 0.01, -2.3}};
  c.provenance.created_by = "exodaq calibrate 0.1.0";
  c.provenance.date = "2024-05-01T12:00:00Z";
  c.provenance.model = "config/models/macaque_exo.yaml";
  c.provenance.inputs = {"enc \"1\".csv", "mocap\\x.csv"};
  c.provenance.rms_before_m = 13.6e-3;
  c.provenance.rms_after_m = 0.52e-3;
  c.provenance.samples = 400;
  c.provenance.notes = "held: dtheta1\nsecond line";
  const std::string path = ::testing::TempDir() + "/roundtrip_cal.yaml";
  exodaq::settings::write_calibration_file(path, c);
  const Calibration r = exodaq::settings::load_calibration_file(path);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(r.encoder_offset_rad[i], c.encoder_offset_rad[i], 1e-15);
  EXPECT_NEAR(r.dh.d2, c.dh.d2, 1e-18);
  EXPECT_NEAR(r.dh.d3, c.dh.d3, 1e-18);
  EXPECT_NEAR(r.dh.d5, c.dh.d5, 1e-18);
  EXPECT_NEAR(r.dh.a3, c.dh.a3, 1e-18);
  EXPECT_NEAR(r.dh.a5, c.dh.a5, 1e-18);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(r.marker_offset_m[i], c.marker_offset_m[i], 1e-18);
    EXPECT_NEAR(r.camera->translation_m[i], c.camera->translation_m[i], 1e-15);
    EXPECT_NEAR(r.camera->euler_xyz_rad[i], c.camera->euler_xyz_rad[i], 1e-15);
  }
  EXPECT_EQ(r.provenance.created_by, c.provenance.created_by);
  EXPECT_EQ(r.provenance.date, c.provenance.date);
  EXPECT_EQ(r.provenance.model, c.provenance.model);
  EXPECT_EQ(r.provenance.inputs, c.provenance.inputs);
  EXPECT_NEAR(*r.provenance.rms_before_m, 13.6e-3, 1e-15);
  EXPECT_NEAR(*r.provenance.rms_after_m, 0.52e-3, 1e-15);
  EXPECT_EQ(*r.provenance.samples, 400);
  EXPECT_EQ(r.provenance.notes, c.provenance.notes);
  // Read -> write -> read is stable (mm <-> m may move the last bit once).
  const Calibration r2 = load_calibration_text(exodaq::settings::calibration_to_yaml(r), "again");
  EXPECT_EQ(exodaq::settings::calibration_to_yaml(r2).size(),
            exodaq::settings::calibration_to_yaml(r).size());
  EXPECT_NEAR(r2.camera->translation_m[1], c.camera->translation_m[1], 1e-15);
  std::remove(path.c_str());
}

TEST(CalibrationFile, ErrorMessagesAreExact) {
  EXPECT_EQ(error_of(replace(kGood, "-2.39]", "]")),
            "cal.yaml:2: 'encoder_offsets_deg' must have 6 numbers, has 5");
  EXPECT_EQ(error_of(replace(kGood, "-17.19", ".nan")),
            "cal.yaml:2: 'encoder_offsets_deg[3]' must be a finite number, found '.nan'");
  EXPECT_EQ(error_of(replace(kGood, "  a5: 0.03\n", "")),
            "cal.yaml:4: missing field 'a5' in calibration.dh_deviations_mm");
  EXPECT_EQ(error_of(replace(kGood, "  a5: 0.03\n", "  a5: 0.03\n  a6: 1\n")),
            "cal.yaml:9: unknown key 'a6' in calibration.dh_deviations_mm (expected one of: a3, "
            "a5, d2, d3, d5)");
  EXPECT_EQ(error_of(replace(kGood, "marker_offset_mm: [-0.10, -0.16, -8.46]\n", "")),
            "cal.yaml:1: missing field 'marker_offset_mm' in calibration");
  EXPECT_EQ(error_of(replace(kGood, "marker_offset_mm", "marker_offset")),
            "cal.yaml:9: unknown key 'marker_offset' in calibration: did you mean "
            "'marker_offset_mm'? (missing field 'marker_offset_mm')");
  EXPECT_EQ(error_of(replace(kGood, "exodaq-calibration-1", "exodaq-calibration-2")),
            "cal.yaml:1: 'format' must be 'exodaq-calibration-1', found 'exodaq-calibration-2'");
  EXPECT_EQ(error_of(replace(kGood, "d3: -0.48", "d3: x")),
            "cal.yaml:5: 'd3' must be a number, found 'x'");
  EXPECT_EQ(error_of(kGood + "camera:\n  translation_mm: [1, 2]\n  euler_xyz_deg: [0, 0, 0]\n"),
            "cal.yaml:11: 'translation_mm' must have 3 numbers, has 2");
  EXPECT_EQ(error_of(kGood + "encoder_offsets_rad: [0, 0, 0, 0, 0, 0]\n"),
            "cal.yaml:10: unknown key 'encoder_offsets_rad' in calibration: did you mean "
            "'encoder_offsets_deg'? (expected one of: "
            "camera, dh_deviations_mm, encoder_offsets_deg, format, marker_offset_mm, provenance)");
  EXPECT_EQ(error_of(kGood + "provenance:\n  rms_after_mm: .inf\n"),
            "cal.yaml:11: 'rms_after_mm' must be a finite number, found '.inf'");
  EXPECT_EQ(error_of(kGood + "provenance:\n  samples: 15555555200\n"),
            "cal.yaml:11: 'samples' must be at most 2147483647");
  EXPECT_EQ(error_of(""), "cal.yaml: empty document");
}

TEST(CalibrationFile, ShippedFilesLoad) {
  const std::string dir = std::string(EXODAQ_SOURCE_DIR) + "/config/calibration/";
  const Calibration nominal = exodaq::settings::load_calibration_file(dir + "nominal.yaml");
  EXPECT_NEAR(nominal.encoder_offset_rad[0], 30.7 * kDeg, 1e-12);
  EXPECT_NEAR(nominal.encoder_offset_rad[4], -25.5 * kDeg, 1e-12);
  EXPECT_EQ(nominal.dh.d5, 0.0);
  const Calibration t4 = exodaq::settings::load_calibration_file(dir + "seed000_table4.yaml");
  EXPECT_NEAR(t4.encoder_offset_rad[2], -13.45 * kDeg, 1e-12);
  EXPECT_NEAR(t4.dh.d5, 2.80e-3, 1e-12);
  EXPECT_NEAR(t4.marker_offset_m[2], -8.46e-3, 1e-12);
  ASSERT_TRUE(t4.camera.has_value());
  EXPECT_NEAR(t4.camera->euler_xyz_rad[2], -135.52 * kDeg, 1e-12);
  EXPECT_NEAR(*t4.provenance.rms_before_m, 13.6e-3, 1e-12);
}

// The camera convention puts z0 (joint 1's vertical axis) along the camera's
// +y ("Y up") for Table 4's angles, and O0 ~0.85 m above the camera origin.
TEST(CalibrationFile, EulerConventionIsSensibleForTable4) {
  const Calibration t4 = exodaq::settings::load_calibration_file(
      std::string(EXODAQ_SOURCE_DIR) + "/config/calibration/seed000_table4.yaml");
  const auto& e = t4.camera->euler_xyz_rad;
  const Eigen::Matrix3d R = (Eigen::AngleAxisd(e[0], Eigen::Vector3d::UnitX()) *
                             Eigen::AngleAxisd(e[1], Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(e[2], Eigen::Vector3d::UnitZ()))
                                .toRotationMatrix();
  const Eigen::Vector3d up = R * Eigen::Vector3d::UnitZ();
  EXPECT_GT(up.y(), 0.999);
  EXPECT_GT(t4.camera->translation_m[1], 0.8);
}

kinematics::Chain rig_chain() {
  const double alpha[6] = {-90, 90, -90, 90, -90, 0};
  std::vector<kinematics::JointDescription> j(6);
  for (int i = 0; i < 6; ++i) {
    j[i].name = "j" + std::to_string(i + 1);
    j[i].dh = kinematics::DhRow{0.0, alpha[i] * kDeg, 0.0, 0.0};
  }
  j[3].dh.d = 0.145;
  j[5].dh.d = 0.152;
  kinematics::Pose tool = kinematics::Pose::Identity();
  tool.translation() = Eigen::Vector3d(0.001, 0.0, 0.0);
  return kinematics::Chain(kinematics::Convention::kStandardDh, j, kinematics::Pose::Identity(),
                           tool);
}

TEST(ApplyCalibration, AddsDeviationsToTheRightRows) {
  const kinematics::Chain nominal = rig_chain();
  const Calibration c = load_calibration_text(kGood, "cal.yaml");
  const kinematics::Chain cal = exodaq::settings::apply_calibration(nominal, c);
  ASSERT_EQ(cal.joint_count(), 6);
  const auto& n = nominal.joints();
  const auto& j = cal.joints();
  EXPECT_DOUBLE_EQ(j[0].dh.d, n[0].dh.d);
  EXPECT_DOUBLE_EQ(j[1].dh.d, n[1].dh.d - 1.79e-3);
  EXPECT_DOUBLE_EQ(j[2].dh.d, n[2].dh.d - 0.48e-3);
  EXPECT_DOUBLE_EQ(j[3].dh.d, 0.145);
  EXPECT_DOUBLE_EQ(j[4].dh.d, n[4].dh.d + 2.80e-3);
  EXPECT_DOUBLE_EQ(j[5].dh.d, 0.152);
  EXPECT_DOUBLE_EQ(j[2].dh.a, n[2].dh.a - 4.01e-3);
  EXPECT_DOUBLE_EQ(j[4].dh.a, n[4].dh.a + 0.03e-3);
  for (int i = 0; i < 6; ++i) {
    EXPECT_DOUBLE_EQ(j[i].dh.alpha, n[i].dh.alpha);
    EXPECT_DOUBLE_EQ(j[i].dh.theta_offset, n[i].dh.theta_offset);
    EXPECT_EQ(j[i].name, n[i].name);
  }
  EXPECT_NEAR(
      (cal.tool().translation() - Eigen::Vector3d(0.001 - 0.10e-3, -0.16e-3, -8.46e-3)).norm(), 0.0,
      1e-15);
  // The palm moves by the marker offset expressed in frame 6.
  kinematics::JointVector q(6);
  q << 0.3, -1.2, 0.7, 0.2, -0.5, 0.4;
  const kinematics::Pose f6 = cal.frame(q, 6);
  const Eigen::Vector3d expect = f6 * cal.tool().translation();
  EXPECT_NEAR((cal.palm(q).translation() - expect).norm(), 0.0, 1e-12);
}

TEST(ApplyCalibration, RejectsOtherConventions) {
  const kinematics::Chain poe = rig_chain().to_product_of_exponentials();
  EXPECT_THROW(exodaq::settings::apply_calibration(poe, Calibration{}), std::invalid_argument);
}

}  // namespace
