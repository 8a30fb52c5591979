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

#include "encoder_logs.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/config/yaml_reader.hpp"

namespace exodaq::calibration {

using config::ConfigError;

namespace {}  // namespace

std::string detail::read_csv_text(const std::string& path) {
  try {
    return files::read_input(path, files::kMaxCsvBytes);
  } catch (const files::FileError& e) {
    throw ConfigError(path, 0, e.reason());
  }
}

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out;
  std::string field;
  std::istringstream in(line);
  while (std::getline(in, field, ',')) out.push_back(trim(field));
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

// Lines of a CSV file with their 1-based numbers; comments and blank lines dropped.
struct CsvLine {
  int number;
  std::vector<std::string> fields;
};

std::vector<CsvLine> csv_lines(const std::string& text) {
  std::vector<CsvLine> out;
  std::istringstream in(text);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    out.push_back({n, split(t)});
  }
  return out;
}

// Header: column name -> index. Unknown columns are errors (a typo in a column
// name would otherwise silently fall back to a default).
std::map<std::string, std::size_t> header(const CsvLine& h, const std::string& name,
                                          const std::vector<std::string>& required,
                                          const std::vector<std::string>& optional) {
  std::map<std::string, std::size_t> cols;
  for (std::size_t i = 0; i < h.fields.size(); ++i) {
    const std::string& c = h.fields[i];
    const bool known = std::find(required.begin(), required.end(), c) != required.end() ||
                       std::find(optional.begin(), optional.end(), c) != optional.end();
    if (!known) {
      std::string all;
      for (const auto& r : required) all += (all.empty() ? "" : ", ") + r;
      for (const auto& o : optional) all += ", " + o + " (optional)";
      throw ConfigError(name, h.number, "unknown column '" + c + "' (expected " + all + ")");
    }
    if (cols.count(c)) throw ConfigError(name, h.number, "column '" + c + "' appears twice");
    cols[c] = i;
  }
  for (const auto& r : required) {
    if (!cols.count(r)) throw ConfigError(name, h.number, "missing column '" + r + "'");
  }
  return cols;
}

std::int64_t parse_int(const std::string& s, const std::string& name, int line,
                       const std::string& col) {
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(s.c_str(), &end, 10);
  if (s.empty() || *end != '\0' || errno == ERANGE) {
    throw ConfigError(name, line, "column '" + col + "': '" + s + "' is not an integer");
  }
  return v;
}

// Finite double; with allow_missing, "" / nan / NaN give nullopt.
std::optional<double> parse_double(const std::string& s, const std::string& name, int line,
                                   const std::string& col, bool allow_missing) {
  if (allow_missing) {
    std::string l = s;
    std::transform(l.begin(), l.end(), l.begin(), [](unsigned char c) { return std::tolower(c); });
    if (l.empty() || l == "nan") return std::nullopt;
  }
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || *end != '\0') {
    throw ConfigError(name, line, "column '" + col + "': '" + s + "' is not a number");
  }
  if (!std::isfinite(v)) {
    throw ConfigError(name, line, "column '" + col + "': '" + s + "' is not a finite number");
  }
  return v;
}

const std::vector<std::string> kEncoderRequired = {"utime_us", "j1_rad", "j2_rad", "j3_rad",
                                                   "j4_rad",   "j5_rad", "j6_rad"};
const std::vector<std::string> kEncoderOptional = {"homed_mask", "fault_mask"};
const std::vector<std::string> kMarkerRequired = {"utime_us", "x_mm", "y_mm", "z_mm"};
const std::vector<std::string> kMarkerOptional = {"marker_id"};

}  // namespace

EncoderSeries EncoderCsvReader::parse(const std::string& text, const std::string& name,
                                      const EncoderReadOptions& o) const {
  const auto lines = csv_lines(text);
  if (lines.empty()) throw ConfigError(name, 0, "empty file (no header)");
  const auto& head = lines[0].fields;
  if (std::find(head.begin(), head.end(), "run_id") != head.end() &&
      std::find(head.begin(), head.end(), "mono_ns") != head.end()) {
    std::vector<detail::CsvRow> rows;
    rows.reserve(lines.size());
    for (const auto& l : lines) rows.push_back({l.number, l.fields});
    return detail::parse_export_csv(rows, name, o);
  }
  const auto cols = header(lines[0], name, kEncoderRequired, kEncoderOptional);
  EncoderSeries out;
  out.source = name;
  out.samples.reserve(lines.size() - 1);
  for (std::size_t k = 1; k < lines.size(); ++k) {
    const CsvLine& l = lines[k];
    if (l.fields.size() != lines[0].fields.size()) {
      throw ConfigError(name, l.number,
                        "expected " + std::to_string(lines[0].fields.size()) + " fields, found " +
                            std::to_string(l.fields.size()));
    }
    EncoderSample s;
    s.utime_us = parse_int(l.fields[cols.at("utime_us")], name, l.number, "utime_us");
    for (int j = 0; j < kJoints; ++j) {
      const std::string c = "j" + std::to_string(j + 1) + "_rad";
      s.theta_r[j] = *parse_double(l.fields[cols.at(c)], name, l.number, c, false);
    }
    for (const char* mask : {"homed_mask", "fault_mask"}) {
      const auto it = cols.find(mask);
      if (it == cols.end()) continue;
      const auto v = parse_int(l.fields[it->second], name, l.number, mask);
      if (v < 0 || v > kAllJoints) {
        throw ConfigError(name, l.number,
                          std::string("column '") + mask + "': " + std::to_string(v) +
                              " is not a 6-bit joint mask (0..63)");
      }
      (std::strcmp(mask, "homed_mask") == 0 ? s.homed_mask : s.fault_mask) =
          static_cast<std::uint8_t>(v);
    }
    if (!out.samples.empty() && s.utime_us <= out.samples.back().utime_us) {
      throw ConfigError(name, l.number,
                        "utime_us " + std::to_string(s.utime_us) +
                            " does not increase (previous row " +
                            std::to_string(out.samples.back().utime_us) + ")");
    }
    out.samples.push_back(s);
  }
  if (out.samples.size() < 2) throw ConfigError(name, 0, "fewer than two encoder samples");
  return out;
}

EncoderSeries EncoderCsvReader::read(const std::string& path, const EncoderReadOptions& o) const {
  return parse(detail::read_csv_text(path), path, o);
}

namespace {

// Which markers a parse keeps: one id (or, with -1, the only one in the
// file), or a set of ids.
struct MarkerSelection {
  int single = -1;
  std::vector<int> ids;
  bool many = false;
  bool keeps(int id) const {
    return many ? std::find(ids.begin(), ids.end(), id) != ids.end() : single < 0 || id == single;
  }
};

void check_fields(const CsvLine& l, const CsvLine& head, const std::string& name) {
  if (l.fields.size() != head.fields.size()) {
    throw ConfigError(name, l.number,
                      "expected " + std::to_string(head.fields.size()) + " fields, found " +
                          std::to_string(l.fields.size()));
  }
}

// x/y/z of a row: all numbers (mm) or all missing.
void read_position(const CsvLine& l, const std::map<std::string, std::size_t>& cols,
                   const std::string& name, MarkerSample& s) {
  const auto x = parse_double(l.fields[cols.at("x_mm")], name, l.number, "x_mm", true);
  const auto y = parse_double(l.fields[cols.at("y_mm")], name, l.number, "y_mm", true);
  const auto z = parse_double(l.fields[cols.at("z_mm")], name, l.number, "z_mm", true);
  const int seen = static_cast<int>(x.has_value()) + static_cast<int>(y.has_value()) +
                   static_cast<int>(z.has_value());
  if (seen != 0 && seen != 3) {
    throw ConfigError(name, l.number,
                      "x_mm, y_mm, z_mm must all be numbers or all empty/nan (marker missing)");
  }
  s.present = seen == 3;
  if (s.present) {
    s.x = *x * 1e-3;
    s.y = *y * 1e-3;
    s.z = *z * 1e-3;
  }
}

// Without --marker-id, a file with a marker_id column must hold one id.
class SingleIdCheck {
 public:
  void check(int id, int line, const std::string& name) {
    if (first_ < 0) {
      first_ = id;
      first_line_ = line;
    } else if (id != first_) {
      throw ConfigError(name, line,
                        "marker_id " + std::to_string(id) + " differs from " +
                            std::to_string(first_) + " (line " + std::to_string(first_line_) +
                            "): select one marker with --marker-id");
    }
  }

 private:
  int first_ = -1;
  int first_line_ = 0;
};

// utime_us must increase from row to row of each marker.
class TimeOrderCheck {
 public:
  void check(const MarkerSample& s, int line, const std::string& name) {
    const auto it = last_.find(s.marker_id);
    if (it != last_.end() && s.utime_us <= it->second) {
      throw ConfigError(name, line,
                        "utime_us " + std::to_string(s.utime_us) +
                            " does not increase (previous row " + std::to_string(it->second) + ")");
    }
    last_[s.marker_id] = s.utime_us;
  }
  bool has(int id) const { return last_.count(id) > 0; }

 private:
  std::map<int, std::int64_t> last_;
};

void check_all_ids_present(const MarkerSelection& sel, const TimeOrderCheck& order,
                           const std::string& name) {
  std::string missing;
  for (int id : sel.ids) {
    if (!order.has(id)) missing += (missing.empty() ? "" : ", ") + std::to_string(id);
  }
  if (!missing.empty()) {
    throw ConfigError(name, 0, "no samples of marker_id " + missing);
  }
}

MarkerSeries parse_markers(const std::string& text, const std::string& name,
                           const MarkerSelection& sel) {
  const auto lines = csv_lines(text);
  if (lines.empty()) throw ConfigError(name, 0, "empty file (no header)");
  const auto cols = header(lines[0], name, kMarkerRequired, kMarkerOptional);
  const bool has_id = cols.count("marker_id") > 0;
  if (sel.many && !has_id) {
    throw ConfigError(name, lines[0].number, "several markers need the 'marker_id' column");
  }
  MarkerSeries out;
  out.source = name;
  SingleIdCheck single;
  TimeOrderCheck order;
  for (std::size_t k = 1; k < lines.size(); ++k) {
    const CsvLine& l = lines[k];
    check_fields(l, lines[0], name);
    MarkerSample s;
    s.utime_us = parse_int(l.fields[cols.at("utime_us")], name, l.number, "utime_us");
    if (has_id) {
      s.marker_id =
          static_cast<int>(parse_int(l.fields[cols.at("marker_id")], name, l.number, "marker_id"));
      if (!sel.many && sel.single < 0) single.check(s.marker_id, l.number, name);
      if (!sel.keeps(s.marker_id)) {
        ++out.other_ids;
        continue;
      }
    }
    read_position(l, cols, name, s);
    order.check(s, l.number, name);
    out.samples.push_back(s);
  }
  if (sel.many) check_all_ids_present(sel, order, name);
  if (out.samples.empty()) {
    throw ConfigError(name, 0,
                      sel.single >= 0 ? "no samples of marker_id " + std::to_string(sel.single)
                                      : std::string("no marker samples"));
  }
  return out;
}

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
      if (e_[i + 1].utime_us - e_[i].utime_us > max_gap_us) return Bracket::kGap;
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

// At most `max_points` evenly spread points of each marker id, order kept.
std::vector<AlignedSample> thin_per_marker(const std::vector<AlignedSample>& in,
                                           std::size_t max_points) {
  std::map<int, std::vector<std::size_t>> by_id;
  for (std::size_t i = 0; i < in.size(); ++i) by_id[in[i].site.id].push_back(i);
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
  std::vector<AlignedSample> out;
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (keep[i]) out.push_back(in[i]);
  }
  return out;
}

}  // namespace

MarkerSeries parse_marker_csv(const std::string& text, const std::string& name, int marker_id) {
  MarkerSelection sel;
  sel.single = marker_id;
  return parse_markers(text, name, sel);
}

MarkerSeries read_marker_csv(const std::string& path, int marker_id) {
  return parse_marker_csv(detail::read_csv_text(path), path, marker_id);
}

MarkerSeries parse_marker_csv_ids(const std::string& text, const std::string& name,
                                  const std::vector<int>& ids) {
  MarkerSelection sel;
  sel.ids = ids;
  sel.many = true;
  return parse_markers(text, name, sel);
}

MarkerSeries read_marker_csv_ids(const std::string& path, const std::vector<int>& ids) {
  return parse_marker_csv_ids(detail::read_csv_text(path), path, ids);
}

std::vector<AlignedSample> align(const EncoderSeries& enc, const MarkerSeries& markers,
                                 const AlignmentOptions& options, AlignmentStats& stats) {
  stats = AlignmentStats{};
  stats.marker_samples = markers.samples.size();
  stats.other_ids = markers.other_ids;
  const EncoderIndex index(enc);
  std::vector<AlignedSample> out;
  for (const MarkerSample& m : markers.samples) {
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
    AlignedSample a = index.interpolate(m.utime_us);
    a.marker = {m.x, m.y, m.z};
    a.site.id = m.marker_id;
    out.push_back(a);
  }
  if (options.max_points > 0) {
    const std::size_t before = out.size();
    out = thin_per_marker(out, options.max_points);
    stats.thinned = before - out.size();
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
