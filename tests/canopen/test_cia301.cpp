// CiA 301 codec: golden frames written by hand from the specification's
// layouts, round trips, and every rejection reason.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>
#include <initializer_list>

#include "exodaq/drivers/canopen/cia301.hpp"

namespace exodaq::drivers::canopen {
namespace {

CanFrame make(std::uint32_t id, std::initializer_list<int> bytes, std::uint8_t flags = 0) {
  CanFrame f;
  f.id = id;
  f.flags = flags;
  f.dlc = static_cast<std::uint8_t>(bytes.size());
  std::size_t i = 0;
  for (int b : bytes) f.data[i++] = static_cast<std::uint8_t>(b);
  return f;
}

// Same identifier, length and payload bytes (the unused tail must be 0 too).
void expect_frame(const CanFrame& f, std::uint32_t id, std::initializer_list<int> bytes) {
  EXPECT_EQ(f.id, id);
  EXPECT_EQ(f.flags, 0);
  ASSERT_EQ(f.dlc, bytes.size());
  std::array<std::uint8_t, 8> want{};
  std::size_t i = 0;
  for (int b : bytes) want[i++] = static_cast<std::uint8_t>(b);
  EXPECT_EQ(f.data, want);
}

Reject reject_of(const CanFrame& f) {
  const Decoded d = decode_frame(f);
  EXPECT_EQ(d.kind, FrameKind::kRejected);
  return d.reject;
}

// --- identifiers -------------------------------------------------------------

TEST(CanopenCobId, PredefinedConnectionSet) {
  EXPECT_EQ(cob::kNmt, 0x000U);
  EXPECT_EQ(cob::kSync, 0x080U);
  EXPECT_EQ(cob::emcy(5), 0x085U);
  EXPECT_EQ(cob::tpdo(1, 5), 0x185U);
  EXPECT_EQ(cob::tpdo(2, 5), 0x285U);
  EXPECT_EQ(cob::tpdo(3, 5), 0x385U);
  EXPECT_EQ(cob::tpdo(4, 5), 0x485U);
  EXPECT_EQ(cob::rpdo(1, 5), 0x205U);
  EXPECT_EQ(cob::rpdo(4, 5), 0x505U);
  EXPECT_EQ(cob::sdo_tx(5), 0x585U);
  EXPECT_EQ(cob::sdo_rx(5), 0x605U);
  EXPECT_EQ(cob::heartbeat(5), 0x705U);
  EXPECT_EQ(cob::heartbeat(127), 0x77FU);
  EXPECT_EQ(cob::tpdo(4, 127), 0x4FFU);
  EXPECT_EQ(cob::function_of(0x585), FunctionCode::kSdoTx);
  EXPECT_EQ(cob::node_of(0x585), 5);
  EXPECT_FALSE(is_node_id(0));
  EXPECT_TRUE(is_node_id(1));
  EXPECT_TRUE(is_node_id(127));
  EXPECT_FALSE(is_node_id(128));
}

// --- golden frames -----------------------------------------------------------

TEST(CanopenCodec, NmtGoldenFrames) {
  expect_frame(encode_nmt(NmtCommand::kStart, 5), 0x000, {0x01, 0x05});
  expect_frame(encode_nmt(NmtCommand::kStop, 5), 0x000, {0x02, 0x05});
  expect_frame(encode_nmt(NmtCommand::kEnterPreOperational, 0), 0x000, {0x80, 0x00});
  expect_frame(encode_nmt(NmtCommand::kResetNode, 12), 0x000, {0x81, 0x0C});
  expect_frame(encode_nmt(NmtCommand::kResetCommunication, 127), 0x000, {0x82, 0x7F});
}

TEST(CanopenCodec, HeartbeatAndBootUpGoldenFrames) {
  expect_frame(encode_heartbeat(5, NmtState::kOperational), 0x705, {0x05});
  expect_frame(encode_heartbeat(5, NmtState::kPreOperational), 0x705, {0x7F});
  expect_frame(encode_heartbeat(5, NmtState::kStopped), 0x705, {0x04});
  expect_frame(encode_boot_up(5), 0x705, {0x00});
}

TEST(CanopenCodec, SyncGoldenFrames) {
  expect_frame(encode_sync(), 0x080, {});
  expect_frame(encode_sync(7), 0x080, {0x07});
}

TEST(CanopenCodec, EmcyGoldenFrame) {
  // Heartbeat error 0x8130, error register generic + communication, three
  // manufacturer bytes.
  EmcyPayload e;
  e.error_code = emcy_code::kHeartbeatError;
  e.error_register = error_register::kGeneric | error_register::kCommunication;
  e.manufacturer = {0xAA, 0xBB, 0xCC, 0x00, 0x00};
  expect_frame(encode_emcy(5, e), 0x085, {0x30, 0x81, 0x11, 0xAA, 0xBB, 0xCC, 0x00, 0x00});
}

TEST(CanopenCodec, SdoGoldenFrames) {
  // Upload (read) 0x1018 sub 1: ccs 2 → 0x40.
  expect_frame(encode_sdo_upload_request(5, {0x1018, 1}), 0x605,
               {0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0});
  // Its expedited answer, 4 bytes (scs 2, n 0, e 1, s 1 → 0x43).
  expect_frame(encode_sdo_upload_response(5, {0x1018, 1}, 0x12345678, 4), 0x585,
               {0x43, 0x18, 0x10, 0x01, 0x78, 0x56, 0x34, 0x12});
  // 2 bytes (n = 2 → 0x4B), 1 byte (n = 3 → 0x4F).
  expect_frame(encode_sdo_upload_response(5, {0x1017, 0}, 100, 2), 0x585,
               {0x4B, 0x17, 0x10, 0x00, 0x64, 0x00, 0, 0});
  expect_frame(encode_sdo_upload_response(5, {0x1001, 0}, 0x81, 1), 0x585,
               {0x4F, 0x01, 0x10, 0x00, 0x81, 0, 0, 0});
  // Download (write) expedited: 4 bytes 0x23, 2 bytes 0x2B, 1 byte 0x2F.
  expect_frame(encode_sdo_download_request(5, {0x1A00, 1}, 0x60040020, 4), 0x605,
               {0x23, 0x00, 0x1A, 0x01, 0x20, 0x00, 0x04, 0x60});
  expect_frame(encode_sdo_download_request(5, {0x1017, 0}, 100, 2), 0x605,
               {0x2B, 0x17, 0x10, 0x00, 0x64, 0x00, 0, 0});
  expect_frame(encode_sdo_download_request(5, {0x1800, 2}, 1, 1), 0x605,
               {0x2F, 0x00, 0x18, 0x02, 0x01, 0, 0, 0});
  // Download response: scs 3 → 0x60.
  expect_frame(encode_sdo_download_response(5, {0x1017, 0}), 0x585,
               {0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0});
  // Abort "object does not exist" (0x06020000) for 0x2000 sub 0.
  expect_frame(encode_sdo_abort(5, {0x2000, 0}, 0x06020000, false), 0x585,
               {0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x02, 0x06});
  expect_frame(encode_sdo_abort(5, {0x1018, 1}, 0x05040000, true), 0x605,
               {0x80, 0x18, 0x10, 0x01, 0x00, 0x00, 0x04, 0x05});
}

TEST(CanopenCodec, AbortCodeNames) {
  EXPECT_EQ(abort_name(0x06020000), "object does not exist in the object dictionary");
  EXPECT_EQ(abort_name(0x06090011), "sub-index does not exist");
  EXPECT_EQ(abort_name(0x06010002), "attempt to write a read only object");
  EXPECT_EQ(abort_name(0x05040000), "SDO protocol timed out");
  EXPECT_EQ(abort_name(0x06040041), "object cannot be mapped to the PDO");
  EXPECT_EQ(abort_name(0x06070012),
            "data type does not match, length of service parameter too high");
  EXPECT_EQ(abort_name(0x12345678), "unknown abort code");
  EXPECT_EQ(static_cast<std::uint32_t>(SdoAbort::kNoObject), 0x06020000U);
}

// --- decoding ----------------------------------------------------------------

TEST(CanopenCodec, DecodesNmt) {
  const Decoded d = decode_frame(make(0x000, {0x01, 0x05}));
  ASSERT_EQ(d.kind, FrameKind::kNmt);
  EXPECT_EQ(d.nmt.command, NmtCommand::kStart);
  EXPECT_EQ(d.nmt.node, 5);
  EXPECT_EQ(decode_frame(make(0x000, {0x82, 0x00})).nmt.command, NmtCommand::kResetCommunication);
}

TEST(CanopenCodec, DecodesHeartbeatStatesAndBootUp) {
  Decoded d = decode_frame(make(0x705, {0x05}));
  ASSERT_EQ(d.kind, FrameKind::kHeartbeat);
  EXPECT_EQ(d.node, 5);
  EXPECT_EQ(d.heartbeat.state, NmtState::kOperational);
  EXPECT_EQ(decode_frame(make(0x705, {0x04})).heartbeat.state, NmtState::kStopped);
  EXPECT_EQ(decode_frame(make(0x705, {0x7F})).heartbeat.state, NmtState::kPreOperational);
  d = decode_frame(make(0x77F, {0x00}));
  EXPECT_EQ(d.kind, FrameKind::kBootUp);
  EXPECT_EQ(d.node, 127);
}

TEST(CanopenCodec, DecodesSyncWithAndWithoutCounter) {
  Decoded d = decode_frame(make(0x080, {}));
  ASSERT_EQ(d.kind, FrameKind::kSync);
  EXPECT_FALSE(d.sync.has_counter);
  d = decode_frame(make(0x080, {240}));
  ASSERT_EQ(d.kind, FrameKind::kSync);
  EXPECT_TRUE(d.sync.has_counter);
  EXPECT_EQ(d.sync.counter, 240);
}

TEST(CanopenCodec, SyncCounterCountsOneToOverflow) {
  EXPECT_EQ(next_sync_counter(1, 240), 2);
  EXPECT_EQ(next_sync_counter(239, 240), 240);
  EXPECT_EQ(next_sync_counter(240, 240), 1);
  EXPECT_EQ(next_sync_counter(5, 5), 1);
  EXPECT_TRUE(is_sync_overflow(0));
  EXPECT_FALSE(is_sync_overflow(1));
  EXPECT_TRUE(is_sync_overflow(2));
  EXPECT_TRUE(is_sync_overflow(240));
  EXPECT_FALSE(is_sync_overflow(241));
}

TEST(CanopenCodec, DecodesEmcy) {
  const Decoded d = decode_frame(make(0x085, {0x10, 0x50, 0x81, 1, 2, 3, 4, 5}));
  ASSERT_EQ(d.kind, FrameKind::kEmcy);
  EXPECT_EQ(d.node, 5);
  EXPECT_EQ(d.emcy.error_code, 0x5010);
  EXPECT_EQ(d.emcy.error_register, 0x81);
  EXPECT_EQ(d.emcy.manufacturer, (std::array<std::uint8_t, 5>{1, 2, 3, 4, 5}));
}

TEST(CanopenCodec, DecodesPdosByFunctionCode) {
  Decoded d = decode_frame(make(0x285, {1, 2, 3}));
  ASSERT_EQ(d.kind, FrameKind::kTpdo);
  EXPECT_EQ(d.pdo.pdo, 2);
  EXPECT_EQ(d.pdo.node, 5);
  EXPECT_EQ(d.pdo.length, 3);
  d = decode_frame(make(0x4FF, {}));
  EXPECT_EQ(d.kind, FrameKind::kTpdo);
  EXPECT_EQ(d.pdo.pdo, 4);
  d = decode_frame(make(0x305, {1}));
  EXPECT_EQ(d.kind, FrameKind::kRpdo);
  EXPECT_EQ(d.pdo.pdo, 2);
}

TEST(CanopenCodec, SdoRoundTrips) {
  const Multiplexer at{0x6001, 0};
  for (std::uint8_t size = 1; size <= 4; ++size) {
    const std::uint32_t value = 0xA1B2C3D4U & (size == 4 ? 0xFFFFFFFFU : (1U << (8 * size)) - 1);
    Decoded d = decode_frame(encode_sdo_download_request(9, at, 0xA1B2C3D4U, size));
    ASSERT_EQ(d.kind, FrameKind::kSdo) << int{size};
    EXPECT_TRUE(d.sdo.from_client);
    EXPECT_EQ(d.sdo.kind, SdoKind::kDownloadRequest);
    EXPECT_EQ(d.sdo.node, 9);
    EXPECT_EQ(d.sdo.at, at);
    EXPECT_EQ(d.sdo.size, size);
    EXPECT_TRUE(d.sdo.size_indicated);
    EXPECT_EQ(d.sdo.value, value);
    d = decode_frame(encode_sdo_upload_response(9, at, 0xA1B2C3D4U, size));
    ASSERT_EQ(d.kind, FrameKind::kSdo);
    EXPECT_FALSE(d.sdo.from_client);
    EXPECT_EQ(d.sdo.kind, SdoKind::kUploadResponse);
    EXPECT_EQ(d.sdo.value, value);
    EXPECT_EQ(d.sdo.size, size);
  }
  Decoded d = decode_frame(encode_sdo_upload_request(9, at));
  EXPECT_EQ(d.sdo.kind, SdoKind::kUploadRequest);
  d = decode_frame(encode_sdo_download_response(9, at));
  EXPECT_EQ(d.sdo.kind, SdoKind::kDownloadResponse);
  EXPECT_EQ(d.sdo.at, at);
  d = decode_frame(encode_sdo_abort(9, at, 0x06010002, false));
  EXPECT_EQ(d.sdo.kind, SdoKind::kAbort);
  EXPECT_FALSE(d.sdo.from_client);
  EXPECT_EQ(d.sdo.abort_code, 0x06010002U);
}

TEST(CanopenCodec, ExpeditedWithoutSizeCarriesFourBytes) {
  // e = 1, s = 0: size not indicated, all four bytes are data.
  const Decoded d = decode_frame(make(0x585, {0x42, 0x04, 0x60, 0x00, 1, 2, 3, 4}));
  ASSERT_EQ(d.kind, FrameKind::kSdo);
  EXPECT_FALSE(d.sdo.size_indicated);
  EXPECT_EQ(d.sdo.size, 4);
  EXPECT_EQ(d.sdo.value, 0x04030201U);
}

TEST(CanopenCodec, ReservedDataBytesOfAnUploadRequestAreIgnored) {
  const Decoded d = decode_frame(make(0x605, {0x40, 0x18, 0x10, 0x01, 9, 9, 9, 9}));
  ASSERT_EQ(d.kind, FrameKind::kSdo);
  EXPECT_EQ(d.sdo.kind, SdoKind::kUploadRequest);
}

// --- rejections --------------------------------------------------------------

TEST(CanopenCodec, RejectsFrameFormatsBeforeTheIdentifier) {
  EXPECT_EQ(reject_of(make(0x705, {0x05}, can::frame_flag::kError)), Reject::kErrorFrame);
  EXPECT_EQ(reject_of(make(0x705, {0x05}, can::frame_flag::kFd)), Reject::kFd);
  EXPECT_EQ(reject_of(make(0x705, {}, can::frame_flag::kRtr)), Reject::kRtr);
  EXPECT_EQ(reject_of(make(0x705, {0x05}, can::frame_flag::kExtended)), Reject::kExtended);
}

TEST(CanopenCodec, RejectsIdentifiersOutsideThePredefinedSet) {
  EXPECT_EQ(reject_of(make(0x001, {0x01, 0x05})), Reject::kUnknownId);  // not NMT
  EXPECT_EQ(reject_of(make(0x101, {})), Reject::kUnknownId);            // TIME + node
  EXPECT_EQ(reject_of(make(0x180, {1})), Reject::kUnknownId);           // TPDO1 of node 0
  EXPECT_EQ(reject_of(make(0x580, {0x60, 0, 0, 0, 0, 0, 0, 0})), Reject::kUnknownId);
  EXPECT_EQ(reject_of(make(0x700, {0x05})), Reject::kUnknownId);  // heartbeat of node 0
  EXPECT_EQ(reject_of(make(0x685, {})), Reject::kUnknownId);      // function code 0xD
  EXPECT_EQ(reject_of(make(0x7E5, {})), Reject::kUnknownId);      // LSS
  EXPECT_EQ(reject_of(make(0x800, {})), Reject::kUnknownId);      // > 11 bits
  EXPECT_EQ(reject_of(make(0x100, {1, 2, 3, 4, 5, 6})), Reject::kUnsupported);  // TIME
}

TEST(CanopenCodec, RejectsWrongLengths) {
  EXPECT_EQ(reject_of(make(0x000, {0x01})), Reject::kWrongLength);
  EXPECT_EQ(reject_of(make(0x000, {0x01, 0x05, 0})), Reject::kWrongLength);
  EXPECT_EQ(reject_of(make(0x080, {1, 2})), Reject::kWrongLength);
  EXPECT_EQ(reject_of(make(0x085, {0, 0, 0, 0, 0, 0, 0})), Reject::kWrongLength);
  EXPECT_EQ(reject_of(make(0x705, {})), Reject::kWrongLength);
  EXPECT_EQ(reject_of(make(0x705, {0x05, 0x00})), Reject::kWrongLength);
  EXPECT_EQ(reject_of(make(0x605, {0x40, 0x18, 0x10, 0x01})), Reject::kWrongLength);
  EXPECT_EQ(reject_of(make(0x585, {0x60, 0x17, 0x10, 0x00, 0, 0, 0})), Reject::kWrongLength);
}

TEST(CanopenCodec, RejectsBadContent) {
  EXPECT_EQ(reject_of(make(0x000, {0x03, 0x05})), Reject::kUnknownCommand);
  EXPECT_EQ(reject_of(make(0x000, {0x01, 0x80})), Reject::kBadNodeId);
  EXPECT_EQ(reject_of(make(0x080, {0})), Reject::kBadSyncCounter);
  EXPECT_EQ(reject_of(make(0x080, {241})), Reject::kBadSyncCounter);
  EXPECT_EQ(reject_of(make(0x705, {0x85})), Reject::kReservedBits);  // node guarding toggle
  EXPECT_EQ(reject_of(make(0x705, {0x01})), Reject::kUnknownState);
}

TEST(CanopenCodec, RejectsSdoCommandsItDoesNotHandle) {
  auto sdo = [](std::uint32_t id, int b0) { return make(id, {b0, 0x00, 0x60, 0, 0, 0, 0, 0}); };
  EXPECT_EQ(reject_of(sdo(0x605, 0x41)), Reject::kReservedBits);  // upload request, bit 0
  EXPECT_EQ(reject_of(sdo(0x605, 0x33)), Reject::kReservedBits);  // download request, bit 4
  EXPECT_EQ(reject_of(sdo(0x605, 0x26)), Reject::kReservedBits);  // n without s
  EXPECT_EQ(reject_of(sdo(0x585, 0x61)), Reject::kReservedBits);  // download response, bit 0
  EXPECT_EQ(reject_of(sdo(0x585, 0x81)), Reject::kReservedBits);  // abort, bit 0
  EXPECT_EQ(reject_of(sdo(0x605, 0x21)), Reject::kUnsupported);   // segmented download
  EXPECT_EQ(reject_of(sdo(0x605, 0x60)), Reject::kUnsupported);   // upload segment
  EXPECT_EQ(reject_of(sdo(0x605, 0xA0)), Reject::kUnsupported);   // block upload
  EXPECT_EQ(reject_of(sdo(0x585, 0x41)), Reject::kUnsupported);   // segmented upload response
  EXPECT_EQ(reject_of(sdo(0x585, 0x00)), Reject::kUnsupported);   // upload segment response
  EXPECT_EQ(reject_of(sdo(0x605, 0xE0)), Reject::kUnknownCommand);
  EXPECT_EQ(reject_of(sdo(0x585, 0xE0)), Reject::kUnknownCommand);
}

TEST(CanopenCodec, RejectedFramesNameTheNodeTheyCameFrom) {
  EXPECT_EQ(decode_frame(make(0x705, {0x01})).node, 5);
  EXPECT_EQ(decode_frame(make(0x087, {0})).node, 7);
  EXPECT_EQ(decode_frame(make(0x000, {0x03, 0x05})).node, 0);
}

TEST(CanopenCodec, EveryRejectReasonHasAName) {
  for (int r = 0; r < kRejectCount; ++r) {
    EXPECT_NE(to_string(static_cast<Reject>(r)), "?") << r;
  }
}

}  // namespace
}  // namespace exodaq::drivers::canopen
