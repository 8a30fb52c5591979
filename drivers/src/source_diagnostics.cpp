#include "exodaq/drivers/source_diagnostics.hpp"

#include <algorithm>

namespace exodaq::drivers {

void SourceDiagnostics::add(std::string_view name, std::int64_t value) noexcept {
  if (count_ >= kMaxCounters) {
    ++dropped_;
    return;
  }
  counters_[static_cast<std::size_t>(count_++)] = {
      name.substr(0, static_cast<std::size_t>(kMaxNameBytes)), value};
}

void SourceDiagnostics::set_state(std::string_view text) noexcept {
  state_size_ = std::min(text.size(), state_.size() - 1);
  std::copy_n(text.data(), state_size_, state_.data());
}

void SourceDiagnostics::clear() noexcept {
  count_ = 0;
  dropped_ = 0;
  state_size_ = 0;
}

const SourceCounter* SourceDiagnostics::find(std::string_view name) const noexcept {
  for (const SourceCounter& c : counters()) {
    if (c.name == name) return &c;
  }
  return nullptr;
}

}  // namespace exodaq::drivers
