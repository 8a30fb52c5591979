// BoardDecoder: cycle assembly, sequence gaps, duplicates, out-of-order,
// partial cycles, index merging, heartbeat and error frames, with exact
// counters and flags.
#include <gtest/gtest.h>

#include <string>

#include "exodaq/drivers/board_decoder.hpp"

namespace can = exodaq::drivers::can;
namespace flag = exodaq::drivers::sample_flag;
using exodaq::drivers::BoardDecoder;
using exodaq::drivers::BoardDecoderConfig;
using exodaq::drivers::BusState;
using exodaq::drivers::EncoderSample;
using exodaq::drivers::SourceDiagnostics;

namespace {

constexpr std::int64_t kMs = 1'000'000;

// Counts of cycle `seq`: channel c reads 1000 * c + seq.
std::array<std::uint16_t, 3> counts_for(int which, int seq) {
  std::array<std::uint16_t, 3> v{};
  for (int i = 0; i < 3; ++i)
    v[static_cast<std::size_t>(i)] = static_cast<std::uint16_t>(1000 * (3 * which + i) + seq);
  return v;
}

can::CanFrame counts(int which, int seq, std::int64_t mono_ns, std::uint8_t latched = 0) {
  can::CanFrame f =
      can::encode_counts(which, counts_for(which, seq), latched, static_cast<std::uint8_t>(seq));
  f.mono_ns = mono_ns;
  f.wall_ns = mono_ns + 1'700'000'000'000'000'000LL;
  return f;
}

class Decoder : public ::testing::Test {
 protected:
  // Feeds both halves of cycle `seq`, A stamped at t, B at t + 130 us.
  void cycle(int seq, std::int64_t t) {
    dec.on_frame(counts(0, seq, t));
    dec.on_frame(counts(1, seq, t + 130'000));
  }
  EncoderSample take() {
    EncoderSample s;
    EXPECT_TRUE(dec.poll_sample(s));
    return s;
  }
  BoardDecoder dec;
};

TEST_F(Decoder, CompleteCycleAssemblesOneSampleStampedByTheLaterFrame) {
  dec.on_frame(counts(0, 5, 10 * kMs));
  EXPECT_EQ(dec.queued(), 0);
  EXPECT_TRUE(dec.has_partial());
  dec.on_frame(counts(1, 5, 10 * kMs + 130'000));
  EXPECT_EQ(dec.queued(), 1);
  EXPECT_FALSE(dec.has_partial());
  const EncoderSample s = take();
  EXPECT_TRUE(s.present);
  EXPECT_EQ(s.seq, 5);
  for (int c = 0; c < 6; ++c) EXPECT_EQ(s.position[static_cast<std::size_t>(c)], 1000 * c + 5);
  EXPECT_EQ(s.channel_fresh, 0x3FU);
  EXPECT_EQ(s.flags, 0U);
  EXPECT_EQ(s.mono_ns, 10 * kMs + 130'000);
  EXPECT_EQ(s.wall_ns, 10 * kMs + 130'000 + 1'700'000'000'000'000'000LL);
  EXPECT_EQ(dec.stats().frames, 2);
  EXPECT_EQ(dec.detail().samples, 1);
  EXPECT_EQ(dec.stats().bus_state, BusState::kActive);
  EncoderSample none;
  EXPECT_FALSE(dec.poll_sample(none));
  EXPECT_FALSE(dec.flush(none));
}

TEST_F(Decoder, BHalfFirstAlsoCompletes) {
  dec.on_frame(counts(1, 9, 2 * kMs));
  dec.on_frame(counts(0, 9, 2 * kMs + 50'000));
  const EncoderSample s = take();
  EXPECT_EQ(s.seq, 9);
  EXPECT_EQ(s.mono_ns, 2 * kMs + 50'000);
  EXPECT_EQ(s.flags, 0U);
}

TEST_F(Decoder, SequenceWrapIsNotAGap) {
  for (int k = 250; k < 262; ++k) {
    cycle(k & 0xFF, k * kMs);
    const EncoderSample s = take();
    EXPECT_EQ(s.seq, k & 0xFF);
    EXPECT_EQ(s.flags, 0U);
  }
  EXPECT_EQ(dec.stats().seq_gaps, 0);
}

TEST_F(Decoder, GapIsCountedAndFlaggedOnTheNextSample) {
  cycle(10, 10 * kMs);
  cycle(14, 14 * kMs);  // 11, 12, 13 lost
  cycle(15, 15 * kMs);
  EXPECT_EQ(take().flags, 0U);
  const EncoderSample s = take();
  EXPECT_EQ(s.seq, 14);
  EXPECT_EQ(s.flags, flag::kSeqGap);
  EXPECT_EQ(take().flags, 0U);
  EXPECT_EQ(dec.stats().seq_gaps, 1);
  EXPECT_EQ(dec.detail().lost_cycles, 3);
}

TEST_F(Decoder, DuplicatesAreDroppedCountedAndFlagged) {
  cycle(1, 1 * kMs);
  dec.on_frame(counts(0, 1, 1 * kMs + 200'000));  // repeat of a taken cycle
  dec.on_frame(counts(1, 1, 1 * kMs + 300'000));
  dec.on_frame(counts(0, 2, 2 * kMs));
  dec.on_frame(counts(0, 2, 2 * kMs + 10'000));  // same half twice while assembling
  dec.on_frame(counts(1, 2, 2 * kMs + 130'000));
  EXPECT_EQ(take().flags, 0U);
  const EncoderSample s = take();
  EXPECT_EQ(s.seq, 2);
  EXPECT_EQ(s.flags, flag::kDuplicate);
  EXPECT_EQ(s.mono_ns, 2 * kMs + 130'000);
  EXPECT_EQ(dec.stats().duplicates, 3);
  EXPECT_EQ(dec.stats().out_of_order, 0);
  EXPECT_EQ(dec.stats().frames, 7);
  EXPECT_EQ(dec.queued(), 0);
}

TEST_F(Decoder, OlderFramesAreOutOfOrder) {
  cycle(20, 20 * kMs);
  cycle(21, 21 * kMs);
  dec.on_frame(counts(0, 19, 22 * kMs));  // older than everything taken
  dec.on_frame(counts(1, 18, 22 * kMs));
  cycle(22, 22 * kMs);
  EXPECT_EQ(take().flags, 0U);
  EXPECT_EQ(take().flags, 0U);
  EXPECT_EQ(take().flags, flag::kOutOfOrder);
  EXPECT_EQ(dec.stats().out_of_order, 2);
  EXPECT_EQ(dec.stats().duplicates, 0);
  EXPECT_EQ(dec.stats().seq_gaps, 0);
}

TEST_F(Decoder, PartialByDeadlineFlushHoldsTheOtherHalf) {
  cycle(1, 1 * kMs);
  EXPECT_EQ(take().flags, 0U);
  dec.on_frame(counts(0, 2, 2 * kMs));  // B of cycle 2 never comes
  EncoderSample s;
  EXPECT_FALSE(dec.poll_sample(s));
  ASSERT_TRUE(dec.flush(s));
  EXPECT_TRUE(s.present);
  EXPECT_EQ(s.seq, 2);
  EXPECT_EQ(s.flags, flag::kPartial);
  EXPECT_EQ(s.channel_fresh, 0x07U);
  EXPECT_EQ(s.position[0], 2);         // fresh
  EXPECT_EQ(s.position[3], 3000 + 1);  // held from cycle 1
  EXPECT_EQ(s.mono_ns, 2 * kMs);
  EXPECT_EQ(dec.detail().partial_samples, 1);
  // B of cycle 2 arriving after the flush is late, not a duplicate.
  dec.on_frame(counts(1, 2, 2 * kMs + 900'000));
  cycle(3, 3 * kMs);
  const EncoderSample n = take();
  EXPECT_EQ(n.flags, flag::kOutOfOrder);
  EXPECT_EQ(n.position[3], 3003);
  EXPECT_EQ(dec.stats().out_of_order, 1);
}

TEST_F(Decoder, PartialClosedByANewerCycleOnlyB) {
  dec.on_frame(counts(1, 7, 7 * kMs));  // A of 7 lost
  cycle(8, 8 * kMs);
  const EncoderSample s7 = take();
  EXPECT_EQ(s7.seq, 7);
  EXPECT_EQ(s7.flags, flag::kPartial);
  EXPECT_EQ(s7.channel_fresh, 0x38U);
  EXPECT_EQ(s7.position[0], 0);  // nothing known yet for A's channels
  EXPECT_EQ(s7.position[4], 4007);
  const EncoderSample s8 = take();
  EXPECT_EQ(s8.flags, 0U);
  EXPECT_EQ(s8.channel_fresh, 0x3FU);
  EXPECT_EQ(dec.detail().partial_samples, 1);
  EXPECT_EQ(dec.stats().seq_gaps, 0);
}

TEST_F(Decoder, MissingHoldsCountsAndCarriesEventFlags) {
  cycle(3, 3 * kMs);
  take();
  dec.on_frame(counts(0, 3, 3 * kMs + 500'000));  // duplicate, then silence
  EncoderSample m;
  dec.make_missing(m, 4 * kMs, 5 * kMs);
  EXPECT_FALSE(m.present);
  EXPECT_EQ(m.flags, flag::kMissing | flag::kDuplicate);
  EXPECT_EQ(m.seq, 3);
  EXPECT_EQ(m.position[5], 5003);
  EXPECT_EQ(m.channel_fresh, 0U);
  EXPECT_EQ(m.mono_ns, 4 * kMs);
  EXPECT_EQ(m.wall_ns, 5 * kMs);
  EXPECT_EQ(dec.stats().missing_samples, 1);
  cycle(5, 5 * kMs);  // 4 lost
  EXPECT_EQ(take().flags, flag::kSeqGap);
}

TEST_F(Decoder, IndexLatchBitsAndIndexFramesMerge) {
  // Board order: INDEX before the counts of its cycle.
  dec.on_frame(can::encode_index(4, 0x2710, 30));
  dec.on_frame(counts(0, 30, 30 * kMs, 0x01));
  dec.on_frame(counts(1, 30, 30 * kMs, 0x02));  // channel 4 latched
  EncoderSample s = take();
  EXPECT_EQ(s.index_latched, (1U << 0) | (1U << 4));
  EXPECT_EQ(s.index_count_valid, 1U << 4);
  EXPECT_EQ(s.index_position[4], 0x2710);
  EXPECT_EQ(dec.detail().index_frames, 1);

  // INDEX after its cycle completed but before it was taken.
  cycle(31, 31 * kMs);
  dec.on_frame(can::encode_index(0, 0x1111, 31));
  s = take();
  EXPECT_EQ(s.index_count_valid, 1U << 0);
  EXPECT_EQ(s.index_position[0], 0x1111);
  EXPECT_EQ(s.index_latched, 0U);

  // INDEX of a cycle already taken: carried by the next sample.
  dec.on_frame(can::encode_index(2, 0x2222, 31));
  dec.on_frame(counts(0, 32, 32 * kMs));
  dec.on_frame(can::encode_index(1, 0x3333, 32));  // into the half-assembled cycle
  dec.on_frame(counts(1, 32, 32 * kMs));
  s = take();
  EXPECT_EQ(s.index_count_valid, (1U << 1) | (1U << 2));
  EXPECT_EQ(s.index_position[1], 0x3333);
  EXPECT_EQ(s.index_position[2], 0x2222);

  // Early INDEX (cycle not started) waits for its cycle.
  dec.on_frame(can::encode_index(3, 0x4444, 34));
  cycle(33, 33 * kMs);
  EXPECT_EQ(take().index_count_valid, 0U);
  cycle(34, 34 * kMs);
  s = take();
  EXPECT_EQ(s.index_count_valid, 1U << 3);
  EXPECT_EQ(s.index_position[3], 0x4444);
}

TEST_F(Decoder, HeartbeatErrorsRaiseBoardErrorWhileSet) {
  can::HeartbeatPayload hb;
  hb.state = static_cast<std::uint8_t>(can::BoardState::kFreeRun);
  hb.errors = can::board_error::kQuadrature;
  hb.channel_quadrature_errors = 0x04;
  hb.protocol_version = 1;
  dec.on_frame(can::encode_heartbeat(hb));
  cycle(1, 1 * kMs);
  cycle(2, 2 * kMs);
  EncoderSample s = take();
  EXPECT_EQ(s.flags, flag::kBoardError);
  EXPECT_EQ(s.board_state, 1U);
  EXPECT_EQ(s.board_errors, 0x0401U);
  EXPECT_EQ(take().flags, flag::kBoardError);  // level, not event
  EXPECT_EQ(dec.stats().board_errors, 0x0401U);
  hb.errors = 0;
  hb.channel_quadrature_errors = 0;
  dec.on_frame(can::encode_heartbeat(hb));
  cycle(3, 3 * kMs);
  s = take();
  EXPECT_EQ(s.flags, 0U);
  EXPECT_EQ(s.board_errors, 0U);
  EXPECT_EQ(dec.detail().heartbeats, 2);
  EXPECT_EQ(dec.detail().protocol_version, 1);
  EXPECT_EQ(dec.stats().board_errors, 0U);
}

TEST_F(Decoder, ErrorFramesCountSetBusStateAndFlag) {
  cycle(1, 1 * kMs);
  take();
  can::ErrorPayload warn;
  warn.classes = can::err_class::kCrtl;
  warn.controller = can::err_crtl::kRxWarning;
  dec.on_frame(can::encode_error(warn));
  EXPECT_EQ(dec.stats().bus_state, BusState::kWarning);
  cycle(2, 2 * kMs);
  EXPECT_EQ(take().flags, flag::kBusError);  // event: once
  cycle(3, 3 * kMs);
  EXPECT_EQ(take().flags, 0U);

  can::ErrorPayload passive;
  passive.classes = can::err_class::kCrtl;
  passive.controller = can::err_crtl::kTxPassive | can::err_crtl::kRxOverflow;
  dec.on_frame(can::encode_error(passive));
  EXPECT_EQ(dec.stats().bus_state, BusState::kPassive);
  EXPECT_EQ(dec.stats().rx_overflows, 1);

  can::ErrorPayload off;
  off.classes = can::err_class::kBusOff;
  dec.on_frame(can::encode_error(off));
  EXPECT_EQ(dec.stats().bus_state, BusState::kOff);
  EncoderSample m;
  dec.make_missing(m, 4 * kMs, 0);
  EXPECT_EQ(m.flags, flag::kMissing | flag::kBusError);
  dec.make_missing(m, 5 * kMs, 0);
  EXPECT_EQ(m.flags, flag::kMissing | flag::kBusError);  // level while bus-off

  can::ErrorPayload restarted;
  restarted.classes = can::err_class::kRestarted;
  dec.on_frame(can::encode_error(restarted));
  EXPECT_EQ(dec.stats().bus_state, BusState::kActive);

  can::ErrorPayload ack;
  ack.classes = can::err_class::kAck | can::err_class::kProt;
  dec.on_frame(can::encode_error(ack));
  EXPECT_EQ(dec.stats().bus_state, BusState::kActive);
  cycle(6, 6 * kMs);
  EXPECT_EQ(take().flags, flag::kBusError | flag::kSeqGap);
  cycle(7, 7 * kMs);
  EXPECT_EQ(take().flags, 0U);
  EXPECT_EQ(dec.stats().bus_errors, 5);
  EXPECT_EQ(dec.stats().bad_frames, 0);

  dec.set_bus_state(BusState::kDown);
  dec.make_missing(m, 8 * kMs, 0);
  EXPECT_EQ(m.flags, flag::kMissing | flag::kBusError);
  dec.add_rx_overflows(3);
  EXPECT_EQ(dec.stats().rx_overflows, 4);
}

TEST_F(Decoder, BadFramesAreCountedByReasonAndChangeNothing) {
  cycle(1, 1 * kMs);
  can::CanFrame wrong_dlc = counts(0, 2, 2 * kMs);
  wrong_dlc.dlc = 6;
  can::CanFrame unknown = counts(0, 2, 2 * kMs);
  unknown.id = 0x300;
  can::CanFrame rtr = counts(0, 2, 2 * kMs);
  rtr.flags = can::frame_flag::kRtr;
  can::CanFrame ext = counts(0, 2, 2 * kMs);
  ext.flags = can::frame_flag::kExtended;
  can::CanFrame fd = counts(0, 2, 2 * kMs);
  fd.flags = can::frame_flag::kFd;
  for (const auto& f : {wrong_dlc, unknown, rtr, ext, fd}) {
    EXPECT_EQ(dec.on_frame(f), can::FrameKind::kRejected);
  }
  EXPECT_EQ(dec.on_frame(can::encode_sync()), can::FrameKind::kSync);
  cycle(2, 2 * kMs);
  EXPECT_EQ(take().flags, 0U);
  EXPECT_EQ(take().flags, 0U);
  const auto& d = dec.detail();
  EXPECT_EQ(d.source.frames, 10);
  EXPECT_EQ(d.source.bad_frames, 5);
  EXPECT_EQ(d.rejected[static_cast<std::size_t>(can::Reject::kWrongDlc)], 1);
  EXPECT_EQ(d.rejected[static_cast<std::size_t>(can::Reject::kUnknownId)], 1);
  EXPECT_EQ(d.rejected[static_cast<std::size_t>(can::Reject::kRtr)], 1);
  EXPECT_EQ(d.rejected[static_cast<std::size_t>(can::Reject::kExtended)], 1);
  EXPECT_EQ(d.rejected[static_cast<std::size_t>(can::Reject::kFd)], 1);
  EXPECT_EQ(d.sync_frames, 1);
  EXPECT_EQ(d.source.seq_gaps, 0);
  // The same counts by name, as source_status_t carries them.
  SourceDiagnostics named;
  dec.diagnose(named);
  for (const char* name : {"rejected_unknown_id", "rejected_wrong_dlc", "rejected_rtr",
                           "rejected_extended_id", "rejected_can_fd", "sync_frames"}) {
    ASSERT_NE(named.find(name), nullptr) << name;
    EXPECT_EQ(named.find(name)->value, 1) << name;
  }
  EXPECT_EQ(named.find("samples")->value, 2);
  EXPECT_EQ(named.find("resyncs")->value, 0);
}

TEST(SourceDiagnostics, HoldsItsCapacityCountsTheRestAndCutsTheState) {
  SourceDiagnostics d;
  for (int i = 0; i < SourceDiagnostics::kMaxCounters + 3; ++i) d.add("counter", i);
  EXPECT_EQ(d.counters().size(), static_cast<std::size_t>(SourceDiagnostics::kMaxCounters));
  EXPECT_EQ(d.dropped(), 3);
  EXPECT_EQ(d.counters().back().value, SourceDiagnostics::kMaxCounters - 1);
  d.set_state(std::string(200, 's'));
  EXPECT_EQ(d.state().size(), static_cast<std::size_t>(SourceDiagnostics::kMaxStateBytes - 1));
  d.add(std::string_view("a_name_longer_than_the_twenty_four_bytes_allowed"), 1);
  d.clear();
  EXPECT_TRUE(d.counters().empty());
  EXPECT_TRUE(d.state().empty());
  EXPECT_EQ(d.dropped(), 0);
  d.add("a_name_longer_than_the_twenty_four_bytes_allowed", 7);
  EXPECT_EQ(d.counters()[0].name, "a_name_longer_than_the_t");
  EXPECT_EQ(d.find("missing"), nullptr);
}

TEST_F(Decoder, ResyncAfterSilence) {
  cycle(100, 100 * kMs);
  take();
  // The board restarts 500 ms later with seq 0, which looks "older" than 100.
  cycle(0, 600 * kMs);
  const EncoderSample s = take();
  EXPECT_EQ(s.seq, 0);
  EXPECT_EQ(s.flags, flag::kSeqGap);
  EXPECT_EQ(dec.detail().resyncs, 1);
  EXPECT_EQ(dec.stats().seq_gaps, 1);
  EXPECT_EQ(dec.stats().out_of_order, 0);
}

// A board held off between the two frames of cycle 118 (the VM's free-running
// stage under host load: COUNTS_B 185 ms after COUNTS_A). The second half
// still belongs to cycle 118 however long the silence: it completes the cycle
// being assembled, or, once the reader flushed the first half as PARTIAL, it
// is too late for it (out of order). Either way cycle 118 is one sample, never
// a second one opened by the silence's resynchronisation.
TEST_F(Decoder, TheOtherHalfAfterASilenceCompletesItsCycle) {
  cycle(117, 100 * kMs);
  take();
  dec.on_frame(counts(0, 118, 110 * kMs));
  dec.on_frame(counts(1, 118, 295 * kMs));
  const EncoderSample s = take();
  EXPECT_EQ(s.seq, 118);
  EXPECT_EQ(s.flags, 0U);
  EXPECT_EQ(s.channel_fresh, 0x3FU);
  EXPECT_EQ(s.mono_ns, 295 * kMs);
  EXPECT_EQ(dec.queued(), 0);
  EXPECT_FALSE(dec.has_partial());
  EXPECT_EQ(dec.detail().resyncs, 0);
  EXPECT_EQ(dec.stats().seq_gaps, 0);
}

TEST_F(Decoder, TheOtherHalfAfterASilenceIsLateForItsFlushedCycle) {
  cycle(117, 100 * kMs);
  take();
  dec.on_frame(counts(0, 118, 110 * kMs));
  EncoderSample s;
  ASSERT_TRUE(dec.flush(s));  // the reader's deadline: PARTIAL
  EXPECT_EQ(s.seq, 118);
  EXPECT_EQ(s.flags, flag::kPartial);
  dec.on_frame(counts(1, 118, 295 * kMs));  // 185 ms later
  EXPECT_EQ(dec.queued(), 0);
  EXPECT_FALSE(dec.has_partial());
  EXPECT_FALSE(dec.flush(s));  // no second sample of cycle 118
  EXPECT_EQ(dec.stats().out_of_order, 1);
  EXPECT_EQ(dec.detail().resyncs, 0);
  cycle(119, 300 * kMs);
  const EncoderSample n = take();
  EXPECT_EQ(n.seq, 119);
  EXPECT_EQ(n.flags, flag::kOutOfOrder);
  // A board that restarts after the silence with another seq still resyncs.
  cycle(3, 900 * kMs);
  EXPECT_EQ(take().flags, flag::kSeqGap);
  EXPECT_EQ(dec.detail().resyncs, 1);
}

TEST_F(Decoder, ResyncAfterConsecutiveRejectsWithoutStamps) {
  for (int k = 100; k < 103; ++k) cycle(k, 0);
  for (int k = 0; k < 3; ++k) take();
  // Board restarted: seq 0..3 look older; 8 dropped, then accepted.
  for (int k = 0; k < 4; ++k) cycle(k, 0);
  cycle(4, 0);
  cycle(5, 0);
  EncoderSample s = take();
  EXPECT_EQ(s.seq, 4);
  EXPECT_EQ(s.flags, flag::kSeqGap | flag::kOutOfOrder);
  EXPECT_EQ(take().flags, 0U);
  EXPECT_EQ(dec.stats().out_of_order, 8);
  EXPECT_EQ(dec.detail().resyncs, 1);
}

TEST_F(Decoder, QueueOverflowDropsTheOldest) {
  for (int k = 0; k < BoardDecoder::kQueueCapacity + 2; ++k) cycle(k, k * kMs);
  EXPECT_EQ(dec.queued(), BoardDecoder::kQueueCapacity);
  EXPECT_EQ(dec.detail().queue_overflows, 2);
  EXPECT_EQ(take().seq, 2);
}

TEST_F(Decoder, BoardOffsetDecoderIgnoresOtherBoards) {
  BoardDecoderConfig cfg;
  cfg.ids.board = 1;
  BoardDecoder b1(cfg);
  b1.on_frame(counts(0, 1, kMs));
  b1.on_frame(can::encode_counts(0, {1, 2, 3}, 0, 1, cfg.ids));
  b1.on_frame(can::encode_counts(1, {4, 5, 6}, 0, 1, cfg.ids));
  EncoderSample s;
  ASSERT_TRUE(b1.poll_sample(s));
  EXPECT_EQ(s.position[5], 6);
  EXPECT_EQ(b1.stats().bad_frames, 1);
}

}  // namespace
