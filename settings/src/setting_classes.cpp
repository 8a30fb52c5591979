#include "exodaq/settings/setting_classes.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <map>
#include <type_traits>

#include "exodaq/common/yaml_reader.hpp"
#include "setting_visit.hpp"

namespace exodaq::settings {

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

namespace detail {

std::vector<std::string> choices_of(const Rule& r) {
  std::vector<std::string> out;
  std::string_view rest = r.choices;
  while (!rest.empty()) {
    const auto bar = rest.find('|');
    out.emplace_back(rest.substr(0, bar));
    rest = bar == std::string_view::npos ? std::string_view{} : rest.substr(bar + 1);
  }
  return out;
}

std::string value_text(const Declaration&, bool v) {
  return v ? "true" : "false";
}
std::string value_text(const Declaration& d, int v) {
  return value_text(d, static_cast<std::int64_t>(v));
}
std::string value_text(const Declaration& d, std::int64_t v) {
  if (d.unit.scale != 1.0) return setting_number(static_cast<double>(v) / d.unit.scale);
  return std::to_string(v);
}
std::string value_text(const Declaration&, double v) {
  return setting_number(v);
}
std::string value_text(const Declaration&, const std::string& v) {
  return v;
}
std::string value_text(const Declaration& d, RequireSync v) {
  const auto choices = choices_of(d.rule);
  const auto i = static_cast<std::size_t>(v);
  return i < choices.size() ? choices[i] : "?";
}

}  // namespace detail

namespace {

using detail::Declaration;

Setting setting(std::string key, std::string value, Apply apply, bool new_segment = false) {
  return {std::move(key), std::move(value), apply, new_segment};
}

// The files' facts: the config itself (read again by every reload; its path
// cannot change), the source (restart-only, with all its backend's options),
// the model and calibration files (a new content starts a new segment).
void config_facts(const ServiceConfig& c, std::vector<Setting>& t) {
  t.push_back(setting("config.path", c.file, Apply::kLive));
  t.push_back(setting("config.sha256", c.config_sha256, Apply::kLive));
}

void source_facts(const ServiceConfig& c, std::vector<Setting>& t) {
  t.push_back(setting("source", drivers::describe(c.source), Apply::kRestart));
}

void file_facts(const ServiceConfig& c, std::vector<Setting>& t) {
  t.push_back(setting("model.path", c.model_path, Apply::kLive));
  t.push_back(setting("model.sha256", c.model_sha256, Apply::kLive, true));
  t.push_back(setting("model.name", c.model.name, Apply::kLive));
  // The joint names are in every joint_state_t and status_t the loop encodes
  // from strings set at start-up (the loop assigns no strings).
  for (std::size_t i = 0; i < c.model.chain.joints().size(); ++i) {
    t.push_back(setting("model.joint_names[" + std::to_string(i) + "]",
                        c.model.chain.joints()[i].name, Apply::kRestart));
  }
  t.push_back(setting("calibration.path", c.calibration_path, Apply::kLive));
  t.push_back(setting("calibration.sha256", c.calibration_sha256, Apply::kLive, true));
  t.push_back(
      setting("calibration.provenance", provenance_text(c.calibration.provenance), Apply::kLive));
  for (std::size_t i = 0; i < c.calibration.encoder_offset_rad.size(); ++i) {
    t.push_back(setting("calibration.encoder_offsets_deg[" + std::to_string(i) + "]",
                        setting_number(c.calibration.encoder_offset_rad[i] / kDegToRad),
                        Apply::kLive));
  }
}

std::string full_key(const std::string& section, const Declaration& d) {
  return section.empty() ? std::string(d.key) : section + "." + std::string(d.key);
}

}  // namespace

std::vector<Setting> settings_of(const ServiceConfig& c) {
  std::vector<Setting> t;
  config_facts(c, t);
  // The facts where --print-config shows them: the source before the
  // encoders, the files before kinematics.
  std::string last;
  detail::visit_settings(c, [&](const std::string& section, const Declaration& d, const auto& v) {
    if (section != last && section == "encoders") source_facts(c, t);
    if (section != last && section == "kinematics") file_facts(c, t);
    last = section;
    t.push_back(setting(full_key(section, d), detail::value_text(d, v),
                        d.reload == Reload::kRestart ? Apply::kRestart : Apply::kLive,
                        d.reload == Reload::kNewSegment));
  });
  return t;
}

namespace {

const char* type_name(const Declaration&, bool) {
  return "true/false";
}
const char* type_name(const Declaration& d, double) {
  return d.rule.choices.empty() ? "number" : "one of";
}
template <typename T, typename = std::enable_if_t<std::is_integral_v<T>>>
const char* type_name(const Declaration& d, T) {
  if (!d.rule.choices.empty()) return "one of";
  return d.unit.scale != 1.0 ? "number" : "integer";
}
const char* type_name(const Declaration& d, const std::string&) {
  return d.rule.choices.empty() ? "text" : "one of";
}
const char* type_name(const Declaration&, RequireSync) {
  return "one of";
}

// A rule for a reader: the error's words after the key, or the choices.
std::string rule_text(const Declaration& d) {
  std::string text(d.rule.text);
  if (text.empty() && !d.rule.choices.empty()) {
    text = "one of";
    for (const auto& c : detail::choices_of(d.rule)) text += (text.size() == 6 ? " " : ", ") + c;
  }
  return text.empty() ? "-" : text;
}

const char* reload_name(Reload r) {
  switch (r) {
    case Reload::kLive:
      return "live";
    case Reload::kNewSegment:
      return "live, new segment";
    case Reload::kRestart:
      break;
  }
  return "restart";
}

}  // namespace

std::string settings_table() {
  std::string out =
      "| key | type | default | rule | unit | reload | what |\n"
      "|---|---|---|---|---|---|---|\n";
  const ServiceConfig defaults;
  detail::visit_settings(defaults, [&](const std::string& section, const Declaration& d,
                                       const auto& v) {
    const bool joint = section.rfind(std::string(detail::kJointsSection), 0) == 0;
    if (joint && section != detail::joint_section(0)) return;
    const std::string key = joint ? std::string(detail::kJointsSection) + "[]." + std::string(d.key)
                                  : full_key(section, d);
    std::string value = d.rule.required ? "required" : detail::value_text(d, v);
    if (value.empty()) value = "\"\"";
    out += "| `" + key + "` | " + type_name(d, v) + " | " + value + " | " + rule_text(d) + " | " +
           std::string(d.unit.name) + " | " + reload_name(d.reload) + " | " + std::string(d.doc) +
           " |\n";
  });
  return out;
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
    if (was != s.value) out.push_back({s.key, was, s.value, s.apply, s.new_segment});
  }
  // Keys only the old configuration had (none today: the lists have fixed keys).
  for (const auto& s : a) {
    if (old.count(s.key) != 0) out.push_back({s.key, s.value, "(none)", s.apply, s.new_segment});
  }
  return out;
}

bool starts_new_segment(const std::vector<SettingChange>& changes) {
  return std::any_of(changes.begin(), changes.end(), [](const SettingChange& c) {
    return c.apply == Apply::kLive && c.new_segment;
  });
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

}  // namespace exodaq::settings
