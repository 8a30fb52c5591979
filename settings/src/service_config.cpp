#include "exodaq/config/service_config.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>

#include "exodaq/common/files.hpp"
#include "exodaq/config/content_hash.hpp"
#include "exodaq/config/setting_classes.hpp"
#include "exodaq/config/yaml_reader.hpp"
#include "exodaq/drivers/source_factory.hpp"

namespace exodaq::config {

namespace {

void parse_loop(MapReader m, LoopSettings& loop) {
  loop.rate_hz = m.number_or("rate_hz", loop.rate_hz);
  if (loop.rate_hz < 10.0 || loop.rate_hz > 10'000.0) {
    m.fail_key("rate_hz", "loop.rate_hz must be between 10 and 10000 Hz");
  }
  loop.cpu = static_cast<int>(m.integer_or("cpu", loop.cpu));
  if (loop.cpu < -1 || loop.cpu > 1023)
    m.fail_key("cpu", "loop.cpu must be -1 (any) or a CPU number");
  loop.priority = static_cast<int>(m.integer_or("priority", loop.priority));
  if (loop.priority < 0 || loop.priority > 99) {
    m.fail_key("priority", "loop.priority must be 0 (SCHED_OTHER) or a SCHED_FIFO priority 1..99");
  }
  loop.lock_memory = m.boolean_or("lock_memory", loop.lock_memory);
  loop.fault_after_ms = m.integer_or("fault_after_ms", loop.fault_after_ms);
  if (loop.fault_after_ms < 1) m.fail_key("fault_after_ms", "loop.fault_after_ms must be positive");
  loop.status_rate_hz = m.number_or("status_rate_hz", loop.status_rate_hz);
  if (loop.status_rate_hz <= 0.0 || loop.status_rate_hz > loop.rate_hz) {
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
  enc.cycles_per_rev = static_cast<int>(m.integer_or("cycles_per_rev", enc.cycles_per_rev));
  if (enc.cycles_per_rev < 1 || enc.cycles_per_rev > 1'000'000) {
    m.fail_key("cycles_per_rev", "encoders.cycles_per_rev must be between 1 and 1000000");
  }
  enc.decoding = static_cast<int>(m.integer_or("decoding", enc.decoding));
  if (enc.decoding != 1 && enc.decoding != 2 && enc.decoding != 4) {
    m.fail_key("decoding", "encoders.decoding must be 1, 2 or 4 (quadrature decoding factor)");
  }
  enc.stale_ms = m.number_or("stale_ms", enc.stale_ms);
  if (enc.stale_ms <= 0.0) m.fail_key("stale_ms", "encoders.stale_ms must be positive");
  enc.index_tolerance_counts = m.integer_or("index_tolerance_counts", enc.index_tolerance_counts);
  if (enc.index_tolerance_counts < 0) {
    m.fail_key("index_tolerance_counts", "encoders.index_tolerance_counts must be >= 0");
  }
  enc.limit_margin_deg = m.number_or("limit_margin_deg", enc.limit_margin_deg);
  if (enc.limit_margin_deg < 0.0)
    m.fail_key("limit_margin_deg", "encoders.limit_margin_deg must be >= 0");
  enc.speed_margin = m.number_or("speed_margin", enc.speed_margin);
  if (enc.speed_margin < 1.0) m.fail_key("speed_margin", "encoders.speed_margin must be >= 1");
  enc.velocity_window = static_cast<int>(m.integer_or("velocity_window", enc.velocity_window));
  if (enc.velocity_window < 2 || enc.velocity_window > kMaxVelocityWindow) {
    m.fail_key("velocity_window", "encoders.velocity_window must be between 2 and " +
                                      std::to_string(kMaxVelocityWindow));
  }
  enc.fault_hold_ms = m.number_or("fault_hold_ms", enc.fault_hold_ms);
  if (enc.fault_hold_ms < 0.0) m.fail_key("fault_hold_ms", "encoders.fault_hold_ms must be >= 0");

  const YAML::Node joints = m.child("joints");
  if (!joints.IsSequence()) m.fail(joints, "encoders.joints must be a list of 6 joints");
  if (joints.size() != kJointCount) {
    m.fail(joints, "encoders.joints must have 6 entries, has " + std::to_string(joints.size()));
  }
  std::set<int> channels;
  for (std::size_t i = 0; i < joints.size(); ++i) {
    MapReader j(m.file(), joints[i], "encoders.joints[" + std::to_string(i) + "]");
    auto& out = enc.joints[i];
    out.channel = static_cast<int>(j.integer("channel"));
    if (out.channel < 0 || out.channel > 5) j.fail_key("channel", "channel must be 0..5");
    if (!channels.insert(out.channel).second) {
      j.fail_key("channel", "channel " + std::to_string(out.channel) + " is used by two joints");
    }
    out.direction = static_cast<int>(j.integer_or("direction", 1));
    if (out.direction != 1 && out.direction != -1)
      j.fail_key("direction", "direction must be 1 or -1");
    out.gear_ratio = j.number_or("gear_ratio", 1.0);
    if (out.gear_ratio <= 0.0 || out.gear_ratio > 100.0) {
      j.fail_key("gear_ratio",
                 "gear_ratio must be in (0, 100] encoder revolutions per joint revolution");
    }
    out.max_speed_rad_s = j.number("max_speed_rad_s");
    if (out.max_speed_rad_s <= 0.0)
      j.fail_key("max_speed_rad_s", "max_speed_rad_s must be positive");
    j.finish();
  }
  m.finish();
}

void parse_lcm(MapReader m, LcmSettings& lcm) {
  lcm.url = m.string_or("url", lcm.url);
  if (lcm.url.rfind("udpm://", 0) != 0 && lcm.url.rfind("file://", 0) != 0 &&
      lcm.url.rfind("memq://", 0) != 0) {
    m.fail_key("url", "lcm.url must be an LCM URL (udpm://group:port?ttl=N)");
  }
  lcm.prefix = m.string_or("prefix", lcm.prefix);
  for (char c : lcm.prefix) {
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-' || c == '.' ||
          c == '/')) {
      m.fail_key("prefix", "lcm.prefix may hold letters, digits and _ - . / only");
    }
  }
  lcm.publish_raw = m.boolean_or("publish_raw", lcm.publish_raw);
  m.finish();
}

void parse_clock(MapReader m, ClockPolicy& clock) {
  const std::string req = m.choice_or("require_sync", {"ignore", "mark", "hold"}, "mark");
  clock.require_sync = req == "ignore" ? RequireSync::kIgnore
                       : req == "hold" ? RequireSync::kHold
                                       : RequireSync::kMark;
  clock.max_est_error_us = m.number_or("max_est_error_us", clock.max_est_error_us);
  clock.max_max_error_us = m.number_or("max_max_error_us", clock.max_max_error_us);
  const double step_ms =
      m.number_or("step_threshold_ms", static_cast<double>(clock.step_threshold_ns) / 1e6);
  if (step_ms <= 0.0) m.fail_key("step_threshold_ms", "clock.step_threshold_ms must be positive");
  clock.step_threshold_ns = static_cast<std::int64_t>(step_ms * 1e6);
  clock.slew_ppm = m.number_or("slew_ppm", clock.slew_ppm);
  if (clock.slew_ppm <= 0.0 || clock.slew_ppm > 1e5)
    m.fail_key("slew_ppm", "clock.slew_ppm must be in (0, 100000]");
  clock.step_slew_ppm = m.number_or("step_slew_ppm", clock.step_slew_ppm);
  if (clock.step_slew_ppm <= 0.0 || clock.step_slew_ppm > 5e5) {
    m.fail_key("step_slew_ppm", "clock.step_slew_ppm must be in (0, 500000]");
  }
  m.finish();
}

void parse_logging(MapReader m, LoggingSettings& log) {
  log.level = m.choice_or("level", {"trace", "debug", "info", "warn", "error", "critical", "off"},
                          log.level);
  log.sink = m.choice_or("sink", {"auto", "stderr", "journal"}, log.sink);
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

ServiceConfig parse(const YAML::Node& root, const std::string& file) {
  ServiceConfig c;
  c.file = file;
  MapReader top(file, root, "config");
  c.rig = top.string("rig");
  if (c.rig.empty() || c.rig.size() > 63) top.fail_key("rig", "rig must be 1 to 63 characters");
  if (auto m = top.optional_map("loop")) parse_loop(*m, c.loop);
  parse_source(top.map("source"), c.source);
  parse_encoders(top.map("encoders"), c.encoders);
  c.model_path = top.path("model");
  c.calibration_path = top.path("calibration");
  if (auto m = top.optional_map("kinematics")) {
    c.singularity_threshold = m->number_or("singularity_threshold", c.singularity_threshold);
    if (c.singularity_threshold < 0.0 || c.singularity_threshold >= 1.0) {
      m->fail_key("singularity_threshold", "kinematics.singularity_threshold must be in [0, 1)");
    }
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
                          " joints; the service publishes exactly 6");
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
  ctx.chain = config.model.chain;
  ctx.rig = config.model.rig;
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

std::string to_yaml(const ServiceConfig& c) {
  const auto n = [](double v) { return setting_number(v); };
  const auto b = [](bool v) { return v ? "true" : "false"; };
  const auto q = [](const std::string& v) { return setting_quoted(v); };
  std::ostringstream o;
  o << "# effective configuration of " << c.file << "\n";
  o << "config: {path: " << q(c.file) << ", sha256: " << c.config_sha256 << "}\n";
  o << "rig: " << q(c.rig) << "\n";
  o << "loop: {rate_hz: " << n(c.loop.rate_hz) << ", cpu: " << c.loop.cpu
    << ", priority: " << c.loop.priority << ", lock_memory: " << b(c.loop.lock_memory)
    << ", fault_after_ms: " << c.loop.fault_after_ms
    << ", status_rate_hz: " << n(c.loop.status_rate_hz) << "}\n";
  o << "source: " << drivers::describe(c.source) << "\n";
  o << "encoders:\n  cycles_per_rev: " << c.encoders.cycles_per_rev
    << "\n  decoding: " << c.encoders.decoding << "\n  stale_ms: " << n(c.encoders.stale_ms)
    << "\n  index_tolerance_counts: " << c.encoders.index_tolerance_counts
    << "\n  limit_margin_deg: " << n(c.encoders.limit_margin_deg)
    << "\n  speed_margin: " << n(c.encoders.speed_margin)
    << "\n  velocity_window: " << c.encoders.velocity_window
    << "\n  fault_hold_ms: " << n(c.encoders.fault_hold_ms) << "\n  joints:\n";
  for (const auto& j : c.encoders.joints) {
    o << "    - {channel: " << j.channel << ", direction: " << j.direction
      << ", gear_ratio: " << n(j.gear_ratio) << ", max_speed_rad_s: " << n(j.max_speed_rad_s)
      << "}\n";
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
  o << "kinematics: {singularity_threshold: " << n(c.singularity_threshold) << "}\n";
  o << "lcm: {url: " << q(c.lcm.url) << ", prefix: " << q(c.lcm.prefix)
    << ", publish_raw: " << b(c.lcm.publish_raw) << "}\n";
  o << "clock: {require_sync: " << require_sync_name(c.clock.require_sync)
    << ", max_est_error_us: " << n(c.clock.max_est_error_us)
    << ", max_max_error_us: " << n(c.clock.max_max_error_us)
    << ", step_threshold_ms: " << n(static_cast<double>(c.clock.step_threshold_ns) / 1e6)
    << ", slew_ppm: " << n(c.clock.slew_ppm) << ", step_slew_ppm: " << n(c.clock.step_slew_ppm)
    << "}\n";
  o << "logging: {level: " << c.logging.level << ", sink: " << c.logging.sink << "}\n";
  return o.str();
}

}  // namespace exodaq::config
