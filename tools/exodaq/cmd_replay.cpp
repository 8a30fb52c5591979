// exodaq replay: re-process a recording through the full pipeline (homing,
// offsets, kinematics, faults) with a configuration's model and calibration,
// and write the results as an LCM log, or publish them live over LCM at the
// recording's pace (docs/replay.md).
//   exodaq replay IN -c C (-o OUT.lcm | --live [--speed 1|4|0.5] [--url URL]
//                 [--share-channels]) [--format auto|lcm|candump]
//                 [--calibration FILE] [--channel NAME] [-p PREFIX] [-q] [-v]
// Exit 1 when the input was damaged or malformed (a damaged or cut LCM log,
// candump lines that do not parse): the output holds what could be replayed.
// The output is written as a files::OutputFile (through messages::LogWriter): it
// appears complete or not at all, and never replaces an input.
//
// Cycles are driven one by one on this thread (Acquisition::run_cycle). Into
// a file they run flat out (the output does not depend on pacing: same input,
// config and calibration, same bytes); --live starts cycle k at
// (recorded_k - recorded_0) / speed after the first and publishes on LCM
// through the daemon's own sink, with the daemon's channels and types, after
// listening on them first: a live run heard there is refused (two streams,
// one run id, interleaved), unless --share-channels. A replay's joint states
// carry SAMPLE_REPLAY and its statuses source "replay".
#include <signal.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>

#include "command.hpp"
#include "exodaq/common/clock_now.hpp"
#include "exodaq/common/files.hpp"
#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/builder.hpp"
#include "exodaq/core/publisher.hpp"
#include "exodaq/drivers/replay_source.hpp"
#include "exodaq/drivers/source_factory.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/settings/service_config.hpp"

namespace exodaq::tools {
namespace {

std::atomic<bool> g_interrupted{false};

void on_interrupt(int /*sig*/) {
  g_interrupted.store(true);
}

std::int64_t thread_cpu_now() {
  return clock_ns(CLOCK_THREAD_CPUTIME_ID);
}

// Fields read in place from the encoded bytes instead of decoding every
// message: LCM writes the 8-byte fingerprint, then the fields in order,
// big-endian; every exodaq message starts utime, mono_ns, seq, run_id, and
// palm_pose_t goes on with `valid`. check_layout() holds these to the
// generated encoders.
constexpr std::size_t kMonoNsOffset = 16;
constexpr std::size_t kPalmValidOffset = 40;

std::int64_t big_endian64(const std::uint8_t* p) noexcept {
  std::uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v = (v << 8) | p[i];
  return static_cast<std::int64_t>(v);
}

void check_layout() {
  std::array<std::uint8_t, core::kMaxMessageBytes> buf{};
  const int cap = static_cast<int>(buf.size());
  joint_state_t j{};
  j.mono_ns = 0x0102030405060708;
  palm_pose_t p{};
  p.mono_ns = -2;
  p.valid = 1;
  const bool joint_ok =
      j.encode(buf.data(), 0, cap) > 0 && big_endian64(buf.data() + kMonoNsOffset) == j.mono_ns;
  const bool palm_ok = p.encode(buf.data(), 0, cap) > 0 &&
                       big_endian64(buf.data() + kMonoNsOffset) == p.mono_ns &&
                       buf[kPalmValidOffset] == 1;
  if (!joint_ok || !palm_ok)
    throw std::logic_error("replay: message layout is not the expected one");
}

// Writes every published message to an LCM log file, as lcm-logger would
// have recorded it live (event timestamp = the message's utime). status_t
// and source_status_t fields that measure the replaying machine rather than
// the recording (mono_ns of the assembly, the work-time percentiles) are set
// to deterministic values: mono_ns = the last cycle's, work_* = 0.
class LcmLogSink final : public core::MessageSink {
 public:
  LcmLogSink(const std::string& path, const std::vector<std::string>& inputs) : log_(path, inputs) {
    check_layout();
  }

  // Messages before arm() (the Acquisition's start-up encoder warm-up) are dropped.
  void arm() noexcept { armed_ = true; }

  bool publish(const std::string& channel, const core::OutgoingMessage& msg) noexcept override {
    if (!armed_) return true;
    const std::uint8_t* data = msg.bytes.data();
    std::size_t size = msg.size;
    if (msg.channel == messages::Kind::kJointState) {
      if (size < kMonoNsOffset + 8) return false;
      last_mono_ns_ = big_endian64(data + kMonoNsOffset);
    } else if (msg.channel == messages::Kind::kPalmPose) {
      if (size <= kPalmValidOffset) return false;
      ++palm_messages_;
      if (data[kPalmValidOffset] != 0) ++valid_;
    } else if (msg.channel == messages::Kind::kStatus) {
      if (!restamp(status_, data, size)) return false;
    } else if (msg.channel == messages::Kind::kSourceStatus) {
      if (!restamp(source_status_, data, size)) return false;
    }
    try {
      log_.write(channel, msg.utime_us, data, size);
    } catch (const std::exception& e) {
      if (error_.empty()) error_ = e.what();
      return false;
    }
    return true;
  }

  // Re-encodes a window's message with the deterministic values above into
  // buffer_; `data` and `size` then point there.
  template <typename Msg>
  bool restamp(Msg& m, const std::uint8_t*& data, std::size_t& size) noexcept {
    if (!messages::decode_into(m, data, size)) return false;
    m.mono_ns = last_mono_ns_;
    if constexpr (std::is_same_v<Msg, status_t>)
      m.work_p50_us = m.work_p99_us = m.work_max_us = 0.0;
    const int n = m.encode(buffer_.data(), 0, static_cast<int>(buffer_.size()));
    if (n < 0) return false;
    data = buffer_.data();
    size = static_cast<std::size_t>(n);
    return true;
  }

  // Flushes and reports the first write error (disk full...) as an exception.
  void finish() {
    if (!error_.empty()) throw std::runtime_error(error_);
    log_.close();
  }

  bool failed() const noexcept { return !error_.empty(); }
  std::int64_t written() const noexcept { return log_.events(); }
  std::int64_t palm_messages() const noexcept { return palm_messages_; }
  std::int64_t valid_palm() const noexcept { return valid_; }

 private:
  messages::LogWriter log_;
  bool armed_ = false;
  std::int64_t last_mono_ns_ = 0;
  std::int64_t palm_messages_ = 0;
  std::int64_t valid_ = 0;
  std::string error_;
  status_t status_;
  source_status_t source_status_;
  std::array<std::uint8_t, core::kMaxMessageBytes> buffer_{};
};

struct ReplayOptions {
  std::string input;
  std::string config;
  std::string out;
  bool live = false;
  std::string url;
  std::string speed = "1";
  std::string format = "auto";
  std::string calibration;
  std::string channel;
  std::string prefix;
  bool prefix_given = false;
  bool share_channels = false;
};

std::string hex_bytes(const std::string& b) {
  std::string out;
  char buf[4];
  for (std::size_t i = 0; i < b.size(); ++i) {
    std::snprintf(buf, sizeof buf, "%s%02x", i ? " " : "", static_cast<unsigned char>(b[i]));
    out += buf;
  }
  return out;
}

// What the input is, said before the backend reads it: "auto" becomes "lcm"
// or "candump", or the error says what the file is not. FIFOs, devices and
// directories are refused here (files::check_input).
std::string check_recording(const std::string& path, const std::string& format) {
  const files::InputInfo info = files::check_input(path, -1);
  if (format == "candump" || format == "lcm") return format;  // the backend's own messages
  if (info.size == 0) {
    throw files::FileError(path, "empty file, not a recording (an LCM log or a candump log)");
  }
  const int fd = files::open_input(path, -1);
  std::string head(256, '\0');
  const ssize_t n = ::read(fd, head.data(), head.size());
  ::close(fd);
  head.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
  if (head.size() >= 4 && static_cast<unsigned char>(head[0]) == 0xED &&
      static_cast<unsigned char>(head[1]) == 0xA1 && static_cast<unsigned char>(head[2]) == 0xDA &&
      static_cast<unsigned char>(head[3]) == 0x01) {
    return "lcm";
  }
  const std::size_t first = head.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && head[first] == '(') return "candump";
  std::string line = head.substr(0, std::min(head.find('\n'), std::size_t{40}));
  for (char& c : line) {
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '.';
  }
  throw files::FileError(path, "not an LCM log (first bytes " + hex_bytes(head.substr(0, 8)) +
                                   ") nor a candump log (line 1, '" + line +
                                   "', does not start with a '(timestamp)')");
}

// The backend's messages start "replay: "; the tool says "exodaq replay: ".
[[noreturn]] void rethrow_without_prefix(const std::exception& e) {
  std::string what = e.what();
  if (what.rfind("replay: ", 0) == 0) what.erase(0, 8);
  throw std::runtime_error(what);
}

class Progress {
 public:
  Progress(std::int64_t total, bool enabled) : total_(total), enabled_(enabled) {}
  void update(std::int64_t done, std::int64_t now_ns, bool force = false) {
    if (!enabled_ || (!force && now_ns - last_ns_ < 100'000'000)) return;
    last_ns_ = now_ns;
    constexpr int kWidth = 30;
    const double f = total_ > 0 ? static_cast<double>(done) / static_cast<double>(total_) : 1.0;
    const int filled = static_cast<int>(f * kWidth);
    char bar[kWidth + 1];
    for (int i = 0; i < kWidth; ++i) bar[i] = i < filled ? '#' : '.';
    bar[kWidth] = '\0';
    std::fprintf(stderr, "\r[%s] %5.1f%%  %lld/%lld cycles", bar, 100.0 * f,
                 static_cast<long long>(done), static_cast<long long>(total_));
    std::fflush(stderr);
  }
  void end() {
    if (enabled_) std::fprintf(stderr, "\n");
  }

 private:
  std::int64_t total_;
  bool enabled_;
  std::int64_t last_ns_ = 0;
};

// What driving the cycles took.
struct ReplayRun {
  std::int64_t cycles = 0;
  double run_s = 0.0;  // wall time
  double cpu_s = 0.0;  // this thread's CPU time
};

// Drives the cycles one by one at the recorded instants (paced by `speed`, or
// flat out when 0) until the recording ends or SIGINT/SIGTERM, then stops the
// acquisition (its final status) and drains what it published.
// A failed output write (a full disk) ends it early: the output is lost anyway.
ReplayRun drive_cycles(core::Acquisition& acq, const drivers::ReplaySource& replay, double speed,
                       bool quiet, const LcmLogSink* sink) {
  struct sigaction sa {};
  sa.sa_handler = on_interrupt;
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);

  const bool tty = !quiet && isatty(STDERR_FILENO) != 0;
  Progress progress(replay.sample_count(), tty);
  core::LogEvent event;
  ReplayRun run;
  std::int64_t last_t = 0;
  std::int64_t first_recorded = -1;
  const std::int64_t run_start = mono_now_ns();
  const std::int64_t cpu_start = thread_cpu_now();
  while (!g_interrupted.load(std::memory_order_relaxed) && (sink == nullptr || !sink->failed())) {
    const std::int64_t next = replay.next_sample_mono_ns();
    const std::int64_t t = next >= 0 ? next : last_t;
    if (speed > 0.0 && next >= 0) {
      if (first_recorded < 0) first_recorded = next;
      sleep_until_mono(
          run_start + static_cast<std::int64_t>(static_cast<double>(next - first_recorded) / speed),
          &g_interrupted);
    }
    // The recorded instant is both deadline and wake-up: a missing sample
    // keeps its recorded mono_ns, and the status timing describes the recording.
    if (!acq.run_cycle(t, t)) break;
    last_t = t;
    ++run.cycles;
    if (speed > 0.0 || (run.cycles & 255) == 0) {
      acq.publisher().drain();
      while (acq.pop_event(event)) {
      }
      if ((run.cycles & 1023) == 0 || speed > 0.0) progress.update(run.cycles, mono_now_ns());
    }
  }
  acq.stop();  // final status
  acq.publisher().drain();
  while (acq.pop_event(event)) {
  }
  run.run_s = static_cast<double>(mono_now_ns() - run_start) * 1e-9;
  run.cpu_s = static_cast<double>(thread_cpu_now() - cpu_start) * 1e-9;
  progress.update(run.cycles, mono_now_ns(), true);
  progress.end();
  return run;
}

void print_report(const ReplayOptions& o, const settings::ServiceConfig& cfg,
                  const drivers::ReplaySource& replay, const std::string& prefix,
                  const LcmLogSink* sink, core::Acquisition& acq, const ReplayRun& run,
                  double load_s) {
  const drivers::ReplayLoadSummary& summary = replay.summary();
  const auto ll = [](std::int64_t v) { return static_cast<long long>(v); };
  const char* fmt = summary.format == drivers::ReplayFormat::kLcm ? "lcm" : "candump";
  std::printf("exodaq replay: %s (%s", o.input.c_str(), fmt);
  if (summary.format == drivers::ReplayFormat::kLcm) {
    std::printf(", channel %s", summary.channel.c_str());
  }
  const std::string target = sink != nullptr ? o.out : "LCM " + cfg.lcm.url;
  std::printf(", run %s) -> %s (prefix '%s')\n", messages::run_id_text(summary.run_id).c_str(),
              target.c_str(), prefix.c_str());
  std::printf("  config %s, calibration %s\n", o.config.c_str(), cfg.calibration_path.c_str());
  // Cycles per second of wall time, and per second of this thread's CPU
  // time (the figure that does not depend on what else the machine runs).
  std::printf("  %lld cycles (%.3f s recorded) in %.3f s (%.3f s CPU)", ll(run.cycles),
              summary.duration_s, run.run_s, run.cpu_s);
  if (run.run_s > 0.0 && run.cpu_s > 0.0) {
    const double rate = static_cast<double>(run.cycles) / run.run_s;
    const double cpu_rate = static_cast<double>(run.cycles) / run.cpu_s;
    const double period_s = cfg.loop.rate_hz > 0 ? 1.0 / cfg.loop.rate_hz : 0.0;
    std::printf(": %.0f cycles/s (%.0fx real time), %.0f per CPU second", rate, rate * period_s,
                cpu_rate);
  }
  std::printf(" (loading %.3f s)\n", load_s);
  // At --speed max the loop waits for the file reader whenever the ring is empty.
  std::printf("  read-ahead ring of %zu samples, found empty %lld times\n",
              replay.buffer_capacity(), ll(replay.buffer_waits()));
  if (sink == nullptr) {
    std::printf("  %lld messages published, %lld not (ring full or LCM refused)\n",
                ll(acq.publisher().published()), ll(acq.publisher().failures()));
  } else {
    std::printf("  %lld messages written; palm pose valid in %lld of %lld cycles (%.1f%%)\n",
                ll(sink->written()), ll(sink->valid_palm()), ll(sink->palm_messages()),
                sink->palm_messages() > 0 ? 100.0 * static_cast<double>(sink->valid_palm()) /
                                                static_cast<double>(sink->palm_messages())
                                          : 0.0);
  }
  if (summary.format == drivers::ReplayFormat::kLcm) {
    std::printf(
        "  input: %lld events, %lld samples (%lld missing), %lld start-up messages skipped, "
        "%lld messages of other runs skipped\n",
        ll(summary.events), ll(summary.samples), ll(summary.missing), ll(summary.skipped_warmup),
        ll(summary.skipped_other_runs));
    if (summary.damaged_stretches > 0) {
      std::printf("  damaged: %lld stretch%s of the log, %lld cycles lost with them (below)\n",
                  ll(summary.damaged_stretches), summary.damaged_stretches == 1 ? "" : "es",
                  ll(summary.damaged_cycles));
    }
    if (summary.resumed_at_seq >= 0) {
      std::printf("  homing: continued from the live run's record of seq %lld (%lld records)\n",
                  ll(summary.resumed_at_seq), ll(summary.homing_records));
    }
  } else {
    const drivers::SourceStats st = replay.stats();
    std::printf(
        "  input: %lld lines, %lld frames, %lld malformed lines, %lld samples (%lld missing), "
        "%lld sequence gaps, %lld bus errors\n",
        ll(summary.events), ll(summary.frames), ll(summary.bad_lines), ll(summary.samples),
        ll(summary.missing), ll(st.seq_gaps), ll(st.bus_errors));
  }
}

// Problems in the input, with their place (file:line for candump, the event
// number for LCM), on stderr even with -q; -v lists every one. True when any
// is damage or a malformed input (exit 1), not only notes.
bool report_issues(const drivers::ReplaySource& replay, const std::string& input) {
  const drivers::ReplayLoadSummary& summary = replay.summary();
  const auto ll = [](std::int64_t v) { return static_cast<long long>(v); };
  if (summary.format == drivers::ReplayFormat::kLcm && summary.resumed_at_seq < 0 &&
      summary.first_seq > 0) {
    std::fprintf(stderr,
                 "exodaq replay: warning: %s starts at seq %lld of its run and holds no homing "
                 "record (EXO_HOMING): the joints start unhomed and home only where they cross "
                 "an index inside it; until then angles count from the first sample and palm "
                 "poses are invalid (INVALID_UNHOMED)\n",
                 input.c_str(), ll(summary.first_seq));
  }
  const auto& issues = replay.issues();
  if (!issues.empty()) {
    const std::int64_t total = summary.format == drivers::ReplayFormat::kCandump
                                   ? summary.bad_lines
                                   : static_cast<std::int64_t>(issues.size());
    std::fprintf(stderr, "exodaq replay: %lld problem(s) in %s:\n", ll(total), input.c_str());
    const std::size_t kShown = common_options().verbose ? issues.size() : 50;
    for (std::size_t i = 0; i < issues.size() && i < kShown; ++i) {
      std::fprintf(stderr, "  %s:%lld: %s\n", input.c_str(), ll(issues[i].line),
                   issues[i].what.c_str());
    }
    if (total > static_cast<std::int64_t>(kShown)) {
      std::fprintf(stderr, "  ... and %lld more\n", ll(total - static_cast<std::int64_t>(kShown)));
    }
  }
  return summary.bad_lines > 0 ||
         std::any_of(issues.begin(), issues.end(), [](const auto& i) { return i.problem; });
}

// --live: who already publishes on the output channels. Listens on the
// prefix's status and joint-state channels for two status periods (at least
// 250 ms, the daemon's own start-up window, instance_guard.hpp); the first
// message with a run id names the publisher ("" when none).
std::string publisher_heard(const std::string& url, const std::string& prefix,
                            double status_rate_hz) {
  messages::Subscriber sub(url);
  std::string heard;
  const auto note = [&heard](std::int64_t run_id, const std::string& what) {
    if (heard.empty() && run_id != 0) heard = "run id " + messages::run_id_text(run_id) + what;
  };
  sub.subscribe(messages::channel_name(prefix, messages::Kind::kStatus), messages::Kind::kStatus,
                [&note](const messages::Received& r) {
                  const auto& s = std::get<status_t>(r.msg);
                  note(s.run_id, " (rig " + messages::printable(s.rig) + ", source " +
                                     messages::printable(s.source) + ")");
                });
  sub.subscribe(
      messages::channel_name(prefix, messages::Kind::kJointState), messages::Kind::kJointState,
      [&note](const messages::Received& r) { note(std::get<joint_state_t>(r.msg).run_id, ""); });
  const double window_ms = std::max(250.0, status_rate_hz > 0.0 ? 2000.0 / status_rate_hz : 250.0);
  const std::int64_t end = mono_now_ns() + static_cast<std::int64_t>(window_ms * 1e6);
  for (std::int64_t now = mono_now_ns(); now < end && heard.empty(); now = mono_now_ns()) {
    if (sub.handle(static_cast<int>(std::max<std::int64_t>(1, (end - now) / 1'000'000))) < 0) break;
  }
  return heard;
}

// The options that go together, and --speed as a number (0: max); nullopt
// after a usage error was printed.
std::optional<double> replay_speed(const ReplayOptions& o, bool speed_given) {
  if (o.live == !o.out.empty()) {
    print_error(o.live ? "--live publishes on LCM; it takes no --out"
                       : "give --out FILE.lcm (write a log) or --live (publish on LCM)");
    return std::nullopt;
  }
  if (!o.live && o.share_channels) {
    print_error("--share-channels goes with --live (a file shares no channels)");
    return std::nullopt;
  }
  if (!o.live && ((speed_given && o.speed != "max") || !o.url.empty())) {
    print_error(std::string(o.url.empty() ? "--speed " + o.speed : "--url") +
                " goes with --live (a file is always written flat out: --speed max)");
    return std::nullopt;
  }
  double speed = 0.0;
  if (o.live && o.speed != "max") {
    char* end = nullptr;
    speed = std::strtod(o.speed.c_str(), &end);
    if (end == o.speed.c_str() || *end != '\0' || !(speed > 0.0) || !std::isfinite(speed)) {
      print_error("--speed must be a positive number (x real time) or 'max', not '" + o.speed +
                  "'");
      return std::nullopt;
    }
  }
  return speed;
}

int run_replay(const ReplayOptions& o, bool speed_given) {
  const std::optional<double> checked_speed = replay_speed(o, speed_given);
  if (!checked_speed) return kExitUsage;
  const double speed = *checked_speed;
  const std::vector<std::string> inputs{o.input, o.config, o.calibration};
  if (!o.live) {
    files::OutputOptions oo;
    oo.inputs = inputs;
    files::check_output(o.out, oo);
  }
  const std::string format = check_recording(o.input, o.format);

  settings::ServiceConfig cfg = settings::load_service_config(o.config);
  if (!o.url.empty()) cfg.lcm.url = o.url;
  if (!o.calibration.empty()) {
    cfg.calibration = settings::load_calibration_file(o.calibration);
    cfg.calibration_path = o.calibration;
  }
  drivers::ReplaySettings replay_settings;
  replay_settings.path = o.input;
  replay_settings.format = format;
  if (!o.channel.empty()) replay_settings.channel = o.channel;
  replay_settings.speed = speed;
  // A candump log is the configured CAN backend's protocol (protocol v1 when
  // the config's backend has no CAN frames, e.g. sim).
  const drivers::Backend* backend = drivers::find_backend(cfg.source.backend);
  if (backend != nullptr && backend->assembler) replay_settings.protocol = cfg.source.backend;
  drivers::SourceContext context = settings::make_source_context(cfg);
  context.frame_assembler = drivers::frame_assemblers(cfg.source, context);
  auto source = std::make_unique<drivers::ReplaySource>(replay_settings, context);
  drivers::ReplaySource* replay = source.get();
  const std::int64_t load_start = mono_now_ns();
  try {
    replay->start();  // loads the input; Acquisition's start() only rewinds
  } catch (const std::runtime_error& e) {
    rethrow_without_prefix(e);
  }
  const double load_s = static_cast<double>(mono_now_ns() - load_start) * 1e-9;
  const drivers::ReplayLoadSummary summary = replay->summary();

  std::string prefix = cfg.lcm.prefix;
  if (o.prefix_given) {
    prefix = o.prefix;
  } else if (summary.format == drivers::ReplayFormat::kLcm) {
    prefix = summary.prefix;  // the recording's channel names
  }
  if (o.live && !o.share_channels) {
    if (const std::string heard = publisher_heard(cfg.lcm.url, prefix, cfg.loop.status_rate_hz);
        !heard.empty()) {
      print_error(heard + " publishes on LCM " + cfg.lcm.url + " with prefix '" + prefix +
                  "': a replay there would interleave with it (two streams on one channel set); "
                  "give another --prefix or --url, or --share-channels to publish anyway");
      return kExitFailure;
    }
  }

  // The daemon's wiring, with the recording as source, a log file as sink
  // (--live: the daemon's LCM sink on lcm.url), the recording's run_id and
  // no real-time scheduling.
  std::unique_ptr<LcmLogSink> sink_owner;
  if (!o.live) sink_owner = std::make_unique<LcmLogSink>(o.out, inputs);
  LcmLogSink* sink = sink_owner.get();
  core::AcquisitionOptions wiring;
  wiring.source = std::move(source);
  wiring.sink = std::move(sink_owner);
  wiring.channel_prefix = prefix;
  wiring.run_id = summary.run_id;
  wiring.realtime = false;
  const auto acq = core::build_acquisition(cfg, std::move(wiring));
  acq->prepare_for_manual_cycles();
  if (sink != nullptr) sink->arm();

  const bool quiet = common_options().quiet;
  const ReplayRun run = drive_cycles(*acq, *replay, speed, quiet, sink);
  if (sink != nullptr) sink->finish();  // throws with the reason when a write failed
  if (!quiet) print_report(o, cfg, *replay, prefix, sink, *acq, run, load_s);
  const bool damaged = report_issues(*replay, o.input);
  if (g_interrupted.load()) {
    print_error("interrupted after " + std::to_string(run.cycles) + " cycles" +
                (sink != nullptr ? "; " + o.out + " holds them" : std::string()));
    return kExitFailure;
  }
  if (damaged) {
    // The output holds what could be replayed; the exit code says the input was not whole.
    print_error(o.input + ": damaged or malformed input (problems above)" +
                (summary.damaged_cycles > 0
                     ? "; " + std::to_string(summary.damaged_cycles) + " cycles lost with it"
                     : std::string()));
    return kExitFailure;
  }
  return kExitOk;
}

std::function<int()> setup_replay(CLI::App& sub) {
  auto o = std::make_shared<ReplayOptions>();
  sub.add_option("input", o->input, "recording: lcm-logger log or candump -l file")->required();
  sub.add_option("-c,--config", o->config, "service configuration (model, calibration, encoders)")
      ->required();
  sub.add_option("-o,--out", o->out, "LCM log to write (every channel the daemon publishes)");
  sub.add_flag("--live", o->live,
               "publish on LCM (the config's lcm.url) at the recording's pace instead of "
               "writing a file");
  auto* speed =
      sub.add_option("--speed", o->speed,
                     "with --live: x real time (1 default, 4, 0.5, ...) or 'max'; files are "
                     "always written flat out");
  sub.add_option("--url", o->url, "with --live: LCM URL (default: the config's lcm.url)");
  sub.add_flag("--share-channels", o->share_channels,
               "with --live: publish even where another publisher (a live run) is heard on the "
               "output channels (tests)");
  sub.add_option("--format", o->format, "input format")
      ->check(CLI::IsMember({"auto", "lcm", "candump"}));
  sub.add_option("--calibration", o->calibration,
                 "calibration file to use instead of the config's");
  sub.add_option("--channel", o->channel,
                 "LCM input: the encoder_raw_t channel (default: the one ending in "
                 "EXO_ENCODER_RAW)");
  auto* prefix =
      add_prefix_option(sub, o->prefix,
                        "of the output; default: the recording's for LCM input, the config's "
                        "for candump");
  return [o, prefix, speed] {
    o->prefix_given = prefix->count() > 0;
    return run_replay(*o, speed->count() > 0);
  };
}

}  // namespace
}  // namespace exodaq::tools

EXODAQ_REGISTER_COMMAND(replay, "replay",
                        "re-process a recording (lcm-logger or candump -l) through the full "
                        "pipeline; write an LCM log of the results or publish them live",
                        exodaq::tools::setup_replay);
