#pragma once
// Inputs of `exodaq calibrate` (docs/calibration.md): the encoder stream (joint
// angles relative to the index, θᴿ of seed 000 eq. 4, with homed and fault
// masks; from calibrate's CSV, `exodaq export`'s CSV or an LCM log) and the
// motion-capture marker stream (the long CSV, C3D, Vicon Nexus and OptiTrack
// Motive CSV exports, told apart by content), and their alignment in time.
// Errors are exodaq::ConfigError "file:line: what". Inputs are regular files
// within files::kMaxCsvBytes, read as streams: memory stays bounded whatever
// their size (kMaxEncoderSamples, kMaxMarkerSamples; docs/robustness.md).
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "exodaq/calibration/marker_layout.hpp"
#include "exodaq/wire_constants.hpp"

namespace exodaq::calibration {

inline constexpr int kJoints = wire::kJointCount;
inline constexpr std::uint8_t kAllJoints = 0x3F;

// Most samples a reader keeps. A longer stream is thinned while it is read:
// every other kept sample is dropped and the spacing doubles (a dropped
// encoder sample's homed/fault masks and gap go into the kept one before it,
// so nothing unhomed, faulted or missing is interpolated across).
inline constexpr std::size_t kMaxEncoderSamples = std::size_t{1} << 20;  // 64 MiB
inline constexpr std::size_t kMaxMarkerSamples = std::size_t{1} << 20;   // 48 MiB

// One encoder sample. theta_r: θᴿ in rad (the angle measured from each
// joint's index, direction and gear ratio already applied).
struct EncoderSample {
  std::int64_t utime_us = 0;  // µs since the Unix epoch, NTP-aligned
  std::array<double, kJoints> theta_r{};
  std::uint8_t homed_mask = kAllJoints;  // bit i: joint i+1 homed
  std::uint8_t fault_mask = 0;           // bit i: joint i+1 flagged (stale, glitch, ...)
  // The widest gap between the recorded samples from this one to the next
  // (set by the readers; 0: the difference of the two utimes).
  std::int32_t widest_gap_us = 0;
  bool valid() const noexcept { return homed_mask == kAllJoints && fault_mask == 0; }
};

struct EncoderSeries {
  std::string source;                  // file name, for messages and provenance
  std::vector<EncoderSample> samples;  // strictly increasing utime
  std::vector<std::string> notes;      // what the reader skipped or assumed, for people
  std::size_t thinned = 0;             // samples dropped to stay within kMaxEncoderSamples
};

// How to read encoder angles from the project's own recordings, which hold
// calibrated angles θ = Δθ⁰ + θᴿ (joint_state_t.position, the `<joint>_rad`
// columns of `exodaq export`): θᴿ = θ − Δθ⁰ of the calibration they were
// computed with.
struct EncoderReadOptions {
  std::optional<std::array<double, kJoints>> recorded_offsets_rad;
  std::string recorded_calibration;   // where those offsets come from, for messages
  std::optional<std::string> prefix;  // LCM logs: the rig's channel prefix (default: the only one)
};

// Encoder CSV, either dialect, told apart by the header:
//  - calibrate's own: `utime_us,j1_rad,...,j6_rad[,homed_mask][,fault_mask]`
//    (θᴿ; any column order, '#' comments, blank lines ignored; missing mask
//    columns mean "all homed, no fault"; unknown columns are errors);
//  - `exodaq export`'s (docs/messages.md "CSV"; has run_id and mono_ns):
//    the six `<joint>_rad` columns less the recorded offsets (required),
//    `<joint>_homed`, and as faults any `<joint>_flags` bit but HELD and
//    UNHOMED, every joint of a SAMPLE_MISSING cycle; other columns ignored.
// Rows must have strictly increasing utime_us.
class EncoderCsvReader {
 public:
  EncoderSeries read(const std::string& path, const EncoderReadOptions& o = {}) const;
  EncoderSeries parse(const std::string& text, const std::string& name,
                      const EncoderReadOptions& o = {}) const;
};

// An LCM log (lcm-logger, exodaq replay): the joint_state_t messages of one
// rig, read as `exodaq export`'s rows are. Needs the recorded offsets.
EncoderSeries read_joint_state_log(const std::string& path, const EncoderReadOptions& o);

// By content: an LCM log (magic number) or a CSV of either dialect. Errors
// are ConfigError "file[:line]: what".
EncoderSeries read_encoder_log(const std::string& path, const EncoderReadOptions& o = {});

struct MarkerSample {
  std::int64_t utime_us = 0;   // epoch µs (long CSV), else µs since the capture's first frame
  bool present = false;        // false: marker occluded (empty/NaN coordinates, invalid point)
  double x = 0, y = 0, z = 0;  // m, camera frame
  int marker_id = -1;          // -1 when the file has no marker_id column
};

// The motion-capture files the readers know, told apart by content
// (docs/calibration.md §3.4).
enum class MarkerFormat {
  kLongCsv,    // the project's CSV: utime_us,x_mm,y_mm,z_mm[,marker_id]
  kC3d,        // C3D (points; Intel, DEC and SGI/MIPS; integer and float storage)
  kViconCsv,   // Vicon Nexus CSV export, its Trajectories section
  kMotiveCsv,  // OptiTrack Motive CSV export (marker and rigid-body-marker columns)
};
const char* format_name(MarkerFormat f) noexcept;

// What a marker file says about itself.
struct MarkerFileInfo {
  MarkerFormat format = MarkerFormat::kLongCsv;
  // Labelled formats: the markers' labels; a marker's id is its 1-based
  // position in this list. Empty for the long CSV (ids from marker_id).
  std::vector<std::string> labels;
  double rate_hz = 0;       // frame rate (0: not stated)
  bool epoch_times = true;  // utime_us since the Unix epoch; false: from the first frame
  std::string start_time;   // the export's own capture start time, as written (Motive)
  std::vector<std::string> notes;
};

// A marker asked for by id, label or both. A labelled export looks up the
// label (the exact label, or the part after the last ':' of exactly one
// label: "Subject:RHand" answers "RHand"), or without one the id (its 1-based
// position); the long CSV looks up the id (marker_id), and a label without an
// id is an error there.
struct MarkerRef {
  int id = -1;
  std::string label;
  std::string text() const { return label.empty() ? std::to_string(id) : label; }
};
// "12" is an id, anything else a label.
MarkerRef marker_ref(const std::string& text);

struct MarkerSeries {
  std::string source;
  std::vector<MarkerSample> samples;  // in file order
  std::size_t other_ids = 0;          // rows of markers that were not selected (counted, not used)
  MarkerFileInfo info;
  std::vector<int> ids;     // the id each requested MarkerRef resolved to
  std::size_t thinned = 0;  // samples dropped to stay within kMaxMarkerSamples
};

// Reads the markers `wanted` from a file of any MarkerFormat, selected by
// content. Empty `wanted`: the file must hold one marker. Every wanted marker
// must exist (labels are checked against the header before the body is read)
// and have samples. Samples of a marker must increase in time.
MarkerSeries read_markers(const std::string& path, const std::vector<MarkerRef>& wanted);
MarkerSeries parse_markers(const std::string& text, const std::string& name,
                           const std::vector<MarkerRef>& wanted);

// The long CSV: header `utime_us,x_mm,y_mm,z_mm[,marker_id]`. Empty fields or
// `nan` in x/y/z mean the marker was not seen (counted, skipped). `marker_id`
// selects one marker when the file holds several (-1: the file must hold one id).
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
  std::size_t thinned = 0;          // dropped by max_points
  std::size_t other_ids = 0;        // rows of markers not selected (MarkerSeries::other_ids)
  std::size_t thinned_reading = 0;  // dropped by the readers' memory bound (both streams)
};

std::vector<AlignedSample> align(const EncoderSeries& enc, const MarkerSeries& markers,
                                 const AlignmentOptions& options, AlignmentStats& stats);

// Sets each point's site from the layout by its marker id. Throws
// std::invalid_argument naming an id the layout does not have.
void apply_layout(std::vector<AlignedSample>& points, const MarkerLayout& layout);

}  // namespace exodaq::calibration
