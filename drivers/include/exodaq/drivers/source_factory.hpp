#pragma once
// The backends this build knows, and the one place that builds a source from
// the configuration (never chosen at compile time).
#include <memory>
#include <string_view>
#include <vector>

#include "exodaq/drivers/backend.hpp"

namespace exodaq::drivers {

// Every backend compiled in (drivers/src/source_factory.cpp lists them).
const std::vector<Backend>& backends();
const Backend* find_backend(std::string_view name) noexcept;

// Throws std::runtime_error when the selected backend is unknown or cannot be
// built (missing file). Opening devices happens later, in EncoderSource::start().
std::unique_ptr<EncoderSource> make_source(const SourceOptions& options,
                                           const SourceContext& context);

}  // namespace exodaq::drivers
