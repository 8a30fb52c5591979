// Writes the binary seed inputs of tests/fuzz/corpus/ (the text seeds are
// checked in as written by hand). Run once after a format change:
//   build/tests/fuzz/fuzz_make_corpus tests/fuzz/corpus
// Seeds are small, valid or near-valid inputs in each target's input layout.

#include <array>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "exodaq/drivers/can_codec.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq_v1/encoder_raw_t.hpp"
#include "sample_messages.hpp"

namespace can = exodaq::drivers::can;
namespace fs = std::filesystem;

namespace {

using Buf = std::vector<std::uint8_t>;

void put_u8(Buf& b, unsigned v) {
  b.push_back(static_cast<std::uint8_t>(v));
}
void put_u16(Buf& b, unsigned v) {
  put_u8(b, v & 0xFF);
  put_u8(b, (v >> 8) & 0xFF);
}
void put_u32(Buf& b, std::uint32_t v) {
  put_u16(b, v & 0xFFFF);
  put_u16(b, v >> 16);
}

void write(const fs::path& dir, const std::string& name, const Buf& b) {
  fs::create_directories(dir);
  std::ofstream(dir / name, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

// can_codec layout: [selector][id u32][dlc][flags][data 8]
Buf frame_input(unsigned selector, const can::CanFrame& f) {
  Buf b;
  put_u8(b, selector);
  put_u32(b, f.id);
  put_u8(b, f.dlc);
  put_u8(b, f.flags);
  for (auto d : f.data) put_u8(b, d);
  return b;
}

exodaq::encoder_raw_t raw_message(std::int64_t seq) {
  return exodaq::test::raw_message(seq, 0x1234);
}

// The same cycle as version 1 wrote it (recordings made before version 2).
exodaq_v1::encoder_raw_t raw_message_v1(std::int64_t seq) {
  const exodaq::encoder_raw_t m = raw_message(seq);
  exodaq_v1::encoder_raw_t v1{};
  v1.utime = m.utime;
  v1.mono_ns = m.mono_ns;
  v1.seq = m.seq;
  v1.run_id = m.run_id;
  v1.present = m.present;
  v1.board_seq = static_cast<std::int16_t>(m.source_seq);
  for (int c = 0; c < 6; ++c) v1.count16[c] = static_cast<std::int16_t>(m.position[c]);
  v1.board_state = m.board_state;
  v1.wall_ns = m.wall_ns;
  return v1;
}

template <typename T>
Buf encoded(const T& m) {
  return exodaq::messages::encode(m);
}

void write_lcm_log(const fs::path& path, const std::vector<std::pair<std::string, Buf>>& events) {
  fs::create_directories(path.parent_path());
  fs::remove(path);
  exodaq::messages::LogWriter log(path);
  std::int64_t t = 1'700'000'000'000'000;
  for (const auto& [channel, data] : events)
    log.write(channel, t += 1000, data.data(), data.size());
  log.close();
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR\n", argv[0]);
    return 2;
  }
  const fs::path root = argv[1];

  // can_codec: one of every frame kind, board 0 and 1, and near misses.
  {
    const fs::path d = root / "can_codec";
    can::ProtocolIds b1;
    b1.board = 1;
    write(d, "sync", frame_input(0, can::encode_sync()));
    write(d, "counts_a", frame_input(0, can::encode_counts(0, {1, 2, 3}, 1, 7)));
    write(d, "counts_b_board1", frame_input(1, can::encode_counts(1, {4, 5, 6}, 0, 8, b1)));
    write(d, "index", frame_input(0, can::encode_index(2, 1234, 9)));
    can::HeartbeatPayload hb{1, 0x11, 0x04, 1};
    write(d, "heartbeat", frame_input(0, can::encode_heartbeat(hb)));
    write(d, "heartbeat_dlc2", frame_input(0, can::encode_heartbeat(hb, 2)));
    can::ErrorPayload e;
    e.classes = can::err_class::kBusOff | can::err_class::kCrtl;
    e.controller = can::err_crtl::kRxPassive;
    write(d, "error", frame_input(0, can::encode_error(e)));
    auto wrong = can::encode_counts(0, {1, 2, 3}, 0, 1);
    wrong.dlc = 7;
    write(d, "counts_wrong_dlc", frame_input(0, wrong));
    auto rtr = can::encode_sync();
    rtr.flags = can::frame_flag::kRtr;
    write(d, "sync_rtr", frame_input(0, rtr));
    auto fd = can::encode_counts(1, {1, 2, 3}, 0, 1);
    fd.flags = can::frame_flag::kFd;
    write(d, "counts_fd", frame_input(0, fd));
    Buf custom = frame_input(0x80, can::encode_index(0, 1, 2));
    for (std::uint32_t v : {0x100U, 0x201U, 0x202U, 0x210U, 0x301U, 0U, 0x40U}) put_u32(custom, v);
    write(d, "custom_ids", custom);
  }

  // board_decoder: op streams (see fuzz_board_decoder.cpp).
  {
    const fs::path d = root / "board_decoder";
    const auto counts = [](Buf& b, int which, unsigned seq, unsigned base, unsigned step) {
      put_u8(b, static_cast<unsigned>(which));
      put_u8(b, seq);
      put_u16(b, base);
      put_u16(b, base + 1);
      put_u16(b, base + 2);
      put_u8(b, 0);     // latched
      put_u8(b, step);  // time step after the frame (x 1 us)
    };
    Buf normal{0, 8};
    for (unsigned s = 0; s < 12; ++s) {
      counts(normal, 0, s, 100 + s, 100);
      counts(normal, 1, s, 200 + s, 250);
      put_u8(normal, 9);  // poll
    }
    write(d, "twelve_cycles", normal);

    Buf faults{0, 8};
    counts(faults, 0, 0, 10, 100);
    counts(faults, 1, 0, 20, 250);
    counts(faults, 0, 1, 11, 100);  // B of seq 1 lost
    counts(faults, 0, 2, 12, 100);
    counts(faults, 1, 2, 22, 250);
    counts(faults, 1, 2, 22, 250);  // duplicate
    counts(faults, 0, 5, 15, 100);  // gap
    counts(faults, 1, 4, 24, 250);  // out of order
    counts(faults, 1, 5, 25, 250);
    put_u8(faults, 4);  // index ch 3
    put_u8(faults, 3);
    put_u16(faults, 777);
    put_u8(faults, 5);
    put_u8(faults, 5);  // heartbeat with errors
    for (unsigned v : {1U, 0x01U, 0x02U, 1U, 4U}) put_u8(faults, v);
    put_u8(faults, 6);  // error frame: bus off
    put_u32(faults, can::err_class::kBusOff);
    put_u8(faults, 0);
    put_u8(faults, 0);
    put_u8(faults, 0);
    put_u8(faults, 9);
    put_u8(faults, 10);  // flush
    put_u8(faults, 11);  // missing
    put_u8(faults, 13);  // time jump
    put_u8(faults, 0);
    put_u16(faults, 5000);
    counts(faults, 0, 200, 30, 100);  // resync after silence
    counts(faults, 1, 200, 40, 250);
    put_u8(faults, 9);
    write(d, "faults", faults);
  }

  // encoder_raw: the raw channel's encoding, and one with present = 0.
  {
    const fs::path d = root / "encoder_raw";
    write(d, "sample", encoded(raw_message(42)));
    auto m = raw_message(43);
    m.present = 0;
    m.source_flags = 1;
    write(d, "missing", encoded(m));
    // Cut the last five bytes. erase, not resize(size() - 5): GCC 12 at -O1
    // with ASan cannot prove size() >= 5 and fails -Werror=stringop-overflow.
    auto t = encoded(raw_message(44));
    t.erase(t.end() - 5, t.end());
    write(d, "truncated", t);
    write(d, "v1-sample", encoded(raw_message_v1(45)));
  }

  // replay_file: small LCM logs (the candump seeds are text, checked in).
  {
    const fs::path d = root / "replay_file";
    std::vector<std::pair<std::string, Buf>> ev;
    ev.push_back({"EXO_ENCODER_RAW", encoded(exodaq::encoder_raw_t{})});  // start-up message
    for (int s = 1; s <= 6; ++s) {
      exodaq::joint_state_t js{};
      js.seq = s;
      js.run_id = 0x1234;
      js.sample_flags = s == 3 ? 0x100 : 0;
      ev.push_back({"EXO_JOINT_STATE", encoded(js)});
      auto r = raw_message(s);
      if (s == 4) r.source_flags = 0x200;  // partial
      ev.push_back({"EXO_ENCODER_RAW", encoded(r)});
    }
    write_lcm_log(d / "lcm_with_joint_state.lcm", ev);
    std::vector<std::pair<std::string, Buf>> prefixed;
    for (int s = 1; s <= 4; ++s)
      prefixed.push_back({"RIG2/EXO_ENCODER_RAW", encoded(raw_message(s))});
    auto other = raw_message(5);
    other.run_id = 0x9999;
    prefixed.push_back({"RIG2/EXO_ENCODER_RAW", encoded(other)});
    prefixed.push_back({"RIG2/EXO_ENCODER_RAW", Buf{1, 2, 3}});
    write_lcm_log(d / "lcm_prefixed_other_run.lcm", prefixed);
    std::vector<std::pair<std::string, Buf>> v1;
    for (int s = 1; s <= 4; ++s) v1.push_back({"EXO_ENCODER_RAW", encoded(raw_message_v1(s))});
    write_lcm_log(d / "lcm_version1.lcm", v1);
  }
  std::printf("seeds written under %s\n", root.c_str());
  return 0;
}
