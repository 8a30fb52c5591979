// Bad service configurations: exodaqd --check-config names the file, the line
// and what is wrong, and exits 1.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "process.hpp"

namespace {

// A valid configuration, one setting per line so each case can break exactly
// one line and know its number.
std::vector<std::string> base_lines() {
  const std::string cfg = std::string(EXODAQ_SOURCE_DIR) + "/config/";
  return {
      "rig: bench",                                               // 1
      "loop:",                                                    // 2
      "  rate_hz: 1000",                                          // 3
      "  priority: 0",                                            // 4
      "source:",                                                  // 5
      "  backend: sim",                                           // 6
      "  sim:",                                                   // 7
      "    loss_percent: 0",                                      // 8
      "encoders:",                                                // 9
      "  decoding: 4",                                            // 10
      "  stale_ms: 20",                                           // 11
      "  joints:",                                                // 12
      "    - {channel: 0, direction: 1, max_speed_rad_s: 0.64}",  // 13
      "    - {channel: 1, direction: 1, max_speed_rad_s: 1.06}",  // 14
      "    - {channel: 2, direction: 1, max_speed_rad_s: 1.80}",  // 15
      "    - {channel: 3, direction: 1, max_speed_rad_s: 5.38}",  // 16
      "    - {channel: 4, direction: 1, max_speed_rad_s: 5.38}",  // 17
      "    - {channel: 5, direction: 1, max_speed_rad_s: 3.0}",   // 18
      "model: " + cfg + "models/macaque_exo.yaml",                // 19
      "calibration: " + cfg + "calibration/sim.yaml",             // 20
      "lcm:",                                                     // 21
      "  url: \"udpm://239.255.76.67:7667?ttl=0\"",               // 22
      "clock:",                                                   // 23
      "  require_sync: mark",                                     // 24
      "logging:",                                                 // 25
      "  level: info",                                            // 26
  };
}

std::string write(const std::string& dir, const std::string& name,
                  const std::vector<std::string>& lines) {
  const std::string path = dir + "/" + name;
  std::ofstream out(path);
  for (const auto& l : lines) out << l << "\n";
  return path;
}

struct BadCase {
  const char* name;
  int line;              // 1-based line to replace (0: append `text` instead)
  std::string text;      // the new line
  int expected_line;     // line the message must name
  std::string expected;  // the "what" part
};

void PrintTo(const BadCase& c, std::ostream* os) {
  *os << c.name;
}

std::vector<BadCase> cases() {
  const std::string cfg = std::string(EXODAQ_SOURCE_DIR) + "/config/";
  return {
      {"unknown_top_level_key", 0, "rigs: 2", 27, "unknown key 'rigs' in config"},
      {"missing_rig", 1, "# no rig", 2, "missing field 'rig' in config"},
      {"rate_not_a_number", 3, "  rate_hz: fast", 3, "'rate_hz' must be a number, found 'fast'"},
      {"rate_out_of_range", 3, "  rate_hz: 0", 3, "loop.rate_hz must be between 10 and 10000 Hz"},
      {"priority_too_high", 4, "  priority: 120", 4,
       "loop.priority must be 0 (SCHED_OTHER) or a SCHED_FIFO priority 1..99"},
      {"unknown_backend", 6, "  backend: serial", 6,
       "'backend' must be one of sim, socketcan, replay, canopen, found 'serial'"},
      {"loss_out_of_range", 8, "    loss_percent: 150", 8,
       "source.sim.loss_percent must be between 0 and 100"},
      {"unknown_sim_key", 8, "    los_percent: 1", 8,
       "unknown key 'los_percent' in config.source.sim"},
      {"decoding_not_quadrature", 10, "  decoding: 3", 10,
       "encoders.decoding must be 1, 2 or 4 (quadrature decoding factor)"},
      {"stale_not_finite", 11, "  stale_ms: .nan", 11,
       "'stale_ms' must be a finite number, found '.nan'"},
      {"five_joints", 18, "", 13, "encoders.joints must have 6 entries, has 5"},
      {"duplicate_channel", 14, "    - {channel: 0, direction: 1, max_speed_rad_s: 1.06}", 14,
       "channel 0 is used by two joints"},
      {"bad_direction", 15, "    - {channel: 2, direction: 2, max_speed_rad_s: 1.80}", 15,
       "direction must be 1 or -1"},
      {"negative_gear", 16, "    - {channel: 3, gear_ratio: -2, max_speed_rad_s: 5.38}", 16,
       "gear_ratio must be in (0, 100] encoder revolutions per joint revolution"},
      {"missing_speed", 17, "    - {channel: 4, direction: 1}", 17,
       "missing field 'max_speed_rad_s' in encoders.joints[4]"},
      {"unknown_joint_key", 17, "    - {channel: 4, dir: 1, max_speed_rad_s: 5.38}", 17,
       "unknown key 'dir' in encoders.joints[4]"},
      {"bad_url", 22, "  url: \"tcp://10.0.0.1:7667\"", 22,
       "lcm.url must be an LCM URL (udpm://group:port?ttl=N)"},
      // Issue 25.10: plausibility. A joint bound that crosses the joint's whole
      // range (the model's limits) in under 50 ms lets glitches pass as motion.
      {"speed_beyond_anatomy", 13, "    - {channel: 0, direction: 1, max_speed_rad_s: 308}", 13,
       "encoders.joints[0].max_speed_rad_s 308 is beyond joint 'shoulder_azimuth': it would "
       "cross its whole range (191 deg, model '" +
           cfg +
           "models/macaque_exo.yaml') in 10.8 ms; at most 66.6 rad/s (the whole range in 50 "
           "ms): a faster bound lets count glitches pass as motion"},
      {"speed_just_beyond_the_elbow", 17, "    - {channel: 4, direction: 1, max_speed_rad_s: 34}",
       17, "encoders.joints[4].max_speed_rad_s 34 is beyond joint 'elbow_flexion'"},
      // A unicast lcm.url failed only when the daemon started.
      {"unicast_url", 22, "  url: \"udpm://10.0.0.1:7667?ttl=0\"", 22,
       "lcm.url group 10.0.0.1 is a unicast address: udpm:// needs a multicast group, 224.0.0.0 "
       "to 239.255.255.255 (239.255.76.67 is LCM's default)"},
      {"url_group_not_an_address", 22, "  url: \"udpm://lcm-group:7667\"", 22,
       "lcm.url group 'lcm-group' is not an IPv4 address"},
      {"url_without_port", 22, "  url: \"udpm://239.255.76.67?ttl=0\"", 22,
       "lcm.url needs a port 1..65535 after the group (udpm://239.255.76.67:7667)"},
      {"bad_require_sync", 24, "  require_sync: maybe", 24,
       "'require_sync' must be one of ignore, mark, hold, found 'maybe'"},
      {"bad_log_level", 26, "  level: loud", 26,
       "'level' must be one of trace, debug, info, warn, error, critical, off, found 'loud'"},
      {"yaml_syntax", 3, "  rate_hz: [1000", 4, "YAML syntax: end of sequence flow not found"},
  };
}

}  // namespace

class BadConfig : public ::testing::TestWithParam<BadCase> {};

TEST_P(BadConfig, NamesFileLineAndWhatAndExitsOne) {
  const BadCase& c = GetParam();
  const std::string dir = exodaq::test::make_temp_dir("badcfg");
  auto lines = base_lines();
  if (c.line == 0) {
    lines.push_back(c.text);
  } else if (c.text.empty()) {
    lines.erase(lines.begin() + (c.line - 1));
  } else {
    lines[static_cast<std::size_t>(c.line - 1)] = c.text;
  }
  const std::string path = write(dir, std::string(c.name) + ".yaml", lines);
  const auto r = exodaq::test::run({EXODAQD, "--config", path, "--check-config"});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  const std::string where =
      c.expected_line > 0 ? path + ":" + std::to_string(c.expected_line) + ": " : path + ":";
  EXPECT_NE(r.err.find("exodaqd: " + where + c.expected), std::string::npos)
      << "expected: " << where << c.expected << "\n     got: " << r.err;
}

INSTANTIATE_TEST_SUITE_P(Cases, BadConfig, ::testing::ValuesIn(cases()),
                         [](const auto& info) { return std::string(info.param.name); });

// The speed bound at its limit: the elbow's 96.8 deg in 50 ms is 33.79 rad/s.
TEST(BadConfig, ASpeedBoundWithinTheAnatomyIsValid) {
  const std::string dir = exodaq::test::make_temp_dir("speedcfg");
  auto lines = base_lines();
  lines[16] = "    - {channel: 4, direction: 1, max_speed_rad_s: 33.7}";
  const std::string path = write(dir, "fast_elbow.yaml", lines);
  const auto r = exodaq::test::run({EXODAQD, "--config", path, "--check-config"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
}

TEST(BadConfig, TheBaseConfigurationIsValid) {
  const std::string dir = exodaq::test::make_temp_dir("goodcfg");
  const std::string path = write(dir, "good.yaml", base_lines());
  const auto r = exodaq::test::run({EXODAQD, "--config", path, "--check-config"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("configuration valid"), std::string::npos);
}

TEST(BadConfig, MissingModelFileIsNamedWithTheOsReason) {
  const std::string dir = exodaq::test::make_temp_dir("badcfg");
  auto lines = base_lines();
  lines[18] = "model: " + dir + "/nope.yaml";
  const std::string path = write(dir, "missing_model.yaml", lines);
  const auto r = exodaq::test::run({EXODAQD, "--config", path, "--check-config"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(dir + "/nope.yaml: cannot open: No such file or directory"),
            std::string::npos)
      << r.err;
}

TEST(BadConfig, BadCalibrationFileIsNamedWithItsOwnLine) {
  const std::string dir = exodaq::test::make_temp_dir("badcfg");
  std::string cal =
      exodaq::test::read_file(std::string(EXODAQ_SOURCE_DIR) + "/config/calibration/sim.yaml");
  const auto pos = cal.find("encoder_offsets_deg: [49, -93, 85, 6, -5, -4]");
  ASSERT_NE(pos, std::string::npos);
  cal.replace(pos, 45, "encoder_offsets_deg: [49, -93, 85, 6, -5]");
  std::ofstream(dir + "/cal.yaml") << cal;
  int cal_line = 1;
  for (std::size_t i = 0; i < pos; ++i) cal_line += cal[i] == '\n';
  auto lines = base_lines();
  lines[19] = "calibration: " + dir + "/cal.yaml";
  const std::string path = write(dir, "bad_cal.yaml", lines);
  const auto r = exodaq::test::run({EXODAQD, "--config", path, "--check-config"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find(dir + "/cal.yaml:" + std::to_string(cal_line) + ": "), std::string::npos)
      << r.err;
}

TEST(BadConfig, UnreadableConfigExitsOne) {
  const auto r =
      exodaq::test::run({EXODAQD, "--config", "/nonexistent/exodaqd.yaml", "--check-config"});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("/nonexistent/exodaqd.yaml: cannot open: No such file or directory"),
            std::string::npos)
      << r.err;
}
