#pragma once
// A reload's hand-over: the main thread stages a new pipeline configuration,
// the loop takes it at a cycle boundary by one pointer exchange, and the
// configuration it replaced is freed by the main thread at the next stage()
// (or at destruction), never on the loop thread.
#include <atomic>
#include <memory>

#include "exodaq/core/pipeline.hpp"

namespace exodaq::core {

class ConfigHandover {
 public:
  explicit ConfigHandover(std::unique_ptr<PipelineConfig> initial);
  ~ConfigHandover();
  ConfigHandover(const ConfigHandover&) = delete;
  ConfigHandover& operator=(const ConfigHandover&) = delete;

  // Loop thread (and before it starts).
  const PipelineConfig& active() const noexcept { return *active_; }
  // Loop thread, at a cycle boundary: the staged configuration, now active,
  // or nullptr when none is staged. The caller switches to it at once: the
  // one it replaces may be freed from here on.
  const PipelineConfig* take_staged() noexcept;

  // Main thread: replaces a configuration staged but not yet taken (whose
  // new_segment `next` inherits).
  void stage(std::unique_ptr<PipelineConfig> next) noexcept;

 private:
  std::unique_ptr<PipelineConfig> active_;
  std::atomic<PipelineConfig*> staged_{nullptr};
  std::atomic<PipelineConfig*> retired_{nullptr};
};

}  // namespace exodaq::core
