#include "exodaq/calibration/inputs.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include "exodaq/config/yaml_reader.hpp"

namespace exodaq::calibration {

using config::ConfigError;

namespace {

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path, 0, std::string("cannot open: ") + std::strerror(errno));
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

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

EncoderSeries EncoderCsvReader::parse(const std::string& text, const std::string& name) const {
  const auto lines = csv_lines(text);
  if (lines.empty()) throw ConfigError(name, 0, "empty file (no header)");
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

EncoderSeries EncoderCsvReader::read(const std::string& path) const {
  return parse(read_text(path), path);
}

EncoderSeries read_encoder_log(const std::string& path) {
  const auto dot = path.rfind('.');
  const std::string ext = dot == std::string::npos ? "" : path.substr(dot + 1);
  if (ext == "csv" || ext == "CSV") return EncoderCsvReader().read(path);
  throw ConfigError(path, 0,
                    "unsupported encoder log format '." + ext +
                        "': give a CSV (utime_us,j1_rad..j6_rad[,homed_mask,fault_mask]; "
                        "docs/calibration.md). LCM logs are read once replay support lands.");
}

MarkerSeries parse_marker_csv(const std::string& text, const std::string& name, int marker_id) {
  const auto lines = csv_lines(text);
  if (lines.empty()) throw ConfigError(name, 0, "empty file (no header)");
  const auto cols = header(lines[0], name, kMarkerRequired, kMarkerOptional);
  const bool has_id = cols.count("marker_id") > 0;
  MarkerSeries out;
  out.source = name;
  int first_id = -1;
  int first_id_line = 0;
  std::int64_t last_time = 0;
  bool have_last = false;
  for (std::size_t k = 1; k < lines.size(); ++k) {
    const CsvLine& l = lines[k];
    if (l.fields.size() != lines[0].fields.size()) {
      throw ConfigError(name, l.number,
                        "expected " + std::to_string(lines[0].fields.size()) + " fields, found " +
                            std::to_string(l.fields.size()));
    }
    MarkerSample s;
    s.utime_us = parse_int(l.fields[cols.at("utime_us")], name, l.number, "utime_us");
    if (has_id) {
      s.marker_id =
          static_cast<int>(parse_int(l.fields[cols.at("marker_id")], name, l.number, "marker_id"));
      if (marker_id < 0) {
        if (first_id < 0) {
          first_id = s.marker_id;
          first_id_line = l.number;
        } else if (s.marker_id != first_id) {
          throw ConfigError(name, l.number,
                            "marker_id " + std::to_string(s.marker_id) + " differs from " +
                                std::to_string(first_id) + " (line " +
                                std::to_string(first_id_line) +
                                "): select one marker with --marker-id");
        }
      } else if (s.marker_id != marker_id) {
        continue;
      }
    }
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
    if (have_last && s.utime_us <= last_time) {
      throw ConfigError(name, l.number,
                        "utime_us " + std::to_string(s.utime_us) +
                            " does not increase (previous row " + std::to_string(last_time) + ")");
    }
    last_time = s.utime_us;
    have_last = true;
    out.samples.push_back(s);
  }
  if (out.samples.empty()) {
    throw ConfigError(name, 0,
                      marker_id >= 0 ? "no samples of marker_id " + std::to_string(marker_id)
                                     : std::string("no marker samples"));
  }
  return out;
}

MarkerSeries read_marker_csv(const std::string& path, int marker_id) {
  return parse_marker_csv(read_text(path), path, marker_id);
}

std::vector<AlignedSample> align(const EncoderSeries& enc, const MarkerSeries& markers,
                                 const AlignmentOptions& options, AlignmentStats& stats) {
  stats = AlignmentStats{};
  stats.marker_samples = markers.samples.size();
  const auto& e = enc.samples;
  // invalid_before[i]: number of invalid samples among e[0..i-1].
  std::vector<std::size_t> invalid_before(e.size() + 1, 0);
  for (std::size_t i = 0; i < e.size(); ++i) {
    invalid_before[i + 1] = invalid_before[i] + (e[i].valid() ? 0 : 1);
  }
  auto by_time = [](const EncoderSample& s, std::int64_t t) { return s.utime_us < t; };
  std::vector<AlignedSample> out;
  for (const MarkerSample& m : markers.samples) {
    if (!m.present) {
      ++stats.marker_missing;
      continue;
    }
    const std::int64_t lo_t = m.utime_us - options.guard_us;
    const std::int64_t hi_t = m.utime_us + options.guard_us;
    if (e.empty() || lo_t < e.front().utime_us || hi_t > e.back().utime_us) {
      ++stats.outside_encoder_log;
      continue;
    }
    // Encoder samples bracketing [lo_t, hi_t].
    auto lo_it = std::lower_bound(e.begin(), e.end(), lo_t, by_time);
    if (lo_it->utime_us > lo_t) --lo_it;
    auto hi_it = std::lower_bound(e.begin(), e.end(), hi_t, by_time);
    const auto lo = static_cast<std::size_t>(lo_it - e.begin());
    const auto hi = static_cast<std::size_t>(hi_it - e.begin());
    bool gap = false;
    for (std::size_t i = lo; i < hi && !gap; ++i) {
      gap = e[i + 1].utime_us - e[i].utime_us > options.max_gap_us;
    }
    if (gap) {
      ++stats.encoder_gap;
      continue;
    }
    if (invalid_before[hi + 1] - invalid_before[lo] != 0) {
      ++stats.unhomed_or_faulted;
      continue;
    }
    auto it = std::lower_bound(e.begin(), e.end(), m.utime_us, by_time);
    std::size_t i1 = static_cast<std::size_t>(it - e.begin());
    std::size_t i0 = i1;
    if (e[i1].utime_us > m.utime_us) i0 = i1 - 1;
    AlignedSample a;
    a.utime_us = m.utime_us;
    a.encoder_index = static_cast<int>(i0);
    const double span = static_cast<double>(e[i1].utime_us - e[i0].utime_us);
    const double w = span > 0 ? static_cast<double>(m.utime_us - e[i0].utime_us) / span : 0.0;
    for (int j = 0; j < kJoints; ++j) {
      a.theta_r[j] = (1.0 - w) * e[i0].theta_r[j] + w * e[i1].theta_r[j];
    }
    a.marker = {m.x, m.y, m.z};
    out.push_back(a);
  }
  if (options.max_points > 0 && out.size() > options.max_points) {
    std::vector<AlignedSample> thin;
    thin.reserve(options.max_points);
    const double step = static_cast<double>(out.size()) / static_cast<double>(options.max_points);
    for (std::size_t k = 0; k < options.max_points; ++k) {
      thin.push_back(out[static_cast<std::size_t>(std::floor(k * step))]);
    }
    stats.thinned = out.size() - thin.size();
    out = std::move(thin);
  }
  stats.used = out.size();
  return out;
}

}  // namespace exodaq::calibration
