#pragma once
// An encoder backend as the service configuration sees it: a name, a parser
// for its own section `source.<name>` of the config, and a factory. Each
// backend defines its Backend in its own files; drivers/src/source_factory.cpp
// lists them (one line each). docs/architecture.md: "Adding a backend".
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "exodaq/drivers/encoder_source.hpp"
#include "exodaq/drivers/frame_assembler.hpp"
#include "exodaq/drivers/source_options.hpp"

namespace exodaq {
class MapReader;  // exodaq/common/yaml_reader.hpp: what a backend's parser reads
}  // namespace exodaq

namespace exodaq::drivers {

// One backend's parsed settings. describe() names every field with its value
// (one YAML flow line), so two settings are equal when their descriptions are.
class BackendSettings {
 public:
  virtual ~BackendSettings() = default;
  virtual std::string describe() const = 0;
};

struct Backend {
  std::string name;
  // Reads `source.<name>`; `section` is null when the file has none. When the
  // backend is the selected one, `selected` is true (a backend that cannot run
  // on defaults says so here, through `source`). Throws exodaq::ConfigError.
  std::function<std::shared_ptr<const BackendSettings>(exodaq::MapReader* section,
                                                       exodaq::MapReader& source, bool selected)>
      parse;
  // Builds the source (devices open later, in start()). Throws std::runtime_error.
  std::function<std::unique_ptr<EncoderSource>(const BackendSettings& settings,
                                               const SourceContext& context)>
      make;
  // A CAN backend: its protocol's assembly of recorded frames (candump
  // replay, frame_assembler.hpp) with these settings (null: the config has
  // no section for it; null returned when the protocol needs one). Empty:
  // the backend has no CAN frames.
  std::function<std::unique_ptr<FrameAssembler>(const BackendSettings* settings,
                                                const SourceContext& context)>
      assembler = {};
};

// The service config's `source:` section: the selected backend and the
// parsed section of every backend the file configures.
struct SourceOptions {
  std::string backend = "sim";
  std::map<std::string, std::shared_ptr<const BackendSettings>, std::less<>> sections;

  const BackendSettings* section(std::string_view name) const noexcept;
  template <typename T>
  const T* section_as(std::string_view name) const noexcept {
    return dynamic_cast<const T*>(section(name));
  }
};

// "{backend: sim, seed: 1, ...}": the selected backend and its settings.
std::string describe(const SourceOptions& options);

}  // namespace exodaq::drivers
