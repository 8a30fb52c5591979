// Fuzz target service_config: load_service_config_text() on any text, as if
// it were config/fuzz.yaml in the source tree, so the model and calibration
// files it names (relative to config/, e.g. models/macaque_exo.yaml and
// calibration/sim.yaml, or absolute) are the real ones on disk. Documented
// behaviour (service_config.hpp): a ServiceConfig or a ConfigError "file:line:
// what" (for the config or for the model/calibration file it names). What it
// accepts yields a pipeline configuration, a source context and a dump.
#include <string>

#include "exodaq/core/builder.hpp"
#include "exodaq/settings/service_config.hpp"
#include "fuzz_input.hpp"

namespace settings = exodaq::settings;
namespace core = exodaq::core;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 16384) return 0;
  const std::string text = exodaq::fuzz::as_text(data, size);
  // Devices and kernel files are no config files: /dev/zero never ends.
  for (const char* device : {"dev/", "proc/", "sys/", "run/"}) {
    if (text.find(device) != std::string::npos) return 0;
  }
  static const std::string name = std::string(EXODAQ_SOURCE_DIR) + "/config/fuzz.yaml";
  settings::ServiceConfig c;
  try {
    c = settings::load_service_config_text(text, name);
  } catch (const exodaq::ConfigError& e) {
    FUZZ_CHECK(e.line() >= 0);
    return 0;
  }
  FUZZ_CHECK(c.model.chain.joint_count() == 6);
  FUZZ_CHECK(core::make_pipeline_config(c) != nullptr);
  (void)settings::make_source_context(c);
  FUZZ_CHECK(!settings::to_yaml(c).empty());
  return 0;
}
