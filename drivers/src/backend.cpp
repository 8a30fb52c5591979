#include "exodaq/drivers/backend.hpp"

namespace exodaq::drivers {

const BackendSettings* SourceOptions::section(std::string_view name) const noexcept {
  const auto it = sections.find(name);
  return it == sections.end() ? nullptr : it->second.get();
}

std::string describe(const SourceOptions& options) {
  const BackendSettings* s = options.section(options.backend);
  std::string d = s != nullptr ? s->describe() : "{}";
  // "{a: 1}" -> "{backend: sim, a: 1}"
  return "{backend: " + options.backend + (d.size() > 2 ? ", " + d.substr(1) : "}");
}

}  // namespace exodaq::drivers
