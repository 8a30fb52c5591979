#pragma once
// What a reload (SIGHUP) does with each setting: every setting of a
// ServiceConfig is either applied live, at a cycle boundary, or needs a
// restart. settings_of() lists them: the declared settings with the class
// their declaration gives (setting_list.hpp), and the files' facts (paths,
// hashes, joint names); a test checks it names every key of to_yaml().
// Settings are compared by value: the text of each value, numbers in their
// shortest exact form.
#include <string>
#include <string_view>
#include <vector>

#include "exodaq/settings/service_config.hpp"

namespace exodaq::settings {

enum class Apply {
  kLive,     // takes effect at the next cycle boundary after the reload
  kRestart,  // read only at start-up: the running value stays until a restart
};

struct Setting {
  std::string key;    // as in --print-config: "loop.lock_memory", "encoders.joints[2].direction"
  std::string value;  // its value as text
  Apply apply = Apply::kLive;
  bool new_segment = false;  // a live change moves the samples (starts_new_segment)
};

// Every setting of `config`, in --print-config's order.
std::vector<Setting> settings_of(const ServiceConfig& config);

struct SettingChange {
  std::string key;
  std::string before;
  std::string after;
  Apply apply = Apply::kLive;
  bool new_segment = false;
};

// The settings whose values differ, in settings_of()'s order.
std::vector<SettingChange> compare_settings(const ServiceConfig& before,
                                            const ServiceConfig& after);

// Whether applying `changes` changes how counts become angles or angles the
// palm pose: the model or calibration file's content, an encoder's
// resolution, channel, direction or gear ratio. The samples after such a
// reload start a new segment (SAMPLE_NEW_SEGMENT): positions may jump there.
bool starts_new_segment(const std::vector<SettingChange>& changes);

// The settings table of docs/operations.md (Markdown): one row per declared
// setting (a joint's as encoders.joints[].key) with its type, default, rule,
// unit, reload class and doc line.
std::string settings_table();

// "loop.lock_memory (false -> true), lcm.publish_raw (true -> false)"; long
// values are cut to `max_value` bytes with "...".
std::string describe_changes(const std::vector<SettingChange>& changes, std::size_t max_value = 80);

// The shortest text that reads back to the same double ("0.1", "1e-06"; -0 is "0").
std::string setting_number(double v);
// A YAML double-quoted string.
std::string setting_quoted(std::string_view v);

}  // namespace exodaq::settings
