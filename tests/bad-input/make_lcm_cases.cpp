// Writes the binary LCM-log inputs of the bad-input catalogue (lcm/*.lcm):
//   build/tests/bad-input/bad_input_make_lcm tests/bad-input/lcm
// Each is a small lcm-logger-format log damaged in one way; the messages they
// must produce are in the checked-in lcm/<name>.expected.

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "sample_messages.hpp"

namespace fs = std::filesystem;

namespace {

using Buf = std::vector<std::uint8_t>;
using Events = std::vector<std::pair<std::string, Buf>>;

exodaq::encoder_raw_t raw(std::int64_t seq, std::int64_t run_id = 0x5eed) {
  return exodaq::test::raw_message(seq, run_id);
}

template <typename T>
Buf encoded(const T& m) {
  return exodaq::messages::encode(m);
}

exodaq::joint_state_t joint_state(std::int64_t seq) {
  exodaq::joint_state_t js{};
  js.seq = seq;
  js.run_id = 0x5eed;
  for (auto& n : js.name) n = std::string(1, 'j');
  return js;
}

void write_log(const fs::path& path, const Events& events) {
  fs::remove(path);
  exodaq::messages::LogWriter log(path);
  std::int64_t t = 1'700'000'000'000'000;
  for (const auto& [channel, data] : events)
    log.write(channel, t += 1000, data.data(), data.size());
  log.close();
}

Events good(int n, const std::string& channel = "EXO_ENCODER_RAW") {
  Events e;
  for (int s = 1; s <= n; ++s) e.push_back({channel, encoded(raw(s))});
  return e;
}

Buf read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return Buf((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void write_bytes(const fs::path& p, const Buf& b) {
  std::ofstream(p, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIR\n", argv[0]);
    return 2;
  }
  const fs::path d = argv[1];
  fs::create_directories(d);

  // Only the recorder's other channels: no raw channel at all.
  Events js;
  for (int s = 1; s <= 3; ++s) js.push_back({"EXO_JOINT_STATE", encoded(joint_state(s))});
  write_log(d / "no_raw_channel.lcm", js);

  // joint_state_t messages published on the raw channel (wrong type).
  Events wrong;
  for (int s = 1; s <= 3; ++s) wrong.push_back({"EXO_ENCODER_RAW", encoded(joint_state(s))});
  write_log(d / "wrong_type_on_raw_channel.lcm", wrong);

  // Two rigs' raw channels in one log, no --channel.
  Events two = good(2, "RIG_A/EXO_ENCODER_RAW");
  for (auto& e : good(2, "RIG_B/EXO_ENCODER_RAW")) two.push_back(e);
  write_log(d / "two_raw_channels.lcm", two);

  // Events 2 and 4 cut short / overwritten: undecodable raw messages among good ones.
  Events mixed = good(5);
  mixed[1].second.resize(20);
  mixed[3].second[3] ^= 0xFF;  // fingerprint
  write_log(d / "undecodable_raw_events.lcm", mixed);

  // A second daemon run (new run_id) in the same log.
  Events runs = good(3);
  for (int s = 1; s <= 2; ++s) runs.push_back({"EXO_ENCODER_RAW", encoded(raw(s, 0xbeef))});
  write_log(d / "second_daemon_run.lcm", runs);

  // Only the daemon's all-zero start-up message.
  write_log(d / "only_startup_message.lcm",
            {{"EXO_ENCODER_RAW", encoded(exodaq::encoder_raw_t{})}});

  // A utime no daemon writes (nanoseconds beyond int64).
  Events future = good(3);
  auto r = raw(2);
  r.utime = INT64_MAX / 100;
  future[1].second = encoded(r);
  write_log(d / "impossible_utime.lcm", future);

  // A negative seq.
  Events neg = good(3);
  auto n = raw(3);
  n.seq = -5;
  neg[2].second = encoded(n);
  write_log(d / "negative_seq.lcm", neg);

  // Nothing at all (an empty file given as --format lcm).
  write_bytes(d / "empty.lcm", {});

  // Garbage instead of an LCM log.
  write_bytes(d / "not_an_lcm_log.lcm", Buf{'h', 'e', 'l', 'l', 'o', '\n'});

  // Garbage appended after three good events (issue 15 point 8): the three
  // are replayed, the garbage reported with its bytes.
  write_log(d / "garbage_after_last_event.lcm", good(3));
  Buf g = read_all(d / "garbage_after_last_event.lcm");
  for (const char ch : std::string("\xde\xad\xbe\xef not an event"))
    g.push_back(static_cast<std::uint8_t>(ch));
  write_bytes(d / "garbage_after_last_event.lcm", g);

  // A recorder killed mid-write: the last event cut short.
  write_log(d / "cut_last_event.lcm", good(3));
  Buf cut = read_all(d / "cut_last_event.lcm");
  cut.erase(cut.end() - 10, cut.end());  // not resize(size() - 10): see make_corpus.cpp
  write_bytes(d / "cut_last_event.lcm", cut);

  // Corrupted: bytes of the second event's header overwritten.
  write_log(d / "corrupt_event_header.lcm", good(4));
  Buf c = read_all(d / "corrupt_event_header.lcm");
  const std::size_t first = 28 + 15 + encoded(raw(1)).size();
  for (std::size_t i = first; i < first + 8; ++i) c[i] = 0x55;
  write_bytes(d / "corrupt_event_header.lcm", c);

  std::printf("LCM cases written under %s\n", d.c_str());
  return 0;
}
