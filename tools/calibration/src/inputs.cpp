#include "exodaq/calibration/inputs.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

#include "csv_text.hpp"
#include "encoder_logs.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "sample_stores.hpp"

namespace exodaq::calibration {

using exodaq::ConfigError;

namespace {

using detail::parse_double;
using detail::parse_int;

const std::vector<std::string> kEncoderRequired = {"utime_us", "j1_rad", "j2_rad", "j3_rad",
                                                   "j4_rad",   "j5_rad", "j6_rad"};
const std::vector<std::string> kEncoderOptional = {"homed_mask", "fault_mask"};

}  // namespace

namespace {

// Calibrate's own encoder CSV after its header.
EncoderSeries read_encoder_rows(detail::LineReader& in, const std::vector<std::string>& head,
                                int head_line) {
  const std::string& name = in.name();
  const auto cols = detail::csv_header(head, head_line, name, kEncoderRequired, kEncoderOptional);
  EncoderSeries out;
  out.source = name;
  detail::EncoderStore store(kMaxEncoderSamples,
                             static_cast<std::size_t>(in.size() / 40));  // rows >= 40 bytes
  std::string line;
  std::vector<std::string> f;
  while (detail::next_row(in, line, f)) {
    const int n = in.line();
    if (f.size() != head.size()) detail::wrong_field_count(name, n, head.size(), f.size());
    EncoderSample s;
    s.utime_us = parse_int(f[cols.at("utime_us")], name, n, "utime_us");
    for (int j = 0; j < kJoints; ++j) {
      const std::string c = "j" + std::to_string(j + 1) + "_rad";
      s.theta_r[j] = *parse_double(f[cols.at(c)], name, n, c, false);
    }
    for (const char* mask : {"homed_mask", "fault_mask"}) {
      const auto it = cols.find(mask);
      if (it == cols.end()) continue;
      const auto v = parse_int(f[it->second], name, n, mask);
      if (v < 0 || v > kAllJoints) {
        throw ConfigError(name, n,
                          std::string("column '") + mask + "': " + std::to_string(v) +
                              " is not a 6-bit joint mask (0..63)");
      }
      (std::strcmp(mask, "homed_mask") == 0 ? s.homed_mask : s.fault_mask) =
          static_cast<std::uint8_t>(v);
    }
    if (!store.empty() && s.utime_us <= store.last_utime()) {
      throw ConfigError(name, n,
                        "utime_us " + std::to_string(s.utime_us) +
                            " does not increase (previous row " +
                            std::to_string(store.last_utime()) + ")");
    }
    store.push(s);
  }
  out.thinned = store.thinned();
  out.samples = store.take();
  if (out.samples.size() < 2) throw ConfigError(name, 0, "fewer than two encoder samples");
  return out;
}

EncoderSeries read_encoder_csv(detail::LineReader in, const EncoderReadOptions& o) {
  std::string line;
  std::vector<std::string> head;
  if (!detail::next_row(in, line, head)) throw ConfigError(in.name(), 0, "empty file (no header)");
  EncoderSeries out = std::find(head.begin(), head.end(), "run_id") != head.end() &&
                              std::find(head.begin(), head.end(), "mono_ns") != head.end()
                          ? detail::parse_export_csv(in, head, in.line(), o)
                          : read_encoder_rows(in, head, in.line());
  if (out.thinned > 0) {
    out.notes.push_back(in.name() + ": " + std::to_string(out.thinned) +
                        " samples thinned while reading (more than " +
                        std::to_string(kMaxEncoderSamples) + " samples; evenly spread)");
  }
  return out;
}

}  // namespace

EncoderSeries EncoderCsvReader::parse(const std::string& text, const std::string& name,
                                      const EncoderReadOptions& o) const {
  return read_encoder_csv(detail::LineReader::from_text(text, name), o);
}

EncoderSeries EncoderCsvReader::read(const std::string& path, const EncoderReadOptions& o) const {
  return read_encoder_csv(detail::LineReader::open_file(path), o);
}

namespace {

// Encoder samples bracketing [lo_t, hi_t] must be valid and without a gap.
enum class Bracket { kOk, kOutside, kGap, kInvalid };

class EncoderIndex {
 public:
  explicit EncoderIndex(const EncoderSeries& enc)
      : e_(enc.samples), invalid_before_(e_.size() + 1) {
    // invalid_before_[i]: number of invalid samples among e[0..i-1].
    for (std::size_t i = 0; i < e_.size(); ++i) {
      invalid_before_[i + 1] = invalid_before_[i] + (e_[i].valid() ? 0 : 1);
    }
  }

  Bracket check(std::int64_t lo_t, std::int64_t hi_t, std::int64_t max_gap_us) const {
    if (e_.empty() || lo_t < e_.front().utime_us || hi_t > e_.back().utime_us) {
      return Bracket::kOutside;
    }
    auto lo_it = std::lower_bound(e_.begin(), e_.end(), lo_t, by_time);
    if (lo_it->utime_us > lo_t) --lo_it;
    auto hi_it = std::lower_bound(e_.begin(), e_.end(), hi_t, by_time);
    const auto lo = static_cast<std::size_t>(lo_it - e_.begin());
    const auto hi = static_cast<std::size_t>(hi_it - e_.begin());
    for (std::size_t i = lo; i < hi; ++i) {
      const std::int64_t gap =
          std::max<std::int64_t>(e_[i + 1].utime_us - e_[i].utime_us, e_[i].widest_gap_us);
      if (gap > max_gap_us) return Bracket::kGap;
    }
    return invalid_before_[hi + 1] - invalid_before_[lo] != 0 ? Bracket::kInvalid : Bracket::kOk;
  }

  // θᴿ linearly interpolated at t (inside the log).
  AlignedSample interpolate(std::int64_t t) const {
    auto it = std::lower_bound(e_.begin(), e_.end(), t, by_time);
    std::size_t i1 = static_cast<std::size_t>(it - e_.begin());
    std::size_t i0 = i1;
    if (e_[i1].utime_us > t) i0 = i1 - 1;
    AlignedSample a;
    a.utime_us = t;
    a.encoder_index = static_cast<int>(i0);
    const double span = static_cast<double>(e_[i1].utime_us - e_[i0].utime_us);
    const double w = span > 0 ? static_cast<double>(t - e_[i0].utime_us) / span : 0.0;
    for (int j = 0; j < kJoints; ++j) {
      a.theta_r[j] = (1.0 - w) * e_[i0].theta_r[j] + w * e_[i1].theta_r[j];
    }
    return a;
  }

 private:
  static bool by_time(const EncoderSample& s, std::int64_t t) { return s.utime_us < t; }
  const std::vector<EncoderSample>& e_;
  std::vector<std::size_t> invalid_before_;
};

void count_skip(Bracket b, AlignmentStats& stats) {
  if (b == Bracket::kOutside) ++stats.outside_encoder_log;
  if (b == Bracket::kGap) ++stats.encoder_gap;
  if (b == Bracket::kInvalid) ++stats.unhomed_or_faulted;
}

// At most `max_points` evenly spread of the usable samples of each marker
// id (indices into the marker series), order kept.
std::vector<std::size_t> thin_per_marker(const MarkerSeries& m, const std::vector<std::size_t>& in,
                                         std::size_t max_points) {
  std::map<int, std::vector<std::size_t>> by_id;
  for (std::size_t i = 0; i < in.size(); ++i) by_id[m.samples[in[i]].marker_id].push_back(i);
  std::vector<bool> keep(in.size(), false);
  for (const auto& [id, idx] : by_id) {
    if (idx.size() <= max_points) {
      for (std::size_t i : idx) keep[i] = true;
      continue;
    }
    const double step = static_cast<double>(idx.size()) / static_cast<double>(max_points);
    for (std::size_t k = 0; k < max_points; ++k) {
      keep[idx[static_cast<std::size_t>(std::floor(static_cast<double>(k) * step))]] = true;
    }
  }
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (keep[i]) out.push_back(in[i]);
  }
  return out;
}

}  // namespace

std::vector<AlignedSample> align(const EncoderSeries& enc, const MarkerSeries& markers,
                                 const AlignmentOptions& options, AlignmentStats& stats) {
  stats = AlignmentStats{};
  stats.marker_samples = markers.samples.size();
  stats.other_ids = markers.other_ids;
  stats.thinned_reading = markers.thinned;
  const EncoderIndex index(enc);
  // Which samples are usable, before anything is built (a long capture would
  // otherwise build every point only to thin them).
  std::vector<std::size_t> usable;
  for (std::size_t i = 0; i < markers.samples.size(); ++i) {
    const MarkerSample& m = markers.samples[i];
    if (!m.present) {
      ++stats.marker_missing;
      continue;
    }
    const Bracket b = index.check(m.utime_us - options.guard_us, m.utime_us + options.guard_us,
                                  options.max_gap_us);
    if (b != Bracket::kOk) {
      count_skip(b, stats);
      continue;
    }
    usable.push_back(i);
  }
  if (options.max_points > 0) {
    const std::size_t before = usable.size();
    usable = thin_per_marker(markers, usable, options.max_points);
    stats.thinned = before - usable.size();
  }
  std::vector<AlignedSample> out;
  out.reserve(usable.size());
  for (std::size_t i : usable) {
    const MarkerSample& m = markers.samples[i];
    AlignedSample a = index.interpolate(m.utime_us);
    a.marker = {m.x, m.y, m.z};
    a.site.id = m.marker_id;
    out.push_back(a);
  }
  stats.used = out.size();
  return out;
}

void apply_layout(std::vector<AlignedSample>& points, const MarkerLayout& layout) {
  for (AlignedSample& p : points) {
    const MarkerSite* site = layout.find(p.site.id);
    if (site == nullptr) {
      throw std::invalid_argument("marker_id " + std::to_string(p.site.id) +
                                  " is not in the marker layout " + layout.source);
    }
    p.site = *site;
  }
}

}  // namespace exodaq::calibration
