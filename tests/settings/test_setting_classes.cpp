// Reload's truth table: every setting --print-config shows is classed live or
// restart-only (settings_of), settings are compared by value, and each
// reproduction of issue 15.4 (lock_memory, fault_after_ms, status_rate_hz,
// publish_raw, a renamed joint, logging.level) is a change reload reports.
// The declarations (setting_list.hpp) against what users read: every key of
// config/*.yaml is declared, and the table in docs/operations.md is theirs.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "exodaq/settings/content_hash.hpp"
#include "exodaq/settings/service_config.hpp"
#include "exodaq/settings/setting_classes.hpp"
#include "process.hpp"

using namespace exodaq::settings;

namespace {
const std::string kConfigDir = std::string(EXODAQ_SOURCE_DIR) + "/config/";

using exodaq::test::read_file;

std::string sim_text() {
  return read_file(kConfigDir + "sim.yaml");
}

ServiceConfig load(const std::string& text) {
  return load_service_config_text(text, kConfigDir + "sim.yaml");
}

std::string replaced(std::string text, const std::string& from, const std::string& to) {
  const auto at = text.find(from);
  EXPECT_NE(at, std::string::npos) << from;
  if (at != std::string::npos) text.replace(at, from.size(), to);
  return text;
}

// Every leaf of a YAML document as "a.b[2].c".
void leaves(const YAML::Node& n, const std::string& key, std::set<std::string>& out) {
  if (n.IsMap()) {
    for (const auto& kv : n) {
      const std::string k = kv.first.as<std::string>();
      leaves(kv.second, key.empty() ? k : key + "." + k, out);
    }
  } else if (n.IsSequence()) {
    for (std::size_t i = 0; i < n.size(); ++i)
      leaves(n[i], key + "[" + std::to_string(i) + "]", out);
  } else {
    out.insert(key);
  }
}

const SettingChange* find(const std::vector<SettingChange>& changes, const std::string& key) {
  for (const auto& c : changes) {
    if (c.key == key) return &c;
  }
  return nullptr;
}
}  // namespace

TEST(ContentHash, IsTheSha256OfTheBytes) {
  // FIPS 180-2 test vectors.
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  const ServiceConfig c = load_service_config(kConfigDir + "sim.yaml");
  EXPECT_EQ(c.config_sha256, sha256_hex(sim_text()));
  EXPECT_EQ(c.calibration_sha256, sha256_hex(read_file(c.calibration_path)));
  EXPECT_EQ(c.model_sha256, sha256_hex(read_file(c.model_path)));
}

TEST(SettingClasses, EverySettingPrintConfigShowsIsClassedOnce) {
  const ServiceConfig c = load(sim_text());
  std::set<std::string> shown;
  leaves(YAML::Load(to_yaml(c)), "", shown);
  std::set<std::string> classed;
  for (const auto& s : settings_of(c)) {
    EXPECT_TRUE(classed.insert(s.key).second) << s.key << " classed twice";
  }
  // A classed key covers itself and, for a value shown as a map (source), its parts.
  const auto covered = [&classed](const std::string& leaf) {
    for (std::string k = leaf;;) {
      if (classed.count(k) != 0) return true;
      const auto dot = k.rfind('.');
      if (dot == std::string::npos) return false;
      k.resize(dot);
    }
  };
  for (const auto& leaf : shown) EXPECT_TRUE(covered(leaf)) << leaf << " is in no class";
  for (const auto& key : classed) {
    const bool in_yaml = std::any_of(shown.begin(), shown.end(), [&key](const std::string& l) {
      return l == key || l.rfind(key + ".", 0) == 0;
    });
    EXPECT_TRUE(in_yaml) << key << " classed but not shown by --print-config";
  }
  EXPECT_GE(classed.size(), 60U);
  // In --print-config's order: reload's messages list changes as it shows them.
  std::vector<std::string> printed;
  std::istringstream yaml(to_yaml(c));
  for (std::string line; std::getline(yaml, line);) {
    const auto colon = line.find(':');
    if (line.empty() || line[0] == ' ' || line[0] == '#' || colon == std::string::npos) continue;
    printed.push_back(line.substr(0, colon));
  }
  std::vector<std::string> sections;
  for (const auto& s : settings_of(c)) {
    const std::string top = s.key.substr(0, s.key.find_first_of(".["));
    if (sections.empty() || sections.back() != top) sections.push_back(top);
  }
  EXPECT_EQ(sections, printed);
}

TEST(SettingClasses, TheIssueReproductionsAreEachReported) {
  const std::string base = sim_text();
  const ServiceConfig before = load(base);
  std::string text = replaced(base, "lock_memory: false", "lock_memory: true");
  text = replaced(text, "fault_after_ms: 500", "fault_after_ms: 400\n  status_rate_hz: 20");
  text = replaced(text, "publish_raw: true", "publish_raw: false");
  text = replaced(text, "level: info", "level: debug");
  // A renamed joint: the model file, copied with one name changed.
  const std::string model = exodaq::test::make_temp_dir("setting-classes") + "/model.yaml";
  std::ofstream(model) << std::regex_replace(read_file(kConfigDir + "models/macaque_exo.yaml"),
                                             std::regex("elbow_flexion"), "elbow");
  text = replaced(text, "model: models/macaque_exo.yaml", "model: " + model);
  const ServiceConfig after = load(text);
  const auto changes = compare_settings(before, after);

  const std::vector<std::pair<std::string, Apply>> expected = {
      {"loop.lock_memory", Apply::kRestart},
      {"loop.fault_after_ms", Apply::kRestart},
      {"loop.status_rate_hz", Apply::kRestart},
      {"lcm.publish_raw", Apply::kRestart},
      {"model.joint_names[4]", Apply::kRestart},
      {"logging.level", Apply::kLive},
      {"model.path", Apply::kLive},
      {"config.sha256", Apply::kLive},
  };
  for (const auto& [key, apply] : expected) {
    const SettingChange* c = find(changes, key);
    ASSERT_NE(c, nullptr) << key << " not reported: " << describe_changes(changes);
    EXPECT_EQ(c->apply, apply) << key;
  }
  EXPECT_EQ(find(changes, "model.joint_names[4]")->before, "elbow_flexion");
  EXPECT_EQ(find(changes, "model.joint_names[4]")->after, "elbow");
  EXPECT_EQ(find(changes, "loop.status_rate_hz")->before, "10");
  EXPECT_EQ(find(changes, "loop.status_rate_hz")->after, "20");
  // The model's hash changed too (its content did); nothing else.
  EXPECT_NE(find(changes, "model.sha256"), nullptr);
  EXPECT_EQ(changes.size(), expected.size() + 1) << describe_changes(changes);
  EXPECT_NE(describe_changes(changes).find("loop.lock_memory (false -> true)"), std::string::npos);
}

// Which reloads start a new segment (SAMPLE_NEW_SEGMENT): those that change
// how counts become angles or angles the palm pose, and no other.
TEST(SettingClasses, ANewSegmentComesWithTheCalibrationModelOrEncoderGeometry) {
  const std::string base = sim_text();
  const ServiceConfig before = load(base);
  const auto segment = [&before](const std::string& text) {
    return starts_new_segment(compare_settings(before, load(text)));
  };
  const std::string cal = exodaq::test::make_temp_dir("segment") + "/calibration.yaml";
  std::ofstream(cal) << replaced(read_file(kConfigDir + "calibration/sim.yaml"),
                                 "encoder_offsets_deg: [49,", "encoder_offsets_deg: [79,");
  EXPECT_TRUE(segment(replaced(base, "calibration: calibration/sim.yaml", "calibration: " + cal)));
  EXPECT_TRUE(segment(replaced(base, "decoding: 4 ", "decoding: 2 ")));
  EXPECT_TRUE(segment(replaced(base, "{channel: 3, direction: -1,", "{channel: 3, direction: 1,")));
  EXPECT_TRUE(segment(replaced(base, "{channel: 0, direction: 1, gear_ratio: 1,",
                               "{channel: 0, direction: 1, gear_ratio: 2,")));
  EXPECT_FALSE(segment(base));
  EXPECT_FALSE(segment(replaced(base, "level: info", "level: debug")));
  EXPECT_FALSE(segment(replaced(base, "stale_ms: 20", "stale_ms: 30")));
  EXPECT_FALSE(segment(replaced(base, "max_speed_rad_s: 0.64}", "max_speed_rad_s: 0.7}")));
  // Restart-only changes apply nothing, so they start nothing.
  EXPECT_FALSE(segment(replaced(base, "lock_memory: false", "lock_memory: true")));
}

TEST(SettingClasses, ComparedByValueNotByText) {
  const std::string base = sim_text();
  // The same values spelled differently, and a comment: only the file's hash differs.
  std::string text = replaced(base, "rate_hz: 1000 ", "rate_hz: 1000.0 ");
  text = replaced(text, "speed_margin: 1.5", "speed_margin: 1.50");
  text += "# a comment\n";
  const auto changes = compare_settings(load(base), load(text));
  ASSERT_EQ(changes.size(), 1U) << describe_changes(changes);
  EXPECT_EQ(changes[0].key, "config.sha256");
  EXPECT_EQ(changes[0].apply, Apply::kLive);
  EXPECT_TRUE(compare_settings(load(base), load(base)).empty());
}

TEST(SettingClasses, NumbersInTheirShortestExactForm) {
  EXPECT_EQ(setting_number(0.1), "0.1");
  EXPECT_EQ(setting_number(-0.0), "0");
  EXPECT_EQ(setting_number(1000.0), "1000");
  EXPECT_EQ(setting_number(1e-6), "1e-06");
  EXPECT_EQ(std::stod(setting_number(0.1 + 0.2)), 0.1 + 0.2);
  EXPECT_EQ(setting_quoted("a\"b\\c\n"), "\"a\\\"b\\\\c\\x0a\"");
}

namespace {
// A leaf key with its joint index made generic: "encoders.joints[].channel".
std::string generic_key(const std::string& key) {
  return std::regex_replace(key, std::regex(R"(\[[0-9]+\])"), "[]");
}
}  // namespace

// Every key the shipped configurations write is a declared setting (or names
// a file, or lies in the source section its backend declares), and every
// declared setting is in the docs' table.
TEST(SettingDeclarations, EveryKeyOfTheShippedConfigsIsDeclared) {
  std::set<std::string> declared;
  for (const auto& s : settings_of(load(sim_text()))) declared.insert(generic_key(s.key));
  int files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(kConfigDir)) {
    if (entry.path().extension() != ".yaml") continue;
    ++files;
    std::set<std::string> written;
    leaves(YAML::LoadFile(entry.path().string()), "", written);
    for (const auto& key : written) {
      if (key == "model" || key == "calibration" || key.rfind("source.", 0) == 0) continue;
      EXPECT_EQ(declared.count(generic_key(key)), 1U)
          << entry.path().filename().string() << ": " << key << " is not declared";
    }
    // Each loads: its values obey the declarations' rules.
    EXPECT_NO_THROW(load_service_config(entry.path().string())) << entry.path();
  }
  EXPECT_GE(files, 3);
}

TEST(SettingDeclarations, TheDocsTableIsTheDeclarations) {
  const std::string doc = read_file(std::string(EXODAQ_SOURCE_DIR) + "/docs/operations.md");
  const std::string begin = "<!-- settings table: generated";
  const std::string end = "<!-- end of settings table -->";
  const auto from = doc.find(begin);
  ASSERT_NE(from, std::string::npos) << "docs/operations.md has no '" << begin << "' marker";
  const auto table_from = doc.find('\n', from) + 1;
  const auto to = doc.find(end, table_from);
  ASSERT_NE(to, std::string::npos) << "docs/operations.md has no '" << end << "' marker";
  EXPECT_EQ(doc.substr(table_from, to - table_from), settings_table())
      << "regenerate it: cmake --build build --target docs-settings-table";
  // One row per declared setting, a joint's once.
  std::set<std::string> declared;
  for (const auto& s : settings_of(load(sim_text()))) declared.insert(generic_key(s.key));
  for (const auto& key : declared) {
    const bool file_fact = key == "source" || key.rfind("config.", 0) == 0 ||
                           key.rfind("model.", 0) == 0 || key.rfind("calibration.", 0) == 0;
    EXPECT_EQ(file_fact, settings_table().find("| `" + key + "` |") == std::string::npos) << key;
  }
}

// The rule a declaration gives is the one the parser applies, in the words
// the table shows.
TEST(SettingDeclarations, TheParserAppliesTheDeclaredRules) {
  const std::string base = sim_text();
  const auto error = [&](const std::string& from, const std::string& to) {
    try {
      load(replaced(base, from, to));
    } catch (const exodaq::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("(accepted)");
  };
  const std::string table = settings_table();
  EXPECT_NE(error("velocity_window: 21", "velocity_window: 65")
                .find("encoders.velocity_window must be between 2 and 64"),
            std::string::npos);
  EXPECT_NE(table.find("| `encoders.velocity_window` | integer | 21 | must be between 2 and 64 |"),
            std::string::npos)
      << table;
  EXPECT_NE(error("step_threshold_ms: 2", "step_threshold_ms: 0")
                .find("clock.step_threshold_ms must be positive"),
            std::string::npos);
  // Written in ms, kept in ns.
  EXPECT_EQ(load(replaced(base, "step_threshold_ms: 2", "step_threshold_ms: 2.5"))
                .clock.step_threshold_ns,
            2'500'000);
  EXPECT_NE(error("decoding: 4 ", "decoding: 3 ").find("encoders.decoding must be 1, 2 or 4"),
            std::string::npos);
  EXPECT_EQ(load(base).clock.require_sync, RequireSync::kIgnore);
  EXPECT_EQ(load(replaced(base, "require_sync: ignore", "require_sync: hold")).clock.require_sync,
            RequireSync::kHold);
}
