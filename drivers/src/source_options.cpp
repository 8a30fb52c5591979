#include "exodaq/drivers/source_options.hpp"

#include <sstream>

namespace exodaq::drivers {

const char* backend_name(SourceBackend b) noexcept {
  switch (b) {
    case SourceBackend::kSim:
      return "sim";
    case SourceBackend::kSocketCan:
      return "socketcan";
    case SourceBackend::kReplay:
      return "replay";
  }
  return "unknown";
}

std::string describe(const SourceOptions& o) {
  std::ostringstream s;
  s << "{backend: " << backend_name(o.backend);
  switch (o.backend) {
    case SourceBackend::kSim:
      s << ", seed: " << o.sim.seed << ", loss_percent: " << o.sim.loss_percent
        << ", jitter_us: " << o.sim.jitter_us;
      if (!o.sim.faults.empty()) s << ", faults: " << o.sim.faults.size();
      break;
    case SourceBackend::kSocketCan:
      s << ", interface: " << o.socketcan.interface << ", sync_master: "
        << (o.socketcan.sync_master ? "true" : "false") << ", board: " << o.socketcan.board;
      break;
    case SourceBackend::kReplay:
      s << ", path: " << o.replay.path << ", format: " << o.replay.format << ", speed: ";
      if (o.replay_speed > 0) {
        s << o.replay_speed;
      } else {
        s << "max";
      }
      break;
  }
  s << "}";
  return s.str();
}

}  // namespace exodaq::drivers
