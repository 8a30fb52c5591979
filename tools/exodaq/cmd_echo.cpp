// `exodaq echo`: live values for people. On a terminal a compact table that
// refreshes in place about ten times a second; otherwise (or with --csv, or
// -o FILE) one CSV line per message of the chosen channel, header first, in
// the schema of docs/messages.md. --count/--duration make it finite for
// scripts and tests. A write that fails (full disk, closed pipe) ends echo
// with exit 1 and the reason; so does nothing received (no file written).
// "received %" counts the cycles the daemon published (its statuses say which
// seq it skipped); interleaved or repeated seq of one run id is warned of.
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <map>
#include <numbers>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "command.hpp"
#include "exodaq/common/clock_now.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/csv.hpp"
#include "exodaq/messages/flag_names.hpp"
#include "exodaq/messages/seq_account.hpp"
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/settings/service_config.hpp"
#include "live_rig.hpp"
#include "rate_meter.hpp"

namespace exodaq::tools {
namespace {

volatile std::sig_atomic_t g_stop = 0;
extern "C" void on_stop_signal(int) {
  g_stop = 1;
}

void install_stop_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: let the wait in lcm_handle_timeout return
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

struct EchoOptions {
  std::string channel = "joint_state";
  LiveRig rig;
  std::string out = "-";
  bool csv = false;
  int64_t count = 0;      // 0: no limit
  double duration = 0.0;  // s, 0: no limit
};

constexpr double kRadToDeg = 180.0 / std::numbers::pi;

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

class Table {
 public:
  explicit Table(const EchoOptions& o) : opt_(o) {}

  void on(const messages::Received& r, int64_t local_ns) {
    if (const auto* j = std::get_if<joint_state_t>(&r.msg)) {
      joint_ = *j;
      joint_local_ns_ = local_ns;
      meter_.add(messages::stamp_of(r.msg), local_ns);
    } else if (const auto* p = std::get_if<palm_pose_t>(&r.msg)) {
      palm_ = *p;
    } else if (const auto* s = std::get_if<status_t>(&r.msg)) {
      status_ = *s;
      status_local_ns_ = local_ns;
      const messages::DaemonCounts c = messages::daemon_counts(*s);
      meter_.add_status(s->run_id, c.seq, c.unpublished);
    } else if (const auto* e = std::get_if<encoder_raw_t>(&r.msg)) {
      raw_ = *e;
    }
  }

  void render(int64_t local_ns) {
    std::vector<std::string> lines;
    char buf[256];
    // The rig's name comes with its status (10 Hz): until then, only the prefix.
    std::snprintf(buf, sizeof buf, "exodaq echo  %s  prefix '%s'  rig %s", opt_.rig.url.c_str(),
                  opt_.rig.prefix.c_str(), status_ ? ("'" + status_->rig + "'").c_str() : "?");
    lines.emplace_back(buf);
    if (!joint_) {
      lines.emplace_back("waiting for " +
                         messages::channel_name(opt_.rig.prefix, messages::Kind::kJointState) +
                         " ...");
    } else {
      const auto& j = *joint_;
      const auto rate = meter_.rate_hz();
      const auto recv = meter_.received_fraction();
      const double age_s = static_cast<double>(local_ns - joint_local_ns_) * 1e-9;
      std::snprintf(buf, sizeof buf, "seq %lld  run %s  rate %s Hz  received %s %%  sample %s%s",
                    static_cast<long long>(j.seq), messages::run_id_text(j.run_id).c_str(),
                    rate ? fmt("%.1f", *rate).c_str() : "-",
                    recv ? fmt("%.2f", *recv * 100.0).c_str() : "-",
                    messages::sample_flag_names(j.sample_flags).c_str(),
                    age_s > 1.0 ? fmt("  (no data for %.0f s)", age_s).c_str() : "");
      lines.emplace_back(buf);
      lines.emplace_back("joint                  angle deg   vel deg/s  homed  flags");
      for (int i = 0; i < wire::kJointCount; ++i) {
        std::snprintf(buf, sizeof buf, "%-20.20s %11.3f %11.2f  %-5s  %s", j.name[i].c_str(),
                      j.position[i] * kRadToDeg, j.velocity[i] * kRadToDeg,
                      j.homed[i] ? "yes" : "no", messages::joint_flag_names(j.flags[i]).c_str());
        lines.emplace_back(buf);
      }
    }
    if (palm_) {
      const auto& p = *palm_;
      std::snprintf(
          buf, sizeof buf, "palm mm  x %8.2f  y %8.2f  z %8.2f  valid %s  manip %.3f%s  seq %lld",
          p.position[0] * 1e3, p.position[1] * 1e3, p.position[2] * 1e3,
          p.valid ? "yes"
                  : ("no (" + messages::invalid_reason_names(p.invalid_reason) + ")").c_str(),
          p.shoulder_manipulability, p.near_singular ? " NEAR-SINGULAR" : "",
          static_cast<long long>(p.seq));
      lines.emplace_back(buf);
    } else {
      lines.emplace_back("palm     waiting for " +
                         messages::channel_name(opt_.rig.prefix, messages::Kind::kPalmPose));
    }
    if (raw_) {
      const auto& e = *raw_;
      std::string positions;
      for (int i = 0; i < wire::kJointCount; ++i) {
        positions += " " + std::to_string(e.position[i]);
      }
      std::snprintf(buf, sizeof buf, "raw      present %s  source_seq %lld  position%s",
                    e.present ? "yes" : "no", static_cast<long long>(e.source_seq),
                    positions.c_str());
      lines.emplace_back(buf);
    }
    if (status_) {
      const auto& s = *status_;
      const double age_s = static_cast<double>(local_ns - status_local_ns_) * 1e-9;
      std::snprintf(buf, sizeof buf, "status   %s  \"%.60s\"  overruns %lld  clock %s  bus %s%s",
                    std::string(messages::state_name(s.state)).c_str(), s.message.c_str(),
                    static_cast<long long>(s.overruns),
                    s.clock_synchronised                                      ? "synced"
                    : opt_.rig.clock_policy == settings::RequireSync::kIgnore ? "unsynced (ignored)"
                                                                              : "UNSYNCED",
                    std::string(messages::bus_state_name(s.bus_state)).c_str(),
                    age_s > 1.0 ? fmt("  (stale %.0f s)", age_s).c_str() : "");
      lines.emplace_back(buf);
    } else {
      lines.emplace_back("status   waiting for " +
                         messages::channel_name(opt_.rig.prefix, messages::Kind::kStatus));
    }

    std::string out;
    if (drawn_lines_ > 0) out += "\x1b[" + std::to_string(drawn_lines_) + "F";  // back to top
    for (const auto& l : lines) out += l + "\x1b[K\n";
    for (int i = static_cast<int>(lines.size()); i < drawn_lines_; ++i) out += "\x1b[K\n";
    drawn_lines_ = std::max(drawn_lines_, static_cast<int>(lines.size()));
    std::fwrite(out.data(), 1, out.size(), stdout);
    std::fflush(stdout);
  }

 private:
  const EchoOptions& opt_;
  std::optional<joint_state_t> joint_;
  std::optional<palm_pose_t> palm_;
  std::optional<status_t> status_;
  std::optional<encoder_raw_t> raw_;
  int64_t joint_local_ns_ = 0;
  int64_t status_local_ns_ = 0;
  RateMeter meter_;
  int drawn_lines_ = 0;
};

// CSV lines in the schema of docs/messages.md, to standard output or a file
// (written as a files::OutputFile: a file appears when echo ends). The header
// goes out with the first message: it names the joints that message names.
class CsvEcho {
 public:
  CsvEcho(const std::string& out, std::optional<messages::Kind> kind)
      : out_(out, output_options()), kind_(kind) {}

  static files::OutputOptions output_options() {
    files::OutputOptions o;
    o.allow_stdout = true;
    return o;
  }

  // False when the message is not of the kind being printed.
  bool on(const messages::Received& r) {
    const auto k = messages::kind_of(r.msg);
    if (!kind_) kind_ = k;
    if (k != *kind_) return false;  // a literal channel carrying mixed types: keep the first
    if (!header_done_) {
      out_.write(messages::csv::line(messages::csv::header(k, messages::csv::joints_of(r.msg))) +
                 "\n");
      header_done_ = true;
    }
    values_.clear();
    messages::csv::append_values(r.msg, values_);
    out_.write(messages::csv::line(values_) + "\n");
    return true;
  }
  void flush() { out_.flush(); }
  void commit() { out_.commit(); }

 private:
  files::OutputFile out_;
  std::optional<messages::Kind> kind_;
  bool header_done_ = false;
  std::vector<std::string> values_;
};

// Each run's per-cycle seq on the rig's channels and its statuses: repeated
// or interleaved seq of one run id is said once per run (a second stream with
// the run's id: replay --live of a live run, a forged message); at the end,
// the chosen channel's cycles, missing ones split by the daemon's counters.
class SeqWatch {
 public:
  void on(const messages::Received& r) {
    const auto parts = messages::split_channel(r.channel);
    if (!parts) return;
    const messages::Stamp st = messages::stamp_of(r.msg);
    if (messages::is_startup_message(st)) return;
    messages::RunAccount& a = runs_[{parts->prefix, st.run_id}];
    if (const auto* s = std::get_if<status_t>(&r.msg)) {
      a.add_status(messages::daemon_counts(*s));
      return;
    }
    const messages::Kind k = messages::kind_of(r.msg);
    const std::int64_t last = a.last_seq(k);
    if (a.add(k, st.seq) == messages::SeqStep::kRepeat &&
        warned_.insert({parts->prefix, st.run_id}).second) {
      print_error("WARNING: run " + messages::run_id_text(st.run_id) + " on prefix '" +
                  parts->prefix + "': seq " + std::to_string(st.seq) + " on " + r.channel +
                  " after seq " + std::to_string(last) +
                  ": interleaved or repeated seq of one run id (a second stream with this run "
                  "id: replay --live of a live run?); rows of both are shown");
    }
  }
  // One line per run of `kind` on `prefix` ("" when none).
  std::vector<std::string> describe(const std::string& prefix, messages::Kind kind) const {
    std::vector<std::string> out;
    for (const auto& [key, a] : runs_) {
      if (key.first != prefix) continue;
      const messages::SeqTally t = a.tally(kind);
      if (t.received > 0)
        out.push_back("run " + messages::run_id_text(key.second) + ": " + messages::describe(t));
    }
    return out;
  }

 private:
  std::map<std::pair<std::string, std::int64_t>, messages::RunAccount> runs_;
  std::set<std::pair<std::string, std::int64_t>> warned_;
};

// What one echo run shares between its subscriptions and its loop.
struct EchoRun {
  const EchoOptions& opt;
  std::string channel;  // the channel counted and printed
  std::optional<messages::Kind> kind;
  bool csv = false;
  std::optional<CsvEcho> csv_out;
  Table table;
  int64_t received = 0;     // messages on the chosen channel
  std::string write_error;  // the first failed write (stops the loop)
  SeqWatch seq;
  explicit EchoRun(const EchoOptions& o) : opt(o), table(o) {}
};

void subscribe(EchoRun& run, messages::Subscriber& subscriber) {
  if (run.csv) {
    subscriber.subscribe(run.channel, run.kind, [&run](const messages::Received& r) {
      if ((run.opt.count > 0 && run.received >= run.opt.count) || !run.write_error.empty()) return;
      run.seq.on(r);
      try {
        if (run.csv_out->on(r)) ++run.received;
      } catch (const files::FileError& e) {  // not through LCM's C frames
        run.write_error = e.what();
      }
    });
    // The rig's statuses, for the account of a per-cycle channel (not printed).
    if (run.kind && messages::is_per_cycle(*run.kind)) {
      subscriber.subscribe(messages::channel_name(run.opt.rig.prefix, messages::Kind::kStatus),
                           messages::Kind::kStatus,
                           [&run](const messages::Received& r) { run.seq.on(r); });
    }
    return;
  }
  std::vector<std::string> channels;
  for (auto k : messages::kAllKinds)
    channels.push_back(messages::channel_name(run.opt.rig.prefix, k));
  if (!run.kind) channels.push_back(run.channel);
  for (const auto& c : channels) {
    subscriber.subscribe(c, std::nullopt, [&run, c](const messages::Received& r) {
      run.table.on(r, mono_now_ns());
      run.seq.on(r);
      if (c == run.channel) ++run.received;
    });
  }
}

// Until --count, --duration, a signal or a write error: kExitOk or kExitFailure.
int echo_loop(EchoRun& run, messages::Subscriber& subscriber) {
  const EchoOptions& opt = run.opt;
  const int64_t start = mono_now_ns();
  const int64_t end = opt.duration > 0 ? start + static_cast<int64_t>(opt.duration * 1e9) : 0;
  constexpr int64_t kRefreshNs = 100'000'000;
  int64_t next_draw = start;
  int64_t last_flush = start;
  while (!g_stop && run.write_error.empty()) {
    if (opt.count > 0 && run.received >= opt.count) break;
    int64_t now = mono_now_ns();
    if (end && now >= end) {
      if (opt.count > 0 && run.received < opt.count) {
        print_error(std::to_string(run.received) + " of " + std::to_string(opt.count) +
                    " messages on " + run.channel + " within " +
                    messages::csv::number(opt.duration) + " s");
        return kExitFailure;
      }
      break;
    }
    if (!run.csv && now >= next_draw) {
      run.table.render(now);
      next_draw = now + kRefreshNs;
    }
    int64_t wait_ns = run.csv ? kRefreshNs : next_draw - now;
    if (end) wait_ns = std::min(wait_ns, end - now);
    const int timeout_ms = static_cast<int>(std::max<int64_t>(1, (wait_ns + 999'999) / 1'000'000));
    const int r = subscriber.handle(timeout_ms);
    if (r < 0 && !g_stop) {
      print_error("LCM receive failed");
      return kExitFailure;
    }
    now = mono_now_ns();
    if (run.csv && run.write_error.empty() && (r == 0 || now - last_flush >= kRefreshNs)) {
      try {
        run.csv_out->flush();
      } catch (const files::FileError& e) {
        run.write_error = e.what();
      }
      last_flush = now;
    }
  }
  return kExitOk;
}

int run_echo(EchoOptions opt) {
  resolve_live_rig(opt.rig);
  EchoRun run(opt);
  run.csv = opt.csv || opt.out != "-" || !isatty(STDOUT_FILENO);
  run.kind = messages::parse_kind(opt.channel);
  // A name we do not know is a literal channel; its type comes from the payload.
  run.channel = run.kind ? messages::channel_name(opt.rig.prefix, *run.kind) : opt.channel;
  if (run.csv) run.csv_out.emplace(opt.out, run.kind);
  messages::Subscriber subscriber(opt.rig.url);
  install_stop_handlers();
  subscribe(run, subscriber);
  subscriber.on_mixed_runs([&run](const messages::RunMix& mix) {
    if (!run.csv) std::fputs("\n", stdout);  // below the table
    print_error("WARNING: " + messages::describe(mix) + "; rows of both are shown");
  });
  if (!run.csv) std::fputs("\x1b[?25l", stdout);  // hide the cursor while redrawing

  const int rc = echo_loop(run, subscriber);
  if (!run.write_error.empty()) {
    print_error(run.write_error);
    return kExitFailure;
  }
  if (common_options().verbose) {
    print_error(std::to_string(run.received) + " messages on " + run.channel + " from " +
                opt.rig.url + ", " + std::to_string(subscriber.undecodable()) + " undecodable");
  }
  if (run.received == 0) {
    // Nothing to show: no file is written, and the exit code says so.
    if (!run.csv) std::fputs("\x1b[?25h\n", stdout);
    if (rc != kExitOk) return rc;  // already said (fewer than --count)
    print_error("nothing received on " + run.channel + " from " + opt.rig.url +
                (opt.duration > 0 ? " within " + messages::csv::number(opt.duration) + " s" : "") +
                " (is the daemon running, with this lcm.url and prefix?)" +
                (run.csv && opt.out != "-" ? "; " + opt.out + " not written" : ""));
    return kExitFailure;
  }
  if (run.csv) {
    run.csv_out->commit();  // throws FileError with the reason
  } else {
    run.table.render(mono_now_ns());
    std::fputs("\x1b[?25h", stdout);
  }
  std::fflush(stdout);
  if (run.kind && messages::is_per_cycle(*run.kind)) {
    for (const auto& line : run.seq.describe(opt.rig.prefix, *run.kind)) print_note(line);
  }
  return rc;
}

std::function<int()> setup_echo(CLI::App& app) {
  auto opt = std::make_shared<EchoOptions>();
  app.add_option("--channel", opt->channel,
                 "joint_state, palm_pose, encoder_raw or status (or EXO_* names; the prefix is "
                 "added), or any other literal channel name")
      ->capture_default_str();
  add_live_rig_options(app, opt->rig);
  app.add_option("-o,--out", opt->out,
                 "CSV to this file (written when echo ends), - for standard output")
      ->capture_default_str();
  app.add_flag("--csv", opt->csv, "CSV lines even on a terminal (the default when piped)");
  app.add_option("--count,-n", opt->count, "stop after N messages of the channel (0: no limit)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--duration,-d", opt->duration,
                 "stop after S seconds (0: no limit); with --count, exit 1 if fewer arrived")
      ->check(CLI::NonNegativeNumber);
  return [opt] { return run_echo(*opt); };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(echo, "echo",
                        "print live joint angles, palm pose and status (table on a terminal, "
                        "CSV otherwise)",
                        ::exodaq::tools::setup_echo);
