#include "exodaq/core/config_handover.hpp"

namespace exodaq::core {

ConfigHandover::ConfigHandover(std::unique_ptr<PipelineConfig> initial)
    : active_(std::move(initial)) {}

ConfigHandover::~ConfigHandover() {
  delete staged_.exchange(nullptr);
  delete retired_.exchange(nullptr);
}

const PipelineConfig* ConfigHandover::take_staged() noexcept {
  PipelineConfig* staged = staged_.exchange(nullptr, std::memory_order_acq_rel);
  if (staged == nullptr) return nullptr;
  PipelineConfig* old = active_.release();
  active_.reset(staged);
  // stage() collects the retired one before staging the next, so the slot is
  // empty here; were it not, leaking beats freeing on the loop thread.
  PipelineConfig* expected = nullptr;
  retired_.compare_exchange_strong(expected, old);
  return staged;
}

void ConfigHandover::stage(std::unique_ptr<PipelineConfig> next) noexcept {
  delete retired_.exchange(nullptr);
  // One staged before and never taken: the loop goes from the active
  // configuration straight to `next`, so `next` starts the segment the
  // skipped one would have started.
  if (PipelineConfig* skipped = staged_.exchange(nullptr, std::memory_order_acq_rel)) {
    next->new_segment = next->new_segment || skipped->new_segment;
    delete skipped;
  }
  staged_.store(next.release(), std::memory_order_release);
}

}  // namespace exodaq::core
