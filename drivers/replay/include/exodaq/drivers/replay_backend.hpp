#pragma once
// The `replay` backend: a recording (lcm-logger or candump log) played back
// through the pipeline, paced by its own time stamps.
#include <string>

#include "exodaq/drivers/backend.hpp"

namespace exodaq::drivers {

// source.replay
struct ReplaySettings final : BackendSettings {
  std::string path;                         // lcm-logger log or candump -l file
  std::string format = "auto";              // auto | lcm | candump
  std::string channel = "EXO_ENCODER_RAW";  // LCM logs: the raw channel (with prefix)
  double speed = 1.0;                       // x real time; <= 0: as fast as possible ("max")
  // candump logs: the CAN backend whose protocol the frames are (its section
  // of the configuration gives the node ids / board number).
  std::string protocol = "socketcan";
  std::string describe() const override;
};

const Backend& replay_backend();

}  // namespace exodaq::drivers
