#include "exodaq/drivers/replay_backend.hpp"

#include <sstream>

#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/drivers/replay_source.hpp"

namespace exodaq::drivers {

namespace {

double parse_speed(exodaq::MapReader& s) {
  const YAML::Node sp = s.child("speed");
  if (sp.IsScalar() && sp.Scalar() == "max") return 0.0;
  const double speed = s.to_number(sp, "speed");
  if (speed <= 0.0) s.fail(sp, "source.replay.speed must be positive or 'max'");
  return speed;
}

std::shared_ptr<const BackendSettings> parse_replay(exodaq::MapReader* s, exodaq::MapReader& src,
                                                    bool selected) {
  auto out = std::make_shared<ReplaySettings>();
  if (s == nullptr) {
    if (selected) src.fail_key("backend", "source.backend replay needs source.replay.path");
    return out;
  }
  out->path = s->path("path");
  out->format = s->choice_or("format", {"auto", "lcm", "candump"}, out->format);
  out->channel = s->string_or("channel", out->channel);
  out->protocol = s->choice_or("protocol", {"socketcan", "canopen"}, out->protocol);
  if (s->has("speed")) out->speed = parse_speed(*s);
  s->finish();
  return out;
}

std::unique_ptr<EncoderSource> make_replay(const BackendSettings& settings,
                                           const SourceContext& ctx) {
  return std::make_unique<ReplaySource>(dynamic_cast<const ReplaySettings&>(settings), ctx);
}

}  // namespace

std::string ReplaySettings::describe() const {
  std::ostringstream s;
  s << "{path: " << path << ", format: " << format << ", channel: " << channel
    << ", protocol: " << protocol << ", speed: ";
  if (speed > 0) {
    s << speed;
  } else {
    s << "max";
  }
  s << "}";
  return s.str();
}

const Backend& replay_backend() {
  static const Backend b{"replay", parse_replay, make_replay};
  return b;
}

}  // namespace exodaq::drivers
