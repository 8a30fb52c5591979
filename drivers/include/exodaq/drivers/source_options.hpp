#pragma once
// Which encoder source to run and its options, as plain values (the daemon's
// config loader fills them from YAML; drivers know nothing of files).
#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "exodaq/drivers/sim_rig.hpp"

namespace exodaq::drivers {

enum class SourceBackend : std::uint8_t { kSim, kSocketCan, kReplay };

struct SimSourceSettings {
  std::uint64_t seed = 1;                // motion and fault randomness; same seed, same stream
  double loss_percent = 0.0;             // samples dropped at random (deterministic for a seed)
  double jitter_us = 0.0;                // sample-instant jitter (uniform, +/-)
  std::uint16_t powerup_count = 0x1234;  // counter value at power-up on every channel
  std::vector<sim::SimFault> faults;     // scripted faults (sim_rig.hpp)
};

struct SocketCanSettings {
  std::string interface = "can0";
  bool sync_master = true;           // send SYNC every cycle; false: follow a free-running board
  int board = 0;                     // board number: shifts every board-sent ID by board * 0x20
  int rcvbuf_bytes = 1 << 20;        // SO_RCVBUF(FORCE), sized for bursts
  double read_deadline_us = 400;     // how long a cycle waits for its count frames after SYNC
  double reopen_interval_ms = 1000;  // interface lost: re-open attempts at most this often
};

struct ReplaySettings {
  std::string path;                         // lcm-logger log or candump -l file
  std::string format = "auto";              // auto | lcm | candump
  std::string channel = "EXO_ENCODER_RAW";  // LCM logs: the raw channel (with prefix)
};

struct SourceOptions {
  SourceBackend backend = SourceBackend::kSim;
  SimSourceSettings sim;
  SocketCanSettings socketcan;
  ReplaySettings replay;
  double replay_speed = 1.0;  // replay pacing: x real time; <= 0 as fast as possible
};

// What every backend needs to know about the rig's encoders (from the
// encoders section, the model and the calibration).
struct SourceJointContext {
  int channel = 0;
  int direction = 1;
  double gear_ratio = 1.0;
  double index_angle_rad = 0.0;  // joint angle at the index (calibration delta_theta0)
  double home_rad = 0.0;         // home posture: where the simulated rig powers up
  double lower_rad = -3.14159;
  double upper_rad = 3.14159;
  double max_speed_rad_s = 1.0;
};

struct SourceContext {
  std::int64_t period_ns = 1'000'000;
  std::int64_t counts_per_rev = 10000;
  std::array<SourceJointContext, 6> joints{};
};

const char* backend_name(SourceBackend b) noexcept;
// One line for logs and --print-config.
std::string describe(const SourceOptions& options);

}  // namespace exodaq::drivers
