// `exodaq ik` end to end: runs the built binary (EXODAQ_TOOL), including a round
// trip through `exodaq fk --json`.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <string>

#include "tool_run.hpp"

namespace {

using exodaq::test::run_tool;
using exodaq::test::ToolResult;

const std::string kModels = std::string(EXODAQ_SOURCE_DIR) + "/config/models/";
const std::string kModel = kModels + "macaque_exo.yaml";
// The home posture's palm: (0, 0, -(L1 + L2)), q = (0, sin 22.5, cos 22.5, 0).
const std::string kHome =
    " --palm-position 0,0,-0.297 --palm-quaternion 0,0.38268343236508978,0.92387953251128674,0";

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

TEST(IkCli, HomePoseText) {
  const ToolResult r = run_tool("ik --model " + kModel + kHome);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, "status: solved, 1 solution within the joint limits")) << r.out;
  EXPECT_TRUE(contains(r.out, "#1 joints (deg): 45.0000 -90.0000 90.0000 0.0000 0.0000 0.0000"))
      << r.out;
  EXPECT_TRUE(contains(r.out, "branch: shoulder_azimuth in [-50.5000, 140.5000] deg")) << r.out;
  EXPECT_TRUE(contains(r.out, "shoulder manipulability: 1.414214 (normalised 1.000000)")) << r.out;
  EXPECT_TRUE(r.err.empty()) << r.err;
}

TEST(IkCli, FkJsonRoundTrip) {
  // fk --json prints the pose at full precision; ik with joint 1 fixed at the
  // posture's value gives the posture back.
  const double q[6] = {30, -70, 40, 10, -40, 20};
  const ToolResult fk =
      run_tool("fk --model " + kModel + " --json --joints-deg 30,-70,40,10,-40,20");
  ASSERT_EQ(fk.code, 0) << fk.err;
  const YAML::Node f = YAML::Load(fk.out);
  std::string pos, rot;
  for (int i = 0; i < 3; ++i) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%s%.17g", i ? "," : "", f["palm_position_m"][i].as<double>());
    pos += buf;
    for (int k = 0; k < 3; ++k) {
      std::snprintf(buf, sizeof buf, "%s%.17g", i + k ? "," : "",
                    f["palm_rotation"][i][k].as<double>());
      rot += buf;
    }
  }
  const ToolResult r =
      run_tool("ik --model " + kModel + " --json --free-joint-deg 30 --palm-position " + pos +
               " --palm-rotation " + rot);
  ASSERT_EQ(r.code, 0) << r.err;
  const YAML::Node j = YAML::Load(r.out);
  EXPECT_EQ(j["status"].as<std::string>(), "solved");
  EXPECT_EQ(j["solver"].as<std::string>(), "closed_form");
  EXPECT_EQ(j["redundancy"].as<int>(), 1);
  EXPECT_EQ(j["free_joint"].as<std::string>(), "shoulder_azimuth");
  ASSERT_EQ(j["solutions"].size(), 1u);
  const YAML::Node s = j["solutions"][0];
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(s["joints_deg"][i].as<double>(), q[i], 1e-9) << i;
  EXPECT_LE(s["position_residual_m"].as<double>(), 1e-12);
  EXPECT_LE(s["orientation_residual_rad"].as<double>(), 1e-12);
  EXPECT_TRUE(s["within_limits"].as<bool>());
  EXPECT_TRUE(s["free_joint_interval_rad"].IsNull());
}

TEST(IkCli, BranchesInJson) {
  const ToolResult r = run_tool("ik --model " + kModel + kHome + " --json");
  ASSERT_EQ(r.code, 0) << r.err;
  const YAML::Node j = YAML::Load(r.out);
  ASSERT_EQ(j["solutions"].size(), 1u);
  EXPECT_NEAR(j["solutions"][0]["free_joint_interval_rad"][0].as<double>(), -50.5 * M_PI / 180,
              1e-12);
  EXPECT_NEAR(j["solutions"][0]["free_joint_interval_rad"][1].as<double>(), 140.5 * M_PI / 180,
              1e-12);
  EXPECT_TRUE(j["elbow_sphere_miss_m"].IsScalar());
}

TEST(IkCli, UnreachableExits1AndSaysWhy) {
  const ToolResult r = run_tool(
      "ik --model " + kModel +
      " --palm-position 0,0,-0.298 --palm-quaternion 0,0.38268343236508978,0.92387953251128674,0");
  EXPECT_EQ(r.code, 1);
  EXPECT_TRUE(contains(r.out,
                       "status: unreachable: no joint vector reaches this palm pose within "
                       "1.0e-06 m and 1.0e-06 rad; the nearest misses by 1.000e-03 m"))
      << r.out;
  EXPECT_TRUE(contains(r.out,
                       "the elbow (fixed in the palm frame) lies 0.001000 m outside the "
                       "sphere the upper arm reaches"))
      << r.out;
  const ToolResult j = run_tool(
      "ik --json --model " + kModel +
      " --palm-position 0,0,-0.298 --palm-quaternion 0,0.38268343236508978,0.92387953251128674,0");
  EXPECT_EQ(j.code, 1);
  const YAML::Node n = YAML::Load(j.out);
  EXPECT_EQ(n["status"].as<std::string>(), "unreachable");
  EXPECT_NEAR(n["elbow_sphere_miss_m"].as<double>(), 1e-3, 1e-12);
  EXPECT_EQ(n["solutions"].size(), 0u);
}

TEST(IkCli, OutsideLimitsExits1AndNamesTheJoint) {
  // fk of (30, -70, 40, 10, -100, 20): elbow at -100 deg, below Table 3's -88.7.
  const ToolResult fk =
      run_tool("fk --model " + kModel + " --json --joints-deg 30,-70,40,10,-100,20");
  ASSERT_EQ(fk.code, 0);
  const YAML::Node f = YAML::Load(fk.out);
  char args[512];
  std::snprintf(args, sizeof args,
                " --palm-position %.17g,%.17g,%.17g --palm-quaternion %.17g,%.17g,%.17g,%.17g",
                f["palm_position_m"][0].as<double>(), f["palm_position_m"][1].as<double>(),
                f["palm_position_m"][2].as<double>(), f["palm_quaternion_wxyz"][0].as<double>(),
                f["palm_quaternion_wxyz"][1].as<double>(),
                f["palm_quaternion_wxyz"][2].as<double>(),
                f["palm_quaternion_wxyz"][3].as<double>());
  const ToolResult r = run_tool("ik --model " + kModel + args);
  EXPECT_EQ(r.code, 1);
  EXPECT_TRUE(contains(r.out, "status: outside_limits")) << r.out;
  EXPECT_TRUE(
      contains(r.out, "outside limits: elbow_flexion (-100.0000 deg, limits [-88.7000, 8.1000])"))
      << r.out;
}

TEST(IkCli, PlanarModelHasTwoSolutions) {
  // Seed 004's arm at (30, 60, -45) deg (exodaq fk --json): palm at (-0.798407, 0.493719, 0) m,
  // turned 45 deg about z; elbow one way or the other.
  const ToolResult r =
      run_tool("ik --model " + kModels +
               "seed004_planar.yaml --palm-position -0.79840663761154795,0.49371872291397034,0 "
               "--palm-quaternion 0.92387953251128674,0,0,0.38268343236508978");
  ASSERT_EQ(r.code, 0) << r.err << r.out;
  EXPECT_TRUE(contains(r.out, "solver: numerical")) << r.out;
  EXPECT_TRUE(contains(r.out, "status: solved, 2 solutions within the joint limits")) << r.out;
  EXPECT_TRUE(contains(r.out, "30.0000 60.0000 -45.0000")) << r.out;
}

TEST(IkCli, BadInputExits2) {
  struct Case {
    std::string args;
    std::string err;
  };
  const Case cases[] = {
      {" --palm-position 0,0 --palm-quaternion 1,0,0,0",
       "exodaq ik: --palm-position needs three finite numbers x,y,z (metres)\n"},
      {" --palm-position 0,0,0",
       "exodaq ik: give the palm orientation with --palm-rotation or --palm-quaternion\n"},
      {" --palm-position 0,0,0 --palm-quaternion 0,0,0,0",
       "exodaq ik: --palm-quaternion has zero length\n"},
      {" --palm-position 0,0,0 --palm-rotation 1,0,0,0,1,0,0,0",
       "exodaq ik: --palm-rotation needs nine finite numbers r11,r12,...,r33 (row by row)\n"},
      {" --palm-position 0,0,0 --palm-rotation 1,0,0,0,1,0,0,0,-1",
       "exodaq ik: --palm-rotation is not a rotation (R^T R differs from I by 0.000000, det "
       "-1.000000; 1e-6 allowed)\n"},
      {" --palm-position 0,0,0 --palm-quaternion 1,0,0,0 --position-tolerance 0",
       "exodaq ik: tolerances must be > 0\n"},
  };
  for (const Case& c : cases) {
    const ToolResult r = run_tool("ik --model " + kModel + c.args);
    EXPECT_EQ(r.code, 2) << c.args;
    EXPECT_EQ(r.err, c.err) << c.args;
    EXPECT_TRUE(r.out.empty()) << r.out;
  }
  const ToolResult m = run_tool(
      "ik --model /nonexistent/model.yaml --palm-position 0,0,0 --palm-quaternion 1,0,0,0");
  EXPECT_EQ(m.code, 2);
  EXPECT_EQ(m.err, "exodaq ik: /nonexistent/model.yaml: cannot open: No such file or directory\n");
  const ToolResult p =
      run_tool("ik --model " + kModels +
               "seed004_planar.yaml --palm-position 0,0,0 --palm-quaternion 1,0,0,0 "
               "--free-joint-deg 3");
  EXPECT_EQ(p.code, 2);
  EXPECT_EQ(p.err, "exodaq ik: model 'seed004_planar' is not redundant: it has no free joint\n");
}

}  // namespace
