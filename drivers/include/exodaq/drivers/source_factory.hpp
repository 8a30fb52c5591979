#pragma once
// The one place that chooses an encoder backend, from configuration (never at
// compile time).
#include <memory>

#include "exodaq/drivers/encoder_source.hpp"
#include "exodaq/drivers/source_options.hpp"

namespace exodaq::drivers {

// Throws std::runtime_error when the backend cannot be built (unknown backend,
// missing file). Opening devices happens later, in EncoderSource::start().
std::unique_ptr<EncoderSource> make_source(const SourceOptions& options,
                                           const SourceContext& context);

}  // namespace exodaq::drivers
