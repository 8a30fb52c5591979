#include "exodaq/config/service_config.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <sstream>

#include "exodaq/config/yaml_reader.hpp"

namespace exodaq::config {

namespace {

std::string resolve(const std::string& base_file, const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  if (p.is_absolute()) return path;
  return (fs::path(base_file).parent_path() / p).lexically_normal().string();
}

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

void parse_source(MapReader m, drivers::SourceOptions& src) {
  const std::string backend = m.choice("backend", {"sim", "socketcan", "replay"});
  src.backend = backend == "sim"         ? drivers::SourceBackend::kSim
                : backend == "socketcan" ? drivers::SourceBackend::kSocketCan
                                         : drivers::SourceBackend::kReplay;
  if (auto s = m.optional_map("sim")) {
    const std::int64_t seed = s->integer_or("seed", static_cast<std::int64_t>(src.sim.seed));
    if (seed < 0) s->fail_key("seed", "source.sim.seed must be >= 0");
    src.sim.seed = static_cast<std::uint64_t>(seed);
    src.sim.loss_percent = s->number_or("loss_percent", src.sim.loss_percent);
    if (src.sim.loss_percent < 0.0 || src.sim.loss_percent > 100.0) {
      s->fail_key("loss_percent", "source.sim.loss_percent must be between 0 and 100");
    }
    src.sim.jitter_us = s->number_or("jitter_us", src.sim.jitter_us);
    if (src.sim.jitter_us < 0.0 || src.sim.jitter_us > 400.0) {
      s->fail_key("jitter_us", "source.sim.jitter_us must be between 0 and 400");
    }
    const std::int64_t pc = s->integer_or("powerup_count", src.sim.powerup_count);
    if (pc < 0 || pc > 0xFFFF)
      s->fail_key("powerup_count", "source.sim.powerup_count must be 0..65535");
    src.sim.powerup_count = static_cast<std::uint16_t>(pc);
    if (auto faults = s->optional_child("faults")) {
      if (!faults->IsSequence()) s->fail(*faults, "source.sim.faults must be a list");
      for (std::size_t i = 0; i < faults->size(); ++i) {
        MapReader f(m.file(), (*faults)[i], "source.sim.faults[" + std::to_string(i) + "]");
        using Kind = drivers::sim::SimFault::Kind;
        static const std::vector<std::pair<std::string, Kind>> kinds = {
            {"glitch", Kind::kCountOffset},     {"lost_counts", Kind::kCountRamp},
            {"excursion", Kind::kExcursion},    {"stuck", Kind::kStuck},
            {"silence", Kind::kSilence},        {"drop", Kind::kDrop},
            {"partial", Kind::kPartial},        {"duplicate", Kind::kDuplicate},
            {"board_error", Kind::kBoardError}, {"reorder", Kind::kReorder},
            {"bad_seq", Kind::kBadSeq},         {"wrong_dlc", Kind::kWrongDlc}};
        std::vector<std::string> names;
        for (const auto& k : kinds) names.push_back(k.first);
        const std::string kind = f.choice("kind", names);
        drivers::sim::SimFault fault;
        for (const auto& k : kinds) {
          if (k.first == kind) fault.kind = k.second;
        }
        fault.start_s = f.number("at_s");
        if (fault.start_s < 0) f.fail_key("at_s", "at_s must be >= 0");
        fault.duration_s = f.number_or("for_s", 0.0);
        const std::int64_t joint = f.integer_or("joint", 1);
        if (joint < 1 || joint > kJointCount) f.fail_key("joint", "joint must be 1..6");
        fault.joint = static_cast<int>(joint - 1);
        fault.counts = f.integer_or("counts", 0);
        fault.percent = f.number_or("percent", 0.0);
        if (fault.percent < 0 || fault.percent > 100)
          f.fail_key("percent", "percent must be in [0, 100]");
        const std::int64_t bits = f.integer_or("error_bits", 0);
        if (bits < 0 || bits > 255) f.fail_key("error_bits", "error_bits must be 0..255");
        fault.error_bits = static_cast<std::uint8_t>(bits);
        f.finish();
        src.sim.faults.push_back(fault);
      }
    }
    s->finish();
  }
  if (auto s = m.optional_map("socketcan")) {
    src.socketcan.interface = s->string_or("interface", src.socketcan.interface);
    if (src.socketcan.interface.empty() || src.socketcan.interface.size() > 15) {
      s->fail_key("interface",
                  "source.socketcan.interface must be a network interface name (1-15 characters)");
    }
    src.socketcan.sync_master = s->boolean_or("sync_master", src.socketcan.sync_master);
    src.socketcan.board = static_cast<int>(s->integer_or("board", src.socketcan.board));
    if (src.socketcan.board < 0 || src.socketcan.board > 7)
      s->fail_key("board", "source.socketcan.board must be 0..7");
    src.socketcan.rcvbuf_bytes =
        static_cast<int>(s->integer_or("rcvbuf_bytes", src.socketcan.rcvbuf_bytes));
    if (src.socketcan.rcvbuf_bytes < 4096)
      s->fail_key("rcvbuf_bytes", "source.socketcan.rcvbuf_bytes must be >= 4096");
    src.socketcan.read_deadline_us =
        s->number_or("read_deadline_us", src.socketcan.read_deadline_us);
    if (src.socketcan.read_deadline_us <= 0.0 || src.socketcan.read_deadline_us > 900.0) {
      s->fail_key("read_deadline_us", "source.socketcan.read_deadline_us must be in (0, 900]");
    }
    src.socketcan.reopen_interval_ms =
        s->number_or("reopen_interval_ms", src.socketcan.reopen_interval_ms);
    if (src.socketcan.reopen_interval_ms < 10.0 || src.socketcan.reopen_interval_ms > 60'000.0) {
      s->fail_key("reopen_interval_ms",
                  "source.socketcan.reopen_interval_ms must be between 10 and 60000");
    }
    s->finish();
  }
  if (auto s = m.optional_map("replay")) {
    src.replay.path = resolve(m.file(), s->string("path"));
    src.replay.format = s->choice_or("format", {"auto", "lcm", "candump"}, src.replay.format);
    src.replay.channel = s->string_or("channel", src.replay.channel);
    if (s->has("speed")) {
      const YAML::Node sp = s->child("speed");
      if (sp.IsScalar() && sp.Scalar() == "max") {
        src.replay_speed = 0.0;
      } else {
        src.replay_speed = s->to_number(sp, "speed");
        if (src.replay_speed <= 0.0) s->fail(sp, "source.replay.speed must be positive or 'max'");
      }
    }
    s->finish();
  }
  if (src.backend == drivers::SourceBackend::kReplay && src.replay.path.empty()) {
    m.fail_key("backend", "source.backend replay needs source.replay.path");
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

ServiceConfig parse(const YAML::Node& root, const std::string& file) {
  ServiceConfig c;
  c.file = file;
  MapReader top(file, root, "config");
  c.rig = top.string("rig");
  if (c.rig.empty() || c.rig.size() > 63) top.fail_key("rig", "rig must be 1 to 63 characters");
  if (auto m = top.optional_map("loop")) parse_loop(*m, c.loop);
  parse_source(top.map("source"), c.source);
  parse_encoders(top.map("encoders"), c.encoders);
  c.model_path = resolve(file, top.string("model"));
  c.calibration_path = resolve(file, top.string("calibration"));
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
  c.model = load_model_file(c.model_path);
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
  c.calibration = load_calibration_file(c.calibration_path);
  c.model.rig.singularity_threshold = c.singularity_threshold;
  return c;
}
}  // namespace

ServiceConfig load_service_config(const std::string& path) {
  return parse(load_yaml_file(path), path);
}

ServiceConfig load_service_config_text(const std::string& text, const std::string& name) {
  return parse(load_yaml_text(text, name), name);
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
  return ctx;
}

std::int64_t period_ns(const ServiceConfig& config) {
  return static_cast<std::int64_t>(1e9 / config.loop.rate_hz);
}

std::string to_yaml(const ServiceConfig& c) {
  std::ostringstream o;
  o.precision(10);
  o << "# effective configuration of " << c.file << "\n";
  o << "rig: " << c.rig << "\n";
  o << "loop: {rate_hz: " << c.loop.rate_hz << ", cpu: " << c.loop.cpu
    << ", priority: " << c.loop.priority
    << ", lock_memory: " << (c.loop.lock_memory ? "true" : "false")
    << ", fault_after_ms: " << c.loop.fault_after_ms
    << ", status_rate_hz: " << c.loop.status_rate_hz << "}\n";
  o << "source: " << drivers::describe(c.source) << "\n";
  o << "encoders:\n  cycles_per_rev: " << c.encoders.cycles_per_rev
    << "\n  decoding: " << c.encoders.decoding << "\n  stale_ms: " << c.encoders.stale_ms
    << "\n  index_tolerance_counts: " << c.encoders.index_tolerance_counts
    << "\n  limit_margin_deg: " << c.encoders.limit_margin_deg
    << "\n  speed_margin: " << c.encoders.speed_margin
    << "\n  velocity_window: " << c.encoders.velocity_window
    << "\n  fault_hold_ms: " << c.encoders.fault_hold_ms << "\n  joints:\n";
  for (const auto& j : c.encoders.joints) {
    o << "    - {channel: " << j.channel << ", direction: " << j.direction
      << ", gear_ratio: " << j.gear_ratio << ", max_speed_rad_s: " << j.max_speed_rad_s << "}\n";
  }
  o << "model: " << c.model_path << "  # " << c.model.name << "\n";
  o << "calibration: " << c.calibration_path << "\n";
  o << "calibration_offsets_deg: [";
  for (int i = 0; i < kJointCount; ++i) {
    o << (i ? ", " : "")
      << c.calibration.encoder_offset_rad[static_cast<std::size_t>(i)] / kDegToRad;
  }
  o << "]\n";
  o << "kinematics: {singularity_threshold: " << c.singularity_threshold << "}\n";
  o << "lcm: {url: \"" << c.lcm.url << "\", prefix: \"" << c.lcm.prefix
    << "\", publish_raw: " << (c.lcm.publish_raw ? "true" : "false") << "}\n";
  const char* req = c.clock.require_sync == RequireSync::kIgnore ? "ignore"
                    : c.clock.require_sync == RequireSync::kHold ? "hold"
                                                                 : "mark";
  o << "clock: {require_sync: " << req << ", max_est_error_us: " << c.clock.max_est_error_us
    << ", max_max_error_us: " << c.clock.max_max_error_us
    << ", step_threshold_ms: " << static_cast<double>(c.clock.step_threshold_ns) / 1e6
    << ", slew_ppm: " << c.clock.slew_ppm << ", step_slew_ppm: " << c.clock.step_slew_ppm << "}\n";
  o << "logging: {level: " << c.logging.level << ", sink: " << c.logging.sink << "}\n";
  return o.str();
}

}  // namespace exodaq::config
