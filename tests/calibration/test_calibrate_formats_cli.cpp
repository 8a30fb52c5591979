// Issue 28, "done when": one synthetic session (Table 4 as the truth, the
// five markers of config/calibration/markers_example.yaml) captured as C3D, a
// Vicon Nexus CSV and an OptiTrack Motive CSV whose clock starts at 0 when the
// encoder recording is 40 s old; each calibrates, without any timing flag, to
// the parameters the long CSV with exact epoch times gives. And the issue's
// 30 ms clock offset without a flag: now a warning.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <map>
#include <random>
#include <regex>
#include <sstream>
#include <string>

#include "capture_writers.hpp"
#include "synthetic.hpp"
#include "tool_run.hpp"

namespace exodaq::calibration {
namespace {

using namespace synth;  // NOLINT

constexpr double kCaptureStartS = 40.0;  // the capture starts 40 s into the encoder recording
constexpr double kCaptureS = 30.0;
constexpr double kRateHz = 100.0;

// One parameter row of the report: estimate and std (display units).
struct Estimate {
  double value = 0, std = 0;
  bool identified = false;
};
using Estimates = std::map<int, Estimate>;

Estimates parse_parameters(const std::string& out) {
  Estimates e;
  std::istringstream in(out);
  std::string line;
  while (std::getline(in, line)) {
    for (int p = 0; p < kParams; ++p) {
      const std::string head = std::string("  ") + param_label(p) + " ";
      if (line.rfind(head, 0) != 0) continue;
      std::istringstream f(line.substr(head.size()));
      double initial = 0;
      Estimate x;
      std::string std_text;
      if (!(f >> initial >> x.value >> std_text)) continue;  // not a table row
      x.identified = line.find("identified") != std::string::npos;
      x.std = std_text == "-" ? 0.0 : std::stod(std_text);
      e[p] = x;
    }
  }
  return e;
}

class CalibrateFormats : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = ::testing::TempDir() + "/exodaq_calibrate_formats_" + std::to_string(::getpid());
    std::filesystem::create_directories(dir_);
    const ParamVector truth = table4_results();
    const NominalModel model = rig_model();
    const MarkerLayout layout = rig_layout(true, true);
    // Encoders: 75 s at 1 kHz, quantised at 10 000 counts/rev.
    EncoderSeries enc;
    const double q = 2 * M_PI / 10000.0;
    for (int k = 0; k <= 75000; ++k) {
      EncoderSample s;
      s.utime_us = kEpochUs + k * 1000;
      for (int j = 0; j < 6; ++j) {
        s.theta_r[j] = std::round((joint_angle(j, k * 1e-3, 3, -1) - truth[kTheta1 + j]) / q) * q;
      }
      enc.samples.push_back(s);
    }
    write_encoder_csv(dir_ + "/enc.csv", enc);
    // The capture: frames at 40 s + k / 100 Hz; 0.3 mm noise; a few gaps.
    writers::Capture cap;
    cap.rate_hz = kRateHz;
    for (const auto& site : layout.sites) cap.labels.push_back(site.label);
    MarkerSeries long_csv;
    std::mt19937_64 rng(5);
    std::normal_distribution<double> noise(0.0, 0.3);
    for (int k = 0; k < static_cast<int>(kCaptureS * kRateHz); ++k) {
      const double t = kCaptureStartS + k / kRateHz;
      std::array<double, 6> theta_r{};
      for (int j = 0; j < 6; ++j) theta_r[j] = joint_angle(j, t, 3, -1) - truth[kTheta1 + j];
      std::vector<std::optional<Eigen::Vector3d>> frame;
      for (const auto& site : layout.sites) {
        Eigen::Vector3d p = predict_marker(model, truth, theta_r, site) * 1e3;
        p += Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
        const bool hidden = (k % 97 == 5 && site.id == 4) || (k >= 700 && k < 720 && site.id == 11);
        frame.push_back(hidden ? std::nullopt : std::optional<Eigen::Vector3d>(p));
        MarkerSample m;
        m.utime_us = kEpochUs + std::llround(t * 1e6);
        m.marker_id = site.id;
        m.present = !hidden;
        m.x = p.x() * 1e-3;
        m.y = p.y() * 1e-3;
        m.z = p.z() * 1e-3;
        long_csv.samples.push_back(m);
      }
      cap.frames.push_back(frame);
    }
    write_marker_csv(dir_ + "/long.csv", long_csv);
    writers::write_file(dir_ + "/capture.c3d", writers::c3d_write(cap, {}));
    writers::write_file(dir_ + "/vicon.csv", writers::vicon_write(cap));
    writers::write_file(dir_ + "/motive.csv", writers::motive_write(cap));
    // The issue's reproduction: one marker, its clock 30 ms late, epoch times.
    MarkerSeries late;
    for (MarkerSample m : long_csv.samples) {
      if (m.marker_id != 3) continue;
      m.utime_us += 30000;
      late.samples.push_back(m);
    }
    write_marker_csv(dir_ + "/late30ms.csv", late);
    baseline_ = new test::MergedResult(calibrate(dir_ + "/long.csv"));
  }
  static void TearDownTestSuite() {
    delete baseline_;
    std::filesystem::remove_all(dir_);
  }
  static test::MergedResult calibrate(const std::string& markers,
                                      const std::string& layout_arg = "") {
    const std::string src = EXODAQ_SOURCE_DIR;
    const std::string layout =
        layout_arg.empty() ? " --marker-layout " + src + "/config/calibration/markers_example.yaml"
                           : layout_arg;
    return test::run_tool_merged("calibrate --encoders " + dir_ + "/enc.csv --markers " + markers +
                                 " --bounds " + src + "/config/calibration/bounds_seed000.yaml" +
                                 layout + " --max-points 300 -o " + dir_ + "/out.yaml");
  }
  // A capture without an epoch: aligned by itself, then the same parameters.
  static void expect_same_as_baseline(const std::string& file) {
    const test::MergedResult r = calibrate(dir_ + "/" + file);
    std::cout << r.output;
    ASSERT_EQ(r.code, 0) << r.output;
    ASSERT_EQ(baseline_->code, 0) << baseline_->output;
    EXPECT_EQ(r.output.find("WARNING"), std::string::npos) << r.output;
    std::smatch m;
    ASSERT_TRUE(
        std::regex_search(r.output, m, std::regex(R"(mocap time \+ offset\): ([0-9.]+) s)")))
        << r.output;
    EXPECT_NEAR(std::stod(m[1]) - kEpochUs * 1e-6, kCaptureStartS, 1e-3);
    const Estimates base = parse_parameters(baseline_->output);
    const Estimates got = parse_parameters(r.output);
    ASSERT_EQ(base.size(), static_cast<std::size_t>(kParams));
    ASSERT_EQ(got.size(), static_cast<std::size_t>(kParams));
    for (int p = 0; p < kParams; ++p) {
      EXPECT_TRUE(got.at(p).identified) << param_label(p);
      EXPECT_NEAR(got.at(p).value, base.at(p).value, std::max(got.at(p).std, 1e-3))
          << param_label(p) << " (std " << got.at(p).std << ")";
    }
  }
  static std::string dir_;
  static test::MergedResult* baseline_;
};
std::string CalibrateFormats::dir_;
test::MergedResult* CalibrateFormats::baseline_ = nullptr;

TEST_F(CalibrateFormats, LongCsvWithExactTimesNeedsNoAlignment) {
  std::cout << baseline_->output;
  ASSERT_EQ(baseline_->code, 0) << baseline_->output;
  EXPECT_EQ(baseline_->output.find("clock offset"), std::string::npos);
  EXPECT_EQ(baseline_->output.find("WARNING"), std::string::npos);
  const Estimates e = parse_parameters(baseline_->output);
  const ParamVector truth = table4_results();
  for (int p = 0; p < kParams; ++p) {
    EXPECT_NEAR(e.at(p).value, to_display(p, truth[p]), 4 * e.at(p).std + 1e-3) << param_label(p);
  }
}

TEST_F(CalibrateFormats, C3dFromItsOwnClock) {
  expect_same_as_baseline("capture.c3d");
}
TEST_F(CalibrateFormats, ViconNexusCsvFromItsOwnClock) {
  expect_same_as_baseline("vicon.csv");
}
TEST_F(CalibrateFormats, MotiveCsvFromItsOwnClock) {
  expect_same_as_baseline("motive.csv");
}

// The issue's reproduction: a 30 ms clock offset, epoch times, no flag. It
// exited 0 with a wrong Δθ5 and no word about the clock.
TEST_F(CalibrateFormats, AThirtyMillisecondOffsetWithoutAFlagIsAWarning) {
  const test::MergedResult r = calibrate(dir_ + "/late30ms.csv", " --marker-id 3");
  std::cout << r.output;
  ASSERT_EQ(r.code, 0) << r.output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      r.output, m,
      std::regex(
          R"(WARNING: the residuals follow the markers' motion: a clock offset of ([-+0-9.]+) ± ([0-9.]+) ms)")))
      << r.output;
  // Marker time = true time + 30 ms: encoder = marker - 30 ms.
  EXPECT_NEAR(std::stod(m[1]), -30.0, 5.0);
}

}  // namespace
}  // namespace exodaq::calibration
