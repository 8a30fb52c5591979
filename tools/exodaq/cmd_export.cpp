// exodaq export: an LCM log (lcm-logger or exodaq replay) to CSV, one row per
// cycle: the joint_state_t of that seq joined with its palm_pose_t.
//   exodaq export LOG [-o OUT.csv|-] [--prefix P]
// The columns are the CSV schema of docs/messages.md (exodaq/messages/csv.hpp);
// values are exact. The daemon's all-zero start-up messages are left out. A
// cycle whose palm_pose_t is missing from the log keeps empty palm columns.
// The output appears only when the log could be read (a damaged log: what
// could be read, and exit 1 naming the damaged bytes).
#include <cstdio>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "command.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/csv.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "export_csv.hpp"

namespace exodaq::tools {

namespace {

constexpr std::int64_t kJoinWindow = 4096;  // cycles a row waits for its other half

struct Row {
  bool have_joint = false;
  bool have_palm = false;
  joint_state_t joint;
  palm_pose_t palm;
};

// Writes rows in seq order; the header goes out with the first row, named
// after its joints.
class CycleWriter {
 public:
  CycleWriter(files::OutputFile& out, CsvExport& result) : out_(out), r_(result) {}

  void write(const Row& row) {
    if (!row.have_joint) return;
    const msg::csv::JointNames names = msg::csv::joint_columns(row.joint.name);
    if (r_.rows == 0) {
      for (int i = 0; i < msg::csv::kJoints; ++i) r_.joint_names[i] = row.joint.name[i];
      columns_ = names;
      out_.write(msg::csv::line(msg::csv::cycle_header(names)) + "\n");
      r_.first_run = msg::run_id_text(row.joint.run_id);
    } else if (names != columns_ && r_.note.empty()) {
      r_.note = "run " + msg::run_id_text(row.joint.run_id) +
                " names its joints differently; the header names those of run " + r_.first_run;
    }
    if (r_.rows == 0 || row.joint.run_id != run_) ++r_.runs;
    run_ = row.joint.run_id;
    values_.clear();
    msg::csv::append_cycle(row.joint, row.have_palm ? &row.palm : nullptr, values_);
    out_.write(msg::csv::line(values_) + "\n");
    ++r_.rows;
  }

 private:
  files::OutputFile& out_;
  CsvExport& r_;
  msg::csv::JointNames columns_{};
  std::int64_t run_ = 0;
  std::vector<std::string> values_;
};

}  // namespace

std::string choose_prefix(const std::string& log_path, const std::optional<std::string>& given) {
  std::set<std::string> prefixes;
  for (const auto& [channel, count] : msg::scan_channels(log_path)) {
    const auto parts = msg::split_channel(channel);
    if (parts && parts->kind == msg::Kind::kJointState) prefixes.insert(parts->prefix);
  }
  if (given) {
    if (prefixes.count(*given) == 0) {
      throw std::runtime_error(log_path + ": no channel " +
                               msg::channel_name(*given, msg::Kind::kJointState) + " (--prefix '" +
                               *given + "')");
    }
    return *given;
  }
  if (prefixes.empty()) {
    throw std::runtime_error(log_path +
                             ": an LCM log without joint states (no *EXO_JOINT_STATE channel)");
  }
  if (prefixes.size() > 1) {
    std::string list;
    for (const auto& p : prefixes) list += (list.empty() ? "'" : ", '") + p + "'";
    throw std::runtime_error(log_path + ": holds several rigs (prefixes " + list +
                             "); choose one with --prefix");
  }
  return *prefixes.begin();
}

CsvExport export_log_csv(const std::string& log_path, const std::string& prefix,
                         files::OutputFile& out) {
  CsvExport result;
  const std::string joint_channel = msg::channel_name(prefix, msg::Kind::kJointState);
  const std::string palm_channel = msg::channel_name(prefix, msg::Kind::kPalmPose);
  const std::string status_channel = msg::channel_name(prefix, msg::Kind::kStatus);
  CycleWriter writer(out, result);
  std::int64_t run_id = 0;
  std::map<std::int64_t, Row> pending;  // by seq, this run
  const auto flush_until = [&](std::int64_t seq_limit) {
    while (!pending.empty() && pending.begin()->first < seq_limit) {
      writer.write(pending.begin()->second);
      pending.erase(pending.begin());
    }
  };
  msg::LogReader log(log_path);
  msg::LogEvent ev;
  joint_state_t js;
  palm_pose_t pp;
  status_t st;
  while (log.next(ev)) {
    const std::string_view ch = ev.channel;
    if (result.rig.empty() && ch == status_channel && msg::decode_into(st, ev.data, ev.size)) {
      result.rig = st.rig;
    }
    std::int64_t seq = 0;
    std::int64_t rid = 0;
    const bool is_joint = ch == joint_channel;
    if (is_joint) {
      if (!msg::decode_into(js, ev.data, ev.size)) {
        ++result.undecodable;
        continue;
      }
      if (js.utime == 0) continue;
      seq = js.seq;
      rid = js.run_id;
    } else if (ch == palm_channel) {
      if (!msg::decode_into(pp, ev.data, ev.size)) {
        ++result.undecodable;
        continue;
      }
      if (pp.utime == 0) continue;
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
  result.damage = log.damage_text();
  if (result.undecodable > 0) {
    result.damage += (result.damage.empty() ? "" : "\n") + log_path + ": " +
                     std::to_string(result.undecodable) + " events on " + joint_channel + " or " +
                     palm_channel + " do not decode (damaged); their cycles are not exported";
  }
  return result;
}

namespace {

struct ExportOptions {
  std::string log;
  std::string out = "-";
  std::string prefix;
};

int run_export(const ExportOptions& o, bool prefix_given) {
  files::OutputOptions oo;
  oo.allow_stdout = true;
  oo.inputs = {o.log};
  files::check_output(o.out, oo);
  const std::string prefix =
      choose_prefix(o.log, prefix_given ? std::optional(o.prefix) : std::nullopt);
  if (common_options().verbose) {
    print_error("reading " + msg::channel_name(prefix, msg::Kind::kJointState) + " and " +
                msg::channel_name(prefix, msg::Kind::kPalmPose) + " of " + o.log);
  }
  files::OutputFile out(o.out, oo);
  const CsvExport r = export_log_csv(o.log, prefix, out);
  if (r.rows == 0) {
    out.discard();
    print_error(o.log + ": no cycles (only the daemon's start-up messages?); nothing written");
    return kExitFailure;
  }
  out.commit();
  if (!r.note.empty()) print_note(r.note);
  if (!common_options().quiet) {
    std::fprintf(stderr, "exodaq export: %lld rows (%lld run%s, first %s) -> %s\n",
                 static_cast<long long>(r.rows), static_cast<long long>(r.runs),
                 r.runs == 1 ? "" : "s", r.first_run.c_str(),
                 out.is_stdout() ? "standard output" : o.out.c_str());
  }
  if (!r.damage.empty()) {
    print_error(r.damage);  // one line per damaged stretch
    return kExitFailure;
  }
  return kExitOk;
}

std::function<int()> setup_export(CLI::App& sub) {
  auto o = std::make_shared<ExportOptions>();
  sub.add_option("log", o->log, "LCM log (lcm-logger or exodaq replay)")->required();
  sub.add_option("-o,--out", o->out, "CSV file to write, - for standard output (default)")
      ->capture_default_str();
  auto* prefix =
      sub.add_option("--prefix", o->prefix, "channel prefix (default: the only one in the log)");
  return [o, prefix] { return run_export(*o, prefix->count() > 0); };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(export, "export",
                        "an LCM log to CSV, one row per cycle (joint angles, velocities, flags, "
                        "palm pose, manipulability, validity)",
                        exodaq::tools::setup_export);
