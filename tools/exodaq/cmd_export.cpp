// exodaq export: an LCM log (lcm-logger or exodaq replay) to CSV, one row per
// cycle: the joint_state_t of that seq joined with its palm_pose_t.
//   exodaq export LOG --csv OUT [--prefix P]
// Values are exact: integers in decimal, doubles in the shortest text that
// reads back to the same double. The daemon's all-zero start-up messages are
// left out. A cycle whose palm_pose_t is missing from the log keeps empty
// palm columns. See docs/replay.md for the columns.
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "command.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/fields.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "export_csv.hpp"

namespace exodaq::tools {

namespace {

constexpr std::int64_t kJoinWindow = 4096;  // cycles a row waits for its other half

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
  const auto dbl = [](double v) { return msg::format_double(v); };
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
  return msg::csv_line(v);
}

}  // namespace

CsvExport export_log_csv(const std::string& log_path, const std::optional<std::string>& given,
                         const std::string& csv_path) {
  CsvExport result;
  std::vector<std::string>* joint_names = &result.joint_names;
  // Which prefix: the one given, or the only one the log has.
  std::string prefix = given.value_or("");
  if (!given) {
    std::set<std::string> prefixes;
    for (const auto& [channel, count] : msg::scan_channels(log_path)) {
      const auto parts = msg::split_channel(channel);
      if (parts && parts->kind == msg::Kind::kJointState) prefixes.insert(parts->prefix);
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
  const std::string joint_channel = msg::channel_name(prefix, msg::Kind::kJointState);
  const std::string palm_channel = msg::channel_name(prefix, msg::Kind::kPalmPose);

  std::ofstream out(csv_path, std::ios::binary);
  if (!out) throw std::runtime_error("cannot create '" + csv_path + "'");
  out << msg::csv_line(header()) << "\n";

  std::int64_t& rows = result.rows;
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
  msg::LogReader log(log_path);
  msg::LogEvent ev;
  joint_state_t js;
  palm_pose_t pp;
  while (log.next(ev)) {
    const std::string_view ch = ev.channel;
    std::int64_t seq = 0;
    std::int64_t rid = 0;
    const bool is_joint = ch == joint_channel;
    if (is_joint) {
      if (!msg::decode_into(js, ev.data, ev.size) || js.utime == 0) continue;
      seq = js.seq;
      rid = js.run_id;
      if (joint_names->empty()) {
        for (int i = 0; i < 6; ++i) joint_names->push_back(js.name[i]);
      }
    } else if (ch == palm_channel) {
      if (!msg::decode_into(pp, ev.data, ev.size) || pp.utime == 0) continue;
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
  result.damage = log.damage_text();
  return result;
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
    const CsvExport r = export_log_csv(
        o->log, prefix->count() > 0 ? std::optional(o->prefix) : std::nullopt, o->csv);
    std::printf("exodaq export: %lld rows -> %s\n", static_cast<long long>(r.rows), o->csv.c_str());
    if (!r.damage.empty()) {
      std::fprintf(stderr, "exodaq export: %s\n", r.damage.c_str());
      return kExitFailure;
    }
    return r.rows > 0 ? kExitOk : kExitFailure;
  };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(export, "export",
                        "an LCM log to CSV, one row per cycle (joint angles, velocities, flags, "
                        "palm pose, manipulability, validity)",
                        exodaq::tools::setup_export);
