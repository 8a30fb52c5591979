// CAN protocol v1 codec: every frame round-trips, every rejection reason is
// reported, error frames decode into linux/can/error.h classes, unwrap() at protocol v1's
// 16-bit modulus.
#include <gtest/gtest.h>

#include "exodaq/drivers/can_codec.hpp"

namespace can = exodaq::drivers::can;

namespace {

TEST(CanCodec, SyncRoundTrip) {
  const can::CanFrame f = can::encode_sync();
  EXPECT_EQ(f.id, 0x080U);
  EXPECT_EQ(f.dlc, 0);
  EXPECT_EQ(f.flags, 0);
  EXPECT_EQ(can::decode(f).kind, can::FrameKind::kSync);
}

TEST(CanCodec, CountsARoundTripWithByteLayout) {
  const can::CanFrame f = can::encode_counts(0, {0x1234, 0xFFFF, 0x8000}, 0x05, 200);
  EXPECT_EQ(f.id, 0x181U);
  EXPECT_EQ(f.dlc, 8);
  const std::array<std::uint8_t, 8> expected{0x34, 0x12, 0xFF, 0xFF, 0x00, 0x80, 0x05, 200};
  EXPECT_EQ(f.data, expected);
  const can::Decoded d = can::decode(f);
  ASSERT_EQ(d.kind, can::FrameKind::kCountsA);
  EXPECT_EQ(d.reject, can::Reject::kNone);
  EXPECT_EQ(d.counts.first_channel, 0);
  EXPECT_EQ(d.counts.count16[0], 0x1234);
  EXPECT_EQ(d.counts.count16[1], 0xFFFF);
  EXPECT_EQ(d.counts.count16[2], 0x8000);
  EXPECT_EQ(d.counts.index_latched, 0x05);
  EXPECT_EQ(d.counts.seq, 200);
}

TEST(CanCodec, CountsBRoundTripAndReservedLatchBitsIgnored) {
  can::CanFrame f = can::encode_counts(1, {1, 2, 3}, 0x02, 7);
  EXPECT_EQ(f.id, 0x182U);
  f.data[6] |= 0xF8;  // reserved bits
  const can::Decoded d = can::decode(f);
  ASSERT_EQ(d.kind, can::FrameKind::kCountsB);
  EXPECT_EQ(d.counts.first_channel, 3);
  EXPECT_EQ(d.counts.count16[0], 1);
  EXPECT_EQ(d.counts.count16[1], 2);
  EXPECT_EQ(d.counts.count16[2], 3);
  EXPECT_EQ(d.counts.index_latched, 0x02);
  EXPECT_EQ(d.counts.seq, 7);
}

TEST(CanCodec, IndexRoundTripEveryChannel) {
  for (int c = 0; c < 6; ++c) {
    const can::CanFrame f = can::encode_index(c, static_cast<std::uint16_t>(0xABCD + c), 99);
    EXPECT_EQ(f.id, 0x190U + static_cast<std::uint32_t>(c));
    EXPECT_EQ(f.dlc, 3);
    EXPECT_EQ(f.data[0], 0xCD + c);
    EXPECT_EQ(f.data[1], 0xAB);
    EXPECT_EQ(f.data[2], 99);
    const can::Decoded d = can::decode(f);
    ASSERT_EQ(d.kind, can::FrameKind::kIndex);
    EXPECT_EQ(d.index.channel, c);
    EXPECT_EQ(d.index.count16, 0xABCD + c);
    EXPECT_EQ(d.index.seq, 99);
  }
}

TEST(CanCodec, HeartbeatRoundTripAndOptionalBytes) {
  can::HeartbeatPayload hb;
  hb.state = static_cast<std::uint8_t>(can::BoardState::kSyncSlave);
  hb.errors = can::board_error::kQuadrature | can::board_error::kCounterOverflow;
  hb.channel_quadrature_errors = 0x21;
  hb.protocol_version = can::kProtocolVersion;
  const can::CanFrame f = can::encode_heartbeat(hb);
  EXPECT_EQ(f.id, 0x701U);
  EXPECT_EQ(f.dlc, 4);
  can::Decoded d = can::decode(f);
  ASSERT_EQ(d.kind, can::FrameKind::kHeartbeat);
  EXPECT_EQ(d.heartbeat.state, 2);
  EXPECT_EQ(d.heartbeat.errors, 0x03);
  EXPECT_EQ(d.heartbeat.channel_quadrature_errors, 0x21);
  EXPECT_EQ(d.heartbeat.protocol_version, 1);

  const can::CanFrame f2 = can::encode_heartbeat(hb, 2);  // minimal: optional bytes absent
  EXPECT_EQ(f2.dlc, 2);
  d = can::decode(f2);
  ASSERT_EQ(d.kind, can::FrameKind::kHeartbeat);
  EXPECT_EQ(d.heartbeat.errors, 0x03);
  EXPECT_EQ(d.heartbeat.channel_quadrature_errors, 0);
  EXPECT_EQ(d.heartbeat.protocol_version, 0);

  EXPECT_EQ(can::decode(can::encode_heartbeat(hb, 8)).kind, can::FrameKind::kHeartbeat);
}

TEST(CanCodec, BoardOffsetMovesEveryBoardIdButNotSync) {
  can::ProtocolIds ids;
  ids.board = 1;
  EXPECT_EQ(ids.counts_a_id(), 0x1A1U);
  EXPECT_EQ(ids.counts_b_id(), 0x1A2U);
  EXPECT_EQ(ids.index_id(0), 0x1B0U);
  EXPECT_EQ(ids.index_id(5), 0x1B5U);
  EXPECT_EQ(ids.heartbeat_id(), 0x721U);
  EXPECT_EQ(ids.sync_id(), 0x080U);
  EXPECT_EQ(can::validate(ids), nullptr);
  // Board 0's count frame is an unknown ID to a board-1 decoder.
  const can::Decoded d = can::decode(can::encode_counts(0, {1, 2, 3}, 0, 0), ids);
  EXPECT_EQ(d.kind, can::FrameKind::kRejected);
  EXPECT_EQ(d.reject, can::Reject::kUnknownId);
  EXPECT_EQ(can::decode(can::encode_counts(0, {1, 2, 3}, 0, 0, ids), ids).kind,
            can::FrameKind::kCountsA);
}

TEST(CanCodec, ValidateRejectsCollisionsAndOversizeIds) {
  EXPECT_EQ(can::validate(can::ProtocolIds{}), nullptr);
  can::ProtocolIds clash;
  clash.counts_b = clash.counts_a;
  EXPECT_NE(can::validate(clash), nullptr);
  can::ProtocolIds index_over_counts;
  index_over_counts.index_base = 0x17F;  // 0x17F..0x184 covers COUNTS_A/B
  EXPECT_NE(can::validate(index_over_counts), nullptr);
  can::ProtocolIds too_big;
  too_big.board = 5;  // heartbeat 0x701 + 5 * 0x100 = 0xC01 > 0x7FF
  too_big.board_stride = 0x100;
  EXPECT_NE(can::validate(too_big), nullptr);
}

can::Reject reject_of(const can::CanFrame& f) {
  const can::Decoded d = can::decode(f);
  EXPECT_EQ(d.kind, can::FrameKind::kRejected);
  return d.reject;
}

TEST(CanCodec, EveryRejectionReason) {
  can::CanFrame unknown = can::encode_counts(0, {1, 2, 3}, 0, 0);
  unknown.id = 0x185;
  EXPECT_EQ(reject_of(unknown), can::Reject::kUnknownId);

  can::CanFrame short_counts = can::encode_counts(0, {1, 2, 3}, 0, 0);
  short_counts.dlc = 7;
  EXPECT_EQ(reject_of(short_counts), can::Reject::kWrongDlc);
  can::CanFrame long_index = can::encode_index(2, 5, 1);
  long_index.dlc = 4;
  EXPECT_EQ(reject_of(long_index), can::Reject::kWrongDlc);
  can::CanFrame sync_with_data = can::encode_sync();
  sync_with_data.dlc = 1;
  EXPECT_EQ(reject_of(sync_with_data), can::Reject::kWrongDlc);
  can::CanFrame hb1 = can::encode_heartbeat({});
  hb1.dlc = 1;
  EXPECT_EQ(reject_of(hb1), can::Reject::kWrongDlc);

  can::CanFrame rtr = can::encode_counts(0, {1, 2, 3}, 0, 0);
  rtr.flags = can::frame_flag::kRtr;
  EXPECT_EQ(reject_of(rtr), can::Reject::kRtr);

  can::CanFrame ext = can::encode_counts(0, {1, 2, 3}, 0, 0);
  ext.flags = can::frame_flag::kExtended;
  EXPECT_EQ(reject_of(ext), can::Reject::kExtended);

  can::CanFrame fd = can::encode_counts(0, {1, 2, 3}, 0, 0);
  fd.flags = can::frame_flag::kFd | can::frame_flag::kRtr;  // FD is checked first
  EXPECT_EQ(reject_of(fd), can::Reject::kFd);

  EXPECT_EQ(can::to_string(can::Reject::kWrongDlc), "wrong dlc");
  EXPECT_EQ(can::to_string(can::FrameKind::kCountsB), "counts_b");
}

TEST(CanCodec, ErrorFramesDecodeLinuxClasses) {
  can::ErrorPayload e;
  e.classes = can::err_class::kBusOff | can::err_class::kCrtl | can::err_class::kProt |
              can::err_class::kAck | can::err_class::kTxTimeout | can::err_class::kRestarted |
              can::err_class::kCnt;
  e.controller = can::err_crtl::kRxPassive | can::err_crtl::kTxWarning;
  e.protocol_type = 0x08;      // CAN_ERR_PROT_BIT0
  e.protocol_location = 0x18;  // CAN_ERR_PROT_LOC_ACK
  e.transceiver = 0x04;
  e.tx_error_count = 130;
  e.rx_error_count = 12;
  const can::CanFrame f = can::encode_error(e);
  EXPECT_EQ(f.flags, can::frame_flag::kError);
  EXPECT_EQ(f.dlc, 8);
  EXPECT_EQ(f.id, 0x36DU);
  const can::Decoded d = can::decode(f);
  ASSERT_EQ(d.kind, can::FrameKind::kError);
  EXPECT_EQ(d.error.classes, 0x36DU);
  EXPECT_EQ(d.error.controller, 0x18);
  EXPECT_EQ(d.error.protocol_type, 0x08);
  EXPECT_EQ(d.error.protocol_location, 0x18);
  EXPECT_EQ(d.error.transceiver, 0x04);
  EXPECT_EQ(d.error.tx_error_count, 130);
  EXPECT_EQ(d.error.rx_error_count, 12);
  // Same values as linux/can/error.h.
  EXPECT_EQ(can::err_class::kTxTimeout, 0x001U);
  EXPECT_EQ(can::err_class::kCrtl, 0x004U);
  EXPECT_EQ(can::err_class::kProt, 0x008U);
  EXPECT_EQ(can::err_class::kAck, 0x020U);
  EXPECT_EQ(can::err_class::kBusOff, 0x040U);
  EXPECT_EQ(can::err_class::kRestarted, 0x100U);
  EXPECT_EQ(can::err_class::kSubscribed, 0x1EDU);
}

TEST(CanCodec, ErrorFlagWinsOverIdAndOtherFlags) {
  can::CanFrame f = can::encode_counts(0, {1, 2, 3}, 0, 0);  // ID 0x181 = classes
  f.flags = can::frame_flag::kError | can::frame_flag::kRtr;
  const can::Decoded d = can::decode(f);
  EXPECT_EQ(d.kind, can::FrameKind::kError);
  EXPECT_EQ(d.error.classes, 0x181U);
}

TEST(Unwrap16, SmallSteps) {
  EXPECT_EQ(exodaq::unwrap(0, 0, exodaq::kCount16Modulus), 0);
  EXPECT_EQ(exodaq::unwrap(0, 5, exodaq::kCount16Modulus), 5);
  EXPECT_EQ(exodaq::unwrap(0, 0xFFFB, exodaq::kCount16Modulus), -5);
  EXPECT_EQ(
      exodaq::unwrap(100000, static_cast<std::uint16_t>(100003 & 0xFFFF), exodaq::kCount16Modulus),
      100003);
  EXPECT_EQ(exodaq::unwrap(-100000, static_cast<std::uint16_t>(-100010 & 0xFFFF),
                           exodaq::kCount16Modulus),
            -100010);
}

TEST(CountDelta16, SmallestSignedStepAcrossTheWrap) {
  EXPECT_EQ(exodaq::wrapped_delta(0xFFFE, 3, exodaq::kCount16Modulus), 5);
  EXPECT_EQ(exodaq::wrapped_delta(3, 0xFFFE, exodaq::kCount16Modulus), -5);
  EXPECT_EQ(exodaq::wrapped_delta(0, 0x7FFF, exodaq::kCount16Modulus), 32767);
  EXPECT_EQ(exodaq::wrapped_delta(0, 0x8000, exodaq::kCount16Modulus), -32768);
  EXPECT_EQ(exodaq::wrapped_delta(1234, 1234, exodaq::kCount16Modulus), 0);
}

TEST(Unwrap16, AcrossTheWrapBothDirections) {
  EXPECT_EQ(exodaq::unwrap(65530, 4, exodaq::kCount16Modulus), 65540);  // up through 0xFFFF → 0
  EXPECT_EQ(exodaq::unwrap(65540, 0xFFFA, exodaq::kCount16Modulus), 65530);  // back down
  EXPECT_EQ(exodaq::unwrap(-1, 1, exodaq::kCount16Modulus), 1);
  EXPECT_EQ(exodaq::unwrap(1, 0xFFFF, exodaq::kCount16Modulus), -1);
  EXPECT_EQ(exodaq::unwrap(32767, 0x8000, exodaq::kCount16Modulus),
            32768);  // int16 overflow is no wrap of the count
  EXPECT_EQ(exodaq::unwrap(-32768, 0x7FFF, exodaq::kCount16Modulus), -32769);
  // Walk many revolutions of the 16-bit counter in steps of 30 000 both ways.
  std::int64_t up = 0;
  std::int64_t down = 0;
  for (int i = 1; i <= 50; ++i) {
    const std::int64_t truth = static_cast<std::int64_t>(i) * 30000;
    up = exodaq::unwrap(up, static_cast<std::uint16_t>(truth & 0xFFFF), exodaq::kCount16Modulus);
    down = exodaq::unwrap(down, static_cast<std::uint16_t>((-truth) & 0xFFFF),
                          exodaq::kCount16Modulus);
    ASSERT_EQ(up, truth);
    ASSERT_EQ(down, -truth);
  }
}

TEST(Unwrap16, LimitsAtPlusMinus32767) {
  EXPECT_EQ(exodaq::unwrap(0, 32767, exodaq::kCount16Modulus), 32767);
  EXPECT_EQ(exodaq::unwrap(0, static_cast<std::uint16_t>(-32767 & 0xFFFF), exodaq::kCount16Modulus),
            -32767);
  EXPECT_EQ(exodaq::unwrap(1000, static_cast<std::uint16_t>((1000 + 32767) & 0xFFFF),
                           exodaq::kCount16Modulus),
            33767);
  EXPECT_EQ(exodaq::unwrap(1000, static_cast<std::uint16_t>((1000 - 32767) & 0xFFFF),
                           exodaq::kCount16Modulus),
            -31767);
  // A step of exactly 32768 is ambiguous and resolves to −32768.
  EXPECT_EQ(exodaq::unwrap(0, 0x8000, exodaq::kCount16Modulus), -32768);
  // Beyond ±32767 the unwrap aliases: +32769 reads as −32767.
  EXPECT_EQ(exodaq::unwrap(0, static_cast<std::uint16_t>(32769), exodaq::kCount16Modulus), -32767);
}

TEST(SeqDelta, WrapsAt256) {
  EXPECT_EQ(can::seq_delta(255, 0), 1);
  EXPECT_EQ(can::seq_delta(0, 255), -1);
  EXPECT_EQ(can::seq_delta(10, 10), 0);
  EXPECT_EQ(can::seq_delta(250, 5), 11);
  EXPECT_EQ(can::seq_delta(0, 127), 127);
  EXPECT_EQ(can::seq_delta(0, 128), -128);
}

}  // namespace
