#include "exodaq/core/builder.hpp"

#include <algorithm>
#include <cmath>

#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/drivers/source_factory.hpp"

namespace exodaq::core {

namespace {
// Where a cut may fall: not inside a UTF-8 sequence.
bool starts_character(const std::string& s, std::size_t at) {
  return at >= s.size() || (static_cast<unsigned char>(s[at]) & 0xC0) != 0x80;
}

// A path that keeps its end (the file name) after "...".
std::string keep_end(const std::string& s, std::size_t max_bytes) {
  if (s.size() <= max_bytes) return s;
  std::size_t from = s.size() - (max_bytes - 3);
  while (!starts_character(s, from)) ++from;
  return "..." + s.substr(from);
}

// A text that keeps its start, then "...".
std::string keep_start(const std::string& s, std::size_t max_bytes) {
  if (s.size() <= max_bytes) return s;
  std::size_t to = max_bytes - 3;
  while (to > 0 && !starts_character(s, to)) --to;
  return s.substr(0, to) + "...";
}

ConfigFiles config_files(const settings::ServiceConfig& c) {
  ConfigFiles f;
  f.config_path = keep_end(c.file, ConfigFiles::kMaxPathBytes);
  f.config_sha256 = c.config_sha256.substr(0, ConfigFiles::kMaxHashBytes);
  f.calibration_path = keep_end(c.calibration_path, ConfigFiles::kMaxPathBytes);
  f.calibration_sha256 = c.calibration_sha256.substr(0, ConfigFiles::kMaxHashBytes);
  f.calibration_provenance = keep_start(settings::provenance_text(c.calibration.provenance),
                                        ConfigFiles::kMaxProvenanceBytes);
  return f;
}
}  // namespace

std::unique_ptr<PipelineConfig> make_pipeline_config(const settings::ServiceConfig& c) {
  auto p = std::make_unique<PipelineConfig>();
  p->files = config_files(c);
  p->chain = settings::apply_calibration(c.model.chain, c.calibration);
  p->rig = c.model.rig;
  const auto& joints = c.model.chain.joints();
  for (int i = 0; i < kJointCount; ++i) {
    const auto& e = c.encoders.joints[static_cast<std::size_t>(i)];
    JointTrackerConfig& t = p->joints[static_cast<std::size_t>(i)];
    t.channel = e.channel;
    t.direction = e.direction;
    t.counts_per_rev = c.encoders.counts_per_rev();
    t.gear_ratio = e.gear_ratio;
    t.offset_rad = c.calibration.encoder_offset_rad[static_cast<std::size_t>(i)];
    t.home_rad = c.model.home_posture.size() > i ? c.model.home_posture[i] : 0.0;
    t.lower_rad = joints[static_cast<std::size_t>(i)].limits.lower;
    t.upper_rad = joints[static_cast<std::size_t>(i)].limits.upper;
    t.limit_margin_rad = c.encoders.limit_margin_deg * exodaq::kDegToRad;
    t.max_speed_rad_s = e.max_speed_rad_s * c.encoders.speed_margin;
    t.board_period_ns = settings::period_ns(c);
    t.index_tolerance_counts = c.encoders.index_tolerance_counts;
    t.stale_ns = static_cast<std::int64_t>(c.encoders.stale_ms * 1e6);
    t.fault_hold_ns = static_cast<std::int64_t>(c.encoders.fault_hold_ms * 1e6);
    t.velocity_window = c.encoders.velocity_window;
  }
  return p;
}

AcquisitionConfig make_acquisition_config(const settings::ServiceConfig& c) {
  AcquisitionConfig a;
  a.rig = c.rig;
  a.period_ns = settings::period_ns(c);
  a.cpu = c.loop.cpu;
  a.priority = c.loop.priority;
  a.lock_memory = c.loop.lock_memory;
  a.fault_after_ms = c.loop.fault_after_ms;
  a.status_every_cycles =
      std::max(1, static_cast<int>(std::lround(c.loop.rate_hz / c.loop.status_rate_hz)));
  a.publish_raw = c.lcm.publish_raw;
  a.clock = c.clock;
  const auto& joints = c.model.chain.joints();
  for (int i = 0; i < kJointCount; ++i) {
    a.joint_names[static_cast<std::size_t>(i)] = joints[static_cast<std::size_t>(i)].name;
  }
  return a;
}

std::unique_ptr<Acquisition> build_acquisition(const settings::ServiceConfig& c,
                                               AcquisitionOptions o) {
  AcquisitionConfig a = make_acquisition_config(c);
  if (!o.realtime) {
    a.cpu = -1;
    a.priority = 0;
    a.lock_memory = false;
  }
  a.run_id = o.run_id;
  a.record_lateness_cycles = o.record_lateness_cycles;
  auto source = o.source ? std::move(o.source)
                         : drivers::make_source(c.source, settings::make_source_context(c));
  auto sink = o.sink ? std::move(o.sink) : make_lcm_sink(c.lcm.url);
  return std::make_unique<Acquisition>(std::move(a), make_pipeline_config(c), std::move(source),
                                       std::move(sink), o.channel_prefix.value_or(c.lcm.prefix),
                                       std::move(o.clock), std::move(o.loop_clock));
}

}  // namespace exodaq::core
