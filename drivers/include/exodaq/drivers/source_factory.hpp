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
// The source gets `context` with its frame_assembler set (frame_assemblers()).
std::unique_ptr<EncoderSource> make_source(const SourceOptions& options,
                                           const SourceContext& context);

// SourceContext::frame_assembler for these options: the named backend's
// assembler with the options' section for it (null when there is none).
std::function<std::unique_ptr<FrameAssembler>(std::string_view backend)> frame_assemblers(
    const SourceOptions& options, const SourceContext& context);

}  // namespace exodaq::drivers
