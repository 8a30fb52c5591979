#include "scenario.hpp"

#include <stdexcept>

#include "exodaq/core/builder.hpp"

namespace exodaq::test {

namespace {
class KeepingSink final : public core::MessageSink {
 public:
  ScenarioResult* out = nullptr;
  bool publish(const std::string&, const core::OutgoingMessage& m) noexcept override {
    try {
      switch (m.channel) {
        case exodaq::messages::Kind::kJointState: {
          exodaq::joint_state_t js;
          js.decode(m.bytes.data(), 0, static_cast<int>(m.size));
          if (static_cast<std::size_t>(js.seq) >= out->cycles.size()) {
            out->cycles.resize(static_cast<std::size_t>(js.seq) + 1);
          }
          out->cycles[static_cast<std::size_t>(js.seq)].joint = js;
          break;
        }
        case exodaq::messages::Kind::kPalmPose: {
          exodaq::palm_pose_t p;
          p.decode(m.bytes.data(), 0, static_cast<int>(m.size));
          if (static_cast<std::size_t>(p.seq) >= out->cycles.size()) {
            out->cycles.resize(static_cast<std::size_t>(p.seq) + 1);
          }
          out->cycles[static_cast<std::size_t>(p.seq)].palm = p;
          break;
        }
        case exodaq::messages::Kind::kStatus: {
          exodaq::status_t s;
          s.decode(m.bytes.data(), 0, static_cast<int>(m.size));
          out->statuses.push_back(s);
          break;
        }
        case exodaq::messages::Kind::kEncoderRaw:
        case exodaq::messages::Kind::kHoming:
        case exodaq::messages::Kind::kSourceStatus:
          break;
      }
    } catch (...) {
      return false;
    }
    return true;
  }
};
}  // namespace

settings::ServiceConfig sim_config() {
  return settings::load_service_config(std::string(EXODAQ_SOURCE_DIR) + "/config/sim.yaml");
}

ScenarioResult run_scenario(const settings::ServiceConfig& config, double seconds,
                            const settings::ServiceConfig* rig) {
  ScenarioResult r;
  r.config = config;
  const settings::ServiceConfig& rig_side = rig != nullptr ? *rig : config;
  auto source = drivers::make_source(rig_side.source, settings::make_source_context(rig_side));
  r.sim = dynamic_cast<const drivers::SimSource*>(source.get());
  if (r.sim == nullptr) throw std::runtime_error("scenario needs the sim backend");
  auto sink = std::make_unique<KeepingSink>();
  sink->out = &r;
  settings::ServiceConfig daemon_side = config;
  daemon_side.clock.require_sync = core::RequireSync::kIgnore;
  core::AcquisitionOptions wiring;
  wiring.source = std::move(source);
  wiring.sink = std::move(sink);
  wiring.channel_prefix = "";
  wiring.realtime = false;
  r.acquisition = core::build_acquisition(daemon_side, std::move(wiring));
  r.acquisition->prepare_for_manual_cycles();
  const std::int64_t t0 = 1000LL * 1'000'000'000LL;
  const auto n = static_cast<std::int64_t>(seconds * 1000.0);
  for (std::int64_t k = 0; k < n; ++k) {
    r.acquisition->run_cycle(t0 + k * 1'000'000, t0 + k * 1'000'000 + 20'000);
    if (k % 128 == 0) r.acquisition->publisher().drain();
  }
  r.acquisition->publisher().drain();
  return r;
}

}  // namespace exodaq::test
