#pragma once
// Inputs of `exodaq calibrate` (docs/calibration.md): the encoder stream (joint
// angles relative to the index, θᴿ of seed 000 eq. 4, with homed and fault
// masks) and the motion-capture marker stream, and their alignment by the
// NTP-aligned timestamps. Errors are config::ConfigError "file:line: what".
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "exodaq/calibration/marker_layout.hpp"

namespace exodaq::calibration {

inline constexpr int kJoints = 6;
inline constexpr std::uint8_t kAllJoints = 0x3F;

// One encoder sample. theta_r: θᴿ in rad (the angle measured from each
// joint's index, direction and gear ratio already applied).
struct EncoderSample {
  std::int64_t utime_us = 0;  // µs since the Unix epoch, NTP-aligned
  std::array<double, kJoints> theta_r{};
  std::uint8_t homed_mask = kAllJoints;  // bit i: joint i+1 homed
  std::uint8_t fault_mask = 0;           // bit i: joint i+1 flagged (stale, glitch, ...)
  bool valid() const noexcept { return homed_mask == kAllJoints && fault_mask == 0; }
};

struct EncoderSeries {
  std::string source;                  // file name, for messages and provenance
  std::vector<EncoderSample> samples;  // strictly increasing utime
};

// A reader of one encoder-log format. CSV now; the LCM-log reader (issue
// "Record, replay and look at recordings") implements the same interface.
class EncoderLogReader {
 public:
  virtual ~EncoderLogReader() = default;
  virtual EncoderSeries read(const std::string& path) const = 0;
};

// CSV: header `utime_us,j1_rad,...,j6_rad[,homed_mask][,fault_mask]` (any column
// order, '#' comments, blank lines ignored). Missing mask columns mean "all
// homed, no fault". Rows must have strictly increasing utime_us.
class EncoderCsvReader final : public EncoderLogReader {
 public:
  EncoderSeries read(const std::string& path) const override;
  EncoderSeries parse(const std::string& text, const std::string& name) const;
};

// Picks the reader by the file's extension (.csv). Throws ConfigError naming the
// supported formats otherwise.
EncoderSeries read_encoder_log(const std::string& path);

struct MarkerSample {
  std::int64_t utime_us = 0;
  bool present = false;        // false: marker occluded (empty/NaN coordinates)
  double x = 0, y = 0, z = 0;  // m, camera frame
  int marker_id = -1;          // -1 when the file has no marker_id column
};

struct MarkerSeries {
  std::string source;
  std::vector<MarkerSample> samples;
  std::size_t other_ids = 0;  // rows of markers that were not selected (counted, not used)
};

// CSV: header `utime_us,x_mm,y_mm,z_mm[,marker_id]`. Empty fields or `nan` in
// x/y/z mean the marker was not seen (counted, skipped). `marker_id` selects
// one marker when the file holds several (-1: the file must hold one id).
// utime_us must increase from row to row of each marker.
MarkerSeries read_marker_csv(const std::string& path, int marker_id = -1);
MarkerSeries parse_marker_csv(const std::string& text, const std::string& name, int marker_id = -1);

// Several markers (a marker layout, a motion-capture session): the rows of the
// given ids, in file order. Needs the marker_id column; every id must have rows.
MarkerSeries read_marker_csv_ids(const std::string& path, const std::vector<int>& ids);
MarkerSeries parse_marker_csv_ids(const std::string& text, const std::string& name,
                                  const std::vector<int>& ids);

// One calibration point: the encoder stream interpolated at the marker time.
struct AlignedSample {
  std::int64_t utime_us = 0;
  std::array<double, kJoints> theta_r{};
  std::array<double, 3> marker{};  // m, camera frame
  int encoder_index = 0;           // encoder sample at or before utime_us
  // Which marker, and where it sits (default: seed 000's one marker at the tool
  // point; apply_layout() fills in the others).
  MarkerSite site;
};

struct AlignmentOptions {
  // Largest gap between the two encoder samples bracketing a marker time
  // (a dropped stretch of the log is not interpolated across).
  std::int64_t max_gap_us = 5000;
  // Encoder samples within ±guard_us of a marker time must be valid (so a time
  // offset estimated within that range never interpolates from bad samples).
  std::int64_t guard_us = 0;
  // Keep at most this many points of each marker, evenly spread (0: all).
  std::size_t max_points = 0;
};

struct AlignmentStats {
  std::size_t marker_samples = 0;
  std::size_t used = 0;
  std::size_t marker_missing = 0;  // occluded
  std::size_t outside_encoder_log = 0;
  std::size_t encoder_gap = 0;  // bracketing encoder samples too far apart
  std::size_t unhomed_or_faulted = 0;
  std::size_t thinned = 0;    // dropped by max_points
  std::size_t other_ids = 0;  // rows of markers not selected (MarkerSeries::other_ids)
};

std::vector<AlignedSample> align(const EncoderSeries& enc, const MarkerSeries& markers,
                                 const AlignmentOptions& options, AlignmentStats& stats);

// Sets each point's site from the layout by its marker id. Throws
// std::invalid_argument naming an id the layout does not have.
void apply_layout(std::vector<AlignedSample>& points, const MarkerLayout& layout);

}  // namespace exodaq::calibration
