// Motion-capture marker files, told apart by content (docs/calibration.md
// §3.4): the project's long CSV, the Vicon Nexus CSV export (its Trajectories
// section), the OptiTrack Motive CSV export, and C3D (c3d_reader.cpp). Every
// reader streams its file and keeps only the selected markers' samples, within
// kMaxMarkerSamples (sample_stores.hpp).
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <map>
#include <set>

#include "csv_text.hpp"
#include "exodaq/calibration/inputs.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "marker_readers.hpp"
#include "sample_stores.hpp"

namespace exodaq::calibration {

using detail::LineReader;
using exodaq::ConfigError;

const char* format_name(MarkerFormat f) noexcept {
  switch (f) {
    case MarkerFormat::kLongCsv:
      return "long CSV";
    case MarkerFormat::kC3d:
      return "C3D";
    case MarkerFormat::kViconCsv:
      return "Vicon Nexus CSV";
    case MarkerFormat::kMotiveCsv:
      return "OptiTrack Motive CSV";
  }
  return "?";
}

MarkerRef marker_ref(const std::string& text) {
  const bool number =
      !text.empty() && text.size() < 10 && std::all_of(text.begin(), text.end(), [](char c) {
        return std::isdigit(static_cast<unsigned char>(c)) != 0;
      });
  MarkerRef r;
  if (number) {
    r.id = std::stoi(text);
  } else {
    r.label = text;
  }
  return r;
}

namespace detail {

namespace {

std::string label_list(const std::vector<std::string>& labels) {
  std::string out;
  for (std::size_t k = 0; k < labels.size() && k < 12; ++k) {
    out += (k ? ", " : "") + labels[k];
  }
  if (labels.size() > 12) out += ", ... (" + std::to_string(labels.size()) + " in all)";
  return out.empty() ? "none" : out;
}

int find_label(const std::vector<std::string>& labels, const std::string& want,
               const std::string& name) {
  for (std::size_t k = 0; k < labels.size(); ++k) {
    if (labels[k] == want) return static_cast<int>(k) + 1;
  }
  int found = 0;
  for (std::size_t k = 0; k < labels.size(); ++k) {
    const auto colon = labels[k].rfind(':');
    if (colon != std::string::npos && labels[k].substr(colon + 1) == want) {
      if (found != 0) {
        throw ConfigError(name, 0,
                          "marker '" + want + "' matches both '" + labels[found - 1] + "' and '" +
                              labels[k] + "': give the whole label");
      }
      found = static_cast<int>(k) + 1;
    }
  }
  if (found == 0) {
    throw ConfigError(name, 0,
                      "no marker '" + want + "' (the file has " + label_list(labels) + ")");
  }
  return found;
}

}  // namespace

std::vector<int> resolve_labels(const std::vector<std::string>& labels,
                                const std::vector<MarkerRef>& wanted, const std::string& name) {
  if (wanted.empty()) {
    if (labels.size() != 1) {
      throw ConfigError(name, 0,
                        "holds " + std::to_string(labels.size()) + " markers (" +
                            label_list(labels) +
                            "): select one with --marker-id or use a marker layout");
    }
    return {1};
  }
  std::vector<int> ids;
  for (const MarkerRef& r : wanted) {
    int id = 0;
    if (!r.label.empty()) {
      id = find_label(labels, r.label, name);
    } else if (r.id >= 1 && static_cast<std::size_t>(r.id) <= labels.size()) {
      id = r.id;
    } else {
      throw ConfigError(name, 0,
                        "no marker " + std::to_string(r.id) + ": the file has " +
                            std::to_string(labels.size()) +
                            " markers, numbered 1.. in its order (" + label_list(labels) +
                            "); prefer their labels");
    }
    if (std::find(ids.begin(), ids.end(), id) != ids.end()) {
      throw ConfigError(name, 0, "marker '" + labels[id - 1] + "' is asked for twice");
    }
    ids.push_back(id);
  }
  return ids;
}

}  // namespace detail

namespace {

using detail::parse_double;
using detail::parse_int;

// x/y/z fields of one marker: all numbers (converted to m) or all missing.
void read_xyz(const std::string* f, double to_m, const std::string& name, int line,
              const std::string& what, MarkerSample& s) {
  const auto x = parse_double(f[0], name, line, what + " x", true);
  const auto y = parse_double(f[1], name, line, what + " y", true);
  const auto z = parse_double(f[2], name, line, what + " z", true);
  const int seen = static_cast<int>(x.has_value()) + static_cast<int>(y.has_value()) +
                   static_cast<int>(z.has_value());
  if (seen != 0 && seen != 3) {
    throw ConfigError(name, line,
                      what + ": x, y, z must all be numbers or all empty/nan (marker missing)");
  }
  s.present = seen == 3;
  if (s.present) {
    s.x = *x * to_m;
    s.y = *y * to_m;
    s.z = *z * to_m;
  }
}

// --- the project's long CSV ---------------------------------------------------

const std::vector<std::string> kMarkerRequired = {"utime_us", "x_mm", "y_mm", "z_mm"};
const std::vector<std::string> kMarkerOptional = {"marker_id"};

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
  int first() const { return first_; }

 private:
  int first_ = -1;
  int first_line_ = 0;
};

// Time must increase from sample to sample of each marker.
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

MarkerSeries read_long_csv(LineReader& in, const std::vector<std::string>& head,
                           const MarkerSelection& sel) {
  const std::string& name = in.name();
  const auto cols = detail::csv_header(head, in.line(), name, kMarkerRequired, kMarkerOptional);
  const bool has_id = cols.count("marker_id") > 0;
  if (sel.many && !has_id) {
    throw ConfigError(name, in.line(), "several markers need the 'marker_id' column");
  }
  MarkerSeries out;
  out.source = name;
  out.info.format = MarkerFormat::kLongCsv;
  detail::MarkerStore store;
  SingleIdCheck single;
  TimeOrderCheck order;
  std::string line;
  std::vector<std::string> f;
  while (detail::next_row(in, line, f)) {
    const int n = in.line();
    if (f.size() != head.size()) detail::wrong_field_count(name, n, head.size(), f.size());
    MarkerSample s;
    s.utime_us = parse_int(f[cols.at("utime_us")], name, n, "utime_us");
    if (has_id) {
      s.marker_id = static_cast<int>(parse_int(f[cols.at("marker_id")], name, n, "marker_id"));
      if (!sel.many && sel.single < 0) single.check(s.marker_id, n, name);
      if (!sel.keeps(s.marker_id)) {
        ++out.other_ids;
        continue;
      }
    }
    const std::string xyz[3] = {f[cols.at("x_mm")], f[cols.at("y_mm")], f[cols.at("z_mm")]};
    const auto x = parse_double(xyz[0], name, n, "x_mm", true);
    const auto y = parse_double(xyz[1], name, n, "y_mm", true);
    const auto z = parse_double(xyz[2], name, n, "z_mm", true);
    const int seen = static_cast<int>(x.has_value()) + static_cast<int>(y.has_value()) +
                     static_cast<int>(z.has_value());
    if (seen != 0 && seen != 3) {
      throw ConfigError(name, n,
                        "x_mm, y_mm, z_mm must all be numbers or all empty/nan (marker missing)");
    }
    s.present = seen == 3;
    if (s.present) {
      s.x = *x * 1e-3;
      s.y = *y * 1e-3;
      s.z = *z * 1e-3;
    }
    order.check(s, n, name);
    store.push(s);
  }
  if (sel.many) {
    std::string missing;
    for (int id : sel.ids) {
      if (!order.has(id)) missing += (missing.empty() ? "" : ", ") + std::to_string(id);
    }
    if (!missing.empty()) throw ConfigError(name, 0, "no samples of marker_id " + missing);
  }
  out.thinned = store.thinned();
  out.samples = store.take();
  if (out.samples.empty()) {
    throw ConfigError(name, 0,
                      sel.single >= 0 ? "no samples of marker_id " + std::to_string(sel.single)
                                      : std::string("no marker samples"));
  }
  out.ids = sel.many ? sel.ids : std::vector<int>{sel.single >= 0 ? sel.single : single.first()};
  return out;
}

MarkerSelection long_csv_selection(const std::vector<MarkerRef>& wanted, const std::string& name) {
  MarkerSelection sel;
  for (const MarkerRef& r : wanted) {
    if (r.id < 0) {
      throw ConfigError(name, 0,
                        "marker '" + r.label +
                            "': the long CSV names its markers by marker_id, not by label "
                            "(give the marker's id)");
    }
  }
  if (wanted.size() == 1) {
    sel.single = wanted[0].id;
  } else if (wanted.size() > 1) {
    sel.many = true;
    for (const MarkerRef& r : wanted) sel.ids.push_back(r.id);
  }
  return sel;
}

// --- shared by the labelled text formats ----------------------------------------

// A marker's three columns in a wide (one row per frame) export.
struct WideMarker {
  std::string label;
  std::size_t column = 0;  // of its X; Y and Z follow
  double to_m = 1e-3;
};

double length_unit(const std::string& unit, const std::string& name, int line) {
  std::string u = unit;
  std::transform(u.begin(), u.end(), u.begin(), [](unsigned char c) { return std::tolower(c); });
  if (u == "mm" || u == "millimeters" || u == "millimetres") return 1e-3;
  if (u == "cm" || u == "centimeters" || u == "centimetres") return 1e-2;
  if (u == "m" || u == "meters" || u == "metres") return 1.0;
  throw ConfigError(name, line, "unknown length unit '" + unit + "' (mm, cm or m)");
}

// The selected markers of each data row of a wide export.
class WideRows {
 public:
  WideRows(const std::vector<WideMarker>& markers, const std::vector<int>& ids, std::size_t width)
      : markers_(markers), ids_(ids), width_(width) {}

  // fields: one data row; t_us its time. Rows may stop early (missing
  // trailing markers), not run past the header.
  void add(std::vector<std::string>& f, std::int64_t t_us, const std::string& name, int line) {
    if (f.size() > width_) detail::wrong_field_count(name, line, width_, f.size());
    f.resize(width_);
    for (int id : ids_) {
      const WideMarker& m = markers_[static_cast<std::size_t>(id - 1)];
      MarkerSample s;
      s.utime_us = t_us;
      s.marker_id = id;
      read_xyz(&f[m.column], m.to_m, name, line, m.label, s);
      order_.check(s, line, name);
      store_.push(s);
    }
  }
  void finish(MarkerSeries& out, const std::string& name) {
    out.thinned = store_.thinned();
    out.samples = store_.take();
    if (out.samples.empty()) throw ConfigError(name, 0, "no frames");
  }

 private:
  const std::vector<WideMarker>& markers_;
  const std::vector<int>& ids_;
  std::size_t width_;
  detail::MarkerStore store_;
  TimeOrderCheck order_;
};

std::vector<std::string> labels_of(const std::vector<WideMarker>& markers) {
  std::vector<std::string> out;
  for (const auto& m : markers) out.push_back(m.label);
  return out;
}

std::int64_t seconds_to_us(double t) {
  return static_cast<std::int64_t>(std::llround(t * 1e6));
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

// --- Vicon Nexus CSV --------------------------------------------------------------
//   Trajectories
//   100                                  frame rate (Hz)
//   ,,Subject:LASI,,,Subject:RASI,,,     one label per marker, over its X column
//   Frame,Sub Frame,X,Y,Z,X,Y,Z          column roles
//   ,,mm,mm,mm,mm,mm,mm                  units
//   1,0,123.4,234.5,345.6,,,             data; empty: not seen
// Other sections (Devices, Model Outputs, ...) are skipped; a blank line ends one.

const std::set<std::string> kViconSections = {"Devices", "Trajectories", "Model Outputs",
                                              "Segments", "Joints"};

bool vicon_section(const std::vector<std::string>& f) {
  return !f.empty() && kViconSections.count(f[0]) &&
         std::all_of(f.begin() + 1, f.end(), [](const std::string& s) { return s.empty(); });
}

// Reads one header line of the Trajectories section (a blank line or the end is an error).
std::vector<std::string> vicon_line(LineReader& in, const char* what) {
  std::string line;
  if (!in.next(line) || detail::trim(line).empty()) {
    throw ConfigError(in.name(), in.line(),
                      std::string("Trajectories section ends before its ") + what + " line");
  }
  return detail::split_fields(line);
}

std::vector<WideMarker> vicon_markers(LineReader& in, const std::string& name) {
  const auto labels = vicon_line(in, "marker names");
  const int label_line = in.line();
  const auto roles = vicon_line(in, "column names (Frame,Sub Frame,X,Y,Z,...)");
  const int role_line = in.line();
  const auto units = vicon_line(in, "units");
  if (roles.size() < 2 || lower(roles[0]) != "frame") {
    throw ConfigError(name, role_line, "expected 'Frame,Sub Frame,X,Y,Z,...'");
  }
  std::vector<WideMarker> out;
  for (std::size_t c = 2; c < labels.size(); ++c) {
    if (labels[c].empty()) continue;
    const bool xyz =
        c + 2 < roles.size() && roles[c] == "X" && roles[c + 1] == "Y" && roles[c + 2] == "Z";
    if (!xyz) {
      throw ConfigError(name, role_line,
                        "marker '" + labels[c] + "' (line " + std::to_string(label_line) +
                            ") does not have X, Y, Z columns");
    }
    WideMarker m{labels[c], c, 1e-3};
    if (c < units.size() && !units[c].empty()) m.to_m = length_unit(units[c], name, in.line());
    out.push_back(m);
  }
  if (out.empty()) throw ConfigError(name, label_line, "no marker in the Trajectories section");
  return out;
}

bool is_trajectories(const std::vector<std::string>& f) {
  return vicon_section(f) && f[0] == "Trajectories";
}

// `first`: the file's first line, a section name.
MarkerSeries read_vicon(LineReader& in, const std::vector<std::string>& first,
                        const std::vector<MarkerRef>& wanted) {
  const std::string& name = in.name();
  std::string line;
  bool found = is_trajectories(first);
  while (!found && in.next(line)) found = is_trajectories(detail::split_fields(line));
  if (!found) {
    throw ConfigError(name, 0,
                      "a Vicon Nexus export without a Trajectories section (export the "
                      "trajectories)");
  }
  const auto rate_f = vicon_line(in, "frame rate");
  const double rate = *parse_double(rate_f[0], name, in.line(), "frame rate", false);
  if (!(rate > 0)) throw ConfigError(name, in.line(), "frame rate must be > 0");
  const std::vector<WideMarker> markers = vicon_markers(in, name);
  MarkerSeries out;
  out.source = name;
  out.info.format = MarkerFormat::kViconCsv;
  out.info.labels = labels_of(markers);
  out.info.rate_hz = rate;
  out.info.epoch_times = false;
  out.ids = detail::resolve_labels(out.info.labels, wanted, name);
  const std::size_t width = markers.back().column + 3;
  WideRows rows(markers, out.ids, width);
  std::vector<std::string> f;
  while (in.next(line)) {
    if (detail::trim(line).empty()) break;  // end of the section
    f = detail::split_fields(line);
    const int n = in.line();
    const std::int64_t frame = parse_int(f[0], name, n, "Frame");
    const double sub = f.size() > 1 && !f[1].empty()
                           ? static_cast<double>(parse_int(f[1], name, n, "Sub Frame"))
                           : 0.0;
    if (sub != 0.0)
      throw ConfigError(name, n, "sub-frames are not trajectories (Sub Frame must be 0)");
    rows.add(f, seconds_to_us(static_cast<double>(frame - 1) / rate), name, n);
  }
  rows.finish(out, name);
  return out;
}

// --- OptiTrack Motive CSV -----------------------------------------------------------
//   Format Version,1.23,Take Name,...,Capture Frame Rate,120,Export Frame Rate,120,
//     Capture Start Time,2024-05-01 02.15.41.228 PM,...,Length Units,Millimeters,...
//   (blank)
//   ,Type,Marker,Marker,Marker,Rigid Body,...,Rigid Body Marker,...
//   ,Name,Hand1,Hand1,Hand1,RB1,...,RB1:Marker1,...
//   ,ID,1,1,1,...
//   ,,Position,Position,Position,Rotation,...,Position,...
//   Frame,Time (Seconds),X,Y,Z,X,Y,Z,W,...
//   0,0.000000,12.3,45.6,78.9,...

std::map<std::string, std::string> motive_settings(const std::vector<std::string>& f) {
  std::map<std::string, std::string> kv;
  for (std::size_t k = 0; k + 1 < f.size(); k += 2) kv[f[k]] = f[k + 1];
  return kv;
}

struct MotiveHeader {
  std::vector<std::string> type, name, kind, axis;
  int axis_line = 0;
};

MotiveHeader motive_rows(LineReader& in) {
  MotiveHeader h;
  std::string line;
  std::vector<std::string> f;
  while (in.next(line)) {
    if (detail::trim(line).empty()) continue;
    f = detail::split_fields(line);
    if (f.size() >= 2 && f[0].empty() && f[1] == "Type") {
      h.type = f;
    } else if (f.size() >= 2 && f[0].empty() && f[1] == "Name") {
      h.name = f;
    } else if (f.size() >= 2 && f[0].empty() && f[1] == "ID") {
      continue;
    } else if (f.size() >= 2 && f[0].empty() && f[1].empty()) {
      h.kind = f;
    } else if (!f.empty() && f[0] == "Frame") {
      h.axis = f;
      h.axis_line = in.line();
      return h;
    } else {
      throw ConfigError(in.name(), in.line(),
                        "unexpected line in the Motive header (expected the Type, Name, ID and "
                        "Frame rows of format version 1.2 or later)");
    }
  }
  throw ConfigError(in.name(), in.line(), "the Motive header ends before its 'Frame,Time' row");
}

std::vector<WideMarker> motive_markers(const MotiveHeader& h, double to_m,
                                       const std::string& name) {
  if (h.type.empty() || h.name.empty() || h.kind.empty()) {
    throw ConfigError(name, h.axis_line, "the Motive header lacks its Type, Name or data-kind row");
  }
  const auto at = [](const std::vector<std::string>& v, std::size_t c) {
    return c < v.size() ? v[c] : std::string();
  };
  std::vector<WideMarker> out;
  for (std::size_t c = 2; c + 2 < h.axis.size(); ++c) {
    const std::string type = at(h.type, c);
    const bool marker = type == "Marker" || type == "Rigid Body Marker" || type == "Bone Marker";
    if (!marker || at(h.kind, c) != "Position" || h.axis[c] != "X") continue;
    if (h.axis[c + 1] != "Y" || h.axis[c + 2] != "Z" || at(h.name, c + 2) != at(h.name, c)) {
      throw ConfigError(name, h.axis_line,
                        "marker '" + at(h.name, c) + "' does not have X, Y, Z position columns");
    }
    out.push_back(WideMarker{at(h.name, c), c, to_m});
    c += 2;
  }
  if (out.empty()) {
    throw ConfigError(name, h.axis_line,
                      "no marker or rigid-body-marker position columns (export markers)");
  }
  return out;
}

MarkerSeries read_motive(LineReader& in, const std::vector<std::string>& first,
                         const std::vector<MarkerRef>& wanted) {
  const std::string& name = in.name();
  auto kv = motive_settings(first);
  MarkerSeries out;
  out.source = name;
  out.info.format = MarkerFormat::kMotiveCsv;
  out.info.epoch_times = false;
  out.info.start_time = kv["Capture Start Time"];
  const std::string rate =
      kv.count("Export Frame Rate") ? kv["Export Frame Rate"] : kv["Capture Frame Rate"];
  if (!rate.empty()) out.info.rate_hz = *parse_double(rate, name, 1, "Export Frame Rate", false);
  double to_m = 1.0;
  if (kv.count("Length Units")) {
    to_m = length_unit(kv["Length Units"], name, 1);
  } else {
    out.info.notes.push_back(name + ": no 'Length Units' in the header: metres assumed");
  }
  const MotiveHeader h = motive_rows(in);
  const std::vector<WideMarker> markers = motive_markers(h, to_m, name);
  out.info.labels = labels_of(markers);
  out.ids = detail::resolve_labels(out.info.labels, wanted, name);
  if (h.axis.size() < 2 || h.axis[1].rfind("Time", 0) != 0) {
    throw ConfigError(name, h.axis_line, "expected 'Frame,Time (Seconds),...'");
  }
  WideRows rows(markers, out.ids, h.axis.size());
  std::string line;
  std::vector<std::string> f;
  while (in.next(line)) {
    if (detail::trim(line).empty()) continue;
    f = detail::split_fields(line);
    const int n = in.line();
    parse_int(f[0], name, n, "Frame");
    const double t = *parse_double(f.size() > 1 ? f[1] : "", name, n, "Time", false);
    rows.add(f, seconds_to_us(t), name, n);
  }
  rows.finish(out, name);
  return out;
}

// --- by content -----------------------------------------------------------------------

enum class TextKind { kLong, kVicon, kMotive };

TextKind text_kind(const std::vector<std::string>& first) {
  if (!first.empty() && first[0] == "Format Version") return TextKind::kMotive;
  if (vicon_section(first)) return TextKind::kVicon;
  return TextKind::kLong;
}

// The first line that is not blank (a UTF-8 byte-order mark dropped), split.
bool first_fields(LineReader& in, std::vector<std::string>& f) {
  std::string line;
  while (in.next(line)) {
    if (in.line() == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
    if (detail::trim(line).empty()) continue;
    f = detail::split_fields(line);
    return true;
  }
  return false;
}

MarkerSeries read_text(LineReader in, const std::vector<MarkerRef>& wanted) {
  std::vector<std::string> first;
  if (!first_fields(in, first)) throw ConfigError(in.name(), 0, "empty file (no header)");
  switch (text_kind(first)) {
    case TextKind::kMotive:
      return read_motive(in, first, wanted);
    case TextKind::kVicon:
      return read_vicon(in, first, wanted);
    case TextKind::kLong:
      break;
  }
  // The long CSV: '#' comments before the header are allowed.
  if (!first.empty() && !first[0].empty() && first[0][0] == '#') {
    std::string line;
    if (!detail::next_row(in, line, first))
      throw ConfigError(in.name(), 0, "empty file (no header)");
  }
  return read_long_csv(in, first, long_csv_selection(wanted, in.name()));
}

}  // namespace

namespace {

// The first bytes of a file (up to 512), after the input checks.
std::string first_bytes(const std::string& path) {
  int fd = -1;
  try {
    fd = files::open_input(path, files::kMaxCsvBytes);
  } catch (const files::FileError& e) {
    throw ConfigError(path, 0, e.reason());
  }
  std::string head(512, '\0');
  std::size_t got = 0;
  while (got < head.size()) {
    const ssize_t n = ::read(fd, head.data() + got, head.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
  head.resize(got);
  return head;
}

bool is_c3d(const std::string& head) {
  return detail::looks_like_c3d(reinterpret_cast<const unsigned char*>(head.data()), head.size());
}

std::vector<MarkerRef> id_refs(const std::vector<int>& ids) {
  std::vector<MarkerRef> refs;
  for (int id : ids) refs.push_back(MarkerRef{id, ""});
  return refs;
}

// The long CSV with several ids, as the layouts read it (the marker_id column required).
MarkerSeries long_csv_ids(LineReader in, const std::vector<int>& ids) {
  std::vector<std::string> head;
  std::string line;
  if (!detail::next_row(in, line, head)) throw ConfigError(in.name(), 0, "empty file (no header)");
  MarkerSelection sel;
  sel.many = true;
  sel.ids = ids;
  return read_long_csv(in, head, sel);
}

}  // namespace

MarkerSeries read_markers(const std::string& path, const std::vector<MarkerRef>& wanted) {
  if (is_c3d(first_bytes(path))) return detail::read_c3d(path, wanted);
  return read_text(LineReader::open_file(path), wanted);
}

MarkerSeries parse_markers(const std::string& text, const std::string& name,
                           const std::vector<MarkerRef>& wanted) {
  if (is_c3d(text.substr(0, 512))) {
    throw ConfigError(name, 0, "a C3D file: read it from a file (read_markers)");
  }
  return read_text(LineReader::from_text(text, name), wanted);
}

MarkerSeries read_marker_csv(const std::string& path, int marker_id) {
  return read_markers(path, marker_id >= 0 ? id_refs({marker_id}) : std::vector<MarkerRef>{});
}

MarkerSeries parse_marker_csv(const std::string& text, const std::string& name, int marker_id) {
  return parse_markers(text, name,
                       marker_id >= 0 ? id_refs({marker_id}) : std::vector<MarkerRef>{});
}

MarkerSeries read_marker_csv_ids(const std::string& path, const std::vector<int>& ids) {
  if (is_c3d(first_bytes(path))) return detail::read_c3d(path, id_refs(ids));
  LineReader in = LineReader::open_file(path);
  std::vector<std::string> first;
  {
    LineReader probe = LineReader::open_file(path);
    if (first_fields(probe, first) && text_kind(first) != TextKind::kLong) {
      return read_text(std::move(in), id_refs(ids));
    }
  }
  return long_csv_ids(std::move(in), ids);
}

MarkerSeries parse_marker_csv_ids(const std::string& text, const std::string& name,
                                  const std::vector<int>& ids) {
  return long_csv_ids(LineReader::from_text(text, name), ids);
}

}  // namespace exodaq::calibration
