#pragma once
// What a reload (SIGHUP) does with each setting: every setting of a
// ServiceConfig is either applied live, at a cycle boundary, or needs a
// restart, and settings_of() is the one table that says which (a test checks
// it names every key of to_yaml(), so a new setting cannot go unclassified).
// Settings are compared by value: the text of each value, numbers in their
// shortest exact form.
#include <string>
#include <string_view>
#include <vector>

#include "exodaq/config/service_config.hpp"

namespace exodaq::config {

enum class Apply {
  kLive,     // takes effect at the next cycle boundary after the reload
  kRestart,  // read only at start-up: the running value stays until a restart
};

struct Setting {
  std::string key;    // as in --print-config: "loop.lock_memory", "encoders.joints[2].direction"
  std::string value;  // its value as text
  Apply apply = Apply::kLive;
};

// Every setting of `config`, in --print-config's order.
std::vector<Setting> settings_of(const ServiceConfig& config);

struct SettingChange {
  std::string key;
  std::string before;
  std::string after;
  Apply apply = Apply::kLive;
};

// The settings whose values differ, in settings_of()'s order.
std::vector<SettingChange> compare_settings(const ServiceConfig& before,
                                            const ServiceConfig& after);

// "loop.lock_memory (false -> true), lcm.publish_raw (true -> false)"; long
// values are cut to `max_value` bytes with "...".
std::string describe_changes(const std::vector<SettingChange>& changes, std::size_t max_value = 80);

// The shortest text that reads back to the same double ("0.1", "1e-06"; -0 is "0").
std::string setting_number(double v);
// A YAML double-quoted string.
std::string setting_quoted(std::string_view v);
const char* require_sync_name(RequireSync r);

}  // namespace exodaq::config
