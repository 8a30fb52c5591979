// Reload's truth table: every setting --print-config shows is classed live or
// restart-only (settings_of), settings are compared by value, and each
// reproduction of issue 15.4 (lock_memory, fault_after_ms, status_rate_hz,
// publish_raw, a renamed joint, logging.level) is a change reload reports.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <fstream>
#include <regex>
#include <set>

#include "exodaq/config/content_hash.hpp"
#include "exodaq/config/service_config.hpp"
#include "exodaq/config/setting_classes.hpp"
#include "process.hpp"

using namespace exodaq::config;

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
