#pragma once
// Aligning the motion-capture clock with the encoder clock when they share no
// epoch (docs/calibration.md §4.1): a coarse offset from a signal that does
// not depend on the calibration, the speed of a hand marker against the speed
// the model predicts for it from the encoder angles (both are independent of
// where the camera is), cross-correlated over every offset the two streams
// allow, from coarse to fine steps. The least squares then refine it (τ).
#include <cstdint>
#include <string>
#include <vector>

#include "exodaq/calibration/inputs.hpp"
#include "exodaq/calibration/solver.hpp"

namespace exodaq::calibration {

struct CoarseOffset {
  double offset_s = 0;        // encoder time = marker time + offset
  double step_s = 0;          // the finest grid searched (the offset is within ± step/2)
  double correlation = 0;     // of the two speed profiles at the offset
  double runner_up = 0;       // the best correlation at least 2 s away from it
  double runner_up_at_s = 0;  // where
  double overlap_s = 0;       // of the two streams at the offset
  bool ambiguous() const noexcept { return runner_up > 0.85 * correlation; }
  std::string describe() const;
};

struct CoarseOffsetOptions {
  // Offsets searched: every one that leaves this much of the shorter stream overlapping.
  double min_overlap_s = 10.0;
  double min_overlap_fraction = 0.3;
  double finest_step_s = 0.002;
};

// The offset of `markers` (the samples of `site`, a hand marker) against the
// encoder stream, with the model at parameters `x` (the bounds file's initial
// guesses will do). Throws std::runtime_error when the streams cannot overlap
// or the marker never moves.
CoarseOffset coarse_time_offset(const NominalModel& model, const ParamVector& x,
                                const EncoderSeries& encoders, const MarkerSeries& markers,
                                const MarkerSite& site, const CoarseOffsetOptions& options = {});

// Whether a marker series needs aligning to an encoder stream: it carries no
// epoch (a capture's own clock), or fewer than half its samples fall within
// the encoder stream's time span.
bool needs_time_alignment(const EncoderSeries& encoders, const MarkerSeries& markers);

// The series with every time shifted by `offset_s` (into encoder time).
MarkerSeries shifted_markers(MarkerSeries m, double offset_s);

}  // namespace exodaq::calibration
