#pragma once
// Private helpers shared by the calibration library's translation units: unit
// constants, the time-offset column index and number formatting.
#include <cstdio>
#include <string>

#include "exodaq/calibration/solver.hpp"

namespace exodaq::calibration::detail {

inline constexpr double kRadToDeg = 57.29577951308232;
inline constexpr double kDegToRad = 0.017453292519943295;
inline constexpr double kMToMm = 1e3;
inline constexpr int kTau = kParams;  // column index of the time offset in full Jacobians

inline std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

}  // namespace exodaq::calibration::detail
