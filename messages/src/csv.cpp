#include "exodaq/messages/csv.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <set>
#include <type_traits>
#include <variant>

namespace exodaq::messages::csv {

namespace {

std::string num(std::int64_t v) {
  return std::to_string(v);
}

void add_stamp(std::vector<std::string>& h) {
  for (const char* c : {"utime_us", "mono_ns", "seq", "run_id"}) h.emplace_back(c);
}

template <typename T>
void append_stamp(const T& m, std::vector<std::string>& out) {
  out.push_back(num(m.utime));
  out.push_back(num(m.mono_ns));
  out.push_back(num(m.seq));
  out.push_back(run_id_text(m.run_id));
}

void per_joint(std::vector<std::string>& h, const JointNames& joints, std::string_view suffix) {
  for (const auto& j : joints) h.push_back(j + std::string(suffix));
}

template <typename T, std::size_t N, typename F>
void each(const T (&a)[N], std::vector<std::string>& out, F f) {
  for (std::size_t i = 0; i < N; ++i) out.push_back(f(a[i]));
}

const auto kNum = [](auto v) { return num(v); };
const auto kDbl = [](double v) { return number(v); };
const auto kBool = [](std::int8_t v) { return std::string(v ? "1" : "0"); };

// The columns of each message type after the header: header() names them (with
// `joints`, the per-joint columns' names), values() fills them in the same
// order; kTextColumns, where present, names those holding text. One
// specialisation per type of the list (message_list.def): a type without one
// does not compile.
template <typename T>
struct Columns;

template <>
struct Columns<joint_state_t> {
  static void header(std::vector<std::string>& h, const JointNames& j) {
    per_joint(h, j, kPositionSuffix);
    per_joint(h, j, kVelocitySuffix);
    per_joint(h, j, kCountSuffix);
    per_joint(h, j, kHomedSuffix);
    per_joint(h, j, kFlagsSuffix);
    h.emplace_back("sample_flags");
  }

  static void values(const joint_state_t& m, std::vector<std::string>& out) {
    each(m.position, out, kDbl);
    each(m.velocity, out, kDbl);
    each(m.raw_count, out, kNum);
    each(m.homed, out, kBool);
    each(m.flags, out, kNum);
    out.push_back(num(m.sample_flags));
  }
};

// palm_pose_t
constexpr const char* kPalmColumns[] = {"palm_x_m",      "palm_y_m",       "palm_z_m",
                                        "palm_qw",       "palm_qx",        "palm_qy",
                                        "palm_qz",       "elbow_x_m",      "elbow_y_m",
                                        "elbow_z_m",     "manipulability", "manipulability_raw",
                                        "near_singular", "palm_valid",     "palm_invalid_reason"};
constexpr std::size_t kPalmCount = sizeof kPalmColumns / sizeof kPalmColumns[0];

template <>
struct Columns<palm_pose_t> {
  static void header(std::vector<std::string>& h, const JointNames&) {
    h.insert(h.end(), std::begin(kPalmColumns), std::end(kPalmColumns));
  }

  static void values(const palm_pose_t& m, std::vector<std::string>& out) {
    each(m.position, out, kDbl);
    each(m.orientation, out, kDbl);
    each(m.elbow, out, kDbl);
    out.push_back(number(m.shoulder_manipulability));
    out.push_back(number(m.shoulder_manipulability_raw));
    out.push_back(kBool(m.near_singular));
    out.push_back(kBool(m.valid));
    out.push_back(num(m.invalid_reason));
  }
};

// encoder_raw_t: arrays by source channel.
template <>
struct Columns<encoder_raw_t> {
  static void header(std::vector<std::string>& h, const JointNames&) {
    for (const char* c : {"present", "source_seq", "source_seq_modulus"}) h.emplace_back(c);
    for (const char* f : {"position_ch", "modulus_ch", "index_position_ch"}) {
      for (int c = 0; c < kJoints; ++c) h.push_back(f + std::to_string(c));
    }
    for (const char* c : {"index_latched", "index_count_valid", "absolute", "channel_fresh",
                          "board_state", "board_errors", "source_flags", "wall_ns"}) {
      h.emplace_back(c);
    }
  }

  static void values(const encoder_raw_t& m, std::vector<std::string>& out) {
    out.push_back(kBool(m.present));
    out.push_back(num(m.source_seq));
    out.push_back(num(m.source_seq_modulus));
    each(m.position, out, kNum);
    each(m.modulus, out, kNum);
    each(m.index_position, out, kNum);
    for (const std::int64_t v :
         {std::int64_t{m.index_latched}, std::int64_t{m.index_count_valid},
          std::int64_t{m.absolute}, std::int64_t{m.channel_fresh}, std::int64_t{m.board_state},
          std::int64_t{m.board_errors}, std::int64_t{m.source_flags}, m.wall_ns}) {
      out.push_back(num(v));
    }
  }
};

// homing_t: arrays by joint (numbered: the record carries no names).
template <>
struct Columns<homing_t> {
  static void header(std::vector<std::string>& h, const JointNames&) {
    h.emplace_back("changed");
    for (const char* f : {"counted_j", "count_j", "powerup_count_j", "homing_j", "index_count_j",
                          "index_turns_j", "index_angle_rad_j"}) {
      for (int c = 0; c < kJoints; ++c) h.push_back(f + std::to_string(c + 1));
    }
  }

  static void values(const homing_t& m, std::vector<std::string>& out) {
    out.push_back(num(m.changed));
    each(m.counted, out, kBool);
    each(m.count, out, kNum);
    each(m.powerup_count, out, kNum);
    each(m.homing, out, kNum);
    each(m.index_count, out, kNum);
    each(m.index_turns, out, kNum);
    each(m.index_angle, out, kDbl);
  }
};

// status_t
constexpr const char* kStatusTimingColumns[] = {
    "period_p50_us",   "period_p99_us", "period_max_us", "lateness_p50_us", "lateness_p99_us",
    "lateness_max_us", "work_p50_us",   "work_p99_us",   "work_max_us"};
constexpr const char* kStatusCounterColumns[] = {"overruns",
                                                 "cycles",
                                                 "publish_failures",
                                                 "source",
                                                 "frames",
                                                 "bad_frames",
                                                 "missing_samples",
                                                 "seq_gaps",
                                                 "duplicates",
                                                 "out_of_order",
                                                 "bus_errors",
                                                 "rx_overflows",
                                                 "bus_state",
                                                 "board_errors",
                                                 "clock_synchronised",
                                                 "clock_est_error_us",
                                                 "clock_max_error_us",
                                                 "clock_offset_us",
                                                 "utime_correction_us",
                                                 "clock_steps",
                                                 "config_path",
                                                 "config_sha256",
                                                 "calibration_path",
                                                 "calibration_sha256",
                                                 "calibration_provenance",
                                                 "reloads",
                                                 "foreign_run_id"};
constexpr const char* kStatusJointSuffixes[] = {"_homing",       "_flags",
                                                "_glitches",     "_lost_count_events",
                                                "_stale_events", "_out_of_range_events"};

template <>
struct Columns<status_t> {
  // The columns values() fills with text.
  static constexpr const char* kTextColumns[] = {"rig",
                                                 "message",
                                                 "source",
                                                 "config_path",
                                                 "config_sha256",
                                                 "calibration_path",
                                                 "calibration_sha256",
                                                 "calibration_provenance",
                                                 "foreign_run_id"};

  static void header(std::vector<std::string>& h, const JointNames& j) {
    for (const char* c : {"rig", "state", "message", "window_cycles"}) h.emplace_back(c);
    for (const char* c : kStatusTimingColumns) h.emplace_back(c);
    for (const char* c : kStatusCounterColumns) h.emplace_back(c);
    for (const char* s : kStatusJointSuffixes) per_joint(h, j, s);
  }

  static void values(const status_t& m, std::vector<std::string>& out) {
    out.push_back(m.rig);
    out.push_back(num(m.state));
    out.push_back(m.message);
    out.push_back(num(m.window_cycles));
    for (const double v :
         {m.period_p50_us, m.period_p99_us, m.period_max_us, m.lateness_p50_us, m.lateness_p99_us,
          m.lateness_max_us, m.work_p50_us, m.work_p99_us, m.work_max_us}) {
      out.push_back(number(v));
    }
    for (const std::int64_t v : {m.overruns, m.cycles, m.publish_failures}) out.push_back(num(v));
    out.push_back(m.source);
    for (const std::int64_t v : {m.frames, m.bad_frames, m.missing_samples, m.seq_gaps,
                                 m.duplicates, m.out_of_order, m.bus_errors, m.rx_overflows}) {
      out.push_back(num(v));
    }
    out.push_back(num(m.bus_state));
    out.push_back(num(m.board_errors));
    out.push_back(kBool(m.clock_synchronised));
    for (const double v :
         {m.clock_est_error_us, m.clock_max_error_us, m.clock_offset_us, m.utime_correction_us}) {
      out.push_back(number(v));
    }
    out.push_back(num(m.clock_steps));
    for (const std::string* v : {&m.config_path, &m.config_sha256, &m.calibration_path,
                                 &m.calibration_sha256, &m.calibration_provenance}) {
      out.push_back(*v);
    }
    out.push_back(num(m.reloads));
    out.push_back(run_id_text(m.foreign_run_id));
    each(m.homing, out, kNum);
    each(m.joint_flags, out, kNum);
    each(m.glitches, out, kNum);
    each(m.lost_count_events, out, kNum);
    each(m.stale_events, out, kNum);
    each(m.out_of_range_events, out, kNum);
  }
};

// The backend's counters in one text column, "name=value" separated by
// spaces in the message's order (their set is the backend's, not fixed).
template <>
struct Columns<source_status_t> {
  static constexpr const char* kTextColumns[] = {"source", "state", "counters"};

  static void header(std::vector<std::string>& h, const JointNames&) {
    for (const char* c : kTextColumns) h.emplace_back(c);
  }

  static void values(const source_status_t& m, std::vector<std::string>& out) {
    out.push_back(m.source);
    out.push_back(m.state);
    std::string counters;
    for (std::size_t i = 0; i < counters_in(m); ++i) {
      if (i > 0) counters += ' ';
      counters += m.counter_name[i] + '=' + num(m.counter_value[i]);
    }
    out.push_back(std::move(counters));
  }
};

template <typename T>
bool is_text(std::string_view column) {
  if constexpr (requires { Columns<T>::kTextColumns; }) {
    for (const char* c : Columns<T>::kTextColumns) {
      if (column == c) return true;
    }
  }
  return false;
}

}  // namespace

JointNames joint_columns(const std::string (&names)[kJoints]) {
  JointNames out;
  std::set<std::string> seen;
  for (int i = 0; i < kJoints; ++i) {
    std::string c = names[i];
    for (char& ch : c) {
      if (!std::isalnum(static_cast<unsigned char>(ch)) && ch != '_') ch = '_';
    }
    if (c.empty() || !seen.insert(c).second) c = "joint" + std::to_string(i + 1);
    out[static_cast<std::size_t>(i)] = c;
  }
  return out;
}

JointNames numbered_joints() {
  JointNames out;
  for (int i = 0; i < kJoints; ++i)
    out[static_cast<std::size_t>(i)] = "joint" + std::to_string(i + 1);
  return out;
}

std::vector<std::string> header(Kind k, const JointNames& joints) {
  std::vector<std::string> h;
  add_stamp(h);
  switch (k) {
#define EXODAQ_MESSAGE(kind, type, channel, per_cycle, aliases) \
  case Kind::kind:                                              \
    Columns<type>::header(h, joints);                           \
    break;
#include "exodaq/messages/message_list.def"
#undef EXODAQ_MESSAGE
  }
  return h;
}

JointNames joints_of(const Message& m) {
  if (const auto* j = std::get_if<joint_state_t>(&m)) return joint_columns(j->name);
  if (const auto* s = std::get_if<status_t>(&m)) return joint_columns(s->joint_name);
  return numbered_joints();
}

void append_values(const Message& m, std::vector<std::string>& out) {
  std::visit(
      [&out](const auto& v) {
        append_stamp(v, out);
        Columns<std::decay_t<decltype(v)>>::values(v, out);
      },
      m);
}

bool is_text_column(Kind k, std::string_view column) {
  if (column == "run_id") return true;
  switch (k) {
#define EXODAQ_MESSAGE(kind, type, channel, per_cycle, aliases) \
  case Kind::kind:                                              \
    return is_text<type>(column);
#include "exodaq/messages/message_list.def"
#undef EXODAQ_MESSAGE
  }
  return false;
}

std::vector<std::string> cycle_header(const JointNames& joints) {
  std::vector<std::string> h = header(Kind::kJointState, joints);
  h.insert(h.end(), std::begin(kPalmColumns), std::end(kPalmColumns));
  return h;
}

void append_cycle(const joint_state_t& joints, const palm_pose_t* palm,
                  std::vector<std::string>& out) {
  append_stamp(joints, out);
  Columns<joint_state_t>::values(joints, out);
  if (palm != nullptr) {
    Columns<palm_pose_t>::values(*palm, out);
  } else {
    out.resize(out.size() + kPalmCount);
  }
}

std::string number(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  if (v == 0.0) return "0";  // and -0
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

std::string escape(std::string_view v) {
  if (v.find_first_of(",\"\r\n") == std::string_view::npos) return std::string(v);
  std::string out = "\"";
  for (char c : v) {
    if (c == '"') out += '"';
    out += c;
  }
  out += '"';
  return out;
}

std::string line(const std::vector<std::string>& values) {
  std::string out;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i) out += ',';
    out += escape(values[i]);
  }
  return out;
}

namespace {
std::string_view trimmed(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string_view::npos) return {};
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}
}  // namespace

bool split(std::string_view text, std::vector<std::string>& out, Spaces spaces) {
  const bool trim = spaces == Spaces::kTrim;
  out.clear();
  std::string field;
  bool quoted = false, was_quoted = false;
  auto finish = [&] {
    out.push_back(trim && !was_quoted ? std::string(trimmed(field)) : std::move(field));
    field.clear();
    was_quoted = false;
  };
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quoted) {
      if (c == '"' && i + 1 < text.size() && text[i + 1] == '"') {
        field += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        field += c;
      }
    } else if (c == '"' && (!trim || trimmed(field).empty())) {
      quoted = was_quoted = true;
      if (trim) field.clear();
    } else if (c == ',') {
      finish();
    } else {
      field += c;
    }
  }
  finish();
  return !quoted;
}

}  // namespace exodaq::messages::csv
