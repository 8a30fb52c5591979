#include "exodaq/drivers/source_factory.hpp"

#include <stdexcept>

#include "exodaq/drivers/canopen/canopen_backend.hpp"
#include "exodaq/drivers/replay_backend.hpp"
#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/socketcan_backend.hpp"

namespace exodaq::drivers {

const std::vector<Backend>& backends() {
  static const std::vector<Backend> list = {
      sim_backend(),
      socketcan_backend(),
      replay_backend(),
      canopen::canopen_backend(),
  };
  return list;
}

const Backend* find_backend(std::string_view name) noexcept {
  for (const Backend& b : backends()) {
    if (b.name == name) return &b;
  }
  return nullptr;
}

std::function<std::unique_ptr<FrameAssembler>(std::string_view backend)> frame_assemblers(
    const SourceOptions& options, const SourceContext& context) {
  SourceContext plain = context;
  plain.frame_assembler = nullptr;
  return [options, plain](std::string_view name) -> std::unique_ptr<FrameAssembler> {
    const Backend* backend = find_backend(name);
    if (backend == nullptr || !backend->assembler) return nullptr;
    return backend->assembler(options.section(name), plain);
  };
}

std::unique_ptr<EncoderSource> make_source(const SourceOptions& options,
                                           const SourceContext& context) {
  const Backend* backend = find_backend(options.backend);
  const BackendSettings* settings = options.section(options.backend);
  if (backend == nullptr || settings == nullptr) {
    throw std::runtime_error("source backend '" + options.backend +
                             "' is not available in this build");
  }
  SourceContext with = context;
  with.frame_assembler = frame_assemblers(options, context);
  return backend->make(*settings, with);
}

}  // namespace exodaq::drivers
