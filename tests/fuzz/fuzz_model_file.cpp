// Fuzz target model_file: load_model_text() on any text. Documented
// behaviour (model_file.hpp, docs/kinematics.md): a KinematicModel or a
// ConfigError "file:line: what"; nothing else. A model it accepts can be
// evaluated at its home posture, which lies within its joint limits.
#include "exodaq/kinematics/rig_kinematics.hpp"
#include "exodaq/settings/model_file.hpp"
#include "fuzz_input.hpp"

namespace settings = exodaq::settings;
namespace kinematics = exodaq::kinematics;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 16384) return 0;
  settings::KinematicModel model;
  try {
    model = settings::load_model_text(exodaq::fuzz::as_text(data, size), "fuzz.yaml");
  } catch (const exodaq::ConfigError& e) {
    FUZZ_CHECK(e.file() == "fuzz.yaml");
    FUZZ_CHECK(e.line() >= 0);
    return 0;
  }
  const int n = model.chain.joint_count();
  FUZZ_CHECK(n >= 1 && n <= 8);
  FUZZ_CHECK(model.home_posture.size() == n);
  for (int i = 0; i < n; ++i) {
    const auto& lim = model.chain.joints()[static_cast<std::size_t>(i)].limits;
    FUZZ_CHECK(lim.lower < lim.upper);
    FUZZ_CHECK(model.home_posture[i] >= lim.lower && model.home_posture[i] <= lim.upper);
  }
  kinematics::RigPose pose;
  kinematics::evaluate_rig(model.chain, model.rig, model.home_posture, pose);
  return 0;
}
