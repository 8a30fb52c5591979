#include "exodaq/core/daemon_runtime.hpp"

#include <signal.h>
#include <spdlog/async.h>
#include <spdlog/cfg/env.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/sinks/systemd_sink.h>
#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>
#include <time.h>

#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <iostream>

#include "exodaq/config/yaml_reader.hpp"
#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/service_config.hpp"
#include "exodaq/drivers/source_factory.hpp"
#include "exodaq/version.hpp"

namespace exodaq::core {

namespace {

std::int64_t mono_now() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

bool under_systemd() {
  return std::getenv("JOURNAL_STREAM") != nullptr || std::getenv("INVOCATION_ID") != nullptr ||
         std::getenv("NOTIFY_SOCKET") != nullptr;
}

// spdlog, asynchronous: the loop thread never logs, and the main thread's
// logging never waits on the journal or a terminal.
std::shared_ptr<spdlog::logger> make_logger(const LoggingSettings& settings,
                                            const std::string& level_override) {
  spdlog::init_thread_pool(8192, 1);
  spdlog::sink_ptr sink;
  const bool journal = settings.sink == "journal" || (settings.sink == "auto" && under_systemd());
  if (journal) {
    sink = std::make_shared<spdlog::sinks::systemd_sink_mt>("exodaqd");
  } else {
    sink = std::make_shared<spdlog::sinks::stderr_color_sink_mt>();
  }
  auto logger = std::make_shared<spdlog::async_logger>(
      "exodaqd", sink, spdlog::thread_pool(), spdlog::async_overflow_policy::overrun_oldest);
  logger->set_pattern(journal ? "%v" : "%Y-%m-%d %H:%M:%S.%e %^%l%$ %v");
  spdlog::set_default_logger(logger);
  spdlog::set_level(spdlog::level::from_str(settings.level));
  spdlog::cfg::load_env_levels();  // SPDLOG_LEVEL overrides the file
  if (!level_override.empty()) spdlog::set_level(spdlog::level::from_str(level_override));
  spdlog::flush_every(std::chrono::seconds(1));
  return logger;
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

void log_event(const LogEvent& e, const AcquisitionConfig& ac) {
  switch (e.kind) {
    case LogEvent::Kind::kJoint: {
      const auto& name = ac.joint_names[static_cast<std::size_t>(e.joint)];
      const double deg = e.value * 57.29577951308232;
      if (e.joint_event == JointEvent::kHomed) {
        spdlog::info("joint {} {} (seq {}, angle {:.3f} deg)", name,
                     joint_event_text(e.joint_event), e.seq, deg);
      } else if (e.joint_event == JointEvent::kLostCounts) {
        spdlog::warn("joint {} {} (seq {}, drift {} counts)", name, joint_event_text(e.joint_event),
                     e.seq, e.count);
      } else {
        spdlog::warn("joint {} {} (seq {}, angle {:.3f} deg)", name,
                     joint_event_text(e.joint_event), e.seq, deg);
      }
      break;
    }
    case LogEvent::Kind::kOverrun:
      spdlog::warn("loop overrun at seq {}: cycle took {:.1f} us, {} deadline(s) skipped", e.seq,
                   e.value, e.count);
      break;
    case LogEvent::Kind::kClockStep:
      spdlog::warn(
          "wall clock stepped (step #{} at seq {}): utime is slewed by {:.3f} ms, samples flagged "
          "CLOCK_STEP meanwhile",
          e.count, e.seq, e.value);
      break;
    case LogEvent::Kind::kStateChange:
      spdlog::info("service state: {} (seq {})", state_name(e.state), e.seq);
      break;
    case LogEvent::Kind::kReloadApplied:
      spdlog::info("new configuration in effect from seq {}", e.seq);
      break;
    case LogEvent::Kind::kEndOfStream:
      spdlog::info("source ended at seq {}", e.seq);
      break;
  }
}

AcquisitionConfig make_acquisition_config(const ServiceConfig& c) {
  AcquisitionConfig a;
  a.rig = c.rig;
  a.period_ns = static_cast<std::int64_t>(1e9 / c.loop.rate_hz);
  a.cpu = c.loop.cpu;
  a.priority = c.loop.priority;
  a.lock_memory = c.loop.lock_memory;
  a.fault_after_ms = c.loop.fault_after_ms;
  a.status_every_cycles =
      std::max(1, static_cast<int>(c.loop.rate_hz / c.loop.status_rate_hz + 0.5));
  a.publish_raw = c.lcm.publish_raw;
  a.clock = c.clock;
  const auto& joints = c.model.chain.joints();
  for (int i = 0; i < kJointCount; ++i)
    a.joint_names[static_cast<std::size_t>(i)] = joints[static_cast<std::size_t>(i)].name;
  a.replay = c.source.backend == drivers::SourceBackend::kReplay;
  a.replay_speed = c.source.replay_speed;
  return a;
}

// Settings a reload cannot change without a restart.
std::string restart_only_changes(const ServiceConfig& a, const ServiceConfig& b) {
  std::string out;
  const auto note = [&out](bool changed, const char* what) {
    if (changed) out += (out.empty() ? "" : ", ") + std::string(what);
  };
  note(a.loop.rate_hz != b.loop.rate_hz || a.loop.cpu != b.loop.cpu ||
           a.loop.priority != b.loop.priority,
       "loop");
  note(drivers::describe(a.source) != drivers::describe(b.source), "source");
  note(a.lcm.url != b.lcm.url || a.lcm.prefix != b.lcm.prefix, "lcm");
  note(a.rig != b.rig, "rig");
  return out;
}

void notify(const std::string& text) {
  sd_notify(0, text.c_str());
}

}  // namespace

int run_daemon(const DaemonOptions& options) {
  ServiceConfig config;
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

  // Every thread created from here on inherits the blocked set: signals are
  // taken synchronously by the main thread only.
  sigset_t signals;
  sigemptyset(&signals);
  sigaddset(&signals, SIGTERM);
  sigaddset(&signals, SIGINT);
  sigaddset(&signals, SIGHUP);
  pthread_sigmask(SIG_BLOCK, &signals, nullptr);

  auto logger = make_logger(config.logging, options.log_level);
  AcquisitionConfig acq_config = make_acquisition_config(config);
  if (!options.lateness_log.empty()) {
    const double seconds = options.duration_s > 0 ? options.duration_s + 5.0 : 3600.0;
    acq_config.record_lateness_cycles = static_cast<std::int64_t>(seconds * config.loop.rate_hz);
  }
  const std::int64_t started_ns = mono_now();
  std::unique_ptr<Acquisition> acq;
  try {
    const drivers::SourceContext ctx = make_source_context(config);
    acq = std::make_unique<Acquisition>(acq_config, make_pipeline_config(config),
                                        drivers::make_source(config.source, ctx),
                                        make_lcm_sink(config.lcm.url), config.lcm.prefix, nullptr);
    acq->start();
  } catch (const std::exception& e) {
    spdlog::critical("cannot start: {}", e.what());
    notify("STATUS=cannot start: " + std::string(e.what()));
    logger->flush();
    spdlog::shutdown();
    std::fprintf(stderr, "exodaqd: cannot start: %s\n", e.what());
    return 1;
  }
  spdlog::info(
      "exodaqd {} started: rig {}, source {}, {:.0f} Hz, model {}, calibration {}, LCM {} prefix "
      "'{}', run id {}",
      exodaq::kVersion, config.rig, drivers::describe(config.source), config.loop.rate_hz,
      config.model_path, config.calibration_path, config.lcm.url, config.lcm.prefix, acq->run_id());

  // Watchdog: ping at half the interval, and only while cycles progress, so a
  // stalled loop lets systemd's watchdog fire.
  std::uint64_t watchdog_usec = 0;
  const bool watchdog = sd_watchdog_enabled(0, &watchdog_usec) > 0 && watchdog_usec > 0;
  const std::int64_t watchdog_every_ns = static_cast<std::int64_t>(watchdog_usec) * 1000 / 2;
  std::int64_t last_ping_ns = mono_now();
  std::int64_t cycles_at_last_ping = 0;
  std::int64_t last_status_ns = mono_now();
  std::int64_t cycles_at_last_status = 0;
  bool ready = false;
  bool realtime_logged = false;
  const char* stall_env = std::getenv("EXODAQ_TEST_STALL_AFTER_CYCLES");
  const std::int64_t stall_after = stall_env != nullptr ? std::atoll(stall_env) : -1;

  int exit_code = 0;
  bool running = true;
  while (running) {
    timespec wait{0, 20'000'000};
    siginfo_t info{};
    const int sig = sigtimedwait(&signals, &info, &wait);
    if (sig == SIGTERM || sig == SIGINT) {
      spdlog::info("{} received: stopping", sig == SIGTERM ? "SIGTERM" : "SIGINT");
      running = false;
    } else if (sig == SIGHUP) {
      try {
        ServiceConfig next = load_service_config(options.config_path);
        const std::string fixed = restart_only_changes(config, next);
        if (!fixed.empty())
          spdlog::warn("reload: changes to {} take effect only after a restart", fixed);
        acq->stage_reload(make_pipeline_config(next), next.clock);
        spdlog::info("reload: {} and {} accepted", next.calibration_path, next.model_path);
        config = std::move(next);
      } catch (const std::exception& e) {
        spdlog::error("reload rejected, previous configuration stays: {}", e.what());
      }
    }
    LogEvent event;
    while (acq->pop_event(event)) log_event(event, acq_config);
    if (!realtime_logged && acq->cycles() > 0) {
      spdlog::info("loop thread: {}", acq->realtime_report());
      realtime_logged = true;
    }

    const std::int64_t cycles = acq->cycles();
    const std::int64_t now = mono_now();
    if (!ready && cycles > 0) {
      notify("READY=1\nSTATUS=homing");
      ready = true;
    }
    if (stall_after >= 0 && cycles >= stall_after) acq->set_stall_for_test(true);
    if (watchdog && now - last_ping_ns >= watchdog_every_ns) {
      if (cycles > cycles_at_last_ping) {
        notify("WATCHDOG=1");
        cycles_at_last_ping = cycles;
      }
      last_ping_ns = now;
    }
    if (now - last_status_ns >= 1'000'000'000) {
      const double rate = static_cast<double>(cycles - cycles_at_last_status) * 1e9 /
                          static_cast<double>(now - last_status_ns);
      const auto stats = acq->source().stats();
      char text[256];
      std::snprintf(text, sizeof(text),
                    "STATUS=%s, %.1f Hz, %" PRId64 " missing samples, %" PRId64
                    " overruns, clock %s",
                    state_name(acq->state()), rate, stats.missing_samples, acq->overruns(),
                    acq->clock_shared().synchronised.load() ? "synchronised" : "unsynchronised");
      notify(text);
      last_status_ns = now;
      cycles_at_last_status = cycles;
    }
    if (options.duration_s > 0 &&
        now - started_ns >= static_cast<std::int64_t>(options.duration_s * 1e9)) {
      spdlog::info("--duration {} s reached: stopping", options.duration_s);
      running = false;
    }
    if (acq->finished()) {
      spdlog::info("source finished");
      running = false;
    }
  }
  notify("STOPPING=1");
  acq->stop();
  LogEvent event;
  while (acq->pop_event(event)) log_event(event, acq_config);
  if (!options.lateness_log.empty()) {
    if (std::FILE* f = std::fopen(options.lateness_log.c_str(), "w")) {
      for (const std::int32_t v : acq->lateness_record()) std::fprintf(f, "%d\n", v);
      std::fclose(f);
    } else {
      spdlog::error("cannot write {}", options.lateness_log);
    }
  }
  spdlog::info("stopped after {} cycles ({} overruns, {} publish failures)", acq->cycles(),
               acq->overruns(), acq->publisher().failures());
  logger->flush();
  spdlog::shutdown();
  return exit_code;
}

}  // namespace exodaq::core
