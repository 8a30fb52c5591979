// Encoder and marker CSV readers and the time alignment.
#include <gtest/gtest.h>

#include <array>
#include <string>

#include "exodaq/calibration/inputs.hpp"
#include "exodaq/common/yaml_reader.hpp"

namespace exodaq::calibration {
namespace {

std::string encoder_error(const std::string& text) {
  try {
    EncoderCsvReader().parse(text, "enc.csv");
  } catch (const exodaq::ConfigError& e) {
    return e.what();
  }
  return "no error";
}

std::string marker_error(const std::string& text, int id = -1) {
  try {
    parse_marker_csv(text, "mocap.csv", id);
  } catch (const exodaq::ConfigError& e) {
    return e.what();
  }
  return "no error";
}

const std::string kEncHeader =
    "utime_us,j1_rad,j2_rad,j3_rad,j4_rad,j5_rad,j6_rad,homed_mask,fault_mask\n";

TEST(EncoderCsv, ParsesColumnsInAnyOrder) {
  const auto e = EncoderCsvReader().parse(
      "# comment\n"
      "j6_rad,j5_rad,j4_rad,j3_rad,j2_rad,j1_rad,utime_us\n"
      "\n"
      "6,5,4,3,2,1,1000\n"
      "0.6,0.5,0.4,0.3,0.2,0.1,2000\n",
      "enc.csv");
  ASSERT_EQ(e.samples.size(), 2u);
  EXPECT_EQ(e.samples[0].utime_us, 1000);
  EXPECT_EQ(e.samples[0].theta_r[0], 1.0);
  EXPECT_EQ(e.samples[0].theta_r[5], 6.0);
  EXPECT_EQ(e.samples[1].theta_r[2], 0.3);
  EXPECT_TRUE(e.samples[1].valid());
}

TEST(EncoderCsv, MalformedRowsNameTheLine) {
  EXPECT_EQ(encoder_error(kEncHeader + "1000,0,0,0,0,0,0,63,0\n2000,0,0,x,0,0,0,63,0\n"),
            "enc.csv:3: column 'j3_rad': 'x' is not a number");
  EXPECT_EQ(encoder_error(kEncHeader + "1000,0,0,0,0,0,0,63,0\n2000,0,0,0,0,0,63,0\n"),
            "enc.csv:3: expected 9 fields, found 8");
  EXPECT_EQ(encoder_error(kEncHeader + "1000,0,0,0,0,0,0,63,0\n1000,0,0,0,0,0,0,63,0\n"),
            "enc.csv:3: utime_us 1000 does not increase (previous row 1000)");
  EXPECT_EQ(encoder_error(kEncHeader + "1000,0,0,0,0,0,0,64,0\n"),
            "enc.csv:2: column 'homed_mask': 64 is not a 6-bit joint mask (0..63)");
  EXPECT_EQ(encoder_error(kEncHeader + "1000,0,0,0,0,0,inf,63,0\n"),
            "enc.csv:2: column 'j6_rad': 'inf' is not a finite number");
  EXPECT_EQ(encoder_error("utime_us,j1_rad,j2_rad,j3_rad,j4_rad,j5_rad\n"),
            "enc.csv:1: missing column 'j6_rad'");
  EXPECT_EQ(encoder_error("utime_us,j1_deg,j2_rad,j3_rad,j4_rad,j5_rad,j6_rad\n"),
            "enc.csv:1: unknown column 'j1_deg' (expected utime_us, j1_rad, j2_rad, j3_rad, "
            "j4_rad, j5_rad, j6_rad, homed_mask (optional), fault_mask (optional))");
  EXPECT_EQ(encoder_error(kEncHeader + "1000,0,0,0,0,0,0,63,0\n"),
            "enc.csv: fewer than two encoder samples");
}

TEST(EncoderLog, AMissingOrSpecialFileIsAClearError) {
  const auto error = [](const std::string& path) {
    try {
      read_encoder_log(path);
    } catch (const exodaq::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error("/nonexistent/run.lcm"),
            "/nonexistent/run.lcm: cannot open: No such file or directory");
  EXPECT_EQ(error("/dev/zero"), "/dev/zero: is a character device, not a regular file");
  EXPECT_EQ(error("/tmp"), "/tmp: is a directory, not a regular file");
}

// The CSV of `exodaq export` (docs/messages.md): calibrated angles, read as
// θᴿ = θ − the recorded calibration's offsets; homed and flags per joint.
const std::string kExportHeader =
    "utime_us,mono_ns,seq,run_id,a_rad,b_rad,c_rad,d_rad,e_rad,f_rad,"
    "a_vel_rad_s,b_vel_rad_s,c_vel_rad_s,d_vel_rad_s,e_vel_rad_s,f_vel_rad_s,"
    "a_count,b_count,c_count,d_count,e_count,f_count,"
    "a_homed,b_homed,c_homed,d_homed,e_homed,f_homed,"
    "a_flags,b_flags,c_flags,d_flags,e_flags,f_flags,sample_flags,palm_x_m\n";

std::string export_row(std::int64_t utime, double pos, int homed, int flags, int sample_flags) {
  std::string r = std::to_string(utime) + ",1,2,0000000000005eed";
  for (int j = 0; j < 6; ++j) r += "," + std::to_string(pos + j);
  for (int j = 0; j < 6; ++j) r += ",0";
  for (int j = 0; j < 6; ++j) r += ",100";
  for (int j = 0; j < 6; ++j) r += "," + std::to_string(j == 2 ? homed : 1);
  for (int j = 0; j < 6; ++j) r += "," + std::to_string(j == 4 ? flags : 0);
  return r + "," + std::to_string(sample_flags) + ",\n";
}

TEST(EncoderCsv, ReadsExodaqExportWithTheRecordedCalibration) {
  const std::string text = kExportHeader + export_row(1000, 1.0, 1, 0, 0) +
                           export_row(2000, 2.0, 0, 0, 0) + export_row(3000, 3.0, 1, 64, 0) +
                           export_row(4000, 4.0, 1, 4, 0) + export_row(5000, 5.0, 1, 0, 1);
  EncoderReadOptions o;
  o.recorded_offsets_rad = std::array<double, 6>{0.5, 0.25, 0, 0, 0, -1};
  o.recorded_calibration = "cal.yaml";
  const auto e = EncoderCsvReader().parse(text, "export.csv", o);
  ASSERT_EQ(e.samples.size(), 5u);
  EXPECT_EQ(e.samples[0].utime_us, 1000);
  EXPECT_EQ(e.samples[0].theta_r[0], 0.5);   // 1 - 0.5
  EXPECT_EQ(e.samples[0].theta_r[1], 1.75);  // 2 - 0.25
  EXPECT_EQ(e.samples[0].theta_r[5], 7.0);   // 6 + 1
  EXPECT_TRUE(e.samples[0].valid());
  EXPECT_EQ(e.samples[1].homed_mask, 0x3F & ~0x04);  // joint 3 not homed
  EXPECT_TRUE(e.samples[2].valid());                 // JOINT_HELD is not a fault
  EXPECT_EQ(e.samples[3].fault_mask, 0x10);          // GLITCH on joint 5
  EXPECT_EQ(e.samples[4].fault_mask, 0x3F);          // SAMPLE_MISSING: nothing measured

  // Without the calibration: refused, naming what to give.
  try {
    EncoderCsvReader().parse(text, "export.csv");
    FAIL();
  } catch (const exodaq::ConfigError& err) {
    EXPECT_EQ(std::string(err.what()),
              "export.csv:1: holds calibrated joint angles (theta = offset + theta_R): name the "
              "calibration they were computed with (-c CONFIG or --recorded-calibration FILE)");
  }
}

TEST(MarkerCsv, MissingMarkerAndMillimetres) {
  const auto m = parse_marker_csv(
      "utime_us,x_mm,y_mm,z_mm\n"
      "1000,1,2,3\n"
      "2000,,,\n"
      "3000,nan,NaN,nan\n",
      "mocap.csv");
  ASSERT_EQ(m.samples.size(), 3u);
  EXPECT_TRUE(m.samples[0].present);
  EXPECT_DOUBLE_EQ(m.samples[0].z, 3e-3);
  EXPECT_FALSE(m.samples[1].present);
  EXPECT_FALSE(m.samples[2].present);
}

TEST(MarkerCsv, MalformedRowsNameTheLine) {
  EXPECT_EQ(marker_error("utime_us,x_mm,y_mm,z_mm\n1000,1,2,3\n2000,1,,3\n"),
            "mocap.csv:3: x_mm, y_mm, z_mm must all be numbers or all empty/nan (marker missing)");
  EXPECT_EQ(marker_error("utime_us,x_mm,y_mm,z_mm\n1000,1,2,3\n1.5e3,1,2,3\n"),
            "mocap.csv:3: column 'utime_us': '1.5e3' is not an integer");
  EXPECT_EQ(marker_error("utime_us,x_mm,y_mm,z_mm,marker_id\n1000,1,2,3,1\n2000,1,2,3,2\n"),
            "mocap.csv:3: marker_id 2 differs from 1 (line 2): select one marker with --marker-id");
  EXPECT_EQ(marker_error("utime_us,x_mm,y_mm,z_mm,marker_id\n1000,1,2,3,1\n", 4),
            "mocap.csv: no samples of marker_id 4");
  const auto m = parse_marker_csv(
      "utime_us,x_mm,y_mm,z_mm,marker_id\n1000,1,2,3,1\n1000,4,5,6,2\n2000,1,2,3,1\n", "m.csv", 2);
  ASSERT_EQ(m.samples.size(), 1u);
  EXPECT_DOUBLE_EQ(m.samples[0].x, 4e-3);
}

TEST(Alignment, InterpolatesAndCountsSkippedSamples) {
  EncoderSeries e;
  for (int k = 0; k <= 10; ++k) {
    EncoderSample s;
    s.utime_us = 1000 * k;
    s.theta_r.fill(0.01 * k);
    if (k == 6) s.homed_mask = 0x1F;  // joint 6 not homed yet
    if (k >= 9) s.utime_us += 20000;  // a 20 ms hole before sample 9
    e.samples.push_back(s);
  }
  MarkerSeries m;
  auto add = [&](std::int64_t t, bool present) {
    MarkerSample s;
    s.utime_us = t;
    s.present = present;
    s.x = 1;
    m.samples.push_back(s);
  };
  add(2500, true);   // used: θ = 0.025
  add(3000, false);  // missing
  add(5500, true);   // bracketed by sample 6 (unhomed)
  add(-10, true);    // before the log
  add(15000, true);  // in the hole
  add(4000, true);   // exactly on a sample... (out of order on purpose? no: align keeps order)
  AlignmentStats st;
  const auto pts = align(e, m, AlignmentOptions{}, st);
  EXPECT_EQ(st.marker_samples, 6u);
  EXPECT_EQ(st.marker_missing, 1u);
  EXPECT_EQ(st.unhomed_or_faulted, 1u);
  EXPECT_EQ(st.outside_encoder_log, 1u);
  EXPECT_EQ(st.encoder_gap, 1u);
  ASSERT_EQ(pts.size(), 2u);
  EXPECT_NEAR(pts[0].theta_r[3], 0.025, 1e-15);
  EXPECT_NEAR(pts[1].theta_r[0], 0.04, 1e-15);
  EXPECT_EQ(st.used, 2u);
}

}  // namespace
}  // namespace exodaq::calibration
