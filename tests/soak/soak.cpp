// Soak (issue 11 part 4): exodaqd on the simulated rig at 1 kHz for N minutes
// with this process as an LCM subscriber, sampling the daemon's RSS and open
// file descriptors from /proc. Passes (exit 0) when
//   - the daemon exits 0 after --duration, one run, joint_state seq from 0,
//     strictly increasing, and every cycle missing at the subscriber is one
//     the daemon counted: skipped (overruns) or not sent (publish_failures),
//     or a datagram the subscriber's own socket dropped (the kernel counts
//     those: /proc/net/udp; the LCM queue is unbounded, so nothing else);
//   - the subscriber's own counts agree with the daemon's final status:
//     joint_state received + not published == status cycles, every
//     per-cycle message missing is a counted publish failure or socket drop, missing
//     samples 0, board seq gaps only from overruns, no bad, duplicate or
//     out-of-order frames, never FAULT;
//   - after the warm-up, VmRSS stays within 1 MiB (max - min) and the number
//     of open file descriptors never exceeds its value at the end of warm-up.
// With --free-running (issue 15) the sim's board samples on its own clock
// (board_clock: free_running, --drift-ppm, a third of a period out of phase):
// then also every board sample arrives once, in order (encoder_raw board_seq
// without a skip beyond counted publish failures), none MISSING, no board seq
// gap, and a skipped deadline is no seq hole (its sample came late, flagged
// LATE). --stress-bursts ON:OFF runs `stress-ng --cpu 2` for ON seconds every
// ON + OFF seconds during the run. Lateness and the LATE samples are reported.
// Writes soak.json and soak.txt to --out. scripts/soak is the front end.
#include <lcm/lcm.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "exodaq/common/clock_now.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"
#include "process.hpp"
#include "sim_daemon.hpp"

namespace {

using Clock = std::chrono::steady_clock;

struct Subscriber {
  std::string prefix;
  std::mutex mutex;
  // joint_state
  std::int64_t joints = 0;
  std::int64_t first_seq = -1;
  std::int64_t last_seq = -1;
  std::int64_t holes = 0;
  std::int64_t out_of_order = 0;                 // seq not increasing (must stay 0)
  std::map<std::int64_t, std::int64_t> run_ids;  // run_id -> messages
  std::int64_t joint_sample_flags_or = 0;
  // LATE samples; runs of consecutive LATE samples (a stall caught up): how
  // many, the longest; LATE ones received within a period of their stamp
  // (impossible: must stay 0); samples received over a period after their
  // stamp without LATE (the network's and this process's delay, reported).
  std::int64_t late = 0;
  std::int64_t late_runs = 0;
  std::int64_t longest_late_run = 0;
  std::int64_t late_run = 0;
  std::int64_t late_but_on_time = 0;
  std::int64_t received_late_unflagged = 0;
  std::int64_t period_ns = 1'000'000;
  // encoder_raw: board samples, by board seq
  std::int64_t raw_last_seq = -1;
  std::int64_t raw_last_board_seq = -1;
  std::int64_t board_seq_skips = 0;  // board samples not received (beyond lost messages)
  std::int64_t raw_lost = 0;         // encoder_raw messages not received (seq holes)
  std::int64_t not_present = 0;      // MISSING samples
  // palm_pose, encoder_raw
  std::int64_t palms = 0;
  std::int64_t valid_palms = 0;
  std::int64_t raws = 0;
  std::int64_t decode_errors = 0;
  // status
  std::vector<exodaq::status_t> statuses;
};

void on_message(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
  auto* s = static_cast<Subscriber*>(user);
  const std::string ch(channel);
  const auto size = static_cast<int>(rbuf->data_size);
  std::lock_guard<std::mutex> lock(s->mutex);
  if (ch == s->prefix + "EXO_JOINT_STATE") {
    exodaq::joint_state_t m;
    if (m.decode(rbuf->data, 0, size) < 0) {
      ++s->decode_errors;
      return;
    }
    ++s->joints;
    ++s->run_ids[m.run_id];
    s->joint_sample_flags_or |= m.sample_flags;
    const std::int64_t received = exodaq::mono_now_ns();
    const bool late = (m.sample_flags & exodaq::joint_state_t::SAMPLE_LATE) != 0;
    if (late) {
      ++s->late;
      if (s->late_run == 0) ++s->late_runs;
      s->longest_late_run = std::max(s->longest_late_run, ++s->late_run);
      if (received - m.mono_ns <= s->period_ns) ++s->late_but_on_time;
    } else {
      s->late_run = 0;
      if (received - m.mono_ns > s->period_ns) ++s->received_late_unflagged;
    }
    if (s->first_seq < 0) {
      s->first_seq = m.seq;
    } else if (m.seq <= s->last_seq) {
      ++s->out_of_order;
    } else {
      s->holes += m.seq - s->last_seq - 1;
    }
    s->last_seq = std::max(s->last_seq, m.seq);
  } else if (ch == s->prefix + "EXO_PALM_POSE") {
    exodaq::palm_pose_t m;
    if (m.decode(rbuf->data, 0, size) < 0) {
      ++s->decode_errors;
      return;
    }
    ++s->palms;
    if (m.valid) ++s->valid_palms;
  } else if (ch == s->prefix + "EXO_ENCODER_RAW") {
    exodaq::encoder_raw_t m;
    if (m.decode(rbuf->data, 0, size) < 0) {
      ++s->decode_errors;
      return;
    }
    ++s->raws;
    if (!m.present) ++s->not_present;
    if (m.present && m.source_seq >= 0) {
      if (s->raw_last_seq >= 0 && m.seq > s->raw_last_seq) {
        // d cycles on, the board seq should be d on as well (one board sample a cycle).
        const std::int64_t d = m.seq - s->raw_last_seq;
        s->raw_lost += d - 1;
        const std::int64_t board_d = ((m.source_seq - s->raw_last_board_seq) % 256 + 256) % 256;
        s->board_seq_skips += ((board_d - d) % 256 + 256) % 256;
      }
      s->raw_last_seq = m.seq;
      s->raw_last_board_seq = m.source_seq;
    }
  } else if (ch == s->prefix + "EXO_STATUS") {
    exodaq::status_t m;
    if (m.decode(rbuf->data, 0, size) < 0) {
      ++s->decode_errors;
      return;
    }
    s->statuses.push_back(m);
  }
}

struct ProcSample {
  double t_s = 0;
  long rss_kb = -1;
  long hwm_kb = -1;
  long threads = -1;
  long fds = -1;
};

ProcSample sample_proc(pid_t pid, double t_s) {
  ProcSample p;
  p.t_s = t_s;
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line)) {
    const auto value = [&](const char* key) {
      return std::strtol(line.c_str() + std::strlen(key), nullptr, 10);
    };
    if (line.rfind("VmRSS:", 0) == 0) p.rss_kb = value("VmRSS:");
    if (line.rfind("VmHWM:", 0) == 0) p.hwm_kb = value("VmHWM:");
    if (line.rfind("Threads:", 0) == 0) p.threads = value("Threads:");
  }
  std::error_code ec;
  long n = 0;
  for (std::filesystem::directory_iterator it("/proc/" + std::to_string(pid) + "/fd", ec), end;
       !ec && it != end; it.increment(ec)) {
    ++n;
  }
  if (!ec) p.fds = n;
  return p;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  const auto i = static_cast<std::size_t>(std::ceil(p / 100.0 * static_cast<double>(v.size())));
  return v[std::min(v.size() - 1, i == 0 ? 0 : i - 1)];
}

struct Check {
  std::string what;
  bool ok = false;
};

std::string json_escape(const std::string& s) {
  std::string o;
  for (const char c : s) {
    if (c == '"' || c == '\\') o += '\\';
    o += c;
  }
  return o;
}

int usage() {
  std::fprintf(stderr,
               "usage: exodaq_soak [--minutes N] [--out DIR] [--warmup S] [--sample S] "
               "[--exodaqd PATH] [--free-running 0|1] [--drift-ppm D] [--stress-bursts ON:OFF]\n");
  return 2;
}

// `stress-ng --cpu 2` for on_s seconds every on_s + off_s seconds (the first
// burst after off_s) until `stop`; counts the bursts started.
void stress_bursts(double on_s, double off_s, const std::string& dir, std::atomic<bool>& stop,
                   std::atomic<int>& bursts) {
  const auto pause = [&](double seconds) {
    const auto until = Clock::now() + std::chrono::milliseconds(static_cast<long>(seconds * 1000));
    while (!stop.load() && Clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
  };
  for (;;) {
    pause(off_s);
    if (stop.load()) return;
    ++bursts;
    exodaq::test::Process stress(
        {"stress-ng", "--cpu", "2", "--timeout", std::to_string(on_s) + "s", "--quiet"},
        dir + "/stress.out", dir + "/stress.err");
    while (!stop.load() && !stress.wait(std::chrono::milliseconds(100))) {
    }
    if (stop.load()) {
      stress.signal(SIGTERM);
      stress.wait(std::chrono::seconds(5));
      return;
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  double minutes = 10.0;
  std::string out_dir;
  double warmup_s = -1;
  double sample_s = -1;
  std::string exodaqd = EXODAQD;
  bool free_running = false;
  double drift_ppm = 50.0;
  double burst_on_s = 0;
  double burst_off_s = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) return usage();
    const std::string v = argv[++i];
    if (a == "--minutes") {
      minutes = std::stod(v);
    } else if (a == "--out") {
      out_dir = v;
    } else if (a == "--warmup") {
      warmup_s = std::stod(v);
    } else if (a == "--sample") {
      sample_s = std::stod(v);
    } else if (a == "--exodaqd") {
      exodaqd = v;
    } else if (a == "--free-running") {
      free_running = v != "0";
    } else if (a == "--drift-ppm") {
      drift_ppm = std::stod(v);
    } else if (a == "--stress-bursts") {
      const auto colon = v.find(':');
      if (colon == std::string::npos) return usage();
      burst_on_s = std::stod(v.substr(0, colon));
      burst_off_s = std::stod(v.substr(colon + 1));
      if (!(burst_on_s > 0) || !(burst_off_s > 0)) return usage();
    } else {
      return usage();
    }
  }
  if (!(minutes > 0)) return usage();
  const double duration_s = minutes * 60.0;
  // Warm-up: the simulated operator homes every joint in ~11 s; the first
  // status windows, LCM's buffers and the allocator settle. 60 s on a full
  // soak, a third of a short one.
  if (warmup_s < 0) warmup_s = std::min(60.0, duration_s / 3.0);
  if (sample_s < 0) sample_s = duration_s >= 120 ? 5.0 : 1.0;
  if (out_dir.empty()) out_dir = exodaq::test::make_temp_dir("soak");
  std::filesystem::create_directories(out_dir);

  Subscriber sub;
  sub.prefix = exodaq::test::unique_prefix("soak");
  // A private UDP port: other daemons on this machine (concurrent tests) do
  // not fill this subscriber's socket. The subscriber keeps up by design: a
  // 4 MiB receive buffer and an unbounded LCM queue (LCM's default of 30
  // queued messages per subscription is 10 ms at 3 kHz), so a gap it sees is
  // the daemon's, and its own socket's drop counter is reported.
  const int port = 7668 + static_cast<int>(getpid() % 1000);
  std::string config_text =
      exodaq::test::read_file(exodaq::test::write_sim_config(out_dir, sub.prefix));
  const std::string from = ":7667?";
  const auto at = config_text.find(from);
  if (at == std::string::npos) {
    std::fprintf(stderr, "soak: no LCM URL with port 7667 in the sim config\n");
    return 1;
  }
  config_text.replace(at, from.size(), ":" + std::to_string(port) + "?");
  if (free_running) {
    const auto sim = config_text.find("  sim:\n");
    if (sim == std::string::npos) {
      std::fprintf(stderr, "soak: no source.sim section in the sim config\n");
      return 1;
    }
    char clock[160];
    std::snprintf(clock, sizeof clock,
                  "    board_clock: {free_running: true, drift_ppm: %g, phase: 0.3}\n", drift_ppm);
    config_text.insert(sim + 7, clock);
  }
  const std::string config = out_dir + "/exodaqd.yaml";
  std::ofstream(config) << config_text;
  const std::string url =
      "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0&recv_buf_size=4194304";
  lcm_t* lcm = lcm_create(url.c_str());
  if (lcm == nullptr) {
    std::fprintf(stderr, "soak: cannot open LCM %s\n", url.c_str());
    return 1;
  }
  lcm_subscription_t* subscription =
      lcm_subscribe(lcm, (sub.prefix + "EXO_.*").c_str(), on_message, &sub);
  lcm_subscription_set_queue_capacity(subscription, 0);
  std::atomic<bool> stop{false};
  std::thread listener([&] {
    while (!stop.load()) lcm_handle_timeout(lcm, 50);
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(300));

  std::printf(
      "soak: exodaqd on the sim at 1 kHz for %.1f min (warm-up %.0f s, sampling every %.0f "
      "s), board %s, output in %s\n",
      minutes, warmup_s, sample_s,
      free_running ? ("free-running at " + std::to_string(drift_ppm) + " ppm").c_str()
                   : "aligned to the loop (sync master)",
      out_dir.c_str());
  if (burst_on_s > 0) {
    std::printf("soak: stress-ng --cpu 2 bursts of %.0f s every %.0f s\n", burst_on_s,
                burst_on_s + burst_off_s);
  }
  std::fflush(stdout);
  std::vector<ProcSample> samples;
  std::optional<int> code;
  std::atomic<bool> stop_stress{false};
  std::atomic<int> bursts{0};
  std::thread stresser;
  if (burst_on_s > 0) {
    stresser =
        std::thread([&] { stress_bursts(burst_on_s, burst_off_s, out_dir, stop_stress, bursts); });
  }
  const auto t0 = Clock::now();
  {
    exodaq::test::Process daemon(
        {exodaqd, "--config", config, "--duration", std::to_string(duration_s)},
        out_dir + "/exodaqd.out", out_dir + "/exodaqd.err");
    const auto interval = std::chrono::milliseconds(static_cast<int>(sample_s * 1000));
    const auto limit = t0 + std::chrono::milliseconds(static_cast<long>(duration_s * 1000) + 30000);
    // Sample after each interval (the first one after exec and start-up).
    while (!code && Clock::now() < limit) {
      code = daemon.wait(interval);
      if (code) break;
      const double t = std::chrono::duration<double>(Clock::now() - t0).count();
      const ProcSample p = sample_proc(daemon.pid(), t);
      if (p.rss_kb >= 0 && p.fds >= 0) samples.push_back(p);
    }
    if (!code) {
      std::fprintf(stderr, "soak: exodaqd did not stop after --duration; killing it\n");
      daemon.signal(SIGKILL);
      code = daemon.wait(std::chrono::seconds(5));
    }
  }
  stop_stress.store(true);
  if (stresser.joinable()) stresser.join();
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  stop.store(true);
  listener.join();
  // Datagrams the kernel dropped on this process's UDP sockets.
  const long socket_drops = static_cast<long>(exodaq::test::udp_drops(getpid()));
  lcm_destroy(lcm);
  const double wall_s = std::chrono::duration<double>(Clock::now() - t0).count();

  // ---- checks ----
  std::vector<Check> checks;
  const auto check = [&](bool ok, const std::string& what) { checks.push_back({what, ok}); };
  std::lock_guard<std::mutex> lock(sub.mutex);
  check(code && *code == 0, "exodaqd exited 0 after --duration");
  check(!sub.statuses.empty(), "status received");
  exodaq::status_t last;
  if (!sub.statuses.empty()) last = sub.statuses.back();
  check(last.state == exodaq::status_t::STATE_STOPPING || socket_drops > 0,
        "final status is STOPPING (unless the subscriber's socket dropped datagrams)");
  check(sub.run_ids.size() == 1, "one run_id");
  check(sub.first_seq == 0, "joint_state seq starts at 0");
  check(sub.out_of_order == 0, "joint_state seq strictly increasing");
  // The daemon counts two kinds of gap: cycles it skipped (overruns) and
  // messages its publisher could not send (publish_failures: a full ring
  // when the publishing thread is starved, or a failed send), all channels.
  // The subscriber loses only what the kernel drops on its socket (its LCM
  // queue is unbounded), and the kernel counts that (socket_drops): every
  // other gap is the daemon's, and must be counted.
  const std::int64_t drops = socket_drops;
  const std::int64_t uncounted =
      std::max<std::int64_t>(0, sub.holes - last.overruns - last.publish_failures - drops);
  check(uncounted == 0, "zero uncounted sequence gaps (holes " + std::to_string(sub.holes) +
                            " <= overruns " + std::to_string(last.overruns) +
                            " + publish failures " + std::to_string(last.publish_failures) +
                            " + subscriber socket drops " + std::to_string(drops) + ")");
  const std::int64_t lost_messages =
      (last.cycles - sub.joints) + (last.cycles - sub.palms) + (last.cycles - sub.raws);
  check(lost_messages >= 0 && lost_messages <= last.publish_failures + drops,
        "every per-cycle message not received is a counted publish failure or socket drop (" +
            std::to_string(lost_messages) + " <= " + std::to_string(last.publish_failures) + " + " +
            std::to_string(drops) + ")");
  check(sub.joints + sub.holes == sub.last_seq + 1, "received + holes == last seq + 1");
  // Sync master, a skipped deadline is a seq never published; following a
  // free-running board its sample comes late, so it is no hole. Cycles after
  // the last one received (`tail`) can only be socket drops.
  const std::int64_t skipped = free_running ? 0 : last.overruns;
  const std::int64_t tail = last.seq - sub.last_seq;
  check(sub.joints + (sub.holes - skipped) + tail == last.cycles,
        "joint_state received (" + std::to_string(sub.joints) + ") + not received (" +
            std::to_string(sub.holes - skipped) + " + " + std::to_string(tail) +
            " after the last) == status cycles (" + std::to_string(last.cycles) + ")");
  check(tail >= 0 && tail <= drops, "final status covers the last cycle received");
  check(last.missing_samples == 0, "missing samples 0 on a fault-free sim");
  check(sub.not_present == 0, "no MISSING sample received");
  check(last.seq_gaps <= skipped, free_running ? "no board seq gap (every board sample taken)"
                                               : "board seq gaps only from overruns");
  check(sub.late_but_on_time == 0, "no LATE sample received within a period of its stamp");
  if (free_running) {
    check(sub.holes <= last.publish_failures + drops,
          "no seq hole but counted publish failures and socket drops (overruns caught up, not "
          "skipped)");
    check(sub.board_seq_skips == 0, "0 board samples lost: encoder_raw board seq without a skip (" +
                                        std::to_string(sub.board_seq_skips) + " skipped beyond " +
                                        std::to_string(sub.raw_lost) + " messages not received)");
  }
  check(last.bad_frames == 0 && last.duplicates == 0 && last.out_of_order == 0,
        "no bad, duplicate or out-of-order frames");
  check(sub.decode_errors == 0, "every message decodes");
  std::map<int, std::int64_t> states;
  for (const auto& s : sub.statuses) ++states[s.state];
  check(states[exodaq::status_t::STATE_FAULT] == 0, "never FAULT");
  bool cycles_monotonic = true;
  for (std::size_t i = 1; i < sub.statuses.size(); ++i) {
    cycles_monotonic = cycles_monotonic && sub.statuses[i].cycles >= sub.statuses[i - 1].cycles;
  }
  check(cycles_monotonic, "status cycles never decrease");

  std::vector<ProcSample> steady;
  for (const auto& p : samples) {
    if (p.t_s >= warmup_s) steady.push_back(p);
  }
  long rss_min = 0, rss_max = 0, fd_start = 0, fd_max = 0, fd_min = 0;
  if (!steady.empty()) {
    rss_min = rss_max = steady.front().rss_kb;
    fd_start = fd_max = fd_min = steady.front().fds;
    for (const auto& p : steady) {
      rss_min = std::min(rss_min, p.rss_kb);
      rss_max = std::max(rss_max, p.rss_kb);
      fd_max = std::max(fd_max, p.fds);
      fd_min = std::min(fd_min, p.fds);
    }
  }
  check(steady.size() >= 3,
        "at least 3 /proc samples after warm-up (" + std::to_string(steady.size()) + ")");
  check(rss_max - rss_min <= 1024,
        "RSS flat within 1 MiB after warm-up (" + std::to_string(rss_max - rss_min) + " KiB)");
  check(fd_max <= fd_start, "open file descriptors do not grow after warm-up (" +
                                std::to_string(fd_start) + " -> max " + std::to_string(fd_max) +
                                ")");

  // Lateness from the status windows (reported, not judged).
  std::vector<double> p50, p99, mx, work99;
  for (const auto& s : sub.statuses) {
    if (s.window_cycles <= 0) continue;
    p50.push_back(s.lateness_p50_us);
    p99.push_back(s.lateness_p99_us);
    mx.push_back(s.lateness_max_us);
    work99.push_back(s.work_p99_us);
  }
  const bool pass = std::all_of(checks.begin(), checks.end(), [](const Check& c) { return c.ok; });
  const long first_rss = samples.empty() ? 0 : samples.front().rss_kb;
  const long last_rss = samples.empty() ? 0 : samples.back().rss_kb;
  const long threads = samples.empty() ? 0 : samples.back().threads;
  const long hwm = samples.empty() ? 0 : samples.back().hwm_kb;

  std::ostringstream txt;
  txt << "exodaq soak: " << (pass ? "PASS" : "FAIL") << "\n";
  char line[512];
  std::snprintf(line, sizeof line,
                "duration %.1f min (wall %.1f s), warm-up %.0f s, %zu /proc samples (%zu after "
                "warm-up)\n",
                minutes, wall_s, warmup_s, samples.size(), steady.size());
  txt << line;
  std::snprintf(line, sizeof line,
                "daemon status: cycles %lld, seq %lld, overruns %lld, missing %lld, board seq gaps "
                "%lld, publish failures %lld\n",
                static_cast<long long>(last.cycles), static_cast<long long>(last.seq),
                static_cast<long long>(last.overruns), static_cast<long long>(last.missing_samples),
                static_cast<long long>(last.seq_gaps),
                static_cast<long long>(last.publish_failures));
  txt << line;
  std::snprintf(line, sizeof line,
                "subscriber: joint_state %lld (seq %lld..%lld, holes %lld, uncounted %lld), "
                "palm_pose %lld (valid %lld), encoder_raw %lld, status %zu; its socket dropped "
                "%ld datagrams\n",
                static_cast<long long>(sub.joints), static_cast<long long>(sub.first_seq),
                static_cast<long long>(sub.last_seq), static_cast<long long>(sub.holes),
                static_cast<long long>(uncounted), static_cast<long long>(sub.palms),
                static_cast<long long>(sub.valid_palms), static_cast<long long>(sub.raws),
                sub.statuses.size(), socket_drops);
  txt << line;
  std::snprintf(line, sizeof line,
                "RSS: first %ld KiB, after warm-up %ld..%ld KiB (spread %ld KiB), last %ld KiB, "
                "peak (VmHWM) %ld KiB; fds after warm-up %ld..%ld (start %ld); threads %ld\n",
                first_rss, rss_min, rss_max, rss_max - rss_min, last_rss, hwm, fd_min, fd_max,
                fd_start, threads);
  txt << line;
  std::snprintf(line, sizeof line,
                "lateness (status windows of 100 ms, %zu): median p50 %.1f us, median p99 %.1f "
                "us, worst p99 %.1f us, worst max %.1f us; work p99 median %.1f us\n",
                p50.size(), percentile(p50, 50), percentile(p99, 50), percentile(p99, 100),
                percentile(mx, 100), percentile(work99, 50));
  txt << line;
  std::snprintf(
      line, sizeof line,
      "board %s; LATE samples %lld in %lld runs (longest %lld), LATE but received "
      "on time %lld, received over a period late unflagged %lld; encoder_raw "
      "present=false %lld, board seq skips %lld; stress bursts %d\n",
      free_running ? "free-running" : "aligned (sync master)", static_cast<long long>(sub.late),
      static_cast<long long>(sub.late_runs), static_cast<long long>(sub.longest_late_run),
      static_cast<long long>(sub.late_but_on_time),
      static_cast<long long>(sub.received_late_unflagged), static_cast<long long>(sub.not_present),
      static_cast<long long>(sub.board_seq_skips), bursts.load());
  txt << line;
  txt << "states (status messages):";
  for (const auto& [state, n] : states) txt << " " << state << "=" << n;
  txt << "\n";
  for (const auto& c : checks) txt << (c.ok ? "  ok   " : "  FAIL ") << c.what << "\n";

  std::ostringstream js;
  js << "{\n  \"pass\": " << (pass ? "true" : "false") << ",\n  \"minutes\": " << minutes
     << ",\n  \"wall_s\": " << wall_s << ",\n  \"warmup_s\": " << warmup_s
     << ",\n  \"daemon_exit\": " << (code ? *code : -1)
     << ",\n  \"status\": {\"cycles\": " << last.cycles << ", \"seq\": " << last.seq
     << ", \"overruns\": " << last.overruns << ", \"missing_samples\": " << last.missing_samples
     << ", \"seq_gaps\": " << last.seq_gaps << ", \"publish_failures\": " << last.publish_failures
     << "},\n  \"subscriber\": {\"joint_state\": " << sub.joints
     << ", \"first_seq\": " << sub.first_seq << ", \"last_seq\": " << sub.last_seq
     << ", \"holes\": " << sub.holes << ", \"uncounted_gaps\": " << uncounted
     << ", \"palm_pose\": " << sub.palms << ", \"valid_palm_pose\": " << sub.valid_palms
     << ", \"encoder_raw\": " << sub.raws << ", \"status\": " << sub.statuses.size()
     << ", \"socket_drops\": " << socket_drops << ", \"late\": " << sub.late
     << ", \"late_runs\": " << sub.late_runs << ", \"longest_late_run\": " << sub.longest_late_run
     << ", \"late_but_on_time\": " << sub.late_but_on_time
     << ", \"received_late_unflagged\": " << sub.received_late_unflagged
     << ", \"not_present\": " << sub.not_present << ", \"board_seq_skips\": " << sub.board_seq_skips
     << ", \"raw_lost\": " << sub.raw_lost
     << "},\n  \"free_running\": " << (free_running ? "true" : "false")
     << ",\n  \"drift_ppm\": " << (free_running ? drift_ppm : 0.0)
     << ",\n  \"stress_bursts\": " << bursts.load() << ",\n  \"rss_kib\": {\"first\": " << first_rss
     << ", \"min_after_warmup\": " << rss_min << ", \"max_after_warmup\": " << rss_max
     << ", \"last\": " << last_rss << ", \"hwm\": " << hwm
     << "},\n  \"fds\": {\"at_warmup\": " << fd_start << ", \"min\": " << fd_min
     << ", \"max\": " << fd_max << "},\n  \"threads\": " << threads
     << ",\n  \"lateness_us\": {\"median_p50\": " << percentile(p50, 50)
     << ", \"median_p99\": " << percentile(p99, 50) << ", \"worst_p99\": " << percentile(p99, 100)
     << ", \"worst_max\": " << percentile(mx, 100) << "},\n  \"samples\": [";
  for (std::size_t i = 0; i < samples.size(); ++i) {
    js << (i ? ", " : "") << "[" << samples[i].t_s << ", " << samples[i].rss_kb << ", "
       << samples[i].fds << "]";
  }
  js << "],\n  \"checks\": [";
  for (std::size_t i = 0; i < checks.size(); ++i) {
    js << (i ? ",\n    " : "\n    ") << "{\"ok\": " << (checks[i].ok ? "true" : "false")
       << ", \"what\": \"" << json_escape(checks[i].what) << "\"}";
  }
  js << "\n  ]\n}\n";
  std::ofstream(out_dir + "/soak.json") << js.str();
  std::ofstream(out_dir + "/soak.txt") << txt.str();
  std::fputs(txt.str().c_str(), stdout);
  std::printf("report: %s/soak.txt, %s/soak.json\n", out_dir.c_str(), out_dir.c_str());
  return pass ? 0 : 1;
}
