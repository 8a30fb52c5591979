// The SocketCAN backend's frame handling and state machine, driven through the
// in-memory CanPort (no kernel CAN needed): sync master, deadlines, partial
// and late cycles, error frames, interface loss and recovery, kernel drops,
// timestamps, zero allocations in read().
#include <gtest/gtest.h>

#include <cerrno>
#include <memory>

#include "alloc_counter.hpp"
#include "exodaq/drivers/sim_rig.hpp"
#include "exodaq/drivers/socketcan_backend.hpp"
#include "exodaq/drivers/socketcan_source.hpp"
#include "memory_can_port.hpp"

namespace exodaq::drivers {
namespace {

using can::CanFrame;
using test::MemoryCanPort;

constexpr std::int64_t kPeriod = 1'000'000;
constexpr std::int64_t kT0 = 10'000'000'000;  // first cycle deadline (port clock)

// A board that answers each SYNC with the simulated rig's next cycle: INDEX
// frames, COUNTS_A after `latency_a`, COUNTS_B after `latency_b`, heartbeats.
struct Board {
  explicit Board(MemoryCanPort& port) : rig(sim::SimOptions{}) {
    port.on_send = [this](const CanFrame& f, MemoryCanPort& p) { on_send(f, p); };
  }
  void on_send(const CanFrame& f, MemoryCanPort& p) {
    if (f.id != 0x080 || silent) return;
    const std::int64_t k = next++;
    const int n = rig.step(k, frames, 0, 0);
    for (int i = 0; i < n; ++i) {
      const CanFrame& fr = frames[static_cast<std::size_t>(i)];
      const bool is_b = fr.id == 0x182;
      if (is_b && drop_b_at == k) continue;
      std::int64_t at = p.mono + (is_b ? latency_b : latency_a);
      if (late_at == k) at += late_by;
      p.push(fr, at);
      if (is_b) last_b_arrival = at;
    }
  }
  sim::SimRig rig;
  sim::SimBoard::Frames frames{};
  std::int64_t next = 0;
  std::int64_t latency_a = 100'000;
  std::int64_t latency_b = 150'000;
  std::int64_t drop_b_at = -1;
  std::int64_t late_at = -1;
  std::int64_t late_by = 0;
  std::int64_t last_b_arrival = 0;
  bool silent = false;
};

struct Fixture {
  explicit Fixture(bool sync_master = true) {
    auto p = std::make_unique<MemoryCanPort>();
    port = p.get();
    SocketCanSettings s;
    s.interface = "vcan0";
    s.sync_master = sync_master;
    cfg = socketcan_config_from(s, SourceContext{});
    source = std::make_unique<SocketCanSource>(cfg, std::move(p));
  }
  ReadStatus cycle(std::int64_t k) {
    CycleTime t;
    t.deadline_mono_ns = kT0 + k * kPeriod;
    t.now_mono_ns = t.deadline_mono_ns;
    t.period_ns = kPeriod;
    t.cycle = k;
    port->advance_to(t.deadline_mono_ns);
    return source->read(t, sample);
  }
  std::int64_t deadline(std::int64_t k) const { return kT0 + k * kPeriod; }
  // One board cycle's two COUNTS frames, the second (completing it) 10 µs after `at`.
  void cycle_frames(std::uint8_t seq, std::int64_t at) {
    port->push(can::encode_counts(0, {1, 2, 3}, 0, seq), at);
    port->push(can::encode_counts(1, {4, 5, 6}, 0, seq), at + 10'000);
  }
  // A free-running board: its cycles 0 .. cycles - 1 put on the port in
  // advance, cycle k's frames from first + k * period on, 1 µs apart.
  void free_run(std::int64_t cycles, std::int64_t first) {
    sim::SimRig rig{sim::SimOptions{}};
    sim::SimBoard::Frames frames{};
    for (std::int64_t k = 0; k < cycles; ++k) {
      const int n = rig.step(k, frames, 0, 0);
      for (int i = 0; i < n; ++i)
        port->push(frames[static_cast<std::size_t>(i)], first + k * kPeriod + i * 1000);
    }
  }

  SocketCanSourceConfig cfg;
  MemoryCanPort* port = nullptr;
  std::unique_ptr<SocketCanSource> source;
  EncoderSample sample;
};

TEST(SocketCanSource, ConfigFromSettings) {
  SocketCanSettings s;
  s.interface = "can1";
  s.board = 1;
  s.sync_master = false;
  s.read_deadline_us = 250;
  const SocketCanSourceConfig c = socketcan_config_from(s, SourceContext{});
  EXPECT_EQ(c.port.interface, "can1");
  EXPECT_EQ(c.decoder.ids.counts_a_id(), 0x1A1U);
  // Board 1's blocks and SYNC's (another node is sync master).
  EXPECT_TRUE(c.port.filters.passes(0x1A1U));
  EXPECT_TRUE(c.port.filters.passes(0x1B5U));
  EXPECT_TRUE(c.port.filters.passes(0x721U));
  EXPECT_TRUE(c.port.filters.passes(0x080U));
  EXPECT_FALSE(c.port.filters.passes(0x181U));
  EXPECT_FALSE(c.port.filters.passes(0x701U));
  EXPECT_FALSE(c.sync_master);
  EXPECT_EQ(c.read_deadline_ns, 250'000);
  EXPECT_EQ(c.reopen_interval_ns, 1'000'000'000);
}

TEST(SocketCanSource, SyncMasterNormalCycles) {
  Fixture f;
  Board board(*f.port);
  f.source->start();
  for (std::int64_t k = 0; k < 300; ++k) {
    ASSERT_EQ(f.cycle(k), ReadStatus::kSample) << k;
    ASSERT_TRUE(f.sample.present);
    EXPECT_EQ(f.sample.seq, k % 256);
    EXPECT_EQ(f.sample.flags & ~sample_flag::kBoardError, 0U) << k;
    EXPECT_EQ(f.sample.channel_fresh, 0x3FU);
    // The sample instant is the kernel receive stamp of COUNTS_B, the frame
    // that completed the cycle; mono_ns is the same instant on CLOCK_MONOTONIC.
    EXPECT_EQ(f.sample.wall_ns, board.last_b_arrival + MemoryCanPort::kWallOffsetNs);
    EXPECT_EQ(f.sample.mono_ns, board.last_b_arrival);
    // read() returned as soon as the cycle was complete, not at the deadline.
    EXPECT_EQ(f.port->mono, f.deadline(k) + board.latency_b);
    // Counts are what the simulated board counted.
    for (int c = 0; c < 6; ++c) {
      EXPECT_EQ(f.sample.position[static_cast<std::size_t>(c)],
                static_cast<std::uint16_t>(board.rig.encoders().count(c) & 0xFFFF));
    }
  }
  // One SYNC per cycle, DLC 0, ID 0x080.
  ASSERT_EQ(f.port->sent.size(), 300U);
  for (const CanFrame& s : f.port->sent) {
    EXPECT_EQ(s.id, 0x080U);
    EXPECT_EQ(s.dlc, 0);
  }
  const SourceStats st = f.source->stats();
  EXPECT_EQ(st.seq_gaps, 0);
  EXPECT_EQ(st.missing_samples, 0);
  EXPECT_EQ(st.bad_frames, 0);
  EXPECT_EQ(st.bus_state, BusState::kActive);
  EXPECT_EQ(f.source->detail().sync_sent, 300);
  EXPECT_EQ(f.source->detail().superseded_samples, 0);
}

TEST(SocketCanSource, NoBoardWaitsUntilThePollDeadlineThenMissing) {
  Fixture f;
  f.source->start();
  for (std::int64_t k = 0; k < 5; ++k) {
    EXPECT_EQ(f.cycle(k), ReadStatus::kNoSample);
    EXPECT_FALSE(f.sample.present);
    EXPECT_NE(f.sample.flags & sample_flag::kMissing, 0U);
    // Waited exactly read_deadline_us after the cycle start.
    EXPECT_EQ(f.port->mono, f.deadline(k) + 400'000);
    // A missing sample is stamped with the cycle's deadline.
    EXPECT_EQ(f.sample.mono_ns, f.deadline(k));
    EXPECT_EQ(f.sample.wall_ns, f.deadline(k) + MemoryCanPort::kWallOffsetNs);
  }
  EXPECT_EQ(f.port->sent.size(), 5U);
  EXPECT_EQ(f.source->stats().missing_samples, 5);
}

TEST(SocketCanSource, PollDeadlineNeverPastTheCycle) {
  Fixture f;
  SocketCanSettings s;
  s.read_deadline_us = 900;
  auto p = std::make_unique<MemoryCanPort>();
  MemoryCanPort* port = p.get();
  SocketCanSource src(socketcan_config_from(s, SourceContext{}), std::move(p));
  src.start();
  CycleTime t;
  t.deadline_mono_ns = kT0;
  t.period_ns = kPeriod;
  port->advance_to(kT0);
  EncoderSample out;
  EXPECT_EQ(src.read(t, out), ReadStatus::kNoSample);
  EXPECT_EQ(port->mono, kT0 + kPeriod - kPeriod / 10);  // guard of period / 10
}

TEST(SocketCanSource, PartialCycleFlushedAtTheDeadline) {
  Fixture f;
  Board board(*f.port);
  board.drop_b_at = 5;
  f.source->start();
  for (std::int64_t k = 0; k < 10; ++k) {
    ASSERT_EQ(f.cycle(k), ReadStatus::kSample) << k;
    if (k == 5) {
      EXPECT_NE(f.sample.flags & sample_flag::kPartial, 0U);
      EXPECT_EQ(f.sample.channel_fresh, 0x07U);
      EXPECT_EQ(f.port->mono, f.deadline(k) + 400'000);  // waited for B until the deadline
      EXPECT_EQ(f.sample.mono_ns, f.deadline(k) + board.latency_a);  // stamped by A
    } else {
      EXPECT_EQ(f.sample.flags & sample_flag::kPartial, 0U) << k;
      EXPECT_EQ(f.sample.channel_fresh, 0x3FU);
    }
  }
  EXPECT_EQ(f.source->detail().partial_flushes, 1);
  EXPECT_EQ(f.source->decoder().detail().partial_samples, 1);
}

TEST(SocketCanSource, LateAnswerIsSupersededAndItsIndexLatchKept) {
  Fixture f;
  f.source->start();
  // Cycle 0: complete on time.
  const auto counts = [&](int which, std::uint8_t seq, std::uint8_t idx, std::int64_t at) {
    f.port->push(can::encode_counts(which, {1, 2, 3}, idx, seq), at);
  };
  counts(0, 0, 0, f.deadline(0) + 100'000);
  counts(1, 0, 0, f.deadline(0) + 110'000);
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  EXPECT_EQ(f.sample.seq, 0);
  // Cycle 1: the answer (with an index latch on channel 1) only arrives after
  // the poll deadline → missing.
  f.port->push(can::encode_index(1, 777, 1), f.deadline(1) + 500'000);
  counts(0, 1, 0x02, f.deadline(1) + 500'000);
  counts(1, 1, 0, f.deadline(1) + 510'000);
  EXPECT_EQ(f.cycle(1), ReadStatus::kNoSample);
  // Cycle 2: seq 1 is queued, seq 2 arrives → the newest is delivered, seq 1
  // superseded, its index latch merged in.
  counts(0, 2, 0, f.deadline(2) + 100'000);
  counts(1, 2, 0, f.deadline(2) + 110'000);
  ASSERT_EQ(f.cycle(2), ReadStatus::kSample);
  EXPECT_EQ(f.sample.seq, 2);
  EXPECT_NE(f.sample.index_latched & 0x02U, 0U);
  EXPECT_NE(f.sample.index_count_valid & 0x02U, 0U);
  EXPECT_EQ(f.sample.index_position[1], 777);
  EXPECT_EQ(f.source->detail().superseded_samples, 1);
  EXPECT_EQ(f.source->stats().seq_gaps, 0);
  // Sync master waited for the answer to this cycle's SYNC (seq 2), not for seq 1.
  EXPECT_EQ(f.port->mono, f.deadline(2) + 110'000);
}

TEST(SocketCanSource, MalformedFramesCountedNotFatal) {
  Fixture f;
  Board board(*f.port);
  f.source->start();
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  CanFrame wrong_dlc = can::encode_counts(0, {1, 2, 3}, 0, 9);
  wrong_dlc.dlc = 4;
  CanFrame unknown;
  unknown.id = 0x185;
  unknown.dlc = 8;
  CanFrame rtr;
  rtr.id = 0x181;
  rtr.flags = can::frame_flag::kRtr;
  f.port->push(wrong_dlc, f.deadline(1));
  f.port->push(unknown, f.deadline(1));
  f.port->push(rtr, f.deadline(1));
  ASSERT_EQ(f.cycle(1), ReadStatus::kSample);
  EXPECT_EQ(f.source->stats().bad_frames, 3);
  EXPECT_EQ(f.source->decoder().detail().rejected[static_cast<int>(can::Reject::kWrongDlc)], 1);
  EXPECT_EQ(f.source->decoder().detail().rejected[static_cast<int>(can::Reject::kUnknownId)], 1);
  EXPECT_EQ(f.source->decoder().detail().rejected[static_cast<int>(can::Reject::kRtr)], 1);
  EXPECT_EQ(f.sample.seq, 1);
}

TEST(SocketCanSource, ErrorFramesDriveBusStateAndBusErrors) {
  Fixture f;
  Board board(*f.port);
  f.source->start();
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  EXPECT_EQ(f.source->stats().bus_state, BusState::kActive);

  can::ErrorPayload warn;
  warn.classes = can::err_class::kCrtl;
  warn.controller = can::err_crtl::kRxWarning;
  f.port->push(can::encode_error(warn), f.deadline(1));
  ASSERT_EQ(f.cycle(1), ReadStatus::kSample);
  EXPECT_EQ(f.source->stats().bus_state, BusState::kWarning);
  EXPECT_NE(f.sample.flags & sample_flag::kBusError, 0U);  // event flag on this sample
  ASSERT_EQ(f.cycle(2), ReadStatus::kSample);
  EXPECT_EQ(f.sample.flags & sample_flag::kBusError, 0U);  // warning is not a level flag

  can::ErrorPayload off;
  off.classes = can::err_class::kBusOff;
  f.port->push(can::encode_error(off), f.deadline(3));
  ASSERT_EQ(f.cycle(3), ReadStatus::kSample);
  EXPECT_EQ(f.source->stats().bus_state, BusState::kOff);
  ASSERT_EQ(f.cycle(4), ReadStatus::kSample);
  EXPECT_NE(f.sample.flags & sample_flag::kBusError, 0U);  // level flag while bus-off

  can::ErrorPayload restarted;
  restarted.classes = can::err_class::kRestarted;
  f.port->push(can::encode_error(restarted), f.deadline(5));
  ASSERT_EQ(f.cycle(5), ReadStatus::kSample);
  EXPECT_EQ(f.source->stats().bus_state, BusState::kActive);
  ASSERT_EQ(f.cycle(6), ReadStatus::kSample);
  EXPECT_EQ(f.sample.flags & sample_flag::kBusError, 0U);
  EXPECT_EQ(f.source->stats().bus_errors, 3);
}

TEST(SocketCanSource, InterfaceDownDegradesThenRecovers) {
  Fixture f;
  Board board(*f.port);
  f.source->start();
  std::int64_t k = 0;
  for (; k < 10; ++k) ASSERT_EQ(f.cycle(k), ReadStatus::kSample);
  const int opens = f.port->open_calls;

  // ip link set vcan0 down: the socket reports ENETDOWN once.
  f.port->take_down();
  f.port->send_error = ENETDOWN;
  ASSERT_EQ(f.cycle(k++), ReadStatus::kNoSample);
  EXPECT_EQ(f.source->stats().bus_state, BusState::kDown);
  EXPECT_NE(f.sample.flags & sample_flag::kBusError, 0U);
  EXPECT_NE(f.sample.flags & sample_flag::kMissing, 0U);
  EXPECT_EQ(f.source->detail().link.interface_losses, 1);
  EXPECT_FALSE(f.port->is_open());

  // While down: missing samples, no re-open more often than once a second.
  const std::int64_t lost_at = f.port->mono;
  for (; f.deadline(k) < lost_at + 2'500'000'000; ++k) {
    ASSERT_EQ(f.cycle(k), ReadStatus::kNoSample);
    EXPECT_NE(f.sample.flags & sample_flag::kBusError, 0U);
    // Down: read() returns at once (no waiting on a closed socket).
    EXPECT_EQ(f.port->mono, f.deadline(k));
  }
  EXPECT_EQ(f.port->open_calls - opens, 2);  // at +1 s and +2 s
  EXPECT_EQ(f.source->detail().link.reopen_attempts, 2);
  EXPECT_EQ(f.source->detail().link.last_errno, ENETDOWN);
  // What source_status_t and the daemon's log carry.
  SourceDiagnostics down;
  f.source->diagnose(down);
  EXPECT_EQ(down.state(), f.source->config().port.interface + " down: ENETDOWN");
  ASSERT_NE(down.find("interface_losses"), nullptr);
  EXPECT_EQ(down.find("interface_losses")->value, 1);
  EXPECT_EQ(down.find("reopen_attempts")->value, 2);
  EXPECT_EQ(down.find("reopens")->value, 0);
  EXPECT_EQ(down.find("samples")->value, 10);  // the decoder's, after the source's own
  EXPECT_EQ(down.dropped(), 0);

  // ip link set vcan0 up: recovered at the next attempt (≤ 1 s later).
  f.port->bring_up();
  f.port->send_error = 0;
  std::int64_t recovered = -1;
  for (int i = 0; i < 1100; ++i, ++k) {
    if (f.cycle(k) == ReadStatus::kSample) {
      recovered = k;
      break;
    }
  }
  ASSERT_GE(recovered, 0);
  EXPECT_EQ(f.source->detail().link.reopens, 1);
  EXPECT_EQ(f.source->stats().bus_state, BusState::kActive);
  EXPECT_EQ(f.sample.flags & sample_flag::kBusError, 0U);
  for (int i = 0; i < 10; ++i) ASSERT_EQ(f.cycle(++k), ReadStatus::kSample);
  SourceDiagnostics up;
  f.source->diagnose(up);
  EXPECT_EQ(up.state(), f.source->config().port.interface + " open, last error ENETDOWN");
  EXPECT_EQ(up.find("reopens")->value, 1);
}

TEST(SocketCanSource, InterfaceRemovedAndRecreated) {
  Fixture f;
  Board board(*f.port);
  f.source->start();
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  f.port->remove();
  f.port->send_error = ENODEV;
  ASSERT_EQ(f.cycle(1), ReadStatus::kNoSample);
  EXPECT_EQ(f.source->stats().bus_state, BusState::kDown);
  std::int64_t k = 2;
  for (; k < 1200; ++k) f.cycle(k);  // an attempt at +1 s fails with ENODEV
  EXPECT_EQ(f.source->detail().link.last_errno, ENODEV);
  f.port->bring_up();
  f.port->send_error = 0;
  for (; k < 2300 && f.cycle(k) != ReadStatus::kSample; ++k) {
  }
  EXPECT_EQ(f.source->stats().bus_state, BusState::kActive);
  EXPECT_EQ(f.source->detail().link.reopens, 1);
}

TEST(SocketCanSource, StartsDegradedWhenTheInterfaceIsMissing) {
  Fixture f;
  f.port->exists = false;
  f.port->up = false;
  EXPECT_NO_THROW(f.source->start());
  EXPECT_EQ(f.source->stats().bus_state, BusState::kDown);
  EXPECT_EQ(f.cycle(0), ReadStatus::kNoSample);
  EXPECT_TRUE(f.port->sent.empty());
}

TEST(SocketCanSource, StartThrowsWithoutCanSupport) {
  Fixture f;
  f.port->open_error = EAFNOSUPPORT;
  EXPECT_THROW(f.source->start(), std::runtime_error);
}

TEST(SocketCanSource, KernelDropsCountedAsRxOverflows) {
  Fixture f;
  Board board(*f.port);
  f.source->start();
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  f.port->pending_drops = 5;
  ASSERT_EQ(f.cycle(1), ReadStatus::kSample);
  f.port->pending_drops = 2;
  ASSERT_EQ(f.cycle(2), ReadStatus::kSample);
  EXPECT_EQ(f.source->stats().rx_overflows, 7);
}

TEST(SocketCanSource, SyncSendQueueFullIsCountedNotBlocking) {
  Fixture f;
  Board board(*f.port);
  f.source->start();
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  f.port->send_error = ENOBUFS;
  EXPECT_EQ(f.cycle(1), ReadStatus::kNoSample);
  f.port->send_error = EAGAIN;
  EXPECT_EQ(f.cycle(2), ReadStatus::kNoSample);
  f.port->send_error = 0;
  EXPECT_EQ(f.cycle(3), ReadStatus::kSample);
  EXPECT_EQ(f.source->detail().sync_send_failures, 2);
  EXPECT_EQ(f.source->detail().link.interface_losses, 0);
  EXPECT_EQ(f.source->stats().bus_state, BusState::kActive);
}

TEST(SocketCanSource, FreeRunningBoardFollowed) {
  Fixture f(false);
  f.source->start();
  // The board samples at its own 1 kHz, 700 µs after each of our deadlines:
  // later than the poll deadline, so each read() delivers the previous
  // board cycle at once without waiting.
  f.free_run(100, f.deadline(0) + 700'000);
  EXPECT_EQ(f.cycle(0), ReadStatus::kNoSample);
  for (std::int64_t k = 1; k < 100; ++k) {
    ASSERT_EQ(f.cycle(k), ReadStatus::kSample) << k;
    EXPECT_EQ(f.sample.seq, k - 1);
    EXPECT_EQ(f.port->mono, f.deadline(k));  // no waiting
    EXPECT_EQ(f.sample.flags & ~sample_flag::kBoardError, 0U);
  }
  EXPECT_TRUE(f.port->sent.empty());  // not sync master: no SYNC
  EXPECT_EQ(f.source->stats().seq_gaps, 0);
}

TEST(SocketCanSource, FreeRunningBoardEarlyInTheCycle) {
  Fixture f(false);
  f.source->start();
  f.free_run(50, f.deadline(0) + 200'000);
  for (std::int64_t k = 0; k < 50; ++k) {
    ASSERT_EQ(f.cycle(k), ReadStatus::kSample) << k;
    EXPECT_EQ(f.sample.seq, k);  // waited for it within the cycle
  }
}

// A free-running board's cycles queued in the socket while the reader was away
// (here 300 cycles, far more than the decoder's queue): the reader delivers
// them all, oldest first, one per read, saying after each whether more wait;
// catch-up reads never wait and never send anything. Nothing superseded,
// nothing dropped from the decoder's queue, no sequence gap.
TEST(SocketCanSource, FreeRunningBacklogIsDeliveredOldestFirstWithNothingSuperseded) {
  Fixture f(false);
  f.source->start();
  constexpr std::int64_t kQueued = 300;
  f.free_run(kQueued, f.deadline(0) - kQueued * kPeriod + 200'000);
  CycleTime t;
  t.deadline_mono_ns = f.deadline(0);
  t.now_mono_ns = f.deadline(0);
  t.period_ns = kPeriod;
  f.port->advance_to(t.deadline_mono_ns);
  EXPECT_TRUE(f.source->free_running());
  std::int64_t k = 0;
  for (; k < kQueued; ++k) {
    ASSERT_EQ(f.source->read(t, f.sample), ReadStatus::kSample) << k;
    EXPECT_EQ(f.sample.seq, k % 256);
    EXPECT_TRUE(f.sample.present);
    EXPECT_EQ(f.sample.flags & ~sample_flag::kBoardError, 0U) << k;
    // Stamped when its COUNTS_B came in, long before this read.
    EXPECT_LT(f.sample.mono_ns, f.deadline(0) - (kQueued - k) * kPeriod + 210'000);
    EXPECT_GT(f.sample.mono_ns, f.deadline(0) - (kQueued - k) * kPeriod + 200'000);
    EXPECT_EQ(f.source->backlog() > 0, k + 1 < kQueued) << k;
    EXPECT_EQ(f.port->mono, f.deadline(0));  // never waited
    t.catch_up = true;
  }
  EXPECT_EQ(f.source->read(t, f.sample), ReadStatus::kNothingDue);
  EXPECT_TRUE(f.port->sent.empty());
  EXPECT_EQ(f.source->stats().superseded_samples, 0);
  EXPECT_EQ(f.source->detail().superseded_samples, 0);
  EXPECT_EQ(f.source->decoder().detail().queue_overflows, 0);
  EXPECT_EQ(f.source->stats().seq_gaps, 0);
  EXPECT_EQ(f.source->stats().missing_samples, 0);
}

// Following a free-running board whose clock is a little slow: a read that
// finds nothing by its poll deadline while the last sample is barely a period
// old has nothing to publish (no MISSING); once the board is overdue (1.5
// periods), MISSING every read until it comes back.
TEST(SocketCanSource, FreeRunningNothingDueUntilTheBoardIsOverdue) {
  Fixture f(false);
  f.source->start();
  f.cycle_frames(0, f.deadline(0) + 390'000);  // complete at 400 µs: just within the wait
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  EXPECT_EQ(f.sample.mono_ns, f.deadline(0) + 400'000);
  f.cycle_frames(1, f.deadline(1) + 395'000);      // complete at 405 µs: just after it
  EXPECT_EQ(f.cycle(1), ReadStatus::kNothingDue);  // 1.0 periods since the last: not overdue
  EXPECT_EQ(f.port->mono, f.deadline(1) + 400'000);
  ASSERT_EQ(f.cycle(2), ReadStatus::kSample);  // there at once
  EXPECT_EQ(f.sample.seq, 1);
  EXPECT_EQ(f.port->mono, f.deadline(2));
  // Then silence: at the next poll deadline the last sample is 1.995 periods
  // old, overdue: MISSING, every read.
  EXPECT_EQ(f.cycle(3), ReadStatus::kNoSample);
  EXPECT_NE(f.sample.flags & sample_flag::kMissing, 0U);
  EXPECT_EQ(f.sample.mono_ns, f.deadline(3));
  EXPECT_EQ(f.cycle(4), ReadStatus::kNoSample);
  EXPECT_EQ(f.source->stats().missing_samples, 2);
  EXPECT_EQ(f.source->stats().superseded_samples, 0);
}

// Following a free-running board, the reader is descheduled for 100 µs after
// its poll deadline, just before it reads the clock to judge the board
// overdue; the board's cycle reached the socket 50 µs after that deadline.
// It is taken, not declared MISSING with the frames already queued (the VM's
// free-running stage under host load, CI of stop 22).
TEST(SocketCanSource, FreeRunningACycleQueuedBeforeTheOverdueClockReadingIsTaken) {
  Fixture f(false);
  f.source->start();
  f.cycle_frames(0, f.deadline(0) + 390'000);
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  EXPECT_EQ(f.cycle(1), ReadStatus::kNothingDue);  // silent, 1.0 periods: not overdue
  const std::int64_t poll_deadline = f.deadline(2) + 400'000;
  f.cycle_frames(1, poll_deadline + 40'000);  // complete 50 µs after the poll deadline
  bool descheduled = false;
  f.port->on_now = [&](MemoryCanPort& p) {
    if (descheduled || p.mono < poll_deadline) return;
    descheduled = true;
    p.mono += 100'000;
  };
  ASSERT_EQ(f.cycle(2), ReadStatus::kSample);
  EXPECT_TRUE(descheduled);
  EXPECT_EQ(f.sample.seq, 1);
  EXPECT_EQ(f.sample.mono_ns, poll_deadline + 50'000);
  EXPECT_EQ(f.source->stats().missing_samples, 0);
  // Then silence: not overdue at the next poll deadline (0.95 periods), then
  // overdue with nothing queued: MISSING.
  EXPECT_EQ(f.cycle(3), ReadStatus::kNothingDue);
  EXPECT_EQ(f.cycle(4), ReadStatus::kNoSample);
  EXPECT_EQ(f.source->stats().missing_samples, 1);
}

// Following a free-running board whose cycle 1 the kernel stamped 1.11
// periods after cycle 0 (as it entered the stack) but queued to the socket
// only 2.3 periods after it (the receive softirq deferred to ksoftirqd, or the
// sender's vCPU held off by the host between the two: the VM's free-running
// stage under host load). MISSING is judged on what reached the socket by the
// overdue clock reading, not on stamps: wake 2 finds nothing 2.0 periods after
// the last sample and publishes MISSING; the cycle is published at the next
// wake, with its own stamp, after the MISSING (docs/can-protocol.md, "One
// cycle", step 7).
TEST(SocketCanSource, FreeRunningACycleQueuedAfterTheOverdueReadingIsMissingThenPublished) {
  Fixture f(false);
  f.source->start();
  f.cycle_frames(0, f.deadline(0) + 390'000);
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  const std::int64_t heard = f.sample.mono_ns;
  const std::int64_t stamp_a = f.deadline(1) + 500'000, stamp_b = stamp_a + 10'000;
  const std::int64_t queued = f.deadline(2) + 700'000;
  f.port->push(can::encode_counts(0, {1, 2, 3}, 0, 1), queued, stamp_a);
  f.port->push(can::encode_counts(1, {4, 5, 6}, 0, 1), queued, stamp_b);
  EXPECT_EQ(f.cycle(1), ReadStatus::kNothingDue);  // 1.0 periods: not overdue
  ASSERT_EQ(f.cycle(2), ReadStatus::kNoSample);    // 2.0 periods, nothing in the socket
  EXPECT_NE(f.sample.flags & sample_flag::kMissing, 0U);
  EXPECT_LT(stamp_b - heard, kPeriod + kPeriod / 2);  // the stamps show no such silence
  EXPECT_LT(f.port->mono, queued);
  ASSERT_EQ(f.cycle(3), ReadStatus::kSample);
  EXPECT_EQ(f.sample.seq, 1);
  EXPECT_EQ(f.sample.mono_ns, stamp_b);
  EXPECT_EQ(f.sample.flags & sample_flag::kMissing, 0U);
  EXPECT_EQ(f.source->stats().missing_samples, 1);
  EXPECT_EQ(f.source->stats().seq_gaps, 0);
  EXPECT_EQ(f.source->stats().superseded_samples, 0);
}

// Following a free-running board, the kernel queues cycle 1 to the socket
// after cycle 2 (the board simulator sent them from two vCPUs, cycle 1's
// receive softirq deferred). The decoder has closed cycle 2 when cycle 1's
// frames come: both are dropped as out of order and counted, cycle 2 carries
// SEQ_GAP (one cycle lost) and the next sample OUT_OF_ORDER: the board cycle
// is not published, and it is counted (docs/can-protocol.md, "Cycle assembly").
TEST(SocketCanSource, FreeRunningACycleQueuedAfterANewerOneIsCountedOutOfOrder) {
  Fixture f(false);
  f.source->start();
  f.cycle_frames(0, f.deadline(0) + 100'000);
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  const std::int64_t late = f.deadline(1) + 950'000;  // both in the socket before wake 2
  f.cycle_frames(2, f.deadline(1) + 900'000);         // cycle 2 sent late, queued first
  f.port->push(can::encode_counts(0, {1, 2, 3}, 0, 1), late, f.deadline(1) + 100'000);
  f.port->push(can::encode_counts(1, {4, 5, 6}, 0, 1), late, f.deadline(1) + 110'000);
  f.cycle_frames(3, f.deadline(3) + 100'000);
  EXPECT_EQ(f.cycle(1), ReadStatus::kNothingDue);
  ASSERT_EQ(f.cycle(2), ReadStatus::kSample);
  EXPECT_EQ(f.sample.seq, 2);
  EXPECT_EQ(f.sample.flags & ~sample_flag::kBoardError, sample_flag::kSeqGap);
  EXPECT_EQ(f.source->backlog(), 0);
  ASSERT_EQ(f.cycle(3), ReadStatus::kSample);
  EXPECT_EQ(f.sample.seq, 3);
  EXPECT_EQ(f.sample.flags & ~sample_flag::kBoardError, sample_flag::kOutOfOrder);
  EXPECT_EQ(f.source->stats().out_of_order, 2);
  EXPECT_EQ(f.source->stats().seq_gaps, 1);
  EXPECT_EQ(f.source->decoder().detail().lost_cycles, 1);
  EXPECT_EQ(f.source->stats().missing_samples, 0);
  EXPECT_EQ(f.source->stats().superseded_samples, 0);
}

// Following a free-running board that stops half-way through a cycle: its
// COUNTS_A comes 1.17 periods after the last sample, COUNTS_B never. The
// reader wakes late, 1.56 periods after that sample and 0.39 after the half:
// the board was heard from, so nothing is due (not MISSING); the next wake
// flushes the half as PARTIAL, stamped when it came; MISSING only once that
// is 1.5 periods old. (The VM's free-running stage: the board simulator killed
// between the two frames of its last cycle gave a MISSING inside a 1.2-period
// silence, CI of stop 22.)
TEST(SocketCanSource, FreeRunningAHalfCycleIsNotSilence) {
  Fixture f(false);
  f.source->start();
  f.cycle_frames(0, f.deadline(0) + 380'000);
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  const std::int64_t half_at = f.deadline(1) + 560'000;
  f.port->push(can::encode_counts(0, {7, 8, 9}, 0, 1), half_at);
  f.port->advance_to(f.deadline(1) + 950'000);     // a late wake
  EXPECT_EQ(f.cycle(1), ReadStatus::kNothingDue);  // overdue, were the half not heard
  ASSERT_EQ(f.cycle(2), ReadStatus::kSample);      // the half is over half a period old
  EXPECT_NE(f.sample.flags & sample_flag::kPartial, 0U);
  EXPECT_EQ(f.sample.seq, 1);
  EXPECT_EQ(f.sample.mono_ns, half_at);
  EXPECT_EQ(f.cycle(3), ReadStatus::kNoSample);  // 1.84 periods since the half: MISSING
  EXPECT_EQ(f.source->stats().missing_samples, 1);
}

// Sync master, the loop 2.5 ms late: the SYNC leaves late and is counted; the
// reader waits for its answer from the SYNC on (not from the missed
// deadline, whose poll deadline has long passed), so the sample arrives with
// its true stamp instead of going MISSING and being superseded later.
TEST(SocketCanSource, ALateSyncIsCountedAndItsAnswerWaitedFor) {
  Fixture f;
  Board board(*f.port);
  f.source->start();
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  CycleTime t;
  t.deadline_mono_ns = f.deadline(1);
  t.period_ns = kPeriod;
  t.cycle = 1;
  const std::int64_t sync_at = f.deadline(1) + 2'500'000;
  f.port->advance_to(sync_at);
  t.now_mono_ns = sync_at;
  ASSERT_EQ(f.source->read(t, f.sample), ReadStatus::kSample);
  EXPECT_EQ(f.sample.seq, 1);
  EXPECT_EQ(f.sample.mono_ns, sync_at + board.latency_b);  // the true instant
  EXPECT_EQ(f.source->detail().late_syncs, 1);
  // 50 µs late is not late.
  f.port->advance_to(f.deadline(4) + 50'000);
  t.deadline_mono_ns = f.deadline(4);
  t.now_mono_ns = f.port->mono;
  ASSERT_EQ(f.source->read(t, f.sample), ReadStatus::kSample);
  EXPECT_EQ(f.source->detail().late_syncs, 1);
  EXPECT_EQ(f.source->stats().missing_samples, 0);
  EXPECT_EQ(f.source->detail().superseded_samples, 0);
  EXPECT_EQ(f.source->backlog(), 0);  // sync master: one SYNC, one sample
}

TEST(SocketCanSource, UnstampedFramesStampedAtReadTime) {
  Fixture f;
  Board board(*f.port);
  f.port->stamp = false;
  f.source->start();
  ASSERT_EQ(f.cycle(0), ReadStatus::kSample);
  EXPECT_EQ(f.sample.mono_ns, f.deadline(0) + board.latency_b);
  EXPECT_GE(f.source->detail().link.unstamped_frames, 2);
}

TEST(SocketCanSource, ReadAllocatesNothing) {
  Fixture f;
  Board board(*f.port);
  board.drop_b_at = 7;
  board.late_at = 20;
  board.late_by = 900'000;
  f.source->start();
  std::int64_t k = 0;
  for (; k < 5; ++k) f.cycle(k);  // warm-up
  SourceDiagnostics diagnostics;
  test::AllocationScope scope;
  for (; k < 2000; ++k) {
    if (k == 100) {
      can::ErrorPayload off;
      off.classes = can::err_class::kBusOff;
      f.port->push(can::encode_error(off), f.deadline(k));
    }
    if (k == 200) {
      f.port->take_down();
      f.port->send_error = ENETDOWN;
    }
    if (k == 700) {
      f.port->bring_up();
      f.port->send_error = 0;
    }
    if (k == 1500) f.port->pending_drops = 3;
    f.cycle(k);
    if (k % 100 == 0) {  // a status window
      diagnostics.clear();
      f.source->diagnose(diagnostics);
    }
  }
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(f.source->detail().link.reopens, 1);
  EXPECT_EQ(f.source->stats().rx_overflows, 3);
}

}  // namespace
}  // namespace exodaq::drivers
