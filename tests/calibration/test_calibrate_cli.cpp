// `exodaq calibrate` end to end on generated CSVs (1 kHz encoders, 480 Hz mocap).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "tool_run.hpp"

#include "exodaq/settings/calibration_file.hpp"
#include "synthetic.hpp"

namespace exodaq::calibration {
namespace {

using namespace synth;  // NOLINT

using Result = test::MergedResult;
const auto run = &test::run_tool_merged;

class CalibrateCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // Per process: other checkouts may run the same test at the same time.
    dir_ = ::testing::TempDir() + "/exodaq_calibrate_cli_" + std::to_string(::getpid());
    std::system(("mkdir -p " + dir_).c_str());
    TrajectoryOptions o;
    o.marker_rate_hz = 480.0;
    o.seed = 1;
    SyntheticData train = make_data(o);
    // A few occluded markers and an unhomed stretch, as on a real rig.
    for (std::size_t k = 100; k < train.markers.samples.size(); k += 997) {
      train.markers.samples[k].present = false;
    }
    for (std::size_t k = 300; k < 700; ++k) train.encoders.samples[k].homed_mask = 0x1E;
    write_encoder_csv(dir_ + "/enc.csv", train.encoders);
    write_marker_csv(dir_ + "/mocap.csv", train.markers);
    o.seed = 2;
    o.marker_rate_hz = 10.0;
    const SyntheticData val = make_data(o);
    write_encoder_csv(dir_ + "/enc_val.csv", val.encoders);
    write_marker_csv(dir_ + "/mocap_val.csv", val.markers);
    // Five markers (config/calibration/markers_example.yaml) at 100 Hz.
    o.seed = 1;
    o.marker_rate_hz = 100.0;
    o.layout = rig_layout(true, true);
    const SyntheticData multi = make_data(o);
    write_encoder_csv(dir_ + "/enc_multi.csv", multi.encoders);
    write_marker_csv(dir_ + "/mocap_multi.csv", multi.markers);
  }
  static void TearDownTestSuite() { std::system(("rm -rf " + dir_).c_str()); }
  static std::string dir_;
};
std::string CalibrateCli::dir_;

TEST_F(CalibrateCli, WritesACalibrationTheDaemonLoads) {
  const std::string src = EXODAQ_SOURCE_DIR;
  const std::string out = dir_ + "/calibration.yaml";
  const Result r =
      run("calibrate --encoders " + dir_ + "/enc.csv --markers " + dir_ + "/mocap.csv --model " +
          src + "/config/models/macaque_exo.yaml --bounds " + src +
          "/config/calibration/bounds_seed000.yaml --out " + out + " --max-points 400 --validate " +
          dir_ + "/enc_val.csv," + dir_ + "/mocap_val.csv --plot " + dir_ + "/residuals.png");
  std::cout << r.output;
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("marker missing"), std::string::npos);
  EXPECT_NE(r.output.find("unhomed/faulted joints"), std::string::npos);
  EXPECT_NE(r.output.find("Δθ1⁰ is exactly unobservable"), std::string::npos);
  EXPECT_NE(r.output.find("Δθ6⁰ is exactly unobservable"), std::string::npos);
  EXPECT_NE(r.output.find("Cross-validation"), std::string::npos);
  EXPECT_NE(r.output.find("13.60 -> 1.05"), std::string::npos);

  const settings::Calibration c = settings::load_calibration_file(out);
  ASSERT_TRUE(c.provenance.rms_after_m.has_value());
  EXPECT_LT(*c.provenance.rms_after_m, 1.2 * 0.52e-3);
  EXPECT_GT(*c.provenance.rms_before_m, 5e-3);
  EXPECT_EQ(*c.provenance.samples, 400);
  EXPECT_NE(c.provenance.notes.find("held at prior: dtheta1_deg"), std::string::npos)
      << c.provenance.notes;
  const ParamVector truth = table4_results();
  // Identifiable parameters come back close to the truth (the test of the
  // library checks them against their standard deviations).
  EXPECT_NEAR(c.encoder_offset_rad[1], truth[kTheta2], 0.1 * kDeg);
  EXPECT_NEAR(c.encoder_offset_rad[2], truth[kTheta3], 0.1 * kDeg);
  EXPECT_NEAR(c.dh.d5, truth[kDd5], 0.5e-3);
  EXPECT_NEAR(c.marker_offset_m[2], truth[kPz], 1.0e-3);
  // Held at the prior, not "solved".
  EXPECT_NEAR(c.encoder_offset_rad[0], 30.7 * kDeg, 1e-12);
  EXPECT_TRUE(std::ifstream(dir_ + "/residuals_residuals.csv").good());
}

// Issue 18: hand and base markers identify all 20 parameters, Δθ1 included.
TEST_F(CalibrateCli, MarkerLayoutIdentifiesEveryParameter) {
  const std::string src = EXODAQ_SOURCE_DIR;
  const std::string out = dir_ + "/calibration_multi.yaml";
  const Result r =
      run("calibrate --encoders " + dir_ + "/enc_multi.csv --markers " + dir_ +
          "/mocap_multi.csv --bounds " + src +
          "/config/calibration/bounds_seed000.yaml --marker-layout " + src +
          "/config/calibration/markers_example.yaml --out " + out + " --max-points 400 --quiet");
  std::cout << r.output;
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(
      r.output.find("20000 marker samples, 2000 used (skipped: 18000 thinned (--max-points))"),
      std::string::npos);
  EXPECT_NE(r.output.find("Identifiability by observations"), std::string::npos);
  EXPECT_NE(r.output.find("+ base markers 10, 11, 12"), std::string::npos);
  EXPECT_NE(r.output.find("Identifiability: every free parameter is identifiable"),
            std::string::npos);
  const settings::Calibration c = settings::load_calibration_file(out);
  const ParamVector truth = table4_results();
  for (int j = 0; j < 6; ++j) {
    EXPECT_NEAR(c.encoder_offset_rad[j], truth[kTheta1 + j], 0.1 * kDeg) << "joint " << j + 1;
  }
  EXPECT_NEAR(c.dh.a5, truth[kDa5], 0.5e-3);
  EXPECT_NE(c.provenance.notes.find("marker layout"), std::string::npos);
  EXPECT_EQ(c.provenance.notes.find("held at prior"), std::string::npos) << c.provenance.notes;
}

TEST_F(CalibrateCli, MarkerLayoutAndMarkerIdExcludeEachOther) {
  const std::string src = EXODAQ_SOURCE_DIR;
  const Result r =
      run("calibrate --encoders " + dir_ + "/enc_multi.csv --markers " + dir_ +
          "/mocap_multi.csv --bounds " + src +
          "/config/calibration/bounds_seed000.yaml --marker-layout " + src +
          "/config/calibration/markers_example.yaml --marker-id 3 --out " + dir_ + "/z.yaml");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("excludes"), std::string::npos) << r.output;
}

TEST_F(CalibrateCli, MalformedMocapRowIsReportedWithItsLine) {
  const std::string src = EXODAQ_SOURCE_DIR;
  {
    std::ofstream bad(dir_ + "/bad.csv");
    bad << "utime_us,x_mm,y_mm,z_mm\n1700000000300000,1,2,3\n1700000000400000,1,2\n";
  }
  const Result r =
      run("calibrate --encoders " + dir_ + "/enc.csv --markers " + dir_ + "/bad.csv --bounds " +
          src + "/config/calibration/bounds_seed000.yaml --out " + dir_ + "/x.yaml");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("exodaq calibrate: " + dir_ + "/bad.csv:3: expected 4 fields, found 3"),
            std::string::npos)
      << r.output;
}

TEST_F(CalibrateCli, TooFewPointsFails) {
  const std::string src = EXODAQ_SOURCE_DIR;
  const Result r = run(
      "calibrate --encoders " + dir_ + "/enc.csv --markers " + dir_ + "/mocap.csv --bounds " + src +
      "/config/calibration/bounds_seed000.yaml --out " + dir_ + "/y.yaml --max-points 10 --quiet");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("too few calibration points: 10"), std::string::npos) << r.output;
}

// Issue 28 (minor): --plot x_residuals.png wrote x_residuals_residuals.csv,
// and the solver printed about 78 progress lines with an unchanged RMS.
TEST_F(CalibrateCli, ThePlotsCsvIsNotNamedTwiceAndProgressIsShort) {
  const std::string src = EXODAQ_SOURCE_DIR;
  const Result r = run("calibrate --encoders " + dir_ + "/enc_val.csv --markers " + dir_ +
                       "/mocap_val.csv --bounds " + src +
                       "/config/calibration/bounds_seed000.yaml --max-points 100 -o " + dir_ +
                       "/p.yaml --plot " + dir_ + "/x_residuals.png");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(std::ifstream(dir_ + "/x_residuals.csv").good());
  EXPECT_FALSE(std::ifstream(dir_ + "/x_residuals_residuals.csv").good());
  std::istringstream lines(r.output);
  std::string line;
  int iterations = 0, stages = 0;
  while (std::getline(lines, line)) {
    iterations += line.find("] iter ") != std::string::npos ? 1 : 0;
    stages += line.find("] done after ") != std::string::npos ? 1 : 0;
  }
  EXPECT_GE(stages, 1);
  EXPECT_LE(iterations, 15 * stages) << r.output;  // lines where the RMS moved, not every step
}

// Issue 15 point 6: the calibration file is written safely.
class CalibrateOutput : public CalibrateCli {
 protected:
  Result calibrate_to(const std::string& out) {
    const std::string src = EXODAQ_SOURCE_DIR;
    return run("calibrate --encoders " + dir_ + "/enc_val.csv --markers " + dir_ +
               "/mocap_val.csv --bounds " + src +
               "/config/calibration/bounds_seed000.yaml --max-points 100 -q -o " + out);
  }
  // Files in `dir` whose names start with '.' (a left-over temporary file).
  static int hidden_files(const std::string& dir) {
    int n = 0;
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
      n += e.path().filename().string()[0] == '.' ? 1 : 0;
    }
    return n;
  }
};

TEST_F(CalibrateOutput, ASymlinkIsFollowedAndKept) {
  // The reproduction: current.yaml -> rig-2026-11.yaml became a regular file.
  const std::string d = dir_ + "/link";
  std::filesystem::create_directories(d);
  std::ofstream(d + "/rig-2026-11.yaml") << "old\n";
  std::filesystem::permissions(d + "/rig-2026-11.yaml", std::filesystem::perms(0640));
  std::filesystem::create_symlink("rig-2026-11.yaml", d + "/current.yaml");
  const Result r = calibrate_to(d + "/current.yaml");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(std::filesystem::is_symlink(d + "/current.yaml"));
  EXPECT_EQ(std::filesystem::read_symlink(d + "/current.yaml"), "rig-2026-11.yaml");
  EXPECT_NO_THROW(settings::load_calibration_file(d + "/rig-2026-11.yaml"));
  // The replaced file keeps its mode.
  EXPECT_EQ(std::filesystem::status(d + "/rig-2026-11.yaml").permissions(),
            std::filesystem::perms(0640));
  EXPECT_EQ(hidden_files(d), 0);
}

TEST_F(CalibrateOutput, ADeviceNodeIsNotReplaced) {
  // The reproduction: as root, --out on a device node replaced it.
  const std::string d = dir_ + "/dev";
  std::filesystem::create_directories(d);
  const std::string node = d + "/null";
  if (::mknod(node.c_str(), S_IFCHR | 0666, makedev(1, 3)) != 0) {
    GTEST_SKIP() << "mknod needs root";
  }
  const Result r = calibrate_to(node);
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("exodaq calibrate: " + node +
                          ": is a character device, not a regular file: not replaced"),
            std::string::npos)
      << r.output;
  struct stat st {};
  ASSERT_EQ(::stat(node.c_str(), &st), 0);
  EXPECT_TRUE(S_ISCHR(st.st_mode));
  EXPECT_EQ(hidden_files(d), 0);
}

TEST_F(CalibrateOutput, AnInputIsNotReplaced) {
  const std::string before = [&] {
    std::ifstream in(dir_ + "/mocap_val.csv");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }();
  const Result r = calibrate_to(dir_ + "/mocap_val.csv");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("is also an input"), std::string::npos) << r.output;
  std::ifstream in(dir_ + "/mocap_val.csv");
  std::stringstream after;
  after << in.rdbuf();
  EXPECT_EQ(after.str(), before);
}

TEST_F(CalibrateOutput, AFullFilesystemLeavesNothingAndSaysWhy) {
  // A 64 KiB tmpfs filled to the last byte (root: the test machine is).
  const std::string d = dir_ + "/full";
  std::filesystem::create_directories(d);
  if (std::system(("mount -t tmpfs -o size=64k tmpfs " + d + " 2>/dev/null").c_str()) != 0) {
    GTEST_SKIP() << "cannot mount a tmpfs (needs root)";
  }
  std::ofstream(d + "/calibration.yaml") << "previous\n";  // an earlier file...
  std::system(("dd if=/dev/zero of=" + d + "/filler bs=4k count=100 2>/dev/null").c_str());
  const Result r = calibrate_to(d + "/calibration.yaml");
  std::string previous;
  std::getline(std::ifstream(d + "/calibration.yaml"), previous);
  const int hidden = hidden_files(d);
  std::system(("umount " + d).c_str());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("exodaq calibrate: " + d +
                          "/calibration.yaml: cannot write: No space left on device"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(previous, "previous");  // ... is left as it was
  EXPECT_EQ(hidden, 0);             // and no temporary file
}

}  // namespace
}  // namespace exodaq::calibration
