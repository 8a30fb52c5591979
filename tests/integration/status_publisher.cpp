// A foreign publisher for tests: status_t messages with a given run id and
// rig ("fake-rig" unless given) on one channel, at a rate, until SIGTERM or a
// duration; seq counts the messages from 0.
//   exodaq_test_status_publisher URL CHANNEL RUN_ID_HEX RATE_HZ SECONDS [RIG]
#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>

#include "exodaq/status_t.hpp"

namespace {
volatile std::sig_atomic_t g_stop = 0;
}

int main(int argc, char** argv) {
  if (argc != 6 && argc != 7) {
    std::fprintf(stderr, "usage: %s URL CHANNEL RUN_ID_HEX RATE_HZ SECONDS [RIG]\n", argv[0]);
    return 2;
  }
  std::signal(SIGTERM, [](int) { g_stop = 1; });
  lcm::LCM lcm(argv[1]);
  if (!lcm.good()) return 1;
  const std::string channel = argv[2];
  exodaq::status_t st{};
  st.run_id = static_cast<std::int64_t>(std::strtoull(argv[3], nullptr, 16));
  st.rig = argc == 7 ? argv[6] : "fake-rig";
  st.source = "fake";
  st.state = exodaq::status_t::STATE_RUNNING;
  const auto period = std::chrono::duration<double>(1.0 / std::atof(argv[4]));
  const auto end =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(std::atof(argv[5]));
  long sent = 0;
  while (g_stop == 0 && std::chrono::steady_clock::now() < end) {
    st.utime = std::chrono::duration_cast<std::chrono::microseconds>(
                   std::chrono::system_clock::now().time_since_epoch())
                   .count();
    st.seq = sent;
    if (lcm.publish(channel, &st) == 0) ++sent;
    std::this_thread::sleep_for(period);
  }
  std::printf("%ld\n", sent);
  return 0;
}
