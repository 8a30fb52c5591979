// A daemon's stream with known holes, for the recorder and the clients:
//   exodaq_test_seq_publisher URL PREFIX
// Run 0x5eed: cycles 0..599 (joint_state_t, palm_pose_t, encoder_raw_t), one
// every 2 ms, and a status_t after every 100th, as exodaqd publishes them.
// Seq 100..102 and 250 the "daemon" skipped (its statuses count them:
// seq + 1 - cycles); seq 180, 300 and 301 it published but the network
// "lost" (not sent, counted as published). Then seq 10..14 again (a second
// stream with this run id) and the final STOPPING status.
// Expected per kind: 593 received, 7 missing: 4 skipped by the daemon,
// 3 lost; 5 repeated.
#include <chrono>
#include <cstdio>
#include <set>
#include <string>
#include <thread>

#include "exodaq/core/udpm_sender.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/message.hpp"

namespace {

using namespace exodaq;

constexpr std::int64_t kRun = 0x5eed;
constexpr int kCycles = 600;

template <typename T>
void stamp(T& m, std::int64_t seq) {
  m.utime = 1'700'000'000'000'000 + seq * 1000;
  m.mono_ns = 5'000'000'000 + seq * 1'000'000;
  m.seq = seq;
  m.run_id = kRun;
}

template <typename T>
void send(core::UdpmSender& tx, const std::string& channel, const T& m) {
  const auto bytes = messages::encode(m);
  if (tx.send(channel, bytes.data(), bytes.size()) != 0) std::fprintf(stderr, "send failed\n");
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: %s URL PREFIX\n", argv[0]);
    return 2;
  }
  const std::string url = argv[1];
  const std::string prefix = argv[2];
  const auto address = core::parse_udpm_url(url);
  if (!address) return 2;
  core::UdpmSender tx(*address, url);
  const std::set<std::int64_t> skipped{100, 101, 102, 250};
  const std::set<std::int64_t> lost{180, 300, 301};
  const auto cycle = [&](std::int64_t seq) {
    joint_state_t j{};
    stamp(j, seq);
    for (auto& n : j.name) n = "j";
    palm_pose_t p{};
    stamp(p, seq);
    encoder_raw_t r{};
    stamp(r, seq);
    send(tx, messages::channel_name(prefix, messages::Kind::kJointState), j);
    send(tx, messages::channel_name(prefix, messages::Kind::kPalmPose), p);
    send(tx, messages::channel_name(prefix, messages::Kind::kEncoderRaw), r);
  };
  std::int64_t unpublished = 0;
  const auto status = [&](std::int64_t seq, std::int8_t state) {
    status_t s{};
    stamp(s, seq);
    s.rig = "seq-publisher";
    s.state = state;
    s.cycles = seq + 1 - unpublished;
    s.overruns = unpublished;
    for (auto& n : s.joint_name) n = "j";
    send(tx, messages::channel_name(prefix, messages::Kind::kStatus), s);
  };
  for (std::int64_t seq = 0; seq < kCycles; ++seq) {
    if (skipped.count(seq) != 0) {
      ++unpublished;
    } else if (lost.count(seq) == 0) {
      cycle(seq);
    }
    if (seq % 100 == 99) status(seq, status_t::STATE_RUNNING);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  for (std::int64_t seq = 10; seq < 15; ++seq) cycle(seq);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  status(kCycles - 1, status_t::STATE_STOPPING);
  return 0;
}
