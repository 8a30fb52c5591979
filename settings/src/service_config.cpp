#include "exodaq/settings/service_config.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <sstream>
#include <type_traits>

#include "exodaq/common/files.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/drivers/source_factory.hpp"
#include "exodaq/settings/content_hash.hpp"
#include "exodaq/settings/setting_classes.hpp"
#include "setting_visit.hpp"

namespace exodaq::settings {

namespace {

using detail::Declaration;

bool obeys(const Rule& r, double v) {
  if (!r.choices.empty()) {
    const auto choices = detail::choices_of(r);
    return std::find(choices.begin(), choices.end(), setting_number(v)) != choices.end();
  }
  const bool above_lo = r.lo_open ? v > r.lo : v >= r.lo;
  const bool below_hi = r.hi_open ? v < r.hi : v <= r.hi;
  return above_lo && below_hi;
}

// Reads the declared settings of one mapping into their fields, each checked
// against its rule: "<prefix>.<key> <rule text>" at the key's line.
class SettingReader {
 public:
  SettingReader(MapReader& m, std::string prefix) : m_(m), prefix_(std::move(prefix)) {}

  void operator()(const Declaration& d, bool& v) {
    v = d.rule.required ? m_.boolean(key(d)) : m_.boolean_or(key(d), v);
  }
  void operator()(const Declaration& d, double& v) {
    v = d.rule.required ? m_.number(key(d)) : m_.number_or(key(d), v);
    check(d, v);
  }
  template <typename T, typename = std::enable_if_t<std::is_integral_v<T>>>
  void operator()(const Declaration& d, T& v) {
    if (d.unit.scale != 1.0) {  // written in a larger unit than kept
      const double written = d.rule.required
                                 ? m_.number(key(d))
                                 : m_.number_or(key(d), static_cast<double>(v) / d.unit.scale);
      check(d, written);
      v = static_cast<T>(written * d.unit.scale);
      return;
    }
    const std::int64_t read = d.rule.required ? m_.integer(key(d)) : m_.integer_or(key(d), v);
    check(d, static_cast<double>(read));
    v = static_cast<T>(read);
  }
  void operator()(const Declaration& d, std::string& v) {
    if (!d.rule.choices.empty()) {
      const auto choices = detail::choices_of(d.rule);
      v = d.rule.required ? m_.choice(key(d), choices) : m_.choice_or(key(d), choices, v);
      return;
    }
    v = d.rule.required ? m_.string(key(d)) : m_.string_or(key(d), v);
    // A text's bounds are its length's.
    if (!obeys(d.rule, static_cast<double>(v.size()))) fail(d);
  }
  void operator()(const Declaration& d, RequireSync& v) {
    const auto choices = detail::choices_of(d.rule);
    const std::string name = m_.choice_or(key(d), choices, choices[static_cast<std::size_t>(v)]);
    v = static_cast<RequireSync>(std::find(choices.begin(), choices.end(), name) - choices.begin());
  }

 private:
  static std::string key(const Declaration& d) { return std::string(d.key); }
  void check(const Declaration& d, double v) const {
    if (!obeys(d.rule, v)) fail(d);
  }
  [[noreturn]] void fail(const Declaration& d) const {
    const std::string name = prefix_.empty() ? key(d) : prefix_ + "." + key(d);
    m_.fail_key(key(d), name + " " + std::string(d.rule.text));
  }
  MapReader& m_;
  std::string prefix_;
};

void parse_loop(MapReader m, LoopSettings& loop) {
  detail::visit_loop(loop, SettingReader(m, "loop"));
  if (loop.status_rate_hz > loop.rate_hz) {
    m.fail_key("status_rate_hz", "loop.status_rate_hz must be positive and at most loop.rate_hz");
  }
  m.finish();
}

// source: the selected backend, and every backend section the file has,
// each parsed by its backend (drivers/backend.hpp).
void parse_source(MapReader m, drivers::SourceOptions& src) {
  std::vector<std::string> names;
  for (const auto& b : drivers::backends()) names.push_back(b.name);
  src.backend = m.choice("backend", names);
  for (const auto& b : drivers::backends()) {
    std::optional<MapReader> section = m.optional_map(b.name);
    const bool selected = b.name == src.backend;
    if (!section && !selected) continue;
    src.sections[b.name] = b.parse(section ? &*section : nullptr, m, selected);
  }
  m.finish();
}

void parse_encoders(MapReader m, EncoderSettings& enc) {
  detail::visit_encoders(enc, SettingReader(m, "encoders"));

  const YAML::Node joints = m.child("joints");
  const std::string n = std::to_string(kJointCount);
  if (!joints.IsSequence()) m.fail(joints, "encoders.joints must be a list of " + n + " joints");
  if (joints.size() != kJointCount) {
    m.fail(joints,
           "encoders.joints must have " + n + " entries, has " + std::to_string(joints.size()));
  }
  std::set<int> channels;
  for (std::size_t i = 0; i < joints.size(); ++i) {
    MapReader j(m.file(), joints[i], "encoders.joints[" + std::to_string(i) + "]");
    auto& out = enc.joints[i];
    // Errors name the key alone: the reader's context names the joint.
    detail::visit_joint(out, SettingReader(j, ""));
    if (!channels.insert(out.channel).second) {
      j.fail_key("channel", "channel " + std::to_string(out.channel) + " is used by two joints");
    }
    j.finish();
  }
  m.finish();
}

// What is wrong with the group and port of a udpm:// URL ("" when nothing):
// LCM joins the group, so a unicast address would fail only at start.
std::string udpm_address_problem(const std::string& url) {
  const std::string rest = url.substr(7);
  const std::string network = rest.substr(0, rest.find('?'));
  if (network.empty()) return {};  // LCM's default group and port
  const std::size_t colon = network.find(':');
  const std::string group = network.substr(0, colon);
  in_addr address{};
  if (inet_pton(AF_INET, group.c_str(), &address) != 1) {
    return "lcm.url group '" + group + "' is not an IPv4 address (udpm://239.255.76.67:7667)";
  }
  if (!IN_MULTICAST(ntohl(address.s_addr))) {
    return "lcm.url group " + group +
           " is a unicast address: udpm:// needs a multicast group, 224.0.0.0 to "
           "239.255.255.255 (239.255.76.67 is LCM's default)";
  }
  const std::string port = colon == std::string::npos ? "" : network.substr(colon + 1);
  char* end = nullptr;
  const long value = std::strtol(port.c_str(), &end, 10);
  if (port.empty() || *end != '\0' || value < 1 || value > 65535) {
    return "lcm.url needs a port 1..65535 after the group (udpm://" + group + ":7667)";
  }
  return {};
}

void parse_lcm(MapReader m, LcmSettings& lcm) {
  detail::visit_lcm(lcm, SettingReader(m, "lcm"));
  if (lcm.url.rfind("udpm://", 0) != 0 && lcm.url.rfind("file://", 0) != 0 &&
      lcm.url.rfind("memq://", 0) != 0) {
    m.fail_key("url", "lcm.url must be an LCM URL (udpm://group:port?ttl=N)");
  }
  if (lcm.url.rfind("udpm://", 0) == 0) {
    if (const std::string problem = udpm_address_problem(lcm.url); !problem.empty()) {
      m.fail_key("url", problem);
    }
  }
  for (char c : lcm.prefix) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.' ||
          c == '/')) {
      m.fail_key("prefix", "lcm.prefix may hold letters, digits and _ - . / only");
    }
  }
  m.finish();
}

void parse_clock(MapReader m, ClockPolicy& clock) {
  detail::visit_clock(clock, SettingReader(m, "clock"));
  m.finish();
}

void parse_logging(MapReader m, LoggingSettings& log) {
  detail::visit_logging(log, SettingReader(m, "logging"));
  m.finish();
}

// A file the config names (model, calibration): one that cannot be opened is
// reported at the config's line, with the path as written and as resolved;
// errors inside it carry its own file:line. `sha256`: of the bytes parsed.
template <typename T>
T load_referenced(const std::string& config_file, const YAML::Node& at, const std::string& key,
                  const std::string& path, T (*load)(const std::string&, const std::string&),
                  std::string& sha256) {
  std::string text;
  try {
    text = files::read_input(path, files::kMaxYamlBytes);
  } catch (const files::FileError& e) {
    const std::string written = at.IsScalar() ? at.Scalar() : path;
    const std::string where =
        written == path ? path : "'" + written + "', relative to the config's folder: " + path;
    throw ConfigError(config_file, line_of(at), key + " file " + where + ": " + e.reason());
  }
  sha256 = sha256_hex(text);
  return load(text, path);
}

// The fastest a joint plausibly moves: across its whole mechanical range (the
// model's limits) in kFullRangeMinS. Faster than any primate arm movement; a
// bound beyond it lets count glitches pass as motion (docs/operations.md,
// "Plausibility checks").
constexpr double kFullRangeMinS = 0.05;

void check_speed_bounds(const ServiceConfig& c, const YAML::Node& root, const std::string& file) {
  const auto& joints = c.model.chain.joints();
  for (std::size_t i = 0; i < joints.size() && i < c.encoders.joints.size(); ++i) {
    const double range = joints[i].limits.upper - joints[i].limits.lower;
    const double speed = c.encoders.joints[i].max_speed_rad_s;
    if (!std::isfinite(range) || range <= 0.0 || speed * kFullRangeMinS <= range) continue;
    const YAML::Node at = root["encoders"]["joints"][i]["max_speed_rad_s"];
    throw ConfigError(
        file, line_of(at),
        "encoders.joints[" + std::to_string(i) + "].max_speed_rad_s " + setting_number(speed) +
            " is beyond joint '" + joints[i].name + "': it would cross its whole range (" +
            setting_number(std::round(range / kDegToRad * 10.0) / 10.0) + " deg, model '" +
            c.model_path + "') in " + setting_number(std::round(range / speed * 1e4) / 10.0) +
            " ms; at most " + setting_number(std::floor(range / kFullRangeMinS * 10.0) / 10.0) +
            " rad/s (the whole range in " + setting_number(kFullRangeMinS * 1e3) +
            " ms): a faster bound lets count glitches pass as motion");
  }
}

ServiceConfig parse(const YAML::Node& root, const std::string& file) {
  ServiceConfig c;
  c.file = file;
  MapReader top(file, root, "config");
  detail::visit_top(c, SettingReader(top, ""));
  if (auto m = top.optional_map("loop")) parse_loop(*m, c.loop);
  parse_source(top.map("source"), c.source);
  parse_encoders(top.map("encoders"), c.encoders);
  c.model_path = top.path("model");
  c.calibration_path = top.path("calibration");
  if (auto m = top.optional_map("kinematics")) {
    detail::visit_kinematics(c, SettingReader(*m, "kinematics"));
    m->finish();
  }
  if (auto m = top.optional_map("lcm")) parse_lcm(*m, c.lcm);
  if (auto m = top.optional_map("clock")) parse_clock(*m, c.clock);
  if (auto m = top.optional_map("logging")) parse_logging(*m, c.logging);
  top.finish();

  // The referenced files, each with its own file:line errors.
  c.model =
      load_referenced(file, root["model"], "model", c.model_path, &load_model_text, c.model_sha256);
  if (c.model.chain.joint_count() != kJointCount) {
    throw ConfigError(file, line_of(root["model"]),
                      "model '" + c.model_path + "' has " +
                          std::to_string(c.model.chain.joint_count()) +
                          " joints; the service publishes exactly " + std::to_string(kJointCount) +
                          " (the arrays of joint_state_t)");
  }
  for (const auto& j : c.model.chain.joints()) {
    if (j.name.size() > 31) {
      throw ConfigError(c.model_path, 0,
                        "joint name '" + j.name + "' is longer than 31 characters");
    }
  }
  c.calibration = load_referenced(file, root["calibration"], "calibration", c.calibration_path,
                                  &load_calibration_text, c.calibration_sha256);
  c.model.rig.singularity_threshold = c.singularity_threshold;
  check_speed_bounds(c, root, file);
  return c;
}
}  // namespace

ServiceConfig load_service_config(const std::string& path) {
  std::string text;
  try {
    text = files::read_input(path, files::kMaxYamlBytes);
  } catch (const files::FileError& e) {
    throw ConfigError(path, 0, e.reason());
  }
  return load_service_config_text(text, path);
}

ServiceConfig load_service_config_text(const std::string& text, const std::string& name) {
  ServiceConfig c = parse(load_yaml_text(text, name), name);
  c.config_sha256 = sha256_hex(text);
  return c;
}

drivers::SourceContext make_source_context(const ServiceConfig& config) {
  drivers::SourceContext ctx;
  ctx.period_ns = period_ns(config);
  ctx.counts_per_rev = config.encoders.counts_per_rev();
  for (int i = 0; i < kJointCount; ++i) {
    const auto idx = static_cast<std::size_t>(i);
    const auto& e = config.encoders.joints[idx];
    auto& j = ctx.joints[idx];
    j.channel = e.channel;
    j.direction = e.direction;
    j.gear_ratio = e.gear_ratio;
    j.index_angle_rad = config.calibration.encoder_offset_rad[idx];
    j.home_rad = config.model.home_posture[i];
    j.lower_rad = config.model.chain.joints()[idx].limits.lower;
    j.upper_rad = config.model.chain.joints()[idx].limits.upper;
    j.max_speed_rad_s = e.max_speed_rad_s;
  }
  ctx.chain = std::make_shared<const kinematics::Chain>(config.model.chain);
  ctx.rig = std::make_shared<const kinematics::RigKinematicsConfig>(config.model.rig);
  return ctx;
}

std::int64_t period_ns(const ServiceConfig& config) {
  return static_cast<std::int64_t>(1e9 / config.loop.rate_hz);
}

std::string provenance_text(const CalibrationProvenance& p) {
  std::string out = p.created_by;
  const auto add = [&out](const std::string& part) {
    if (!part.empty()) out += (out.empty() ? "" : ", ") + part;
  };
  add(p.date);
  if (p.rms_before_m || p.rms_after_m) {
    const auto mm = [](const std::optional<double>& m) {
      return m ? setting_number(*m * 1e3) : std::string("?");
    };
    add("rms " + mm(p.rms_before_m) + " -> " + mm(p.rms_after_m) + " mm");
  }
  if (p.samples) add(std::to_string(*p.samples) + " samples");
  return out;
}

namespace {

// One section's declared settings as "k: v" items, each value as YAML.
class YamlItems {
 public:
  template <typename T>
  void operator()(const Declaration& d, const T& v) {
    std::string text = detail::value_text(d, v);
    if constexpr (std::is_same_v<T, std::string>) {
      if (d.rule.choices.empty()) text = setting_quoted(text);
    }
    items_.push_back(std::string(d.key) + ": " + text);
  }
  std::string flow() const {
    std::string out = "{";
    for (std::size_t i = 0; i < items_.size(); ++i) out += (i ? ", " : "") + items_[i];
    return out + "}";
  }
  std::string block(const std::string& indent) const {
    std::string out;
    for (const auto& item : items_) out += indent + item + "\n";
    return out;
  }

 private:
  std::vector<std::string> items_;
};

template <typename S, typename Visit>
std::string flow_of(const S& s, Visit visit) {
  YamlItems items;
  visit(s, items);
  return items.flow();
}

}  // namespace

std::string to_yaml(const ServiceConfig& c) {
  const auto n = [](double v) { return setting_number(v); };
  const auto q = [](const std::string& v) { return setting_quoted(v); };
  std::ostringstream o;
  o << "# effective configuration of " << c.file << "\n";
  o << "config: {path: " << q(c.file) << ", sha256: " << c.config_sha256 << "}\n";
  YamlItems top;
  detail::visit_top(c, top);
  o << top.block("");
  o << "loop: " << flow_of(c.loop, [](auto& s, auto& v) { detail::visit_loop(s, v); }) << "\n";
  o << "source: " << drivers::describe(c.source) << "\n";
  YamlItems encoders;
  detail::visit_encoders(c.encoders, encoders);
  o << "encoders:\n" << encoders.block("  ") << "  joints:\n";
  for (const auto& j : c.encoders.joints) {
    o << "    - " << flow_of(j, [](auto& s, auto& v) { detail::visit_joint(s, v); }) << "\n";
  }
  o << "model: {path: " << q(c.model_path) << ", sha256: " << c.model_sha256
    << ", name: " << q(c.model.name) << ", joint_names: [";
  for (int i = 0; i < c.model.chain.joint_count(); ++i) {
    o << (i ? ", " : "") << q(c.model.chain.joints()[static_cast<std::size_t>(i)].name);
  }
  o << "]}\n";
  o << "calibration: {path: " << q(c.calibration_path) << ", sha256: " << c.calibration_sha256
    << ", provenance: " << q(provenance_text(c.calibration.provenance))
    << ", encoder_offsets_deg: [";
  for (int i = 0; i < kJointCount; ++i) {
    o << (i ? ", " : "")
      << n(c.calibration.encoder_offset_rad[static_cast<std::size_t>(i)] / kDegToRad);
  }
  o << "]}\n";
  o << "kinematics: " << flow_of(c, [](auto& s, auto& v) { detail::visit_kinematics(s, v); })
    << "\n";
  o << "lcm: " << flow_of(c.lcm, [](auto& s, auto& v) { detail::visit_lcm(s, v); }) << "\n";
  o << "clock: " << flow_of(c.clock, [](auto& s, auto& v) { detail::visit_clock(s, v); }) << "\n";
  o << "logging: " << flow_of(c.logging, [](auto& s, auto& v) { detail::visit_logging(s, v); })
    << "\n";
  return o.str();
}

}  // namespace exodaq::settings
