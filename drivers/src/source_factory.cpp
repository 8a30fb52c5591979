#include "exodaq/drivers/source_factory.hpp"

#include <stdexcept>

#include "exodaq/drivers/replay_source.hpp"
#include "exodaq/drivers/sim_options.hpp"
#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/drivers/socketcan_source.hpp"

namespace exodaq::drivers {

namespace {
std::unique_ptr<EncoderSource> make_sim(const SourceOptions& options, const SourceContext& ctx) {
  return std::make_unique<SimSource>(sim_options_from(options, ctx));
}

std::unique_ptr<EncoderSource> make_socketcan(const SourceOptions& options,
                                              const SourceContext& ctx) {
  const SocketCanSourceConfig config = socketcan_config_from(options.socketcan, ctx);
  return std::make_unique<SocketCanSource>(config, make_socketcan_port(config.port));
}
}  // namespace

std::unique_ptr<EncoderSource> make_source(const SourceOptions& options, const SourceContext& ctx) {
  switch (options.backend) {
    case SourceBackend::kSim:
      return make_sim(options, ctx);
    case SourceBackend::kSocketCan:
      return make_socketcan(options, ctx);
    case SourceBackend::kReplay:
      return std::make_unique<ReplaySource>(options.replay, ctx);
  }
  throw std::runtime_error(std::string("source backend '") + backend_name(options.backend) +
                           "' is not available in this build");
}

}  // namespace exodaq::drivers
