// Two encoder boards on one CAN bus, boards 0 and 1 (docs/can-protocol.md,
// "Several boards on one bus"): rig A's daemon is the bus's sync master, rig
// B's follows it (sync_master: false), and both boards sample on the one SYNC.
// Each rig's SocketCanSource runs its real read() through its own in-memory
// port on one simulated bus, and must deliver its own board's counts in every
// cycle and never decode a frame of the other board: with the kernel's
// receive filter (the other board's frames never reach the socket) and
// without it (they reach the decoder, which counts them as bad frames by
// their unknown IDs and does nothing else with them). Two sync masters on one
// bus, which the docs forbid: every board answers both SYNCs.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <memory>
#include <vector>

#include "exodaq/drivers/sim_rig.hpp"
#include "exodaq/drivers/socketcan_backend.hpp"
#include "exodaq/drivers/socketcan_source.hpp"
#include "memory_can_port.hpp"

namespace exodaq::drivers {
namespace {

using can::CanFrame;
using test::MemoryCanPort;
using Counts = std::array<std::uint16_t, can::kBoardChannels>;

constexpr std::int64_t kPeriod = 1'000'000;
constexpr std::int64_t kT0 = 10'000'000'000;      // rig A's first deadline (both ports' clock)
constexpr std::int64_t kFollowerPhase = 700'000;  // rig B's deadlines come this much later
constexpr std::int64_t kAnswerNs = 50'000;        // SYNC to a board's first frame
constexpr std::int64_t kSlotNs = 30'000;          // one frame on the wire (simplified)

// The socket's filter as the real port applies it (CAN_RAW_FILTER from
// config.filters: for protocol v1 the aligned 32-ID blocks holding the
// board's IDs, plus SYNC's block when another node is sync master); error
// frames always. (The real port's filter is checked on a kernel vcan in
// test_socketcan_port.cpp, inside the VM.)
std::function<bool(const CanFrame&)> kernel_filter(const CanPortConfig& c) {
  const can::CanIdFilterSet filters = c.filters;
  return [filters](const CanFrame& f) {
    if ((f.flags & can::frame_flag::kError) != 0) return true;
    return filters.passes(f.id);
  };
}

// A board on the bus: a simulated rig of its own (its own seed, power-up count
// and first sequence number, so that its counts differ from the other's).
struct BusBoard {
  BusBoard(int board, std::uint64_t seed) : rig(options(board, seed)) {}
  static sim::SimOptions options(int board, std::uint64_t seed) {
    sim::SimOptions o;
    o.seed = seed;
    o.board.ids.board = static_cast<std::uint32_t>(board);
    o.board.first_seq = static_cast<std::uint8_t>(100 * board);
    o.board.state = static_cast<std::uint8_t>(can::BoardState::kSyncSlave);
    for (auto& e : o.encoders) e.power_up_count = 0x1234 + 0x2222 * board;
    return o;
  }
  sim::SimRig rig;
  sim::SimBoard::Frames frames{};
  std::int64_t next = 0;  // the next board cycle
  std::int64_t frames_sent = 0;
  std::vector<Counts> wire;  // the counts each board cycle put on the bus
};

// One CAN bus: a frame on the wire reaches every other node's port (where its
// filter decides), and each SYNC makes every board answer, board 0 first
// (lower IDs win arbitration).
struct Bus {
  std::vector<MemoryCanPort*> ports;
  std::vector<BusBoard*> boards;
  std::int64_t syncs = 0;

  void transmit(const CanFrame& f, std::int64_t at, const MemoryCanPort* sender) {
    for (MemoryCanPort* p : ports) {
      if (p != sender) p->push(f, at);
    }
  }
  void on_send(const CanFrame& f, MemoryCanPort& from) {
    transmit(f, from.mono, &from);
    if (f.id != can::ProtocolIds{}.sync_id() || f.dlc != 0) return;
    ++syncs;
    std::int64_t at = from.mono + kAnswerNs;
    for (BusBoard* b : boards) {
      const int n = b->rig.step(b->next++, b->frames, 0, 0);
      for (int i = 0; i < n; ++i) {
        transmit(b->frames[static_cast<std::size_t>(i)], at, nullptr);
        at += kSlotNs;
        ++b->frames_sent;
      }
      Counts c{};
      for (int ch = 0; ch < can::kBoardChannels; ++ch)
        c[static_cast<std::size_t>(ch)] = static_cast<std::uint16_t>(b->rig.encoders().count(ch));
      b->wire.push_back(c);
    }
  }
};

// One rig's socketcan source on its own port of the bus.
struct Rig {
  Rig(int board, bool sync_master, bool kernel_filtered, std::int64_t phase) : phase(phase) {
    SocketCanSettings s;
    s.interface = "vcan0";
    s.board = board;
    s.sync_master = sync_master;
    cfg = socketcan_config_from(s, SourceContext{});
    auto p = std::make_unique<MemoryCanPort>();
    port = p.get();
    port->mono = kT0 - kPeriod;
    if (kernel_filtered) port->admit = kernel_filter(cfg.port);
    source = std::make_unique<SocketCanSource>(cfg, std::move(p));
  }
  ReadStatus cycle(std::int64_t k) {
    CycleTime t;
    t.deadline_mono_ns = kT0 + phase + k * kPeriod;
    t.now_mono_ns = t.deadline_mono_ns;
    t.period_ns = kPeriod;
    t.cycle = k;
    port->advance_to(t.deadline_mono_ns);
    return source->read(t, sample);
  }
  Counts counts() const {
    Counts c{};
    std::copy(sample.position.begin(), sample.position.begin() + can::kBoardChannels, c.begin());
    return c;
  }

  std::int64_t phase;
  SocketCanSourceConfig cfg;
  MemoryCanPort* port = nullptr;
  std::unique_ptr<SocketCanSource> source;
  EncoderSample sample;
};

void expect_clean(const Rig& r, const char* name) {
  const SourceStats s = r.source->stats();
  EXPECT_EQ(s.seq_gaps, 0) << name;
  EXPECT_EQ(s.missing_samples, 0) << name;
  EXPECT_EQ(s.duplicates, 0) << name;
  EXPECT_EQ(s.out_of_order, 0) << name;
  EXPECT_EQ(r.source->detail().superseded_samples, 0) << name;
  EXPECT_EQ(r.source->detail().partial_flushes, 0) << name;
}

// Rig A (board 0, sync master) and rig B (board 1, follower) for `cycles`
// cycles: each delivers its own board's cycle k at its cycle k, counts equal
// to what that board put on the wire.
void run_two_rigs(bool kernel_filtered) {
  Rig a(0, true, kernel_filtered, 0);
  Rig b(1, false, kernel_filtered, kFollowerPhase);
  BusBoard board0(0, 1);
  BusBoard board1(1, 2);
  Bus bus{{a.port, b.port}, {&board0, &board1}};
  a.port->on_send = [&bus](const CanFrame& f, MemoryCanPort& p) { bus.on_send(f, p); };
  a.source->start();
  b.source->start();
  constexpr std::int64_t kCycles = 3000;  // 3 s: homing sweeps under way, counts moving
  std::int64_t differ = 0;
  for (std::int64_t k = 0; k < kCycles; ++k) {
    ASSERT_EQ(a.cycle(k), ReadStatus::kSample) << k;
    ASSERT_EQ(b.cycle(k), ReadStatus::kSample) << k;
    const auto ku = static_cast<std::size_t>(k);
    ASSERT_TRUE(a.sample.present && b.sample.present) << k;
    ASSERT_EQ(a.sample.seq, k % 256) << k;
    ASSERT_EQ(b.sample.seq, (100 + k) % 256) << k;
    ASSERT_EQ(a.counts(), board0.wire[ku]) << "rig A, cycle " << k;
    ASSERT_EQ(b.counts(), board1.wire[ku]) << "rig B, cycle " << k;
    EXPECT_EQ(a.sample.flags & ~sample_flag::kBoardError, 0U) << k;
    EXPECT_EQ(b.sample.flags & ~sample_flag::kBoardError, 0U) << k;
    if (board0.wire[ku] != board1.wire[ku]) ++differ;
  }
  // The two boards' counts differ in every cycle: a frame of the other board
  // decoded into a sample could not have gone unnoticed above.
  EXPECT_EQ(differ, kCycles);
  EXPECT_EQ(bus.syncs, kCycles);  // only rig A sends SYNC
  EXPECT_EQ(a.source->detail().sync_sent, kCycles);
  EXPECT_EQ(b.source->detail().sync_sent, 0);
  EXPECT_EQ(board0.next, kCycles);  // each board answered each SYNC once
  EXPECT_EQ(board1.next, kCycles);
  expect_clean(a, "rig A");
  expect_clean(b, "rig B");
  // Rig B's socket admits SYNC (another node is sync master); its decoder
  // counts it and moves on. Rig A never hears its own SYNC.
  EXPECT_EQ(b.source->decoder().detail().sync_frames, kCycles);
  EXPECT_EQ(a.source->decoder().detail().sync_frames, 0);

  const auto unknown = static_cast<std::size_t>(can::Reject::kUnknownId);
  if (kernel_filtered) {
    // The other board's frames stay in the kernel: nothing to count.
    EXPECT_EQ(a.port->filtered, board1.frames_sent);
    EXPECT_EQ(b.port->filtered, board0.frames_sent);
    EXPECT_EQ(a.source->stats().bad_frames, 0);
    EXPECT_EQ(b.source->stats().bad_frames, 0);
  } else {
    // Every frame of the other board reached the decoder and was rejected by
    // its ID, nothing else. Rig A stops reading once its board's last cycle is
    // complete: board 1's last frames (after board 0's) are still queued.
    EXPECT_LE(a.port->queued(), 2);
    EXPECT_EQ(b.port->queued(), 0);
    EXPECT_EQ(a.source->stats().bad_frames + a.port->queued(), board1.frames_sent);
    EXPECT_EQ(a.source->decoder().detail().rejected[unknown] + a.port->queued(),
              board1.frames_sent);
    EXPECT_EQ(b.source->stats().bad_frames, board0.frames_sent);
    EXPECT_EQ(b.source->decoder().detail().rejected[unknown], board0.frames_sent);
  }
}

TEST(TwoBoardsOnOneBus, EachRigDecodesOnlyItsOwnBoard) {
  run_two_rigs(true);
}

TEST(TwoBoardsOnOneBus, WithoutTheKernelFilterForeignFramesAreCountedNeverDecoded) {
  run_two_rigs(false);
}

// What the docs forbid: both daemons sync master. Each board answers both
// SYNCs, two board cycles per period (and at 1 Mbit/s, 2 SYNCs + 8 COUNTS
// frames per millisecond are 119 % of the bus): each rig sees every other
// cycle of its board, the one in between superseded.
TEST(TwoBoardsOnOneBus, TwoSyncMastersMakeEveryBoardAnswerTwice) {
  Rig a(0, true, true, 0);
  Rig b(1, true, true, kFollowerPhase);
  BusBoard board0(0, 1);
  BusBoard board1(1, 2);
  Bus bus{{a.port, b.port}, {&board0, &board1}};
  a.port->on_send = [&bus](const CanFrame& f, MemoryCanPort& p) { bus.on_send(f, p); };
  b.port->on_send = a.port->on_send;
  a.source->start();
  b.source->start();
  constexpr std::int64_t kCycles = 200;
  for (std::int64_t k = 0; k < kCycles; ++k) {
    ASSERT_EQ(a.cycle(k), ReadStatus::kSample) << k;
    ASSERT_EQ(b.cycle(k), ReadStatus::kSample) << k;
    EXPECT_EQ(a.sample.seq, (2 * k) % 256) << k;  // its board runs at twice the rate
  }
  EXPECT_EQ(bus.syncs, 2 * kCycles);
  EXPECT_EQ(board0.next, 2 * kCycles);
  EXPECT_EQ(board1.next, 2 * kCycles);
  EXPECT_GE(a.source->detail().superseded_samples, kCycles - 1);
  EXPECT_GE(b.source->detail().superseded_samples, kCycles - 1);
}

}  // namespace
}  // namespace exodaq::drivers
