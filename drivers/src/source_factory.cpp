#include "exodaq/drivers/source_factory.hpp"

#include <stdexcept>

namespace exodaq::drivers {

std::unique_ptr<EncoderSource> make_source(const SourceOptions& options,
                                           const SourceContext& context) {
  (void)context;
  throw std::runtime_error(std::string("source backend '") + backend_name(options.backend) +
                           "' is not available in this build");
}

}  // namespace exodaq::drivers
