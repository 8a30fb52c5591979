// A subscriber process for the integration tests: records every message on
// channels matching a regex, raw, to a file, until SIGTERM/SIGINT.
// Record: u32 channel length, channel, u32 data length, data, i64 receive mono ns.
#include <lcm/lcm.h>
#include <signal.h>
#include <time.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace {
volatile sig_atomic_t g_stop = 0;
void on_signal(int) {
  g_stop = 1;
}

void on_message(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
  auto* out = static_cast<std::FILE*>(user);
  const auto clen = static_cast<std::uint32_t>(std::strlen(channel));
  const auto dlen = static_cast<std::uint32_t>(rbuf->data_size);
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  const std::int64_t now = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
  std::fwrite(&clen, 4, 1, out);
  std::fwrite(channel, 1, clen, out);
  std::fwrite(&dlen, 4, 1, out);
  std::fwrite(rbuf->data, 1, dlen, out);
  std::fwrite(&now, 8, 1, out);
}
}  // namespace

int main(int argc, char** argv) {
  if (argc != 4) {
    std::fprintf(stderr, "usage: lcm_recorder URL CHANNEL_REGEX OUTFILE\n");
    return 2;
  }
  ::signal(SIGTERM, on_signal);
  ::signal(SIGINT, on_signal);
  lcm_t* lcm = lcm_create(argv[1]);
  if (lcm == nullptr) {
    std::fprintf(stderr, "lcm_recorder: cannot open %s\n", argv[1]);
    return 1;
  }
  std::FILE* out = std::fopen(argv[3], "wb");
  if (out == nullptr) return 1;
  // No queue limit: LCM's default of 30 messages is 10 ms at 3 kHz, and a
  // recorder that drops messages itself would blame the daemon.
  lcm_subscription_t* sub = lcm_subscribe(lcm, argv[2], on_message, out);
  lcm_subscription_set_queue_capacity(sub, 0);
  std::fprintf(stderr, "lcm_recorder: ready\n");
  while (g_stop == 0) lcm_handle_timeout(lcm, 50);
  std::fclose(out);
  lcm_destroy(lcm);
  return 0;
}
