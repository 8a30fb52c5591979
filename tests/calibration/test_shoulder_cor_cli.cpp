// `exodaq shoulder-cor` end to end on a generated capture (5 torso markers,
// 7 humerus markers, 100 Hz, a centre that rises by seed 001 Table II).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "tool_run.hpp"

#include "shoulder_synthetic.hpp"

namespace exodaq::calibration {
namespace {

using Result = test::MergedResult;
const auto run = &test::run_tool_merged;

class ShoulderCorCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = ::testing::TempDir() + "/exodaq_shoulder_cor_cli_" + std::to_string(::getpid());
    std::system(("mkdir -p " + dir_).c_str());
    shoulder_synth::Options o;
    o.occluded_fraction = 0.02;
    shoulder_synth::write_csv(dir_ + "/capture.csv", shoulder_synth::make_frames(o));
  }
  static std::string args() {
    return "shoulder-cor --markers " + dir_ +
           "/capture.csv --torso 1,2,3,4,5 --humerus 11,12,13,14,15,16,17 --torso-axis 1,2 "
           "--humerus-axis 11,12";
  }
  static void TearDownTestSuite() { std::system(("rm -rf " + dir_).c_str()); }
  static std::string dir_;
};
std::string ShoulderCorCli::dir_;

TEST_F(ShoulderCorCli, PrintsATableIIStyleTableAndWritesTheBins) {
  const Result r = run(args() + " --plot " + dir_ + "/cor.png");
  std::cout << r.output;
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("capture.csv: 12000 frames, 12000 used"), std::string::npos);
  EXPECT_NE(r.output.find("seed 001 Table II"), std::string::npos);
  // Near 0 deg the axes are nearly vertical: the bin says so.
  EXPECT_NE(r.output.find("WARNING: bin 0-20 deg: poorly determined: vertical ±"),
            std::string::npos);
  std::ifstream in(dir_ + "/cor_bins.csv");
  ASSERT_TRUE(in.good());
  std::string header, line;
  std::getline(in, header);
  EXPECT_EQ(header.rfind("bin,elevation_lo_deg,elevation_hi_deg,mean_elevation_deg", 0), 0u);
  EXPECT_NE(header.find(",vertical_ci95_mm,horizontal_ci95_mm,axis_spread_deg,flags"),
            std::string::npos);
  // The vertical motion per bin against Table II (the synthetic truth).
  const std::size_t col = 12;  // vertical_mm
  for (std::size_t k = 0; std::getline(in, line); ++k) {
    std::stringstream s(line);
    std::string field;
    for (std::size_t c = 0; c <= col; ++c) std::getline(s, field, ',');
    ASSERT_LT(k, 6u);
    EXPECT_NEAR(std::stod(field), shoulder_synth::kTable2Mm[k], 1.0) << "bin " << k;
    for (std::size_t c = col + 1; c <= col + 6; ++c) std::getline(s, field, ',');
    const double vertical_ci = std::stod(field);  // vertical_ci95_mm
    if (k == 0) {
      EXPECT_EQ(vertical_ci, 0.0);  // the reference bin
    } else {
      EXPECT_GT(vertical_ci, 0.05) << "bin " << k;
      EXPECT_LT(vertical_ci, 1.0) << "bin " << k;
    }
  }
}

// --plot cor_bins.png wrote cor_bins_bins.csv.
TEST_F(ShoulderCorCli, ThePlotsCsvIsNotNamedTwice) {
  const Result r = run(args() + " --plot " + dir_ + "/x_bins.png");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(std::ifstream(dir_ + "/x_bins.csv").good());
  EXPECT_FALSE(std::ifstream(dir_ + "/x_bins_bins.csv").good());
}

TEST_F(ShoulderCorCli, BadMarkerIdsAreClearErrors) {
  Result r = run("shoulder-cor --markers " + dir_ +
                 "/capture.csv --torso 1,2,3,4,5 --humerus 11,12,13 --torso-axis 1,9 "
                 "--humerus-axis 11,12");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find(
                "exodaq shoulder-cor: --torso-axis: marker 9 is not one of the --torso markers"),
            std::string::npos)
      << r.output;
  r = run("shoulder-cor --markers " + dir_ +
          "/capture.csv --torso 1,2,3 --humerus 3,12,13 --torso-axis 1,2 --humerus-axis 12,13");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("exodaq shoulder-cor: marker 3 is given twice"), std::string::npos)
      << r.output;
  r = run("shoulder-cor --markers " + dir_ +
          "/capture.csv --torso 1,2,3,4,5 --humerus 11,12,13,14,15,16,17,18 --torso-axis 1,2 "
          "--humerus-axis 11,12");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("capture.csv: no samples of marker_id 18"), std::string::npos)
      << r.output;
}

}  // namespace
}  // namespace exodaq::calibration
