// exodaq export: an LCM log (lcm-logger or exodaq replay) to CSV, one row per
// cycle: the joint_state_t of that seq joined with its palm_pose_t.
//   exodaq export LOG --csv OUT [--prefix P]
// Values are exact: integers in decimal, doubles in the shortest text that
// reads back to the same double. The daemon's all-zero start-up messages are
// left out. A cycle whose palm_pose_t is missing from the log keeps empty
// palm columns. See docs/replay.md for the columns.
#include <lcm/lcm.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "command.hpp"
#include "subscriber.hpp"

namespace exodaq::tools {

namespace {

constexpr std::string_view kJointBase = "EXO_JOINT_STATE";
constexpr std::string_view kPalmBase = "EXO_PALM_POSE";
constexpr std::int64_t kJoinWindow = 4096;  // cycles a row waits for its other half

bool ends_with(std::string_view s, std::string_view suffix) {
  return s.size() >= suffix.size() && s.substr(s.size() - suffix.size()) == suffix;
}

struct EventLog {
  explicit EventLog(const std::string& path) : log(lcm_eventlog_create(path.c_str(), "r")) {
    if (log == nullptr) throw std::runtime_error("cannot open LCM log '" + path + "'");
  }
  ~EventLog() { lcm_eventlog_destroy(log); }
  EventLog(const EventLog&) = delete;
  EventLog& operator=(const EventLog&) = delete;
  lcm_eventlog_t* log;
};
struct EventDeleter {
  void operator()(lcm_eventlog_event_t* e) const noexcept { lcm_eventlog_free_event(e); }
};
using EventPtr = std::unique_ptr<lcm_eventlog_event_t, EventDeleter>;

std::vector<std::string> header() {
  std::vector<std::string> h{"seq", "utime", "mono_ns", "run_id"};
  for (const char* f : {"position", "velocity", "homed", "flags", "raw_count"}) {
    for (int i = 0; i < 6; ++i) h.push_back(std::string(f) + "_" + std::to_string(i));
  }
  for (const char* f : {"sample_flags", "palm_x", "palm_y", "palm_z", "quat_w", "quat_x", "quat_y",
                        "quat_z", "elbow_x", "elbow_y", "elbow_z", "manipulability",
                        "manipulability_raw", "near_singular", "valid", "invalid_reason"}) {
    h.emplace_back(f);
  }
  return h;
}

struct Row {
  bool have_joint = false;
  bool have_palm = false;
  joint_state_t joint;
  palm_pose_t palm;
};

std::string row_text(const Row& r) {
  const auto& j = r.joint;
  const auto num = [](auto v) { return std::to_string(v); };
  const auto dbl = [](double v) { return sub::format_double(v); };
  std::vector<std::string> v{num(j.seq), num(j.utime), num(j.mono_ns), num(j.run_id)};
  for (int i = 0; i < 6; ++i) v.push_back(dbl(j.position[i]));
  for (int i = 0; i < 6; ++i) v.push_back(dbl(j.velocity[i]));
  for (int i = 0; i < 6; ++i) v.push_back(j.homed[i] ? "1" : "0");
  for (int i = 0; i < 6; ++i) v.push_back(num(j.flags[i]));
  for (int i = 0; i < 6; ++i) v.push_back(num(j.raw_count[i]));
  v.push_back(num(j.sample_flags));
  if (r.have_palm) {
    const auto& p = r.palm;
    for (int k = 0; k < 3; ++k) v.push_back(dbl(p.position[k]));
    for (int k = 0; k < 4; ++k) v.push_back(dbl(p.orientation[k]));
    for (int k = 0; k < 3; ++k) v.push_back(dbl(p.elbow[k]));
    v.push_back(dbl(p.shoulder_manipulability));
    v.push_back(dbl(p.shoulder_manipulability_raw));
    v.push_back(p.near_singular ? "1" : "0");
    v.push_back(p.valid ? "1" : "0");
    v.push_back(num(p.invalid_reason));
  } else {
    for (int k = 0; k < 15; ++k) v.emplace_back();
  }
  return sub::csv_line(v);
}

}  // namespace

// Shared with `exodaq plot`. Returns the number of rows written; fills
// joint_names from the first joint_state_t. Throws std::runtime_error.
std::int64_t export_log_csv(const std::string& log_path, const std::string& prefix_option,
                            bool prefix_given, const std::string& csv_path,
                            std::vector<std::string>* joint_names) {
  // Which prefix: the one given, or the only one the log has.
  std::string prefix = prefix_option;
  if (!prefix_given) {
    std::set<std::string> prefixes;
    EventLog log(log_path);
    while (EventPtr ev{lcm_eventlog_read_next_event(log.log)}) {
      const std::string_view ch(ev->channel, static_cast<std::size_t>(ev->channellen));
      if (ends_with(ch, kJointBase)) {
        prefixes.insert(std::string(ch.substr(0, ch.size() - kJointBase.size())));
      }
    }
    if (prefixes.empty()) {
      throw std::runtime_error("'" + log_path + "' has no *EXO_JOINT_STATE channel");
    }
    if (prefixes.size() > 1) {
      std::string list;
      for (const auto& p : prefixes) list += (list.empty() ? "'" : ", '") + p + "'";
      throw std::runtime_error("'" + log_path + "' holds several rigs (prefixes " + list +
                               "); choose one with --prefix");
    }
    prefix = *prefixes.begin();
  }
  const std::string joint_channel = prefix + std::string(kJointBase);
  const std::string palm_channel = prefix + std::string(kPalmBase);

  std::ofstream out(csv_path, std::ios::binary);
  if (!out) throw std::runtime_error("cannot create '" + csv_path + "'");
  out << sub::csv_line(header()) << "\n";

  std::int64_t rows = 0;
  std::int64_t run_id = 0;
  std::map<std::int64_t, Row> pending;  // by seq, this run
  const auto flush_until = [&](std::int64_t seq_limit) {
    while (!pending.empty() && pending.begin()->first < seq_limit) {
      const Row& r = pending.begin()->second;
      if (r.have_joint) {
        out << row_text(r) << "\n";
        ++rows;
      }
      pending.erase(pending.begin());
    }
  };
  EventLog log(log_path);
  joint_state_t js;
  palm_pose_t pp;
  while (EventPtr ev{lcm_eventlog_read_next_event(log.log)}) {
    const std::string_view ch(ev->channel, static_cast<std::size_t>(ev->channellen));
    std::int64_t seq = 0;
    std::int64_t rid = 0;
    const bool is_joint = ch == joint_channel;
    if (is_joint) {
      if (js.decode(ev->data, 0, ev->datalen) < 0 || js.utime == 0) continue;
      seq = js.seq;
      rid = js.run_id;
      if (joint_names != nullptr && joint_names->empty()) {
        for (int i = 0; i < 6; ++i) joint_names->push_back(js.name[i]);
      }
    } else if (ch == palm_channel) {
      if (pp.decode(ev->data, 0, ev->datalen) < 0 || pp.utime == 0) continue;
      seq = pp.seq;
      rid = pp.run_id;
    } else {
      continue;
    }
    if (rid != run_id) {  // a new daemon run: seq restarts
      flush_until(INT64_MAX);
      run_id = rid;
    }
    Row& r = pending[seq];
    if (is_joint) {
      r.joint = js;
      r.have_joint = true;
    } else {
      r.palm = pp;
      r.have_palm = true;
    }
    flush_until(seq - kJoinWindow);
  }
  flush_until(INT64_MAX);
  out.flush();
  if (!out) throw std::runtime_error("error writing '" + csv_path + "'");
  return rows;
}

namespace {

struct ExportOptions {
  std::string log;
  std::string csv;
  std::string prefix;
};

std::function<int()> setup_export(CLI::App& sub) {
  auto o = std::make_shared<ExportOptions>();
  sub.add_option("log", o->log, "LCM log (lcm-logger or exodaq replay)")
      ->required()
      ->check(CLI::ExistingFile);
  sub.add_option("--csv", o->csv, "CSV file to write (one row per cycle)")->required();
  auto* prefix =
      sub.add_option("--prefix", o->prefix, "channel prefix (default: the only one in the log)");
  return [o, prefix] {
    const std::int64_t rows =
        export_log_csv(o->log, o->prefix, prefix->count() > 0, o->csv, nullptr);
    std::printf("exodaq export: %lld rows -> %s\n", static_cast<long long>(rows), o->csv.c_str());
    return rows > 0 ? kExitOk : kExitFailure;
  };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(export, "export",
                        "an LCM log to CSV, one row per cycle (joint angles, velocities, flags, "
                        "palm pose, manipulability, validity)",
                        exodaq::tools::setup_export);
