// A subscriber process for the end-to-end latency benchmark. Each palm_pose_t
// received on CHANNEL is stamped on CLOCK_MONOTONIC first thing in the LCM
// handler; latency = receive time - msg.mono_ns (exodaqd: the sample instant;
// the reference publisher bench_lcm_pub: its send time, its loop deadline in
// run_id). Optionally records status_t's in-loop work and lateness
// percentiles (scaling runs).
//
//   bench_lcm_sub --url URL --channel CH [--status-channel CH] [--out FILE]
//                 [--status-out FILE] [--duration S]
//
// Runs until --duration elapses or SIGTERM/SIGINT, then writes one line per
// message to --out: "seq receive_mono_ns msg.mono_ns msg.run_id", and one line
// per status to --status-out: "seq work_p50_us work_p99_us work_max_us
// lateness_p50_us lateness_p99_us lateness_max_us". Memory is reserved up front.
#include <lcm/lcm.h>
#include <signal.h>
#include <time.h>

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) {
  g_stop.store(true);
}

std::int64_t mono_now() noexcept {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

struct Sample {
  std::int64_t seq;
  std::int64_t recv_ns;
  std::int64_t mono_ns;
  std::int64_t run_id;
};

struct StatusSample {
  std::int64_t seq;
  double work_p50, work_p99, work_max, late_p50, late_p99, late_max;
};

struct State {
  std::vector<Sample> samples;
  std::vector<StatusSample> status;
  std::int64_t decode_errors = 0;
};

void on_pose(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  const std::int64_t now = mono_now();
  auto* st = static_cast<State*>(user);
  exodaq::palm_pose_t msg;
  if (msg.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) < 0) {
    ++st->decode_errors;
    return;
  }
  if (st->samples.size() < st->samples.capacity()) {
    st->samples.push_back({msg.seq, now, msg.mono_ns, msg.run_id});
  }
}

void on_status(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  auto* st = static_cast<State*>(user);
  exodaq::status_t msg;
  if (msg.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) < 0) {
    ++st->decode_errors;
    return;
  }
  st->status.push_back({msg.seq, msg.work_p50_us, msg.work_p99_us, msg.work_max_us,
                        msg.lateness_p50_us, msg.lateness_p99_us, msg.lateness_max_us});
}

}  // namespace

int main(int argc, char** argv) {
  std::string url = "udpm://239.255.76.67:7667?ttl=0";
  std::string channel, status_channel, out_path, status_out_path;
  double duration_s = 0;
  State st;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bench_lcm_sub: %s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--url") {
      url = next();
    } else if (a == "--channel") {
      channel = next();
    } else if (a == "--status-channel") {
      status_channel = next();
    } else if (a == "--out") {
      out_path = next();
    } else if (a == "--status-out") {
      status_out_path = next();
    } else if (a == "--duration") {
      duration_s = std::atof(next().c_str());
    } else {
      std::fprintf(stderr, "bench_lcm_sub: unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  if (channel.empty()) {
    std::fprintf(stderr, "bench_lcm_sub: --channel is required\n");
    return 2;
  }
  st.samples.reserve(static_cast<std::size_t>((duration_s > 0 ? duration_s + 30 : 3600) * 5000));
  st.status.reserve(100'000);

  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);

  lcm_t* lcm = lcm_create(url.c_str());
  if (lcm == nullptr) {
    std::fprintf(stderr, "bench_lcm_sub: cannot create LCM for %s\n", url.c_str());
    return 1;
  }
  lcm_subscribe(lcm, channel.c_str(), on_pose, &st);
  if (!status_channel.empty()) lcm_subscribe(lcm, status_channel.c_str(), on_status, &st);
  // Tell the driver we are subscribed (it waits for this file before starting publishers).
  std::printf("subscribed\n");
  std::fflush(stdout);

  const std::int64_t end =
      duration_s > 0 ? mono_now() + static_cast<std::int64_t>(duration_s * 1e9) : INT64_MAX;
  while (!g_stop.load() && mono_now() < end) lcm_handle_timeout(lcm, 100);
  lcm_destroy(lcm);

  FILE* f = out_path.empty() ? stdout : std::fopen(out_path.c_str(), "w");
  if (f == nullptr) {
    std::perror(out_path.c_str());
    return 1;
  }
  for (const auto& s : st.samples) {
    std::fprintf(f, "%lld %lld %lld %lld\n", static_cast<long long>(s.seq),
                 static_cast<long long>(s.recv_ns), static_cast<long long>(s.mono_ns),
                 static_cast<long long>(s.run_id));
  }
  if (f != stdout) std::fclose(f);
  if (!status_out_path.empty()) {
    FILE* g = std::fopen(status_out_path.c_str(), "w");
    if (g == nullptr) {
      std::perror(status_out_path.c_str());
      return 1;
    }
    for (const auto& s : st.status) {
      std::fprintf(g, "%lld %.3f %.3f %.3f %.3f %.3f %.3f\n", static_cast<long long>(s.seq),
                   s.work_p50, s.work_p99, s.work_max, s.late_p50, s.late_p99, s.late_max);
    }
    std::fclose(g);
  }
  std::fprintf(stderr, "bench_lcm_sub: %zu messages on %s, %zu status, %lld decode errors\n",
               st.samples.size(), channel.c_str(), st.status.size(),
               static_cast<long long>(st.decode_errors));
  return 0;
}
