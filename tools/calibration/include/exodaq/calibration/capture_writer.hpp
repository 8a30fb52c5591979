#pragma once
// Writing a motion capture in the formats the readers take (inputs.hpp,
// MarkerFormat), for `exodaq example-session`: the long CSV (epoch times),
// C3D (Intel byte order, float storage, points only), a Vicon Nexus CSV
// (Trajectories section) and an OptiTrack Motive CSV (format version 1.23,
// Marker columns). The bytes are returned; the caller writes them.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace exodaq::calibration {

struct Capture {
  std::vector<std::string> labels;
  std::vector<int> ids;  // the long CSV's marker_id of each label
  double rate_hz = 100.0;
  // frames[k][m]: marker m at frame k (time k / rate_hz), mm; nullopt: not seen.
  std::vector<std::vector<std::optional<Eigen::Vector3d>>> frames;
};

// utime_us = epoch_start_us + frame time.
std::string long_csv_bytes(const Capture& c, std::int64_t epoch_start_us);
std::string c3d_bytes(const Capture& c);
std::string vicon_csv_bytes(const Capture& c, const std::string& subject);
// start_time: the "Capture Start Time" to write (Motive's own format).
std::string motive_csv_bytes(const Capture& c, const std::string& start_time);

}  // namespace exodaq::calibration
