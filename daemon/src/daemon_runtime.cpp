#include "exodaq/daemon/daemon_runtime.hpp"

#include <signal.h>
#include <spdlog/cfg/env.h>
#include <spdlog/sinks/base_sink.h>
#include <spdlog/spdlog.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <syslog.h>
#include <systemd/sd-daemon.h>
#include <systemd/sd-journal.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <mutex>
#include <optional>
#include <string_view>
#include <vector>

#include "exodaq/common/clock_now.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/builder.hpp"
#include "exodaq/daemon/instance_guard.hpp"
#include "exodaq/drivers/backend.hpp"
#include "exodaq/messages/flag_names.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/settings/service_config.hpp"
#include "exodaq/settings/setting_classes.hpp"
#include "exodaq/version.hpp"
#include "log_output.hpp"
#include "overrun_report.hpp"
#include "publish_watch.hpp"

namespace exodaq::daemon {

using namespace core;  // NOLINT(google-build-using-namespace): the daemon wires the core
using settings::load_service_config;
using settings::LoggingSettings;
using settings::ServiceConfig;
using settings::to_yaml;

namespace {

// Structured journal fields travel with a message through the async logger:
// the payload is "text" kFieldSep "NAME=value" kFieldSep "NAME=value"... The
// journal sink sends them as fields; the stderr sink drops them.
constexpr char kFieldSep = '\x1e';

// stderr is connected to the journal: JOURNAL_STREAM names its device:inode
// (systemd.exec(5)), so a service whose output goes to a file or terminal keeps it.
bool stderr_is_journal() {
  const char* stream = std::getenv("JOURNAL_STREAM");
  if (stream == nullptr) return false;
  unsigned long long dev = 0;
  unsigned long long ino = 0;
  char* end = nullptr;
  dev = std::strtoull(stream, &end, 10);
  if (end == stream || *end != ':') return false;
  const char* rest = end + 1;
  ino = std::strtoull(rest, &end, 10);
  if (end == rest || *end != '\0') return false;
  struct stat st {};
  if (fstat(STDERR_FILENO, &st) != 0) return false;
  return static_cast<unsigned long long>(st.st_dev) == dev &&
         static_cast<unsigned long long>(st.st_ino) == ino;
}

int syslog_priority(spdlog::level::level_enum level) {
  switch (level) {
    case spdlog::level::trace:
    case spdlog::level::debug:
      return LOG_DEBUG;
    case spdlog::level::info:
      return LOG_INFO;
    case spdlog::level::warn:
      return LOG_WARNING;
    case spdlog::level::err:
      return LOG_ERR;
    case spdlog::level::critical:
      return LOG_CRIT;
    default:
      return LOG_INFO;
  }
}

// A sink that formats on the thread that logs and hands the record to the
// LogOutput (log_output.hpp): logging never waits for the output. Lines the
// output dropped while it stalled are noted by a warning before the first
// line that fits again. Control characters in a message (a foreign rig's
// line break or ESC) are escaped: one record, one line.
class QueuedSink : public spdlog::sinks::base_sink<std::mutex> {
 public:
  explicit QueuedSink(std::shared_ptr<LogOutput> output) : output_(std::move(output)) {}

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    if (const std::int64_t lost = output_->unreported_drops(); lost > 0 && output_->has_room(2)) {
      const std::string text =
          fmt::format("log output stalled: {} line(s) dropped ({} since start)", lost,
                      output_->counts().dropped) +
          kFieldSep + "EXODAQ_EVENT=log_dropped" + kFieldSep +
          "EXODAQ_DROPPED=" + std::to_string(lost);
      const spdlog::details::log_msg notice(msg.time, spdlog::source_loc{}, msg.logger_name,
                                            spdlog::level::warn, text);
      if (output_->push(record(notice))) output_->note_reported(lost);
    }
    output_->push(record(msg));
  }
  void flush_() override {}
  // What the output thread gets for `msg`.
  virtual LogRecord record(const spdlog::details::log_msg& msg) = 0;

  // The message text, without the journal fields, escaped.
  static std::string text_of(const spdlog::details::log_msg& msg) {
    const std::string_view payload(msg.payload.data(), msg.payload.size());
    return messages::printable(payload.substr(0, payload.find(kFieldSep)));
  }

 private:
  std::shared_ptr<LogOutput> output_;
};

// The native journal protocol, with the fields carried in the payload
// (EXODAQ_STATE, EXODAQ_JOINT, EXODAQ_EVENT, EXODAQ_SEQ, EXODAQ_RUN_ID ...), so
// `journalctl -u exodaqd EXODAQ_JOINT=elbow` finds one joint's events. Every
// entry names the rig (EXODAQ_RIG: `journalctl EXODAQ_RIG=rig-b`).
class JournalFieldSink final : public QueuedSink {
 public:
  using QueuedSink::QueuedSink;

  // On the output thread: one record to journald, or to stderr when there is
  // no journald (a container, an early boot).
  static LogOutput::Write writer(const std::string& rig, std::shared_ptr<StderrWriter> err) {
    return [rig_field = "EXODAQ_RIG=" + rig, err = std::move(err)](
               const LogRecord& r, const std::function<bool()>& give_up) {
      std::vector<std::string> items = journal_items(r, rig_field);
      std::vector<iovec> iov(items.size());
      for (std::size_t i = 0; i < items.size(); ++i) {
        iov[i].iov_base = items[i].data();
        iov[i].iov_len = items[i].size();
      }
      // (parenthesised: the macro would add this line as CODE_FILE/CODE_LINE)
      if ((sd_journal_sendv)(iov.data(), static_cast<int>(iov.size())) >= 0) {
        return StderrWriter::Result::kWritten;
      }
      return err->write("exodaqd: " + items[0].substr(8) + "\n", give_up);
    };
  }

 protected:
  LogRecord record(const spdlog::details::log_msg& msg) override {
    const std::string_view payload(msg.payload.data(), msg.payload.size());
    const std::size_t cut = payload.find(kFieldSep);
    std::string text = text_of(msg);
    if (cut != std::string_view::npos) text.append(payload.substr(cut));
    return {static_cast<int>(msg.level), std::move(text)};
  }

 private:
  static std::vector<std::string> journal_items(const LogRecord& r, const std::string& rig_field) {
    const std::string_view payload(r.text);
    std::vector<std::string> items;
    std::size_t cut = payload.find(kFieldSep);
    items.push_back("MESSAGE=" + std::string(payload.substr(0, cut)));
    items.push_back("PRIORITY=" + std::to_string(syslog_priority(
                                      static_cast<spdlog::level::level_enum>(r.level))));
    items.emplace_back("SYSLOG_IDENTIFIER=exodaqd");
    items.push_back(rig_field);
    while (cut != std::string_view::npos) {
      const std::size_t next = payload.find(kFieldSep, cut + 1);
      const auto field = payload.substr(
          cut + 1, next == std::string_view::npos ? std::string_view::npos : next - cut - 1);
      if (!field.empty()) items.emplace_back(field);
      cut = next;
    }
    return items;
  }
};

// stderr, without the structured fields; the level coloured on a terminal.
class StderrSink final : public QueuedSink {
 public:
  StderrSink(std::shared_ptr<LogOutput> output, bool colour)
      : QueuedSink(std::move(output)), colour_(colour) {}

 protected:
  LogRecord record(const spdlog::details::log_msg& msg) override {
    const std::string text = text_of(msg);
    spdlog::details::log_msg copy = msg;
    copy.payload = spdlog::string_view_t(text.data(), text.size());
    spdlog::memory_buf_t line;
    formatter_->format(copy, line);
    std::string out(line.data(), line.size());
    if (colour_ && copy.color_range_end > copy.color_range_start) {
      out.insert(copy.color_range_end, "\033[m");
      out.insert(copy.color_range_start, level_colour(msg.level));
    }
    return {static_cast<int>(msg.level), std::move(out)};
  }

 private:
  static const char* level_colour(spdlog::level::level_enum level) {
    switch (level) {
      case spdlog::level::trace:
        return "\033[37m";
      case spdlog::level::debug:
        return "\033[36m";
      case spdlog::level::info:
        return "\033[32m";
      case spdlog::level::warn:
        return "\033[33m\033[1m";
      case spdlog::level::err:
        return "\033[31m\033[1m";
      case spdlog::level::critical:
        return "\033[1m\033[41m";
      default:
        return "";
    }
  }
  bool colour_;
};

struct Logging {
  std::shared_ptr<spdlog::logger> logger;
  std::shared_ptr<LogOutput> output;
  bool journal = false;
};

// The time the log gets at exit to write what is queued (docs/operations.md:
// SIGTERM ends exodaqd within 5 s whatever its output does).
constexpr std::chrono::milliseconds kLogDrain{1000};

// spdlog, through the LogOutput: neither the main thread nor the listener
// ever waits on the journal or a terminal. Level: the config, then
// SPDLOG_LEVEL, then --log-level. Every line names the rig (several daemons
// may share a host and a terminal).
Logging make_logger(const LoggingSettings& settings, const std::string& level_override,
                    const std::string& rig) {
  Logging out;
  out.journal = settings.sink == "journal" || (settings.sink == "auto" && stderr_is_journal());
  auto err = std::make_shared<StderrWriter>();
  spdlog::sink_ptr sink;
  if (out.journal) {
    out.output = std::make_shared<LogOutput>(JournalFieldSink::writer(rig, err));
    sink = std::make_shared<JournalFieldSink>(out.output);
  } else {
    out.output = std::make_shared<LogOutput>(
        [err](const LogRecord& r, const std::function<bool()>& give_up) {
          return err->write(r.text, give_up);
        });
    std::string rig_text;  // literal in the pattern: '%' doubled
    for (const char c : messages::printable(rig))
      rig_text += c == '%' ? std::string("%%") : std::string(1, c);
    sink = std::make_shared<StderrSink>(out.output, isatty(STDERR_FILENO) != 0);
    sink->set_pattern("%Y-%m-%d %H:%M:%S.%e [" + rig_text + "] %^%l%$ %v");
  }
  out.logger = std::make_shared<spdlog::logger>("exodaqd", sink);
  // spdlog's own complaint (a bad format) must not wait on stderr either.
  out.logger->set_error_handler([](const std::string& what) {
    write_stderr("exodaqd: log error: " + messages::printable(what) + "\n",
                 std::chrono::milliseconds(0));
  });
  spdlog::set_default_logger(out.logger);
  spdlog::set_level(spdlog::level::from_str(settings.level));
  spdlog::cfg::load_env_levels();  // SPDLOG_LEVEL overrides the file
  if (!level_override.empty()) spdlog::set_level(spdlog::level::from_str(level_override));
  return out;
}

// The structured-field suffix of a message (see kFieldSep).
std::string fields(std::initializer_list<std::pair<const char*, std::string>> list) {
  std::string out;
  for (const auto& [name, value] : list) {
    out += kFieldSep;
    out += name;
    out += '=';
    out += value;
  }
  return out;
}

const char* joint_event_text(JointEvent e) {
  switch (e) {
    case JointEvent::kHomed:
      return "homed on its index";
    case JointEvent::kHomingRejected:
      return "index rejected: homing would put the joint outside its limits";
    case JointEvent::kLostCounts:
      return "index off its expected count: counts lost or gained, re-homed";
    case JointEvent::kGlitch:
      return "count glitch: faster than the joint can move; flagged until the next index";
    case JointEvent::kStale:
      return "stale: no fresh count";
    case JointEvent::kOutOfRange:
      return "beyond its mechanical limits";
    case JointEvent::kUnwrapAmbiguous:
      return "no count for too long to unwrap safely; flagged until the next index";
    case JointEvent::kNone:
      break;
  }
  return "event";
}

// The EXODAQ_EVENT field of a joint event.
const char* joint_event_id(JointEvent e) {
  switch (e) {
    case JointEvent::kHomed:
      return "homed";
    case JointEvent::kHomingRejected:
      return "homing_rejected";
    case JointEvent::kLostCounts:
      return "lost_counts";
    case JointEvent::kGlitch:
      return "glitch";
    case JointEvent::kStale:
      return "stale";
    case JointEvent::kOutOfRange:
      return "out_of_range";
    case JointEvent::kUnwrapAmbiguous:
      return "unwrap_ambiguous";
    case JointEvent::kNone:
      break;
  }
  return "none";
}

// Overruns as rate-limited lines (overrun_report.hpp), with their journal fields.
void log_overruns(const OverrunLine& line, ServiceState state, std::int64_t run_id) {
  spdlog::warn("{}{}", line.text(),
               fields({{"EXODAQ_EVENT", "overrun"},
                       {"EXODAQ_STATE", state_name(state)},
                       {"EXODAQ_SEQ", std::to_string(line.last_seq)},
                       {"EXODAQ_OVERRUNS", std::to_string(line.skipped)},
                       {"EXODAQ_LATE_WAKES", std::to_string(line.late_wakes)},
                       {"EXODAQ_WORST_LATENESS_US", fmt::format("{:.1f}", line.worst_lateness_us)},
                       {"EXODAQ_RUN_ID", messages::run_id_text(run_id)}}));
}

// Why the state changed, for people (core::describe_cause).
std::string cause_text(const StateCause& cause, const AcquisitionConfig& ac) {
  char text[256];
  const std::string_view joint =
      cause.joint >= 0 && cause.joint < kJointCount
          ? std::string_view(ac.joint_names[static_cast<std::size_t>(cause.joint)])
          : std::string_view();
  return {text, describe_cause(cause, joint, text, sizeof text)};
}

// One loop event, logged on the main thread with its journal fields.
// `state`: the service state when the event was drained; overruns go through
// `overruns` (at most one line per 10 s), each one also at debug level.
void log_event(const LogEvent& e, const AcquisitionConfig& ac, std::int64_t run_id,
               ServiceState state, OverrunReport& overruns) {
  const std::string seq = std::to_string(e.seq);
  const std::string run = messages::run_id_text(run_id);
  switch (e.kind) {
    case LogEvent::Kind::kJoint: {
      const auto& name = ac.joint_names[static_cast<std::size_t>(e.joint)];
      const double deg = e.value * 57.29577951308232;
      const std::string f = fields({{"EXODAQ_EVENT", joint_event_id(e.joint_event)},
                                    {"EXODAQ_JOINT", name},
                                    {"EXODAQ_JOINT_INDEX", std::to_string(e.joint + 1)},
                                    {"EXODAQ_STATE", state_name(state)},
                                    {"EXODAQ_SEQ", seq},
                                    {"EXODAQ_RUN_ID", run}});
      if (e.joint_event == JointEvent::kHomed) {
        spdlog::info("joint {} {} (seq {}, angle {:.3f} deg){}", name,
                     joint_event_text(e.joint_event), e.seq, deg, f);
      } else if (e.joint_event == JointEvent::kLostCounts) {
        spdlog::warn("joint {} {} (seq {}, drift {} counts){}{}", name,
                     joint_event_text(e.joint_event), e.seq, e.count, f,
                     fields({{"EXODAQ_DRIFT_COUNTS", std::to_string(e.count)}}));
      } else {
        spdlog::warn("joint {} {} (seq {}, angle {:.3f} deg){}", name,
                     joint_event_text(e.joint_event), e.seq, deg, f);
      }
      break;
    }
    case LogEvent::Kind::kOverrun:
      spdlog::debug(
          "loop overrun at seq {}: the wake was {:.1f} us late, the cycle's work {:.1f} us; {} "
          "deadline(s) skipped",
          e.seq, e.value, e.work_us, e.count);
      if (const auto line = overruns.add(e, mono_now_ns())) log_overruns(*line, state, run_id);
      break;
    case LogEvent::Kind::kClockStep:
      spdlog::warn(
          "wall clock stepped (step #{} at seq {}): utime is slewed by {:.3f} ms, samples flagged "
          "CLOCK_STEP meanwhile{}",
          e.count, e.seq, e.value,
          fields({{"EXODAQ_EVENT", "clock_step"},
                  {"EXODAQ_STATE", state_name(state)},
                  {"EXODAQ_SEQ", seq},
                  {"EXODAQ_RUN_ID", run}}));
      break;
    case LogEvent::Kind::kStateChange: {
      const bool why = e.cause.reason != StateReason::kNone;
      std::string f = fields({{"EXODAQ_EVENT", "state"},
                              {"EXODAQ_STATE", state_name(e.state)},
                              {"EXODAQ_SEQ", seq},
                              {"EXODAQ_RUN_ID", run}});
      if (why) f += fields({{"EXODAQ_REASON", std::string(reason_name(e.cause.reason))}});
      const std::string cause = why ? ": " + cause_text(e.cause, ac) : std::string();
      if (e.state == ServiceState::kFault || e.state == ServiceState::kDegraded) {
        spdlog::warn("service state: {} (seq {}){}{}", state_name(e.state), e.seq, cause, f);
      } else {
        spdlog::info("service state: {} (seq {}){}{}", state_name(e.state), e.seq, cause, f);
      }
      break;
    }
    case LogEvent::Kind::kReloadApplied:
      spdlog::info(
          "new configuration in effect from seq {}{}", e.seq,
          fields({{"EXODAQ_EVENT", "reload"}, {"EXODAQ_SEQ", seq}, {"EXODAQ_RUN_ID", run}}));
      break;
    case LogEvent::Kind::kNewSegment: {
      const auto& name = ac.joint_names[static_cast<std::size_t>(std::max(e.joint, 0))];
      spdlog::warn(
          "new segment from seq {}: the calibration or model changed, joint {} moved {:.3f} deg "
          "from the sample before; the first sample is flagged NEW_SEGMENT (do not difference or "
          "filter across it){}",
          e.seq, name, e.value * 57.29577951308232,
          fields({{"EXODAQ_EVENT", "new_segment"},
                  {"EXODAQ_JOINT", name},
                  {"EXODAQ_SEQ", seq},
                  {"EXODAQ_RUN_ID", run}}));
      break;
    }
    case LogEvent::Kind::kEndOfStream:
      spdlog::info("source ended at seq {}", e.seq);
      break;
  }
}

// ", bus ACTIVE", ", bus OFF", ...: the names of messages::bus_state_name, the
// ones `exodaq status` prints; nothing while the state is unknown.
std::string bus_state_text(drivers::BusState s) {
  if (s == drivers::BusState::kUnknown) return "";
  return ", bus " + std::string(messages::bus_state_name(static_cast<std::int8_t>(s)));
}

// The state, why, and the homing progress: "homing 4/6", "degraded (OVERRUNS)",
// "fault (NO_SAMPLES), 4/6 homed", "running".
std::string state_text(const Acquisition& acq) {
  const ServiceState state = acq.state();
  const int homed = acq.homed_joints();
  const std::string progress = std::to_string(homed) + "/" + std::to_string(kJointCount);
  if (state == ServiceState::kHoming) return "homing " + progress;
  std::string out = state_name(state);
  if (const StateReason why = acq.state_reason(); why != StateReason::kNone)
    out += " (" + std::string(reason_name(why)) + ")";
  if (homed < kJointCount && state != ServiceState::kStarting) out += ", " + progress + " homed";
  return out;
}

// The clock as the policy sees it: under require_sync: ignore it is not checked.
const char* clock_text(const ClockShared& clock, settings::RequireSync policy) {
  if (policy == settings::RequireSync::kIgnore) return "clock not checked";
  if (!clock.health_valid.load()) return "clock health unknown";
  return clock.synchronised.load() ? "clock synchronised" : "clock UNSYNCHRONISED";
}

// STATUS= for systemctl status: state and homing, loop rate, drops, clock
// health under `policy`, and the log lines the output lost.
std::string status_line(Acquisition& acq, double rate_hz, settings::RequireSync policy,
                        std::int64_t log_dropped = 0) {
  const auto stats = acq.source_counters();
  const PublishHealth publish = acq.publisher().health();
  char text[384];
  std::snprintf(
      text, sizeof(text),
      "STATUS=%s, %.1f Hz, cycle %" PRId64 "; drops: %" PRId64 " missing samples, %" PRId64
      " seq gaps, %" PRId64 " overruns, %" PRId64 " publish failures; %" PRId64 " bus errors%s; %s",
      state_text(acq).c_str(), rate_hz, acq.cycles(), stats.missing_samples, stats.seq_gaps,
      acq.overruns(), publish.failures + publish.ring_drops, stats.bus_errors,
      bus_state_text(stats.bus_state).c_str(), clock_text(acq.clock_shared(), policy));
  std::string line = text + PublishWatch::status_text(publish);
  if (log_dropped > 0) line += "; " + std::to_string(log_dropped) + " log lines dropped";
  return line;
}

void notify(const std::string& text) {
  sd_notify(0, text.c_str());
}

// Every signal that would end or stop the process by its default action is
// blocked and taken by the supervisor (sigtimedwait), except the program
// errors (SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGABRT), whose core dump is the
// evidence, and SIGKILL/SIGSTOP, which cannot be. docs/operations.md, "Signals".
// SIGTERM, SIGINT and SIGQUIT (Ctrl-\) stop; SIGHUP reloads.
constexpr int kStopSignals[] = {SIGTERM, SIGINT, SIGQUIT};
// Job control (Ctrl-Z, a background read or write on the terminal) would
// stop the loop: refused and logged. Blocked, SIGTTOU also lets a background
// exodaqd write to its terminal.
constexpr int kJobControlSignals[] = {SIGTSTP, SIGTTIN, SIGTTOU};
// Signals that mean nothing to the daemon but end a process by default:
// logged, never fatal (and SIGRTMIN..SIGRTMAX).
constexpr int kIgnoredSignals[] = {SIGUSR1, SIGUSR2, SIGALRM, SIGVTALRM, SIGPROF, SIGPOLL,
                                   SIGPWR,  SIGTRAP, SIGSYS,  SIGXCPU,   SIGXFSZ, SIGSTKFLT};

bool is_one_of(int sig, const int* begin, const int* end) {
  return std::find(begin, end, sig) != end;
}

// "SIGTERM", "SIGRTMIN+3".
std::string signal_name(int sig) {
  if (sig >= SIGRTMIN && sig <= SIGRTMAX) return "SIGRTMIN+" + std::to_string(sig - SIGRTMIN);
  const char* abbrev = sigabbrev_np(sig);
  return abbrev != nullptr ? std::string("SIG") + abbrev : "signal " + std::to_string(sig);
}

// The signals the supervisor takes with sigtimedwait().
sigset_t daemon_signals() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGHUP);
  for (const int sig : kStopSignals) sigaddset(&signals, sig);
  for (const int sig : kJobControlSignals) sigaddset(&signals, sig);
  for (const int sig : kIgnoredSignals) sigaddset(&signals, sig);
  for (int sig = SIGRTMIN; sig <= SIGRTMAX; ++sig) sigaddset(&signals, sig);
  return signals;
}

// The log level the configuration's logging.level gives, unless SPDLOG_LEVEL
// or --log-level set it (they win, as at start-up). Empty: overridden.
std::string configured_level(const DaemonOptions& options, const ServiceConfig& config) {
  if (!options.log_level.empty() || std::getenv("SPDLOG_LEVEL") != nullptr) return {};
  return config.logging.level;
}

// The configuration, or the exit code when there is nothing more to do
// (--print-config, --check-config, or a bad file).
std::optional<int> load_config(const DaemonOptions& options, ServiceConfig& config) {
  try {
    config = load_service_config(options.config_path);
  } catch (const exodaq::ConfigError& e) {
    write_stderr("exodaqd: " + std::string(e.what()) + "\n");
    return 1;
  } catch (const std::exception& e) {
    write_stderr("exodaqd: " + options.config_path + ": " + e.what() + "\n");
    return 1;
  }
  if (options.print_config) {
    std::cout << to_yaml(config);
    return 0;
  }
  if (options.check_only) {
    std::printf("exodaqd: %s: configuration valid (rig %s, source %s, model %s, %d joints)\n",
                options.config_path.c_str(), config.rig.c_str(),
                drivers::describe(config.source).c_str(), config.model.name.c_str(),
                config.model.chain.joint_count());
    return 0;
  }
  return std::nullopt;
}

// Lines the log output lost (dropped while it stalled, refused by it).
std::int64_t log_lines_lost(const LogOutput::Counts& c) {
  return c.dropped + c.failed + c.unwritten;
}

// Stops the log output (what is queued gets at most kLogDrain) and says what
// the log lost, when it lost any: in systemd's STATUS= and, if it takes it
// at once, on stderr.
void shut_down_logging(const Logging& logging) {
  const LogOutput::Counts c = logging.output->stop(kLogDrain);
  spdlog::shutdown();
  if (log_lines_lost(c) == 0) return;
  const std::string text = fmt::format(
      "log output: {} lines written, {} dropped while it stalled, {} refused by it, {} not "
      "written at exit",
      c.written, c.dropped, c.failed, c.unwritten);
  notify("STATUS=" + text);
  write_stderr("exodaqd: " + text + "\n", std::chrono::milliseconds(0));
}

// Why the daemon cannot start: to the log, systemd's STATUS= and stderr.
void report_start_failure(const std::string& what, const Logging& logging) {
  spdlog::critical("cannot start: {}{}", what, fields({{"EXODAQ_EVENT", "start_failed"}}));
  notify("STATUS=cannot start: " + messages::printable(what));
  shut_down_logging(logging);
  if (!logging.journal) write_stderr("exodaqd: cannot start: " + messages::printable(what) + "\n");
}

// The channel set claimed for this daemon alone (instance_guard.hpp), or null
// after reporting who else publishes on it.
std::unique_ptr<ChannelClaim> claim_channels(const ServiceConfig& config,
                                             const DaemonOptions& options, const Logging& logging) {
  try {
    auto claim = std::make_unique<ChannelClaim>(config, options.config_path);
    spdlog::info("channel set claimed: lock {}, nobody heard on the status channel for {} ms",
                 claim->lock_file(), claim->listened_ms());
    return claim;
  } catch (const std::exception& e) {
    report_start_failure(e.what(), logging);
    return nullptr;
  }
}

// The running acquisition, or null after reporting why it cannot start.
std::unique_ptr<Acquisition> start_acquisition(const ServiceConfig& config,
                                               const DaemonOptions& options, const Logging& logging,
                                               ChannelClaim& claim) {
  AcquisitionOptions acquisition;
  if (!options.lateness_log.empty()) {
    const double seconds = options.duration_s > 0 ? options.duration_s + 5.0 : 3600.0;
    acquisition.record_lateness_cycles = static_cast<std::int64_t>(seconds * config.loop.rate_hz);
  }
  try {
    auto acq = build_acquisition(config, std::move(acquisition));
    claim.attach(*acq);
    try {
      acq->start();
    } catch (...) {
      claim.detach();  // the listener holds `acq`
      throw;
    }
    return acq;
  } catch (const std::exception& e) {
    report_start_failure(e.what(), logging);
    return nullptr;
  }
}

void log_started(const ServiceConfig& config, std::int64_t run_id) {
  const std::string run = messages::run_id_text(run_id);
  spdlog::info(
      "exodaqd {} started: rig {}, source {}, {:.0f} Hz, config {} (sha256 {}), model {}, "
      "calibration {} (sha256 {}; {}), LCM {} prefix '{}', run id {}{}",
      exodaq::kVersion, config.rig, drivers::describe(config.source), config.loop.rate_hz,
      config.file, config.config_sha256, config.model_path, config.calibration_path,
      config.calibration_sha256, settings::provenance_text(config.calibration.provenance),
      config.lcm.url, config.lcm.prefix, run,
      fields({{"EXODAQ_EVENT", "started"},
              {"EXODAQ_RIG", config.rig},
              {"EXODAQ_RUN_ID", run},
              {"EXODAQ_CONFIG_SHA256", config.config_sha256},
              {"EXODAQ_CALIBRATION_SHA256", config.calibration_sha256},
              {"EXODAQ_VERSION", exodaq::kVersion}}));
}

// The main thread while the loop runs: signals, reloads, the loop's events,
// and systemd's READY=1, WATCHDOG=1 and STATUS=. Signals that arrived during
// start-up were held pending (take_over_signals()) and are taken here.
class Supervisor {
 public:
  // `started_ns`: when start-up began (--duration counts from there).
  // `config`: the configuration the acquisition started with.
  Supervisor(Acquisition& acq, ServiceConfig& config, const DaemonOptions& options,
             const sigset_t& signals, std::int64_t started_ns, const Logging& logging,
             OverrunReport& overruns);
  // Until SIGTERM/SIGINT, --duration or the end of the source.
  void run();

 private:
  void take_signal();
  void reload();
  struct Changes {
    std::vector<settings::SettingChange> live;     // against the last configuration accepted
    std::vector<settings::SettingChange> restart;  // against the one the loop started with
  };
  Changes changes_to(const ServiceConfig& next) const;
  void log_changes(const ServiceConfig& next, const Changes& changes) const;
  void log_realtime() const;
  void drain_events();
  void notify_systemd(std::int64_t now);
  void check_end(std::int64_t now);
  void watch_publishing(std::int64_t now);

  Acquisition& acq_;
  ServiceConfig& config_;  // the last configuration accepted
  // The one the loop started with: the restart-only settings in effect.
  const ServiceConfig started_;
  const DaemonOptions& options_;
  const sigset_t& signals_;
  const std::int64_t started_ns_;
  const Logging& logging_;
  OverrunReport& overruns_;
  std::int64_t log_lost_ = 0;  // lines the log output lost so far
  bool watchdog_ = false;
  std::int64_t watchdog_every_ns_ = 0;
  std::int64_t wait_ns_ = 20'000'000;
  std::int64_t last_ping_ns_ = mono_now_ns();
  std::int64_t cycles_at_last_ping_ = 0;
  std::int64_t last_status_ns_ = mono_now_ns();
  std::int64_t cycles_at_last_status_ = 0;
  double rate_hz_ = 0.0;
  ServiceState notified_state_ = ServiceState::kStarting;
  bool ready_ = false;
  bool realtime_logged_ = false;
  bool running_ = true;
  PublishWatch publish_watch_{config_.lcm.url};
};

Supervisor::Supervisor(Acquisition& acq, ServiceConfig& config, const DaemonOptions& options,
                       const sigset_t& signals, std::int64_t started_ns, const Logging& logging,
                       OverrunReport& overruns)
    : acq_(acq),
      config_(config),
      started_(config),
      options_(options),
      signals_(signals),
      started_ns_(started_ns),
      logging_(logging),
      overruns_(overruns) {
  // Watchdog (WatchdogSec= in the unit): ping at half the interval, and only
  // while cycles progress, so a stalled loop lets systemd's watchdog fire. A
  // loop that cycles without samples (state fault) still pings: restarting
  // would not bring the bus back, and the state says what is wrong.
  std::uint64_t watchdog_usec = 0;
  watchdog_ = sd_watchdog_enabled(0, &watchdog_usec) > 0 && watchdog_usec > 0;
  watchdog_every_ns_ = static_cast<std::int64_t>(watchdog_usec) * 1000 / 2;
  if (watchdog_) {
    spdlog::info("systemd watchdog: {} ms, pinging every {} ms while the loop cycles",
                 watchdog_usec / 1000, watchdog_every_ns_ / 1'000'000);
    // The main thread wakes at least 4 times per ping interval.
    wait_ns_ = std::clamp<std::int64_t>(watchdog_every_ns_ / 4, 1'000'000, 20'000'000);
  }
}

void Supervisor::run() {
  while (running_) {
    take_signal();
    drain_events();
    // The status channel says what the log lost (the log itself may be what stalls).
    log_lost_ = log_lines_lost(logging_.output->counts());
    acq_.set_log_lines_dropped(log_lost_);
    if (!realtime_logged_ && acq_.cycles() > 0) {
      log_realtime();
      realtime_logged_ = true;
    }
    const std::int64_t now = mono_now_ns();
    watch_publishing(now);
    notify_systemd(now);
    check_end(now);
  }
}

// A failing publish path is logged when it starts, at each re-creation of
// the socket and when it recovers (publish_watch.hpp).
void Supervisor::watch_publishing(std::int64_t now) {
  for (const PublishLogLine& line : publish_watch_.check(acq_.publisher().health(), now)) {
    const std::string f = fields({{"EXODAQ_EVENT", line.event},
                                  {"EXODAQ_STATE", state_name(acq_.state())},
                                  {"EXODAQ_ERRNO", std::to_string(line.error)},
                                  {"EXODAQ_RUN_ID", messages::run_id_text(acq_.run_id())}});
    if (line.warning) {
      spdlog::warn("{}{}", line.text, f);
    } else {
      spdlog::info("{}{}", line.text, f);
    }
  }
}

void Supervisor::take_signal() {
  timespec wait{0, static_cast<long>(wait_ns_)};
  siginfo_t info{};
  const int sig = sigtimedwait(&signals_, &info, &wait);
  if (sig <= 0) return;
  const std::string name = signal_name(sig);
  // kill(), sigqueue(), tgkill() name the sender; the kernel (a terminal's
  // Ctrl-Z, a resource limit) does not.
  const std::string from = info.si_code <= 0 ? "from pid " + std::to_string(info.si_pid)
                                             : std::string("from the kernel");
  if (is_one_of(sig, std::begin(kStopSignals), std::end(kStopSignals))) {
    spdlog::info("{} received: stopping", name);
    running_ = false;
  } else if (sig == SIGHUP) {
    reload();
  } else if (is_one_of(sig, std::begin(kJobControlSignals), std::end(kJobControlSignals))) {
    spdlog::warn(
        "{} received {}: not stopping (a stopped loop loses samples; SIGTERM, SIGINT or SIGQUIT "
        "stop exodaqd){}",
        name, from, fields({{"EXODAQ_EVENT", "stop_refused"}, {"EXODAQ_SIGNAL", name}}));
  } else {
    spdlog::warn("{} received {}: ignored (SIGTERM, SIGINT or SIGQUIT stop; SIGHUP reloads){}",
                 name, from, fields({{"EXODAQ_EVENT", "signal_ignored"}, {"EXODAQ_SIGNAL", name}}));
  }
}

// What the loop thread was granted: a refusal (no CAP_SYS_NICE, RLIMIT_MEMLOCK)
// is a warning, so `journalctl -p warning` shows a loop without real-time guarantees.
void Supervisor::log_realtime() const {
  if (acq_.realtime_refused()) {
    spdlog::warn("loop thread: {}{}", acq_.realtime_report(),
                 fields({{"EXODAQ_EVENT", "realtime_refused"}}));
  } else {
    spdlog::info("loop thread: {}", acq_.realtime_report());
  }
}

// A reload applies the live settings at a cycle boundary. One that changes
// the calibration or model starts a new segment; one that leaves restart-only
// settings unapplied takes the file's hash out of the status: no file
// describes the configuration in effect until a restart.
void Supervisor::reload() {
  notify("RELOADING=1\nSTATUS=reloading " + options_.config_path);
  try {
    ServiceConfig next = load_service_config(options_.config_path);
    const Changes changes = changes_to(next);
    std::unique_ptr<PipelineConfig> pipeline = make_pipeline_config(next);
    pipeline->new_segment = settings::starts_new_segment(changes.live);
    pipeline->files.restart_pending = !changes.restart.empty();
    if (pipeline->files.restart_pending) pipeline->files.config_sha256.clear();
    acq_.stage_reload(std::move(pipeline), next.clock);
    if (const std::string level = configured_level(options_, next); !level.empty())
      spdlog::set_level(spdlog::level::from_str(level));
    log_changes(next, changes);
    config_ = std::move(next);
  } catch (const std::exception& e) {
    spdlog::error("reload rejected, previous configuration stays: {}{}", e.what(),
                  fields({{"EXODAQ_EVENT", "reload_rejected"}}));
  }
  notify("READY=1\n" + status_line(acq_, rate_hz_, config_.clock.require_sync, log_lost_));
}

Supervisor::Changes Supervisor::changes_to(const ServiceConfig& next) const {
  Changes out;
  for (auto& c : settings::compare_settings(config_, next)) {
    if (c.apply == settings::Apply::kLive) out.live.push_back(std::move(c));
  }
  for (auto& c : settings::compare_settings(started_, next)) {
    if (c.apply == settings::Apply::kRestart) out.restart.push_back(std::move(c));
  }
  return out;
}

// Every reload says what it changed: the live settings against the last
// configuration accepted (info), and, on every SIGHUP that carries one, each
// restart-only setting whose value differs from the one running (warning).
void Supervisor::log_changes(const ServiceConfig& next, const Changes& changes) const {
  const auto& live = changes.live;
  const auto& restart = changes.restart;
  if (!restart.empty()) {
    spdlog::warn(
        "reload: {} restart-only setting(s) changed, NOT applied until exodaqd restarts: {}; "
        "status_t.config_sha256 is empty until then (no file describes the settings in effect){}",
        restart.size(), settings::describe_changes(restart),
        fields({{"EXODAQ_EVENT", "reload_needs_restart"}}));
  }
  spdlog::info("reload: {} (sha256 {}) accepted, calibration {} (sha256 {}); {} live change(s){}{}",
               next.file, next.config_sha256, next.calibration_path, next.calibration_sha256,
               live.size(), live.empty() ? "" : ": " + settings::describe_changes(live),
               fields({{"EXODAQ_EVENT", "reload_accepted"},
                       {"EXODAQ_CONFIG_SHA256", next.config_sha256},
                       {"EXODAQ_CALIBRATION_SHA256", next.calibration_sha256}}));
  if (settings::starts_new_segment(live)) {
    spdlog::info(
        "reload: the calibration or model changed: the first sample with it starts a new segment "
        "(SAMPLE_NEW_SEGMENT){}",
        fields({{"EXODAQ_EVENT", "reload_new_segment"}}));
  }
  if (configured_level(options_, next).empty() && next.logging.level != config_.logging.level) {
    spdlog::info("reload: logging.level {} not applied: --log-level or SPDLOG_LEVEL sets the level",
                 next.logging.level);
  }
}

void Supervisor::drain_events() {
  LogEvent event;
  while (acq_.pop_event(event))
    log_event(event, acq_.config(), acq_.run_id(), acq_.state(), overruns_);
  if (const auto line = overruns_.due(mono_now_ns()))
    log_overruns(*line, acq_.state(), acq_.run_id());
}

void Supervisor::notify_systemd(std::int64_t now) {
  const std::int64_t cycles = acq_.cycles();
  if (!ready_ && cycles > 0) {
    // The first complete cycle: published, so clients can subscribe now.
    notify("READY=1\n" + status_line(acq_, rate_hz_, config_.clock.require_sync, log_lost_));
    notified_state_ = acq_.state();
    ready_ = true;
  }
  if (watchdog_ && now - last_ping_ns_ >= watchdog_every_ns_) {
    if (cycles > cycles_at_last_ping_) {
      notify("WATCHDOG=1");
      cycles_at_last_ping_ = cycles;
    }
    last_ping_ns_ = now;
  }
  const bool second = now - last_status_ns_ >= 1'000'000'000;
  if (second) {
    rate_hz_ = static_cast<double>(cycles - cycles_at_last_status_) * 1e9 /
               static_cast<double>(now - last_status_ns_);
    last_status_ns_ = now;
    cycles_at_last_status_ = cycles;
  }
  // STATUS=: once a second, and at once when the state changes.
  if (ready_ && (second || acq_.state() != notified_state_)) {
    notified_state_ = acq_.state();
    notify(status_line(acq_, rate_hz_, config_.clock.require_sync, log_lost_));
  }
}

void Supervisor::check_end(std::int64_t now) {
  if (options_.duration_s > 0 &&
      now - started_ns_ >= static_cast<std::int64_t>(options_.duration_s * 1e9)) {
    spdlog::info("--duration {} s reached: stopping", options_.duration_s);
    running_ = false;
  }
  if (acq_.finished()) {
    spdlog::info("source finished");
    running_ = false;
  }
}

void write_lateness_log(const Acquisition& acq, const std::string& path) {
  if (std::FILE* f = std::fopen(path.c_str(), "w")) {
    for (const std::int32_t v : acq.lateness_record()) std::fprintf(f, "%d\n", v);
    std::fclose(f);
  } else {
    spdlog::error("cannot write {}", path);
  }
}

// The source's own state and its counters that are not zero, as the final
// source_status_t carried them: "source socketcan (can0 open): sync_sent=5000 ...".
void log_source_diagnostics(const Acquisition& acq) {
  const drivers::SourceDiagnostics& d = acq.source_diagnostics();
  std::string counters;
  for (const drivers::SourceCounter& c : d.counters()) {
    if (c.value == 0) continue;
    counters += fmt::format(" {}={}", c.name, c.value);
  }
  spdlog::info("source {} ({}):{}", acq.source_name(), d.state(),
               counters.empty() ? std::string(" no counter above zero") : counters);
}

// Stops the loop (its final status published), logs what is left (the
// overruns not yet reported too), exits the logger.
void shut_down(Acquisition& acq, const DaemonOptions& options, const Logging& logging,
               OverrunReport& overruns) {
  notify("STOPPING=1\nSTATUS=stopping");
  acq.stop();
  LogEvent event;
  while (acq.pop_event(event)) log_event(event, acq.config(), acq.run_id(), acq.state(), overruns);
  if (const auto line = overruns.due(mono_now_ns(), true))
    log_overruns(*line, acq.state(), acq.run_id());
  if (acq.events_dropped() > 0) {
    spdlog::warn("{} loop events were not logged: the event ring was full", acq.events_dropped());
  }
  if (!options.lateness_log.empty()) write_lateness_log(acq, options.lateness_log);
  log_source_diagnostics(acq);
  const auto source = acq.source_counters();  // as of the final status window
  spdlog::info(
      "stopped after {} cycles ({} overruns, {} publish failures, {} messages published; {} "
      "samples late, {} caught up after a late wake, {} superseded, {} late SYNCs; {} wakes "
      "left a backlog to the next){}",
      acq.cycles(), acq.overruns(), acq.publisher().failures() + acq.publisher().ring_drops(),
      acq.publisher().published(), acq.late_samples(), acq.caught_up_samples(),
      source.superseded_samples, source.late_syncs, acq.backlog_wakes(),
      fields(
          {{"EXODAQ_EVENT", "stopped"}, {"EXODAQ_RUN_ID", messages::run_id_text(acq.run_id())}}));
  shut_down_logging(logging);
}

}  // namespace

void take_over_signals() {
  signal(SIGPIPE, SIG_IGN);  // a closed log pipe is EPIPE on write, not the end of the run
  const sigset_t signals = daemon_signals();
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);
}

int run_daemon(const DaemonOptions& options) {
  take_over_signals();  // before the configuration: it may take seconds to read
  const sigset_t signals = daemon_signals();
  ServiceConfig config;
  if (const auto exit_code = load_config(options, config)) return *exit_code;
  const Logging logging = make_logger(config.logging, options.log_level, config.rig);
  const std::int64_t started_ns = mono_now_ns();
  const std::unique_ptr<ChannelClaim> claim = claim_channels(config, options, logging);
  if (!claim) return 1;
  const std::unique_ptr<Acquisition> acq = start_acquisition(config, options, logging, *claim);
  if (!acq) return 1;
  log_started(config, acq->run_id());
  OverrunReport overruns;
  Supervisor(*acq, config, options, signals, started_ns, logging, overruns).run();
  claim->detach();
  shut_down(*acq, options, logging, overruns);
  return 0;
}

}  // namespace exodaq::daemon
