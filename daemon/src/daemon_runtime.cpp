#include "exodaq/daemon/daemon_runtime.hpp"

#include <signal.h>
#include <spdlog/async.h>
#include <spdlog/cfg/env.h>
#include <spdlog/sinks/base_sink.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <syslog.h>
#include <systemd/sd-daemon.h>
#include <systemd/sd-journal.h>
#include <time.h>

#include <algorithm>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <mutex>
#include <optional>
#include <string_view>
#include <vector>

#include "exodaq/common/clock_now.hpp"
#include "exodaq/config/service_config.hpp"
#include "exodaq/config/setting_classes.hpp"
#include "exodaq/config/yaml_reader.hpp"
#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/builder.hpp"
#include "exodaq/daemon/instance_guard.hpp"
#include "exodaq/drivers/backend.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/version.hpp"
#include "publish_watch.hpp"

namespace exodaq::daemon {

using namespace core;  // NOLINT(google-build-using-namespace): the daemon wires the core
using config::load_service_config;
using config::LoggingSettings;
using config::ServiceConfig;
using config::to_yaml;

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

// The native journal protocol, with the fields carried in the payload
// (EXODAQ_STATE, EXODAQ_JOINT, EXODAQ_EVENT, EXODAQ_SEQ, EXODAQ_RUN_ID ...), so
// `journalctl -u exodaqd EXODAQ_JOINT=elbow` finds one joint's events. Every
// entry names the rig (EXODAQ_RIG: `journalctl EXODAQ_RIG=rig-b`).
class JournalFieldSink final : public spdlog::sinks::base_sink<std::mutex> {
 public:
  explicit JournalFieldSink(const std::string& rig) : rig_field_("EXODAQ_RIG=" + rig) {}

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    const std::string_view payload(msg.payload.data(), msg.payload.size());
    std::vector<std::string> items;
    std::size_t cut = payload.find(kFieldSep);
    items.push_back("MESSAGE=" + std::string(payload.substr(0, cut)));
    items.push_back("PRIORITY=" + std::to_string(syslog_priority(msg.level)));
    items.emplace_back("SYSLOG_IDENTIFIER=exodaqd");
    items.push_back(rig_field_);
    while (cut != std::string_view::npos) {
      const std::size_t next = payload.find(kFieldSep, cut + 1);
      const auto field = payload.substr(
          cut + 1, next == std::string_view::npos ? std::string_view::npos : next - cut - 1);
      if (!field.empty()) items.emplace_back(field);
      cut = next;
    }
    std::vector<iovec> iov(items.size());
    for (std::size_t i = 0; i < items.size(); ++i) {
      iov[i].iov_base = items[i].data();
      iov[i].iov_len = items[i].size();
    }
    // (parenthesised: the macro would add this line as CODE_FILE/CODE_LINE)
    if ((sd_journal_sendv)(iov.data(), static_cast<int>(iov.size())) < 0) {
      // No journald (a container, an early boot): the text still goes somewhere.
      std::fprintf(stderr, "exodaqd: %s\n", items[0].c_str() + 8);
    }
  }
  void flush_() override {}

 private:
  std::string rig_field_;
};

// stderr, without the structured fields.
class StderrSink final : public spdlog::sinks::base_sink<std::mutex> {
 public:
  StderrSink() : inner_(std::make_shared<spdlog::sinks::stderr_color_sink_st>()) {}
  void set_inner_pattern(const std::string& pattern) { inner_->set_pattern(pattern); }

 protected:
  void sink_it_(const spdlog::details::log_msg& msg) override {
    spdlog::details::log_msg copy = msg;
    const std::string_view payload(msg.payload.data(), msg.payload.size());
    const std::size_t cut = payload.find(kFieldSep);
    if (cut != std::string_view::npos)
      copy.payload = spdlog::string_view_t(msg.payload.data(), cut);
    inner_->log(copy);
  }
  void flush_() override { inner_->flush(); }

 private:
  std::shared_ptr<spdlog::sinks::stderr_color_sink_st> inner_;
};

struct Logging {
  std::shared_ptr<spdlog::logger> logger;
  bool journal = false;
};

// spdlog, asynchronous: the loop thread never logs, and the main thread's
// logging never waits on the journal or a terminal. Level: the config, then
// SPDLOG_LEVEL, then --log-level. Every line names the rig (several daemons
// may share a host and a terminal).
Logging make_logger(const LoggingSettings& settings, const std::string& level_override,
                    const std::string& rig) {
  spdlog::init_thread_pool(8192, 1);
  Logging out;
  out.journal = settings.sink == "journal" || (settings.sink == "auto" && stderr_is_journal());
  spdlog::sink_ptr sink;
  if (out.journal) {
    sink = std::make_shared<JournalFieldSink>(rig);
  } else {
    auto err = std::make_shared<StderrSink>();
    std::string rig_text;  // literal in the pattern: '%' doubled
    for (const char c : rig) rig_text += c == '%' ? std::string("%%") : std::string(1, c);
    err->set_inner_pattern("%Y-%m-%d %H:%M:%S.%e [" + rig_text + "] %^%l%$ %v");
    sink = err;
  }
  out.logger = std::make_shared<spdlog::async_logger>(
      "exodaqd", sink, spdlog::thread_pool(), spdlog::async_overflow_policy::overrun_oldest);
  spdlog::set_default_logger(out.logger);
  spdlog::set_level(spdlog::level::from_str(settings.level));
  spdlog::cfg::load_env_levels();  // SPDLOG_LEVEL overrides the file
  if (!level_override.empty()) spdlog::set_level(spdlog::level::from_str(level_override));
  spdlog::flush_every(std::chrono::seconds(1));
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

// One loop event, logged on the main thread with its journal fields.
// `state`: the service state when the event was drained.
void log_event(const LogEvent& e, const AcquisitionConfig& ac, std::int64_t run_id,
               ServiceState state) {
  const std::string seq = std::to_string(e.seq);
  const std::string run = msg::run_id_text(run_id);
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
      spdlog::warn("loop overrun at seq {}: cycle took {:.1f} us, {} deadline(s) skipped{}", e.seq,
                   e.value, e.count,
                   fields({{"EXODAQ_EVENT", "overrun"},
                           {"EXODAQ_STATE", state_name(state)},
                           {"EXODAQ_SEQ", seq},
                           {"EXODAQ_RUN_ID", run}}));
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
      const std::string f = fields({{"EXODAQ_EVENT", "state"},
                                    {"EXODAQ_STATE", state_name(e.state)},
                                    {"EXODAQ_SEQ", seq},
                                    {"EXODAQ_RUN_ID", run}});
      if (e.state == ServiceState::kFault || e.state == ServiceState::kDegraded) {
        spdlog::warn("service state: {} (seq {}){}", state_name(e.state), e.seq, f);
      } else {
        spdlog::info("service state: {} (seq {}){}", state_name(e.state), e.seq, f);
      }
      break;
    }
    case LogEvent::Kind::kReloadApplied:
      spdlog::info(
          "new configuration in effect from seq {}{}", e.seq,
          fields({{"EXODAQ_EVENT", "reload"}, {"EXODAQ_SEQ", seq}, {"EXODAQ_RUN_ID", run}}));
      break;
    case LogEvent::Kind::kEndOfStream:
      spdlog::info("source ended at seq {}", e.seq);
      break;
  }
}

const char* bus_state_text(drivers::BusState s) {
  switch (s) {
    case drivers::BusState::kUnknown:
      return "";
    case drivers::BusState::kActive:
      return ", bus active";
    case drivers::BusState::kWarning:
      return ", bus warning";
    case drivers::BusState::kPassive:
      return ", bus passive";
    case drivers::BusState::kOff:
      return ", BUS-OFF";
    case drivers::BusState::kDown:
      return ", interface down";
  }
  return "";
}

// STATUS= for systemctl status: state, loop rate, drops, clock health.
std::string status_line(Acquisition& acq, double rate_hz) {
  const auto stats = acq.source_counters();
  const ClockShared& clock = acq.clock_shared();
  const char* clock_text = !clock.health_valid.load()  ? "clock health unknown"
                           : clock.synchronised.load() ? "clock synchronised"
                                                       : "clock UNSYNCHRONISED";
  const PublishHealth publish = acq.publisher().health();
  char text[320];
  std::snprintf(text, sizeof(text),
                "STATUS=%s, %.1f Hz, cycle %" PRId64 "; drops: %" PRId64
                " missing samples, %" PRId64 " seq gaps, %" PRId64 " overruns, %" PRId64
                " publish failures; %" PRId64 " bus errors%s; %s",
                state_name(acq.state()), rate_hz, acq.cycles(), stats.missing_samples,
                stats.seq_gaps, acq.overruns(), publish.failures + publish.ring_drops,
                stats.bus_errors, bus_state_text(stats.bus_state), clock_text);
  return text + PublishWatch::status_text(publish);
}

void notify(const std::string& text) {
  sd_notify(0, text.c_str());
}

// Signals that mean nothing to the daemon but end a process by default:
// taken and logged, never fatal.
constexpr int kIgnoredSignals[] = {SIGUSR1, SIGUSR2, SIGALRM, SIGVTALRM, SIGPOLL, SIGPWR};

const char* signal_name(int sig) {
  switch (sig) {
    case SIGTERM:
      return "SIGTERM";
    case SIGINT:
      return "SIGINT";
    case SIGHUP:
      return "SIGHUP";
    case SIGUSR1:
      return "SIGUSR1";
    case SIGUSR2:
      return "SIGUSR2";
    case SIGALRM:
      return "SIGALRM";
    case SIGVTALRM:
      return "SIGVTALRM";
    case SIGPOLL:
      return "SIGPOLL";
    case SIGPWR:
      return "SIGPWR";
    default:
      return "signal";
  }
}

// The signals the supervisor takes with sigtimedwait().
sigset_t daemon_signals() {
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGHUP);
  for (const int sig : kIgnoredSignals) sigaddset(&signals, sig);
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
  } catch (const config::ConfigError& e) {
    std::fprintf(stderr, "exodaqd: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "exodaqd: %s: %s\n", options.config_path.c_str(), e.what());
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

void shut_down_logging(const Logging& logging) {
  logging.logger->flush();
  spdlog::shutdown();
}

// Why the daemon cannot start: to the log, systemd's STATUS= and stderr.
void report_start_failure(const std::string& what, const Logging& logging) {
  spdlog::critical("cannot start: {}{}", what, fields({{"EXODAQ_EVENT", "start_failed"}}));
  notify("STATUS=cannot start: " + what);
  shut_down_logging(logging);
  if (!logging.journal) std::fprintf(stderr, "exodaqd: cannot start: %s\n", what.c_str());
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
  const std::string run = msg::run_id_text(run_id);
  spdlog::info(
      "exodaqd {} started: rig {}, source {}, {:.0f} Hz, config {} (sha256 {}), model {}, "
      "calibration {} (sha256 {}; {}), LCM {} prefix '{}', run id {}{}",
      exodaq::kVersion, config.rig, drivers::describe(config.source), config.loop.rate_hz,
      config.file, config.config_sha256, config.model_path, config.calibration_path,
      config.calibration_sha256, config::provenance_text(config.calibration.provenance),
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
             const sigset_t& signals, std::int64_t started_ns);
  // Until SIGTERM/SIGINT, --duration or the end of the source.
  void run();

 private:
  void take_signal();
  void reload();
  void log_changes(const ServiceConfig& next) const;
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
                       const sigset_t& signals, std::int64_t started_ns)
    : acq_(acq),
      config_(config),
      started_(config),
      options_(options),
      signals_(signals),
      started_ns_(started_ns) {
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
                                  {"EXODAQ_RUN_ID", msg::run_id_text(acq_.run_id())}});
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
  if (sig == SIGTERM || sig == SIGINT) {
    spdlog::info("{} received: stopping", signal_name(sig));
    running_ = false;
  } else if (sig == SIGHUP) {
    reload();
  } else if (sig > 0) {
    spdlog::warn("{} received from pid {}: ignored (SIGTERM or SIGINT stop, SIGHUP reloads){}",
                 signal_name(sig), info.si_pid,
                 fields({{"EXODAQ_EVENT", "signal_ignored"}, {"EXODAQ_SIGNAL", signal_name(sig)}}));
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

void Supervisor::reload() {
  notify("RELOADING=1\nSTATUS=reloading " + options_.config_path);
  try {
    ServiceConfig next = load_service_config(options_.config_path);
    acq_.stage_reload(make_pipeline_config(next), next.clock);
    if (const std::string level = configured_level(options_, next); !level.empty())
      spdlog::set_level(spdlog::level::from_str(level));
    log_changes(next);
    config_ = std::move(next);
  } catch (const std::exception& e) {
    spdlog::error("reload rejected, previous configuration stays: {}{}", e.what(),
                  fields({{"EXODAQ_EVENT", "reload_rejected"}}));
  }
  notify("READY=1\n" + status_line(acq_, rate_hz_));
}

// Every reload says what it changed: the live settings against the last
// configuration accepted (info), and, on every SIGHUP that carries one, each
// restart-only setting whose value differs from the one running (warning).
void Supervisor::log_changes(const ServiceConfig& next) const {
  std::vector<config::SettingChange> live;
  for (auto& c : config::compare_settings(config_, next)) {
    if (c.apply == config::Apply::kLive) live.push_back(std::move(c));
  }
  std::vector<config::SettingChange> restart;
  for (auto& c : config::compare_settings(started_, next)) {
    if (c.apply == config::Apply::kRestart) restart.push_back(std::move(c));
  }
  if (!restart.empty()) {
    spdlog::warn(
        "reload: {} restart-only setting(s) changed, NOT applied until exodaqd restarts: {}{}",
        restart.size(), config::describe_changes(restart),
        fields({{"EXODAQ_EVENT", "reload_needs_restart"}}));
  }
  spdlog::info("reload: {} (sha256 {}) accepted, calibration {} (sha256 {}); {} live change(s){}{}",
               next.file, next.config_sha256, next.calibration_path, next.calibration_sha256,
               live.size(), live.empty() ? "" : ": " + config::describe_changes(live),
               fields({{"EXODAQ_EVENT", "reload_accepted"},
                       {"EXODAQ_CONFIG_SHA256", next.config_sha256},
                       {"EXODAQ_CALIBRATION_SHA256", next.calibration_sha256}}));
  if (configured_level(options_, next).empty() && next.logging.level != config_.logging.level) {
    spdlog::info("reload: logging.level {} not applied: --log-level or SPDLOG_LEVEL sets the level",
                 next.logging.level);
  }
}

void Supervisor::drain_events() {
  LogEvent event;
  while (acq_.pop_event(event)) log_event(event, acq_.config(), acq_.run_id(), acq_.state());
}

void Supervisor::notify_systemd(std::int64_t now) {
  const std::int64_t cycles = acq_.cycles();
  if (!ready_ && cycles > 0) {
    // The first complete cycle: published, so clients can subscribe now.
    notify("READY=1\n" + status_line(acq_, rate_hz_));
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
    notify(status_line(acq_, rate_hz_));
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

// Stops the loop (its final status published), logs what is left, exits the logger.
void shut_down(Acquisition& acq, const DaemonOptions& options, const Logging& logging) {
  notify("STOPPING=1\nSTATUS=stopping");
  acq.stop();
  LogEvent event;
  while (acq.pop_event(event)) log_event(event, acq.config(), acq.run_id(), acq.state());
  if (acq.events_dropped() > 0) {
    spdlog::warn("{} loop events were not logged: the event ring was full", acq.events_dropped());
  }
  if (!options.lateness_log.empty()) write_lateness_log(acq, options.lateness_log);
  const auto source = acq.source_counters();  // as of the final status window
  spdlog::info(
      "stopped after {} cycles ({} overruns, {} publish failures, {} messages published; {} "
      "samples late, {} caught up after a late wake, {} superseded, {} late SYNCs){}",
      acq.cycles(), acq.overruns(), acq.publisher().failures() + acq.publisher().ring_drops(),
      acq.publisher().published(), acq.late_samples(), acq.caught_up_samples(),
      source.superseded_samples, source.late_syncs,
      fields({{"EXODAQ_EVENT", "stopped"}, {"EXODAQ_RUN_ID", msg::run_id_text(acq.run_id())}}));
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
  Supervisor(*acq, config, options, signals, started_ns).run();
  claim->detach();
  shut_down(*acq, options, logging);
  return 0;
}

}  // namespace exodaq::daemon
