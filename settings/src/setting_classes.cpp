#include "exodaq/config/setting_classes.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <map>

namespace exodaq::config {

std::string setting_number(double v) {
  if (v == 0.0) return "0";
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string setting_quoted(std::string_view v) {
  std::string out = "\"";
  for (const char c : v) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", static_cast<unsigned char>(c));
      out += buf;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

const char* require_sync_name(RequireSync r) {
  switch (r) {
    case RequireSync::kIgnore:
      return "ignore";
    case RequireSync::kHold:
      return "hold";
    case RequireSync::kMark:
      break;
  }
  return "mark";
}

namespace {

class Table {
 public:
  void live(std::string key, std::string value) {
    add(std::move(key), std::move(value), Apply::kLive);
  }
  void restart(std::string key, std::string value) {
    add(std::move(key), std::move(value), Apply::kRestart);
  }
  template <typename T>
  static std::string text(const T& v) {
    if constexpr (std::is_same_v<T, bool>) {
      return v ? "true" : "false";
    } else if constexpr (std::is_floating_point_v<T>) {
      return setting_number(v);
    } else if constexpr (std::is_integral_v<T>) {
      return std::to_string(v);
    } else {
      return std::string(v);
    }
  }
  std::vector<Setting> take() { return std::move(rows_); }

 private:
  void add(std::string key, std::string value, Apply apply) {
    rows_.push_back({std::move(key), std::move(value), apply});
  }
  std::vector<Setting> rows_;
};

// Read only at start-up: the loop thread's scheduling and rate, the status
// rate and fault delay (the loop's state machine), the source, the LCM
// transport and channels, the names strings carried in every message.
void start_up_settings(const ServiceConfig& c, Table& t) {
  t.restart("rig", c.rig);
  t.restart("loop.rate_hz", Table::text(c.loop.rate_hz));
  t.restart("loop.cpu", Table::text(c.loop.cpu));
  t.restart("loop.priority", Table::text(c.loop.priority));
  t.restart("loop.lock_memory", Table::text(c.loop.lock_memory));
  t.restart("loop.fault_after_ms", Table::text(c.loop.fault_after_ms));
  t.restart("loop.status_rate_hz", Table::text(c.loop.status_rate_hz));
  t.restart("source", drivers::describe(c.source));
}

// Applied at a cycle boundary: the joint trackers (a change of channel,
// direction, gear ratio or counts per revolution re-homes the joint), the
// chain with its calibration, the clock policy.
void encoder_settings(const ServiceConfig& c, Table& t) {
  const EncoderSettings& e = c.encoders;
  t.live("encoders.cycles_per_rev", Table::text(e.cycles_per_rev));
  t.live("encoders.decoding", Table::text(e.decoding));
  t.live("encoders.stale_ms", Table::text(e.stale_ms));
  t.live("encoders.index_tolerance_counts", Table::text(e.index_tolerance_counts));
  t.live("encoders.limit_margin_deg", Table::text(e.limit_margin_deg));
  t.live("encoders.speed_margin", Table::text(e.speed_margin));
  t.live("encoders.velocity_window", Table::text(e.velocity_window));
  t.live("encoders.fault_hold_ms", Table::text(e.fault_hold_ms));
  for (std::size_t i = 0; i < e.joints.size(); ++i) {
    const std::string j = "encoders.joints[" + std::to_string(i) + "].";
    t.live(j + "channel", Table::text(e.joints[i].channel));
    t.live(j + "direction", Table::text(e.joints[i].direction));
    t.live(j + "gear_ratio", Table::text(e.joints[i].gear_ratio));
    t.live(j + "max_speed_rad_s", Table::text(e.joints[i].max_speed_rad_s));
  }
}

void file_settings(const ServiceConfig& c, Table& t) {
  t.live("model.path", c.model_path);
  t.live("model.sha256", c.model_sha256);
  t.live("model.name", c.model.name);
  // The joint names are in every joint_state_t and status_t the loop encodes
  // from strings set at start-up (the loop assigns no strings).
  for (std::size_t i = 0; i < c.model.chain.joints().size(); ++i) {
    t.restart("model.joint_names[" + std::to_string(i) + "]", c.model.chain.joints()[i].name);
  }
  t.live("calibration.path", c.calibration_path);
  t.live("calibration.sha256", c.calibration_sha256);
  t.live("calibration.provenance", provenance_text(c.calibration.provenance));
  for (std::size_t i = 0; i < c.calibration.encoder_offset_rad.size(); ++i) {
    t.live("calibration.encoder_offsets_deg[" + std::to_string(i) + "]",
           Table::text(c.calibration.encoder_offset_rad[i] / kDegToRad));
  }
  t.live("kinematics.singularity_threshold", Table::text(c.singularity_threshold));
}

}  // namespace

std::vector<Setting> settings_of(const ServiceConfig& c) {
  Table t;
  // The file itself: read again by every reload (the path cannot change).
  t.live("config.path", c.file);
  t.live("config.sha256", c.config_sha256);
  start_up_settings(c, t);
  encoder_settings(c, t);
  file_settings(c, t);
  t.restart("lcm.url", c.lcm.url);
  t.restart("lcm.prefix", c.lcm.prefix);
  t.restart("lcm.publish_raw", Table::text(c.lcm.publish_raw));
  t.live("clock.require_sync", require_sync_name(c.clock.require_sync));
  t.live("clock.max_est_error_us", Table::text(c.clock.max_est_error_us));
  t.live("clock.max_max_error_us", Table::text(c.clock.max_max_error_us));
  t.live("clock.step_threshold_ms",
         Table::text(static_cast<double>(c.clock.step_threshold_ns) / 1e6));
  t.live("clock.slew_ppm", Table::text(c.clock.slew_ppm));
  t.live("clock.step_slew_ppm", Table::text(c.clock.step_slew_ppm));
  // The daemon sets the level at once (unless --log-level or SPDLOG_LEVEL
  // overrides it); the sink is opened at start-up.
  t.live("logging.level", c.logging.level);
  t.restart("logging.sink", c.logging.sink);
  return t.take();
}

std::vector<SettingChange> compare_settings(const ServiceConfig& before,
                                            const ServiceConfig& after) {
  const std::vector<Setting> a = settings_of(before);
  const std::vector<Setting> b = settings_of(after);
  std::map<std::string, const Setting*> old;
  for (const auto& s : a) old[s.key] = &s;
  std::vector<SettingChange> out;
  for (const auto& s : b) {
    const auto it = old.find(s.key);
    const std::string was = it == old.end() ? "(none)" : it->second->value;
    if (it != old.end()) old.erase(it);
    if (was != s.value) out.push_back({s.key, was, s.value, s.apply});
  }
  // Keys only the old configuration had (none today: the lists have fixed keys).
  for (const auto& s : a) {
    if (old.count(s.key) != 0) out.push_back({s.key, s.value, "(none)", s.apply});
  }
  return out;
}

std::string describe_changes(const std::vector<SettingChange>& changes, std::size_t max_value) {
  const auto cut = [max_value](const std::string& v) {
    return v.size() <= max_value ? v : v.substr(0, max_value) + "...";
  };
  std::string out;
  for (const auto& c : changes) {
    if (!out.empty()) out += ", ";
    out += c.key + " (" + cut(c.before) + " -> " + cut(c.after) + ")";
  }
  return out;
}

}  // namespace exodaq::config
