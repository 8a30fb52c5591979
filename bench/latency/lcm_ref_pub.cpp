// The reference for the end-to-end latency benchmark: a bare LCM publisher,
// one thread, sleeping to absolute CLOCK_MONOTONIC deadlines at RATE Hz and
// publishing a palm_pose_t (the same type and size as exodaqd's) stamped with
// its send time in mono_ns (taken just before encode + lcm_publish), its loop
// deadline in run_id and the cycle number in seq. Scheduling: run it under
// chrt like any process.
//
//   bench_lcm_pub --url URL --channel CH [--rate HZ] [--duration S]
#include <lcm/lcm.h>
#include <signal.h>
#include <time.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "exodaq/palm_pose_t.hpp"

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

void sleep_until(std::int64_t t) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(t / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(t % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR && !g_stop.load()) {
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string url = "udpm://239.255.76.67:7667?ttl=0";
  std::string channel;
  double rate_hz = 1000;
  double duration_s = 10;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "bench_lcm_pub: %s needs a value\n", a.c_str());
      return 2;
    }
    const std::string v = argv[++i];
    if (a == "--url") {
      url = v;
    } else if (a == "--channel") {
      channel = v;
    } else if (a == "--rate") {
      rate_hz = std::atof(v.c_str());
    } else if (a == "--duration") {
      duration_s = std::atof(v.c_str());
    } else {
      std::fprintf(stderr, "bench_lcm_pub: unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  if (channel.empty() || rate_hz <= 0) {
    std::fprintf(stderr, "bench_lcm_pub: --channel and a positive --rate are required\n");
    return 2;
  }
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);

  lcm_t* lcm = lcm_create(url.c_str());
  if (lcm == nullptr) {
    std::fprintf(stderr, "bench_lcm_pub: cannot create LCM for %s\n", url.c_str());
    return 1;
  }
  exodaq::palm_pose_t msg;
  msg.valid = 1;
  msg.position[0] = 0.1;
  msg.position[1] = 0.2;
  msg.position[2] = 0.3;
  msg.orientation[0] = 1.0;
  msg.shoulder_manipulability = 0.5;
  std::array<std::uint8_t, 1024> buf{};
  const int size = msg.getEncodedSize();
  if (size > static_cast<int>(buf.size())) return 1;

  const auto period = static_cast<std::int64_t>(1e9 / rate_hz);
  const auto cycles = static_cast<std::int64_t>(duration_s * rate_hz);
  std::int64_t deadline = mono_now() + period;
  std::int64_t sent = 0, failed = 0;
  for (std::int64_t k = 0; k < cycles && !g_stop.load(); ++k, deadline += period) {
    sleep_until(deadline);
    msg.seq = k;
    msg.run_id = deadline;
    msg.mono_ns = mono_now();
    msg.utime = msg.mono_ns / 1000;
    msg.encode(buf.data(), 0, size);
    if (lcm_publish(lcm, channel.c_str(), buf.data(), static_cast<unsigned>(size)) == 0) {
      ++sent;
    } else {
      ++failed;
    }
  }
  lcm_destroy(lcm);
  std::fprintf(stderr, "bench_lcm_pub: %lld sent, %lld failed, %d bytes each\n",
               static_cast<long long>(sent), static_cast<long long>(failed), size);
  return failed == 0 ? 0 : 1;
}
