#include "exodaq/drivers/sim_backend.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/drivers/sim_task.hpp"
#include "exodaq/kinematics/chain.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"

namespace exodaq::drivers {

namespace {

std::shared_ptr<const BackendSettings> parse_sim(exodaq::MapReader* s, exodaq::MapReader& /*src*/,
                                                 bool /*selected*/) {
  auto out = std::make_shared<SimSourceSettings>();
  if (s == nullptr) return out;
  const std::int64_t seed = s->integer_or("seed", static_cast<std::int64_t>(out->seed));
  if (seed < 0) s->fail_key("seed", "source.sim.seed must be >= 0");
  out->seed = static_cast<std::uint64_t>(seed);
  out->loss_percent = s->number_or("loss_percent", out->loss_percent);
  if (out->loss_percent < 0.0 || out->loss_percent > 100.0) {
    s->fail_key("loss_percent", "source.sim.loss_percent must be between 0 and 100");
  }
  out->jitter_us = s->number_or("jitter_us", out->jitter_us);
  if (out->jitter_us < 0.0 || out->jitter_us > 400.0) {
    s->fail_key("jitter_us", "source.sim.jitter_us must be between 0 and 400");
  }
  const std::int64_t pc = s->integer_or("powerup_count", out->powerup_count);
  if (pc < 0 || pc > 0xFFFF)
    s->fail_key("powerup_count", "source.sim.powerup_count must be 0..65535");
  out->powerup_count = static_cast<std::uint16_t>(pc);
  if (s->has("task")) {
    out->task_path = s->path("task");
    out->task = std::make_shared<const sim::SimTaskFile>(sim::load_sim_task(out->task_path));
  }
  out->motion = s->choice_or("motion", {"curves", "task"}, out->task ? "task" : "curves");
  if (out->motion == "task" && !out->task) {
    s->fail_key("motion", "motion: task needs a task file (source.sim.task)");
  }
  if (auto clock = s->optional_map("board_clock")) {
    out->free_running = clock->boolean_or("free_running", false);
    out->drift_ppm = clock->number_or("drift_ppm", 0.0);
    if (out->drift_ppm < -1000.0 || out->drift_ppm > 1000.0)
      clock->fail_key("drift_ppm", "source.sim.board_clock.drift_ppm must be within ±1000");
    out->phase = clock->number_or("phase", 0.0);
    if (out->phase < 0.0 || out->phase >= 1.0)
      clock->fail_key("phase", "source.sim.board_clock.phase (in periods) must be in [0, 1)");
    if (!out->free_running && (clock->has("drift_ppm") || clock->has("phase")))
      clock->fail_key(clock->has("drift_ppm") ? "drift_ppm" : "phase",
                      "a board clock that is not free_running has no drift or phase");
    clock->finish();
  }
  if (auto faults = s->optional_child("faults")) {
    if (!faults->IsSequence()) s->fail(*faults, "source.sim.faults must be a list");
    for (std::size_t i = 0; i < faults->size(); ++i) {
      exodaq::MapReader f(s->file(), (*faults)[i], "source.sim.faults[" + std::to_string(i) + "]");
      out->faults.push_back(parse_sim_fault(f));
    }
  }
  s->finish();
  return out;
}

std::unique_ptr<EncoderSource> make_sim(const BackendSettings& settings, const SourceContext& ctx) {
  return std::make_unique<SimSource>(
      sim_options_from(dynamic_cast<const SimSourceSettings&>(settings), ctx));
}

}  // namespace

namespace {

// A parameter the fault's kind does not take is an error, not ignored.
bool takes(exodaq::MapReader& f, const sim::SimFaultName& kind, std::uint32_t param,
           const char* key) {
  if ((kind.params & param) != 0) return true;
  if (f.has(key)) {
    f.fail_key(key, "a " + std::string(kind.name) + " fault takes no " + key +
                        " (docs/simulator.md, \"Fault kinds\")");
  }
  return false;
}

}  // namespace

sim::SimFault parse_sim_fault(exodaq::MapReader& f) {
  std::vector<std::string> names;
  for (const auto& n : sim::sim_fault_names()) names.emplace_back(n.name);
  const sim::SimFaultName& kind = *sim::find_sim_fault(f.choice("kind", names));
  namespace p = sim::fault_param;
  sim::SimFault fault;
  fault.kind = kind.kind;
  fault.start_s = f.number("at_s");
  if (fault.start_s < 0) f.fail_key("at_s", "at_s must be >= 0");
  fault.duration_s = f.number_or("for_s", 0.0);
  if (fault.kind == sim::SimFault::Kind::kStall && !(fault.duration_s > 0))
    f.fail_key("for_s", "a stall needs for_s > 0 (seconds the host stalls)");
  if (takes(f, kind, p::kJoint, "joint")) {
    const std::int64_t joint = f.integer_or("joint", 1);
    if (joint < 1 || joint > sim::kJoints) f.fail_key("joint", "joint must be 1..6");
    fault.joint = static_cast<int>(joint - 1);
  }
  if (takes(f, kind, p::kCounts, "counts")) fault.counts = f.integer_or("counts", 0);
  if (takes(f, kind, p::kPercent, "percent")) {
    fault.percent = f.number_or("percent", 0.0);
    if (fault.percent < 0 || fault.percent > 100)
      f.fail_key("percent", "percent must be in [0, 100]");
  }
  if (takes(f, kind, p::kErrorBits, "error_bits")) {
    const std::int64_t bits = f.integer_or("error_bits", 0);
    if (bits < 0 || bits > 255) f.fail_key("error_bits", "error_bits must be 0..255");
    fault.error_bits = static_cast<std::uint8_t>(bits);
  }
  if (takes(f, kind, p::kEvery, "every")) {
    const std::int64_t every = f.integer_or("every", 1);
    if (every < 1 || every > 1'000'000) f.fail_key("every", "every must be 1..1000000");
    fault.every = static_cast<int>(every);
  }
  if (takes(f, kind, p::kDelay, "delay_us")) {
    fault.delay_us = f.number_or("delay_us", 0.0);
    if (fault.delay_us < 0) f.fail_key("delay_us", "delay_us must be >= 0");
  }
  f.finish();
  return fault;
}

std::string SimSourceSettings::describe() const {
  std::ostringstream s;
  s << "{seed: " << seed << ", loss_percent: " << loss_percent << ", jitter_us: " << jitter_us
    << ", powerup_count: " << powerup_count << ", motion: " << motion;
  if (!task_path.empty()) s << ", task: " << task_path;
  if (free_running) {
    s << ", board_clock: {free_running: true, drift_ppm: " << drift_ppm << ", phase: " << phase
      << "}";
  }
  if (!faults.empty()) {
    s << ", faults: [";
    for (std::size_t i = 0; i < faults.size(); ++i) {
      const sim::SimFault& f = faults[i];
      s << (i ? ", " : "") << "{kind: " << sim::sim_fault_name(f.kind) << ", at_s: " << f.start_s
        << ", for_s: " << f.duration_s << ", joint: " << f.joint + 1 << ", counts: " << f.counts
        << ", percent: " << f.percent << ", error_bits: " << int{f.error_bits}
        << ", every: " << f.every << ", delay_us: " << f.delay_us << "}";
    }
    s << "]";
  }
  s << "}";
  return s.str();
}

const Backend& sim_backend() {
  static const Backend b{"sim", parse_sim, make_sim};
  return b;
}

sim::SimOptions sim_options_from(const SourceOptions& options, const SourceContext& ctx) {
  if (const auto* s = options.section_as<SimSourceSettings>("sim"))
    return sim_options_from(*s, ctx);
  return sim_options_from(SimSourceSettings{}, ctx);
}

sim::SimOptions sim_options_from(const SimSourceSettings& settings, const SourceContext& ctx) {
  sim::SimOptions o;
  o.seed = settings.seed;
  o.period_ns = ctx.period_ns;
  o.jitter_ns = static_cast<std::int64_t>(settings.jitter_us * 1000.0);
  o.loss_percent = settings.loss_percent;
  o.faults = settings.faults;
  o.board_clock.free_running = settings.free_running;
  o.board_clock.drift_ppm = settings.drift_ppm;
  o.board_clock.phase_ns = std::min(
      ctx.period_ns - 1, static_cast<std::int64_t>(std::llround(settings.phase * ctx.period_ns)));
  // The simulated rig is the configured one: its encoders sit on the
  // configured channels with the configured direction and gearing, and each
  // index at the calibration's delta_theta0, so a homed joint reads the truth.
  for (std::size_t j = 0; j < ctx.joints.size(); ++j) {
    const SourceJointContext& c = ctx.joints[j];
    auto& e = o.encoders[j];
    e.channel = c.channel;
    e.direction = c.direction;
    e.counts_per_rev = ctx.counts_per_rev;
    e.gear_ratio = c.gear_ratio;
    e.index_angle_rad = c.index_angle_rad;
    e.power_up_count = settings.powerup_count;
    o.motion.home_rad[j] = c.home_rad;
    o.motion.lower_limit_rad[j] = c.lower_rad;
    o.motion.upper_limit_rad[j] = c.upper_rad;
  }
  if (settings.motion == "task" && settings.task) {
    auto task = std::make_shared<sim::SimTask>();
    task->file = settings.task;
    if (ctx.chain) task->chain = *ctx.chain;
    if (ctx.rig) task->rig = *ctx.rig;
    for (std::size_t j = 0; j < ctx.joints.size(); ++j) {
      task->max_speed_rad_s[j] = ctx.joints[j].max_speed_rad_s;
    }
    o.motion.task = std::move(task);
  }
  return o;
}

}  // namespace exodaq::drivers
