// `exodaq fk` end to end: runs the built binary (EXODAQ_TOOL).
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "tool_run.hpp"

namespace {

using Result = exodaq::test::ToolResult;

Result run(const std::string& args) {
  return exodaq::test::run_tool(args);
}

const std::string kModel = std::string(EXODAQ_SOURCE_DIR) + "/config/models/macaque_exo.yaml";

TEST(FkCli, HomePostureText) {
  const Result r = run("fk --model " + kModel + " --joints-deg 45,-90,90,0,0,0");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("palm position (m):              0.000000   0.000000  -0.297000"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("palm quaternion (w, x, y, z):   0.000000   0.382683   0.923880   0.000000"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("elbow position (m):             0.000000   0.000000  -0.145000"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("shoulder manipulability:        1.414214 (normalised 1.000000)"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("-0.707107   0.707107   0.000000"), std::string::npos) << r.out;
  EXPECT_TRUE(r.err.empty()) << r.err;
}

TEST(FkCli, DefaultModelIsTheMacaque) {
  const Result r =
      run("fk --joints-rad 0.7853981633974483,-1.5707963267948966,1.5707963267948966,0,0,0");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("model: macaque_exo"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("-0.297000"), std::string::npos) << r.out;
}

TEST(FkCli, JsonParses) {
  const Result r = run("fk --model " + kModel + " --joints-deg=45,-90,90,0,0,0 --json");
  ASSERT_EQ(r.code, 0) << r.err;
  const YAML::Node j = YAML::Load(r.out);  // JSON is YAML
  ASSERT_TRUE(j.IsMap()) << r.out;
  EXPECT_EQ(j["model"].as<std::string>(), "macaque_exo");
  ASSERT_EQ(j["palm_position_m"].size(), 3u);
  EXPECT_NEAR(j["palm_position_m"][0].as<double>(), 0.0, 1e-15);
  EXPECT_NEAR(j["palm_position_m"][1].as<double>(), 0.0, 1e-15);
  EXPECT_NEAR(j["palm_position_m"][2].as<double>(), -0.297, 1e-15);
  EXPECT_NEAR(j["palm_rotation"][0][0].as<double>(), -std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(j["palm_rotation"][2][2].as<double>(), -1.0, 1e-15);
  EXPECT_NEAR(j["palm_quaternion_wxyz"][2].as<double>(), std::cos(M_PI / 8), 1e-15);
  EXPECT_NEAR(j["elbow_position_m"][2].as<double>(), -0.145, 1e-15);
  EXPECT_NEAR(j["shoulder_manipulability"].as<double>(), std::sqrt(2.0), 1e-14);
  EXPECT_NEAR(j["shoulder_manipulability_normalised"].as<double>(), 1.0, 1e-14);
  EXPECT_FALSE(j["near_singular"].as<bool>());
  EXPECT_EQ(j["joint_names"][0].as<std::string>(), "shoulder_azimuth");
  EXPECT_EQ(j["joints_outside_limits"].size(), 0u);
  EXPECT_NEAR(j["joints_rad"][1].as<double>(), -M_PI / 2, 1e-15);
}

TEST(FkCli, SingularPostureFlagged) {
  const Result r = run("fk --model " + kModel + " --joints-deg=10,-180,0,20,0,0 --json");
  ASSERT_EQ(r.code, 0) << r.err;
  const YAML::Node j = YAML::Load(r.out);
  EXPECT_NEAR(j["shoulder_manipulability"].as<double>(), 0.0, 1e-12);
  EXPECT_TRUE(j["near_singular"].as<bool>());
}

TEST(FkCli, WrongJointCountExits2) {
  const Result r = run("fk --model " + kModel + " --joints-deg 45,-90,90");
  EXPECT_EQ(r.code, 2);
  EXPECT_TRUE(r.out.empty()) << r.out;
  EXPECT_EQ(r.err, "exodaq fk: model 'macaque_exo' has 6 joints, 3 joint values given\n");
}

TEST(FkCli, MissingModelExits2) {
  const Result r = run("fk --model /nonexistent/model.yaml --joints-deg 0,0,0,0,0,0");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err, "exodaq fk: /nonexistent/model.yaml: cannot open: No such file or directory\n");
}

TEST(FkCli, BadModelExits2WithFileLine) {
  const std::string bad = ::testing::TempDir() + "exodaq_bad_model.yaml";
  FILE* f = std::fopen(bad.c_str(), "w");
  ASSERT_NE(f, nullptr);
  std::fputs("name: x\nconvention: dh\nangle_unit: deg\njoints: []\n", f);
  std::fclose(f);
  const Result r = run("fk --model " + bad + " --joints-deg 0");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err,
            "exodaq fk: " + bad +
                ":2: 'convention' must be one of standard_dh, modified_dh, poe, found 'dh'\n");
}

TEST(FkCli, NoJointsExits2) {
  const Result r = run("fk --model " + kModel);
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err, "exodaq fk: give the joints with --joints-deg or --joints-rad\n");
}

TEST(FkCli, NonNumericJointExits2) {
  const Result r = run("fk --model " + kModel + " --joints-deg 1,2,x,4,5,6");
  EXPECT_EQ(r.code, 2);
  EXPECT_FALSE(r.err.empty());
}

}  // namespace
