// Model-file loader: every documented error names file:line: what.
#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <regex>

#include "exodaq/settings/model_file.hpp"
#include "kin_test_util.hpp"

namespace exodaq::settings {
namespace {

// Line numbers below refer to this text.
const std::string kGood =
    "name: test\n"                          // 1
    "convention: standard_dh\n"             // 2
    "angle_unit: deg\n"                     // 3
    "joints:\n"                             // 4
    "  - name: j1\n"                        // 5
    "    dh: {a: 0, alpha: -90, d: 0}\n"    // 6
    "    limits: [-90, 90]\n"               // 7
    "  - name: j2\n"                        // 8
    "    dh: {a: 0.1, alpha: 0, d: 0.2}\n"  // 9
    "    limits: [-90, 90]\n"               // 10
    "home_posture: [10, 20]\n";             // 11

std::string replace(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

std::string error_of(const std::string& text, const std::string& name = "bad.yaml") {
  try {
    load_model_text(text, name);
  } catch (const ConfigError& e) {
    return e.what();
  } catch (const std::exception& e) {
    return std::string("unexpected exception type: ") + e.what();
  }
  return "no error";
}

TEST(ModelFile, GoodTextLoads) {
  const auto m = load_model_text(kGood, "good.yaml");
  EXPECT_EQ(m.name, "test");
  EXPECT_EQ(m.file, "good.yaml");
  ASSERT_EQ(m.chain.joint_count(), 2);
  EXPECT_EQ(m.chain.joints()[1].name, "j2");
  EXPECT_DOUBLE_EQ(m.chain.joints()[1].dh.a, 0.1);
  EXPECT_DOUBLE_EQ(m.chain.joints()[1].dh.d, 0.2);
  EXPECT_NEAR(m.home_posture[1], 20 * kinematics::test::kDeg, 1e-15);
  EXPECT_EQ(m.rig.elbow_frame, 2);  // defaults: min(4, n)
  EXPECT_EQ(m.rig.shoulder_joints, 2);
  // Millimetres and radians.
  const auto mm = load_model_text(
      replace(replace(replace(kGood, "angle_unit: deg", "angle_unit: rad\nlength_unit: mm"),
                      "limits: [-90, 90]\n  - name: j2", "limits: [-1.5, 1.5]\n  - name: j2"),
              "home_posture: [10, 20]", "home_posture: [0.1, 0.2]"),
      "mm.yaml");
  EXPECT_DOUBLE_EQ(mm.chain.joints()[1].dh.a, 1e-4);
  EXPECT_DOUBLE_EQ(mm.chain.joints()[0].dh.alpha, -90.0);  // radians as written
  EXPECT_DOUBLE_EQ(mm.home_posture[1], 0.2);
}

TEST(ModelFile, InstalledModelsLoad) {
  const auto seed000 = load_model_file(kinematics::test::model_path("macaque_exo.yaml"));
  EXPECT_NEAR(seed000.rig.shoulder_manipulability_max, std::sqrt(2.0), 1e-15);
  const auto seed004 = load_model_file(kinematics::test::model_path("seed004_planar.yaml"));
  EXPECT_EQ(seed004.rig.elbow_frame, 1);
}

struct BadCase {
  const char* what;
  std::string text;
  std::string message;
};

TEST(ModelFile, EveryBadModelGivesItsDocumentedMessage) {
  const std::vector<BadCase> cases = {
      {"unknown key", kGood + "colour: red\n",
       "bad.yaml:12: unknown key 'colour' in model (expected one of: angle_unit, base, "
       "convention, description, elbow_frame, home_posture, joints, length_unit, name, "
       "shoulder_joints, shoulder_manipulability_max, singularity_threshold, tool)"},
      {"unknown key in a joint",
       replace(kGood, "    limits: [-90, 90]\n  - name: j2",
               "    limits: [-90, 90]\n    gear: 2\n  - name: j2"),
       "bad.yaml:8: unknown key 'gear' in joints[0] (expected one of: dh, limits, name)"},
      {"screw in a DH model",
       replace(kGood, "    dh: {a: 0, alpha: -90, d: 0}\n",
               "    dh: {a: 0, alpha: -90, d: 0}\n    screw: {}\n"),
       "bad.yaml:7: unknown key 'screw' in joints[0] (expected one of: dh, limits, name)"},
      {"wrong type", replace(kGood, "d: 0}", "d: abc}"),
       "bad.yaml:6: 'd' must be a number, found 'abc'"},
      {"wrong type: list for a number", replace(kGood, "a: 0.1", "a: [1]"),
       "bad.yaml:9: 'a' must be a number, found a list"},
      {"missing field", replace(kGood, "a: 0, alpha: -90, d: 0", "a: 0, d: 0"),
       "bad.yaml:6: missing field 'alpha' in joints[0].dh"},
      {"missing top-level field", replace(kGood, "angle_unit: deg\n", ""),
       "bad.yaml:1: missing field 'angle_unit' in model"},
      {"non-finite number", replace(kGood, "a: 0.1", "a: .inf"),
       "bad.yaml:9: 'a' must be a finite number, found '.inf'"},
      {"NaN", replace(kGood, "home_posture: [10, 20]", "home_posture: [10, .nan]"),
       "bad.yaml:11: 'home_posture[1]' must be a finite number, found '.nan'"},
      {"wrong array length",
       replace(kGood, "limits: [-90, 90]\n  - name: j2", "limits: [-90, 90, 0]\n  - name: j2"),
       "bad.yaml:7: 'limits' must have 2 numbers, has 3"},
      {"limits reversed",
       replace(kGood, "limits: [-90, 90]\n  - name: j2", "limits: [90, -90]\n  - name: j2"),
       "bad.yaml:7: joint 'j1' limits reversed: lower 90 must be below upper -90"},
      {"unknown convention", replace(kGood, "standard_dh", "craig"),
       "bad.yaml:2: 'convention' must be one of standard_dh, modified_dh, poe, found 'craig'"},
      {"unknown angle unit", replace(kGood, "angle_unit: deg", "angle_unit: grad"),
       "bad.yaml:3: 'angle_unit' must be one of deg, rad, found 'grad'"},
      {"home posture wrong length", replace(kGood, "[10, 20]", "[10]"),
       "bad.yaml:11: 'home_posture' must have 2 numbers (one per joint), has 1"},
      {"home posture outside limits", replace(kGood, "[10, 20]", "[10, 95.5]"),
       "bad.yaml:11: home posture of joint 'j2' (95.5 deg) is outside its limits [-90, 90]"},
      {"joints not a list", replace(kGood, "joints:\n", "joints: 3\nx:\n"),
       "bad.yaml:4: 'joints' must be a list of joints"},
      {"no joints", "name: t\nconvention: poe\nangle_unit: rad\njoints: []\n",
       "bad.yaml:4: 'joints' is empty: a model needs at least one joint"},
      {"duplicate joint name", replace(kGood, "name: j2", "name: j1"),
       "bad.yaml:8: duplicate joint name 'j1'"},
      {"YAML syntax",
       replace(kGood, "limits: [-90, 90]\n  - name: j2", "limits: [-90, 90\n  - name: j2"),
       "bad.yaml:8: YAML syntax: end of sequence flow not found"},
      {"empty", "", "bad.yaml: empty document"},
      {"not a mapping", "- 1\n- 2\n", "bad.yaml:1: top level must be a mapping, found a list"},
      {"home_pose in a DH model", kGood + "home_pose: {translation: [0, 0, 0]}\n",
       "bad.yaml:12: 'home_pose' is only used with convention poe: give 'tool' (frame n to "
       "palm) for standard_dh"},
      {"not a rotation", kGood + "tool:\n  rotation: [[1, 0, 0], [0, 1, 0], [0, 0, 2]]\n",
       "bad.yaml:13: 'rotation' in model.tool is not a rotation matrix (R R^T must be I and "
       "det R = 1 to 1e-6)"},
      {"rpy and rotation",
       kGood + "base: {rpy: [0, 0, 0], rotation: [[1, 0, 0], [0, 1, 0], [0, 0, 1]]}\n",
       "bad.yaml:12: give either 'rpy' or 'rotation' in model.base, not both"},
      {"translation length", kGood + "base: {translation: [0, 0]}\n",
       "bad.yaml:12: 'translation' must have 3 numbers, has 2"},
      {"elbow frame out of range", kGood + "elbow_frame: 4\n",
       "bad.yaml:12: 'elbow_frame' must be a frame 0..3 (0 = base, 3 = palm), found 4"},
      {"shoulder joints out of range", kGood + "shoulder_joints: 0\n",
       "bad.yaml:12: 'shoulder_joints' must be 1..2, found 0"},
  };
  for (const auto& c : cases) {
    EXPECT_EQ(error_of(c.text), c.message) << c.what;
  }
}

const std::string kPoe =
    "name: p\n"                                      // 1
    "convention: poe\n"                              // 2
    "angle_unit: deg\n"                              // 3
    "joints:\n"                                      // 4
    "  - name: j1\n"                                 // 5
    "    screw: {omega: [0, 0, 1], q: [0, 0, 0]}\n"  // 6
    "    limits: [-90, 90]\n"                        // 7
    "home_pose: {translation: [1, 0, 0]}\n";         // 8

TEST(ModelFile, PoeErrors) {
  EXPECT_EQ(error_of(kPoe), "no error");
  EXPECT_EQ(error_of(replace(kPoe, "omega: [0, 0, 1]", "omega: [0, 0, 0]")),
            "bad.yaml:6: joint 'j1': screw axis 'omega' has zero length");
  EXPECT_EQ(error_of(replace(kPoe, "home_pose: {translation: [1, 0, 0]}\n", "")),
            "bad.yaml:1: missing field 'home_pose' in model");
  EXPECT_EQ(error_of(kPoe + "tool: {translation: [0, 0, 0]}\n"),
            "bad.yaml:9: 'tool' is not used with convention poe: give the palm pose at q = 0 as "
            "'home_pose'");
  EXPECT_EQ(error_of(replace(kPoe, "q: [0, 0, 0]", "q: [0, 0]")),
            "bad.yaml:6: 'q' must have 3 numbers, has 2");
  EXPECT_EQ(error_of(replace(kPoe, "screw:", "dh:")),
            "bad.yaml:5: missing field 'screw' in joints[0]");
}

TEST(ModelFile, TooManyJoints) {
  std::string text = "name: t\nconvention: standard_dh\nangle_unit: deg\njoints:\n";
  for (int i = 0; i < kinematics::kMaxJoints + 1; ++i) {
    text += "  - {name: j" + std::to_string(i) + ", dh: {a: 0, alpha: 0, d: 0}, limits: [-1, 1]}\n";
  }
  EXPECT_EQ(error_of(text), "bad.yaml:5: 'joints' has 9 joints, at most 8 are supported");
}

TEST(ModelFile, UnreadableFile) {
  try {
    load_model_file("/nonexistent/model.yaml");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_EQ(std::string(e.what()),
              "/nonexistent/model.yaml: cannot open: No such file or directory");
  }
}

TEST(ModelFile, ErrorsCarryFileAndLine) {
  try {
    load_model_text(replace(kGood, "d: 0}", "d: abc}"), "x.yaml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.file(), "x.yaml");
    EXPECT_EQ(e.line(), 6);
    EXPECT_EQ(e.reason(), "'d' must be a number, found 'abc'");
  }
}

// The loader never crashes: every mutation of a real model file either loads or
// throws ConfigError naming the file.
TEST(ModelFile, MutatedFilesNeverEscapeConfigError) {
  std::ifstream in(kinematics::test::model_path("macaque_exo.yaml"));
  const std::string base((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_GT(base.size(), 100u);
  std::mt19937_64 rng(10);
  const std::string alphabet = " \n\t:-[]{},#&*!|>'\"%@`0123456789.eEinfa_zx";
  int loaded = 0, rejected = 0;
  for (int t = 0; t < 3000; ++t) {
    std::string text = base;
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int e = 0; e < edits; ++e) {
      const std::size_t at = rng() % (text.size() + 1);
      switch (rng() % 3) {
        case 0:
          text.insert(at, 1, alphabet[rng() % alphabet.size()]);
          break;
        case 1:
          if (at < text.size()) text.erase(at, 1 + rng() % 8);
          break;
        default:
          if (at < text.size()) text[at] = alphabet[rng() % alphabet.size()];
          break;
      }
    }
    try {
      load_model_text(text, "fuzz.yaml");
      ++loaded;
    } catch (const ConfigError& e) {
      ++rejected;
      ASSERT_EQ(std::string(e.what()).rfind("fuzz.yaml", 0), 0u) << e.what();
    }
  }
  EXPECT_GT(rejected, 0);
  EXPECT_GT(loaded, 0);
}

}  // namespace
}  // namespace exodaq::settings
