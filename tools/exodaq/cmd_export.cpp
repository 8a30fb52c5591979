// exodaq export: an LCM log (lcm-logger or exodaq replay) to CSV, one row per
// cycle: the joint_state_t of that seq joined with its palm_pose_t.
//   exodaq export LOG [-o OUT.csv|-] [-p PREFIX] [--run-id RUN]
// The columns are the CSV schema of docs/messages.md (exodaq/messages/csv.hpp);
// values are exact. The daemon's all-zero start-up messages are left out. A
// cycle whose palm_pose_t is missing from the log keeps empty palm columns.
// Runs one after another are exported in turn; two runs interleaved (two
// daemons on one channel set) are refused unless --run-id chooses one.
// The output appears only when the log could be read (a damaged log: what
// could be read, and exit 1 naming the damaged bytes and the cycles they
// cost). Messages whose run id or seq is out of line with their neighbours
// (damage, or a second stream with one run id) and seq numbers already read
// (a run held twice) are named, not exported, and exit 1. Each run's seq
// holes are reported, split into the daemon's own (its status counters in the
// log) and those lost (docs/replay.md, "Export").
#include <climits>
#include <cstdio>
#include <deque>
#include <functional>
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
#include "exodaq/messages/run_mix.hpp"
#include "exodaq/messages/seq_account.hpp"
#include "export_csv.hpp"

namespace exodaq::tools {

namespace {

constexpr std::int64_t kJoinWindow = 4096;  // cycles a row waits for its other half
// A run id carried by fewer of the rig's joint and palm messages than this is
// a damaged run id, not a daemon's run (a run publishes 2 per millisecond).
constexpr std::int64_t kStrayRunMessages = 16;
// The largest seq step taken as a continuation of a run (18 hours at 1 kHz):
// judging a seq against its neighbours needs two that agree.
constexpr std::int64_t kPlausibleStep = 1LL << 26;
constexpr std::size_t kListed = 5;  // anomalies named one by one; the rest counted

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
    const messages::csv::JointNames names = messages::csv::joint_columns(row.joint.name);
    if (r_.rows == 0) {
      for (int i = 0; i < messages::csv::kJoints; ++i) r_.joint_names[i] = row.joint.name[i];
      columns_ = names;
      out_.write(messages::csv::line(messages::csv::cycle_header(names)) + "\n");
      r_.first_run = messages::run_id_text(row.joint.run_id);
    } else if (names != columns_ && r_.note.empty()) {
      r_.note = "run " + messages::run_id_text(row.joint.run_id) +
                " names its joints differently; the header names those of run " + r_.first_run;
    }
    if (r_.rows == 0 || row.joint.run_id != run_) ++r_.runs;
    run_ = row.joint.run_id;
    values_.clear();
    messages::csv::append_cycle(row.joint, row.have_palm ? &row.palm : nullptr, values_);
    out_.write(messages::csv::line(values_) + "\n");
    ++r_.rows;
  }

 private:
  files::OutputFile& out_;
  CsvExport& r_;
  messages::csv::JointNames columns_{};
  std::int64_t run_ = 0;
  std::vector<std::string> values_;
};

// One joint_state_t or palm_pose_t from the log, with where it was.
struct Item {
  bool is_joint = false;
  joint_state_t joint;
  palm_pose_t palm;
  std::int64_t run = 0;
  std::int64_t seq = 0;
  std::int64_t event = 0;        // the log's event number
  std::int64_t offset = 0;       // byte offset of its event
  std::size_t after_damage = 0;  // 1 + index of the damaged stretch just before it (0: none)
};

bool continues(std::int64_t run_a, std::int64_t seq_a, const Item& b) {
  std::int64_t step = 0;
  return run_a == b.run && b.seq > seq_a && !__builtin_sub_overflow(b.seq, seq_a, &step) &&
         step <= kPlausibleStep;
}

// A message whose seq is out of line with its neighbours of the same run: the
// one accepted before and the next two. Two that agree with each other around
// it and it not between them: a damaged seq, or a second stream with this
// run id (replay --live of a live run). A run switch or a jump without two
// neighbours that agree is accepted (and then counted by the RunAccount).
class SeqJudge {
 public:
  using Accept = std::function<void(Item&)>;
  using Reject = std::function<void(const Item&, std::int64_t before, std::int64_t after)>;
  SeqJudge(Accept accept, Reject reject) : accept_(std::move(accept)), reject_(std::move(reject)) {}

  void feed(Item item) {
    queue_.push_back(std::move(item));
    if (queue_.size() == 3) decide();
  }
  void finish() {
    while (!queue_.empty()) decide();
  }

 private:
  void decide() {
    Item h = std::move(queue_.front());
    queue_.pop_front();
    const Item* n1 = !queue_.empty() ? &queue_[0] : nullptr;
    const Item* n2 = queue_.size() > 1 ? &queue_[1] : nullptr;
    if (out_of_line(h, n1, n2)) {
      // The damage marker moves to the next message.
      if (h.after_damage != 0 && n1 != nullptr && queue_.front().after_damage == 0) {
        queue_.front().after_damage = h.after_damage;
      }
      reject_(h, have_last_ ? last_seq_ : -1, n1 != nullptr ? n1->seq : -1);
      return;
    }
    have_last_ = true;
    last_run_ = h.run;
    last_seq_ = h.seq;
    accept_(h);
  }

  bool out_of_line(const Item& h, const Item* n1, const Item* n2) const {
    if (have_last_ && last_run_ == h.run) {
      const auto between = [&](const Item& n) { return last_seq_ < h.seq && h.seq < n.seq; };
      if (n1 != nullptr && continues(last_run_, last_seq_, *n1)) return !between(*n1);
      if (n2 != nullptr && continues(last_run_, last_seq_, *n2)) return !between(*n2);
      return false;
    }
    // The first of its run: judged by the two after it.
    return n1 != nullptr && n2 != nullptr && n1->run == h.run && continues(n1->run, n1->seq, *n2) &&
           !continues(h.run, h.seq, *n1);
  }

  Accept accept_;
  Reject reject_;
  std::deque<Item> queue_;
  bool have_last_ = false;
  std::int64_t last_run_ = 0;
  std::int64_t last_seq_ = 0;
};

// Run ids on the rig's joint and palm channels and how many messages carry
// each (from the messages' headers, without decoding them).
std::map<std::int64_t, std::int64_t> count_runs(const std::string& log_path,
                                                const std::string& joint_channel,
                                                const std::string& palm_channel) {
  std::map<std::int64_t, std::int64_t> runs;
  messages::LogReader log(log_path);
  messages::LogEvent ev;
  while (log.next(ev)) {
    if (ev.channel != joint_channel && ev.channel != palm_channel) continue;
    if (const auto ks = messages::peek_stamp(ev.data, ev.size); ks && ks->stamp.utime != 0) {
      ++runs[ks->stamp.run_id];
    }
  }
  return runs;
}

std::string event_place(const Item& m) {
  return "event " + std::to_string(m.event) + " (byte " + std::to_string(m.offset) + ")";
}

// Counted anomalies of one kind: the first few named, the rest counted.
struct Anomalies {
  std::int64_t count = 0;
  std::vector<std::string> named;
  void add(const std::string& what) {
    if (named.size() < kListed) named.push_back(what);
    ++count;
  }
  void report(std::vector<std::string>& out, const std::string& summary) const {
    if (count == 0) return;
    out.push_back(summary);
    for (const auto& n : named) out.push_back("  " + n);
    if (count > static_cast<std::int64_t>(named.size())) {
      out.push_back("  ... and " + std::to_string(count - static_cast<std::int64_t>(named.size())) +
                    " more");
    }
  }
};

// The export of one log: reads it, judges each message, joins and writes rows.
class Exporter {
 public:
  Exporter(const std::string& log_path, const std::string& prefix, files::OutputFile& out,
           std::optional<std::int64_t> only_run)
      : path_(log_path),
        prefix_(prefix),
        joint_channel_(messages::channel_name(prefix, messages::Kind::kJointState)),
        palm_channel_(messages::channel_name(prefix, messages::Kind::kPalmPose)),
        status_channel_(messages::channel_name(prefix, messages::Kind::kStatus)),
        only_run_(only_run),
        writer_(out, result_),
        joints_([this](Item& m) { take(m); },
                [this](const Item& m, std::int64_t b, std::int64_t a) { out_of_line(m, b, a); }),
        palms_([this](Item& m) { take(m); },
               [this](const Item& m, std::int64_t b, std::int64_t a) { out_of_line(m, b, a); }) {}

  CsvExport run() {
    run_messages_ = count_runs(path_, joint_channel_, palm_channel_);
    messages::LogReader log(path_);
    messages::LogEvent ev;
    while (log.next(ev)) {
      if (ev.follows_damage) damage_pending_ = log.damage().size();
      on_event(ev);
    }
    joints_.finish();
    palms_.finish();
    flush_until(INT64_MAX);
    report(log);
    return result_;
  }

 private:
  void on_event(const messages::LogEvent& ev) {
    const std::string_view ch = ev.channel;
    if (ch == status_channel_) {
      on_status(ev);
      return;
    }
    const bool is_joint = ch == joint_channel_;
    if (!is_joint && ch != palm_channel_) return;
    Item m;
    m.is_joint = is_joint;
    m.event = ev.number;
    m.offset = ev.offset;
    const bool decoded = is_joint ? messages::decode_into(m.joint, ev.data, ev.size)
                                  : messages::decode_into(m.palm, ev.data, ev.size);
    if (!decoded) {
      if (is_joint) ++damaged_cycles_;
      const auto end = ev.offset + 28 + static_cast<std::int64_t>(ch.size() + ev.size);
      undecodable_.add(event_place(m) + " on " + std::string(ch) + ", bytes " +
                       std::to_string(ev.offset) + ".." + std::to_string(end));
      return;
    }
    const std::int64_t utime = is_joint ? m.joint.utime : m.palm.utime;
    if (utime == 0) return;  // the daemon's start-up messages
    m.run = is_joint ? m.joint.run_id : m.palm.run_id;
    m.seq = is_joint ? m.joint.seq : m.palm.seq;
    if (only_run_ && m.run != *only_run_) return;
    if (const std::int64_t n = run_messages_[m.run]; n < kStrayRunMessages) {
      if (is_joint) ++damaged_cycles_;
      stray_.add(event_place(m) + ": run id " + messages::run_id_text(m.run) + " (seq " +
                 std::to_string(m.seq) + "), carried by " + std::to_string(n) +
                 " message(s) of the log");
      return;
    }
    if (is_joint && damage_pending_ != 0) {
      m.after_damage = damage_pending_;
      damage_pending_ = 0;
    }
    (is_joint ? joints_ : palms_).feed(std::move(m));
  }

  void on_status(const messages::LogEvent& ev) {
    status_t st;
    if (!messages::decode_into(st, ev.data, ev.size) || st.utime == 0) return;
    if (only_run_ && st.run_id != *only_run_) return;
    if (result_.rig.empty()) result_.rig = st.rig;
    if (run_messages_[st.run_id] >= kStrayRunMessages) {
      accounts_[st.run_id].add_status(messages::daemon_counts(st));
    }
  }

  void out_of_line(const Item& m, std::int64_t before, std::int64_t after) {
    if (m.is_joint) ++damaged_cycles_;
    out_of_line_[m.run].add(event_place(m) + ": " + (m.is_joint ? "joint_state_t" : "palm_pose_t") +
                            " seq " + std::to_string(m.seq) + " between seq " +
                            std::to_string(before) + " and " + std::to_string(after));
  }

  void take(Item& m) {
    if (const auto mix = runs_.observe(prefix_, m.run)) {
      throw MixedRunsError(path_ + ": " + messages::describe(*mix) + "; export one with --run-id " +
                           messages::run_id_text(mix->first) + " or --run-id " +
                           messages::run_id_text(mix->second));
    }
    if (m.run != run_id_) {  // a new daemon run: seq restarts
      flush_until(INT64_MAX);
      run_id_ = m.run;
      flushed_to_ = INT64_MIN;
    }
    messages::RunAccount& account = accounts_[m.run];
    const messages::Kind kind =
        m.is_joint ? messages::Kind::kJointState : messages::Kind::kPalmPose;
    const std::int64_t last = account.last_seq(kind);
    const messages::SeqStep step = account.add(kind, m.seq);
    if (m.is_joint && m.after_damage != 0) damage_cost_[m.after_damage - 1] = {last, m.seq};
    if (step == messages::SeqStep::kRepeat || m.seq < flushed_to_) {
      repeated_[m.run].add(event_place(m) + ": " + (m.is_joint ? "joint_state_t" : "palm_pose_t") +
                           " seq " + std::to_string(m.seq) + " after seq " + std::to_string(last));
      return;
    }
    Row& r = pending_[m.seq];
    if (m.is_joint) {
      r.joint = m.joint;
      r.have_joint = true;
    } else {
      r.palm = m.palm;
      r.have_palm = true;
    }
    flush_until(m.seq - kJoinWindow);
  }

  void flush_until(std::int64_t seq_limit) {
    while (!pending_.empty() && pending_.begin()->first < seq_limit) {
      writer_.write(pending_.begin()->second);
      flushed_to_ = pending_.begin()->first + 1;
      pending_.erase(pending_.begin());
    }
  }

  void report(const messages::LogReader& log);

  std::string path_;
  std::string prefix_;
  std::string joint_channel_;
  std::string palm_channel_;
  std::string status_channel_;
  std::optional<std::int64_t> only_run_;
  CsvExport result_;
  CycleWriter writer_;
  SeqJudge joints_;
  SeqJudge palms_;
  std::map<std::int64_t, std::int64_t> run_messages_;
  messages::RunMixDetector runs_;
  std::int64_t run_id_ = 0;
  std::int64_t flushed_to_ = INT64_MIN;  // rows below this seq are written
  std::map<std::int64_t, Row> pending_;  // by seq, this run
  std::map<std::int64_t, messages::RunAccount> accounts_;
  std::size_t damage_pending_ = 0;
  std::int64_t damaged_cycles_ = 0;  // joint messages lost to damage in the log
  // Per damaged stretch: the joint seq before and after it.
  std::map<std::size_t, std::pair<std::int64_t, std::int64_t>> damage_cost_;
  Anomalies undecodable_;
  Anomalies stray_;
  std::map<std::int64_t, Anomalies> out_of_line_;
  std::map<std::int64_t, Anomalies> repeated_;
};

void Exporter::report(const messages::LogReader& log) {
  std::vector<std::string> problems;
  const auto& damage = log.damage();
  for (std::size_t i = 0; i < damage.size(); ++i) {
    std::string line = messages::LogReader::damage_line(path_, damage[i]);
    if (const auto it = damage_cost_.find(i); it != damage_cost_.end() && it->second.first >= 0) {
      const auto [before, after] = it->second;
      const std::int64_t cycles = after > before ? after - before - 1 : 0;
      damaged_cycles_ += cycles;
      line += "; cycles lost with it: " + std::to_string(cycles) +
              (cycles > 0
                   ? " (seq " + std::to_string(before + 1) + ".." + std::to_string(after - 1) + ")"
                   : std::string());
    }
    problems.push_back(line);
  }
  undecodable_.report(problems, path_ + ": " + std::to_string(undecodable_.count) + " events on " +
                                    joint_channel_ + " or " + palm_channel_ +
                                    " do not decode (damaged); their cycles are not exported:");
  result_.undecodable = undecodable_.count;
  stray_.report(problems, path_ + ": " + std::to_string(stray_.count) +
                              " message(s) with a run id no run of the log has (a damaged run "
                              "id); not exported:");
  for (const auto& [run, a] : out_of_line_) {
    a.report(problems, path_ + ": run " + messages::run_id_text(run) + ": " +
                           std::to_string(a.count) +
                           " message(s) with a seq out of line with their neighbours (a damaged "
                           "seq, or a second stream with this run id: replay --live of a live "
                           "run?); not exported:");
  }
  for (const auto& [run, a] : repeated_) {
    a.report(problems, path_ + ": run " + messages::run_id_text(run) + ": " +
                           std::to_string(a.count) +
                           " message(s) repeat seq numbers already read (the log holds this run "
                           "twice: logs joined with cat, two recorders, or a second stream with "
                           "this run id); not exported again:");
  }
  for (const auto& [run, account] : accounts_) {
    const messages::SeqTally t = account.tally(messages::Kind::kJointState);
    if (t.received == 0) continue;
    std::string line = "run " + messages::run_id_text(run) + ": " + messages::describe(t);
    if (t.widest > 0) {
      line += "; widest hole seq " + std::to_string(t.widest_from) + ".." +
              std::to_string(t.widest_from + t.widest - 1);
    }
    if (!account.last_status() && t.missing > 0) {
      line += " (no status_t of this run in the log: the daemon's share is unknown)";
    }
    result_.notes.push_back(line);
    result_.missing += t.missing;
    result_.lost += t.lost;
  }
  result_.lost = std::max<std::int64_t>(0, result_.lost - damaged_cycles_);
  for (const auto& p : problems) result_.damage += (result_.damage.empty() ? "" : "\n") + p;
}

}  // namespace

std::string choose_prefix(const std::string& log_path, const std::optional<std::string>& given) {
  std::set<std::string> prefixes;
  for (const auto& [channel, count] : messages::scan_channels(log_path)) {
    const auto parts = messages::split_channel(channel);
    if (parts && parts->kind == messages::Kind::kJointState) prefixes.insert(parts->prefix);
  }
  if (given) {
    if (prefixes.count(*given) == 0) {
      throw std::runtime_error(log_path + ": no channel " +
                               messages::channel_name(*given, messages::Kind::kJointState) +
                               " (--prefix '" + *given + "')");
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
                         files::OutputFile& out, std::optional<std::int64_t> only_run) {
  return Exporter(log_path, prefix, out, only_run).run();
}

namespace {

struct ExportOptions {
  std::string log;
  std::string out = "-";
  std::string prefix;
  std::string run_id;  // run_id_text of the one run to export ("": all, unless they interleave)
};

std::optional<std::int64_t> chosen_run(const ExportOptions& o) {
  if (o.run_id.empty()) return std::nullopt;
  const auto id = messages::parse_run_id(o.run_id);
  if (!id) throw std::runtime_error("--run-id '" + o.run_id + "': not 16 hex digits");
  return id;
}

int run_export(const ExportOptions& o, bool prefix_given) {
  const std::optional<std::int64_t> only_run = chosen_run(o);
  files::OutputOptions oo;
  oo.allow_stdout = true;
  oo.inputs = {o.log};
  files::check_output(o.out, oo);
  const std::string prefix =
      choose_prefix(o.log, prefix_given ? std::optional(o.prefix) : std::nullopt);
  if (common_options().verbose) {
    print_error("reading " + messages::channel_name(prefix, messages::Kind::kJointState) + " and " +
                messages::channel_name(prefix, messages::Kind::kPalmPose) + " of " + o.log);
  }
  files::OutputFile out(o.out, oo);
  const CsvExport r = export_log_csv(o.log, prefix, out, only_run);
  if (r.rows == 0) {
    out.discard();
    print_error(o.log + ": no cycles" +
                (only_run ? " of run " + o.run_id
                          : std::string(" (only the daemon's start-up messages?)")) +
                "; nothing written");
    if (!r.damage.empty()) print_error(r.damage);
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
  // Each run's cycles and seq holes; a loss is said even with -q.
  for (const auto& n : r.notes) print_note(n);
  if (r.lost > 0) {
    print_error("WARNING: " + std::to_string(r.lost) +
                " cycles missing from the log that the daemon published (its status counters) "
                "and no damage in the log explains: lost by the recorder or the network");
  }
  if (!r.damage.empty()) {
    print_error(r.damage);  // one line per damaged stretch or anomaly
    return kExitFailure;
  }
  return kExitOk;
}

std::function<int()> setup_export(CLI::App& sub) {
  auto o = std::make_shared<ExportOptions>();
  sub.add_option("log", o->log, "LCM log (lcm-logger or exodaq replay)")->required();
  sub.add_option("-o,--out", o->out, "CSV file to write, - for standard output (default)")
      ->capture_default_str();
  auto* prefix = add_prefix_option(sub, o->prefix, "default: the only one in the log");
  sub.add_option("--run-id", o->run_id,
                 "export only this run (16 hex digits, as exodaq status prints it); needed when "
                 "two daemons' runs interleave in the log");
  return [o, prefix] { return run_export(*o, prefix->count() > 0); };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(export, "export",
                        "an LCM log to CSV, one row per cycle (joint angles, velocities, flags, "
                        "palm pose, manipulability, validity)",
                        exodaq::tools::setup_export);
