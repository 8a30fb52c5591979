// The CANopen encoder node simulator: boot-up, heartbeat, NMT, SDO server
// with its abort codes, synchronous TPDOs, remapping, SYNC production and
// every injected fault, observed as frames on the in-memory bus.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "exodaq/drivers/canopen/node_sim.hpp"
#include "sim_bus.hpp"

namespace exodaq::drivers::canopen {
namespace {

using test::SimBus;

constexpr std::int64_t kMs = 1'000'000;
constexpr NodeId kNode = 5;

struct Fixture {
  SimBus bus;
  std::uint32_t raw = 1000;  // the encoder's raw count
  EncoderNodeSim* node = nullptr;
  std::vector<CanFrame> rx;

  explicit Fixture(NodeSimConfig config = {}) {
    config.node = kNode;
    node = &bus.add(config, [this](std::int64_t) { return SimPosition{raw, raw / 2}; });
    bus.power_on(0);
    bus.run_until(10 * kMs, &rx);
  }

  // Sends `frame` at the bus time and returns what the node sent in the next ms.
  std::vector<CanFrame> exchange(const CanFrame& frame) {
    const std::int64_t t = bus.now();
    bus.send(frame, t);
    std::vector<CanFrame> out;
    bus.run_until(t + kMs, &out);
    return out;
  }

  Decoded sdo(const CanFrame& request) {
    for (const CanFrame& f : exchange(request)) {
      const Decoded d = decode_frame(f);
      if (d.kind == FrameKind::kSdo) return d;
    }
    return {};
  }

  std::uint32_t read(Multiplexer at) {
    const Decoded d = sdo(encode_sdo_upload_request(kNode, at));
    EXPECT_EQ(d.sdo.kind, SdoKind::kUploadResponse) << std::hex << at.index;
    return d.sdo.value;
  }

  std::uint32_t write(Multiplexer at, std::uint32_t value, std::uint8_t size) {
    const Decoded d = sdo(encode_sdo_download_request(kNode, at, value, size));
    EXPECT_EQ(d.kind, FrameKind::kSdo);
    return d.sdo.kind == SdoKind::kAbort ? d.sdo.abort_code : 0;
  }

  void start() { exchange(encode_nmt(NmtCommand::kStart, kNode)); }

  // The TPDO frames answering one SYNC.
  std::vector<CanFrame> sync(const CanFrame& sync_frame = encode_sync()) {
    std::vector<CanFrame> tpdos;
    for (const CanFrame& f : exchange(sync_frame)) {
      if (decode_frame(f).kind == FrameKind::kTpdo) tpdos.push_back(f);
    }
    return tpdos;
  }
};

std::uint32_t u32(const CanFrame& f, int at) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) {
    v |= static_cast<std::uint32_t>(f.data[static_cast<std::size_t>(at + i)]) << (8 * i);
  }
  return v;
}

TEST(CanopenNodeSim, BootsUpAfterItsDelayThenSendsHeartbeats) {
  SimBus bus;
  NodeSimConfig c;
  c.node = kNode;
  c.boot_delay_ns = 2 * kMs;
  c.heartbeat_ms = 100;
  bus.add(c, [](std::int64_t) { return SimPosition{}; });
  bus.power_on(0);
  std::vector<CanFrame> rx;
  bus.run_until(2 * kMs - 1, &rx);
  EXPECT_TRUE(rx.empty());
  bus.run_until(302 * kMs, &rx);
  ASSERT_EQ(rx.size(), 4U);
  EXPECT_EQ(rx[0].id, 0x705U);
  EXPECT_EQ(rx[0].data[0], 0x00);  // boot-up
  EXPECT_EQ(rx[0].mono_ns, 2 * kMs);
  for (int i = 1; i <= 3; ++i) {
    EXPECT_EQ(rx[static_cast<std::size_t>(i)].data[0], 0x7F);  // pre-operational
    EXPECT_EQ(rx[static_cast<std::size_t>(i)].mono_ns, (2 + 100 * i) * kMs);
  }
}

TEST(CanopenNodeSim, SdoServerReadsTheDictionary) {
  NodeSimConfig c;
  c.identity = {0x11, 0x22, 0x33, 0x44};
  Fixture t(c);
  EXPECT_EQ(t.read({0x1018, 1}), 0x11U);
  EXPECT_EQ(t.read({0x1018, 2}), 0x22U);
  EXPECT_EQ(t.read({0x1018, 3}), 0x33U);
  EXPECT_EQ(t.read({0x1018, 4}), 0x44U);
  EXPECT_EQ(t.read({0x1000, 0}) & 0xFFFF, 406U);
  EXPECT_EQ(t.read({0x1017, 0}), 100U);
  EXPECT_EQ(t.read({0x1A00, 1}), 0x60040020U);
  EXPECT_EQ(t.read({0x1800, 1}), 0x185U);
  EXPECT_EQ(t.read({0x1801, 1}), 0x80000285U);  // TPDO2 disabled
  EXPECT_EQ(t.read({0x6004, 0}), 1000U);
  const Decoded d = t.sdo(encode_sdo_upload_request(kNode, {0x1017, 0}));
  EXPECT_EQ(d.sdo.size, 2);  // UNSIGNED16
}

TEST(CanopenNodeSim, SdoServerAbortsWithCia301Codes) {
  Fixture t;
  auto read_abort = [&](Multiplexer at) {
    const Decoded d = t.sdo(encode_sdo_upload_request(kNode, at));
    EXPECT_EQ(d.sdo.kind, SdoKind::kAbort);
    return d.sdo.abort_code;
  };
  EXPECT_EQ(read_abort({0x2000, 0}), 0x06020000U);     // object does not exist
  EXPECT_EQ(read_abort({0x1018, 9}), 0x06090011U);     // sub-index does not exist
  EXPECT_EQ(t.write({0x1018, 1}, 7, 4), 0x06010002U);  // read only
  EXPECT_EQ(t.write({0x6004, 0}, 7, 4), 0x06010002U);
  EXPECT_EQ(t.write({0x1017, 0}, 7, 4), 0x06070012U);           // too long for UNSIGNED16
  EXPECT_EQ(t.write({0x6001, 0}, 7, 2), 0x06070013U);           // too short for UNSIGNED32
  EXPECT_EQ(t.write({0x1019, 0}, 1, 1), 0x06090030U);           // overflow value 1 is reserved
  EXPECT_EQ(t.write({0x1800, 2}, 245, 1), 0x06090030U);         // reserved transmission type
  EXPECT_EQ(t.write({0x1A00, 1}, 0x60040020, 4), 0x06010000U);  // TPDO1 is valid
  EXPECT_EQ(t.write({0x1800, 1}, 0x1F0, 4), 0x06090030U);       // COB-ID of a valid PDO
  EXPECT_EQ(t.write({0x6002, 0}, 0, 4), 0x06090032U);           // range 0
  // An SDO command it cannot parse (ccs 7) is answered with an abort.
  const Decoded d = t.sdo(CanFrame{0x605, 8, 0, {0xE0, 0x00, 0x60, 0, 0, 0, 0, 0}});
  EXPECT_EQ(d.sdo.kind, SdoKind::kAbort);
  EXPECT_EQ(d.sdo.abort_code, 0x05040001U);
}

TEST(CanopenNodeSim, TpdoOnEverySyncOnlyWhenOperational) {
  Fixture t;
  EXPECT_TRUE(t.sync().empty());  // pre-operational
  t.start();
  t.raw = 123456;
  const std::int64_t sync_at = t.bus.now();
  const std::vector<CanFrame> tpdo = t.sync();
  ASSERT_EQ(tpdo.size(), 1U);
  EXPECT_EQ(tpdo[0].id, 0x185U);
  EXPECT_EQ(tpdo[0].dlc, 4);
  EXPECT_EQ(u32(tpdo[0], 0), 123456U);
  EXPECT_EQ(tpdo[0].mono_ns, sync_at + 100'000);  // response_ns after the SYNC
  t.exchange(encode_nmt(NmtCommand::kStop, kNode));
  EXPECT_TRUE(t.sync().empty());
  EXPECT_EQ(t.node->state(), NmtState::kStopped);
  // A stopped node answers no SDO.
  EXPECT_EQ(t.sdo(encode_sdo_upload_request(kNode, {0x1018, 1})).kind, FrameKind::kRejected);
}

TEST(CanopenNodeSim, PositionWrapsAtTheTotalRangeAndFollowsThePreset) {
  Fixture t;
  t.start();
  t.raw = (1U << 25) + 7;
  EXPECT_EQ(u32(t.sync()[0], 0), 7U);
  EXPECT_EQ(t.write({0x6003, 0}, 1000, 4), 0U);
  EXPECT_EQ(t.read({0x6004, 0}), 1000U);
  t.raw += 5;
  EXPECT_EQ(u32(t.sync()[0], 0), 1005U);
  EXPECT_EQ(t.write({0x6003, 0}, 1U << 25, 4), 0x06090031U);  // beyond the range
}

TEST(CanopenNodeSim, RemappingFollowsTheCia301Sequence) {
  NodeSimConfig c;
  c.has_reference_object = true;
  Fixture t(c);
  TpdoSetup setup = position_tpdo(1);
  setup.mapping.add({0x2100, 1, 32});
  std::array<SdoWrite, kMaxPdoWrites> w{};
  const int n = tpdo_setup_writes(kNode, setup, w);
  for (int i = 0; i < n; ++i) {
    const SdoWrite& s = w[static_cast<std::size_t>(i)];
    EXPECT_EQ(t.write(s.at, s.value, s.size), 0U) << i;
  }
  t.start();
  t.raw = 4000;
  const std::vector<CanFrame> tpdo = t.sync();
  ASSERT_EQ(tpdo.size(), 1U);
  EXPECT_EQ(tpdo[0].dlc, 8);
  EXPECT_EQ(u32(tpdo[0], 0), 4000U);
  EXPECT_EQ(u32(tpdo[0], 4), 2000U);  // the reference the source latched
}

TEST(CanopenNodeSim, MappingRulesAbort) {
  NodeSimConfig c;
  c.has_reference_object = true;
  Fixture t(c);
  EXPECT_EQ(t.write({0x1800, 1}, 0x80000185U, 4), 0U);
  EXPECT_EQ(t.write({0x1A00, 2}, 0x21000120U, 4), 0x06010000U);  // count still 1
  EXPECT_EQ(t.write({0x1A00, 0}, 0, 1), 0U);
  EXPECT_EQ(t.write({0x1A00, 2}, 0x10170010U, 4), 0x06040041U);  // 0x1017 not mappable
  EXPECT_EQ(t.write({0x1A00, 2}, 0x60040010U, 4), 0x06040041U);  // wrong length
  EXPECT_EQ(t.write({0x1A00, 2}, 0x20000020U, 4), 0x06040041U);  // no such object
  EXPECT_EQ(t.write({0x1A00, 2}, 0x21000120U, 4), 0U);
  EXPECT_EQ(t.write({0x1A00, 3}, 0x60040020U, 4), 0U);
  EXPECT_EQ(t.write({0x1A00, 0}, 3, 1), 0x06040042U);  // 96 bits
  EXPECT_EQ(t.write({0x1A00, 0}, 9, 1), 0x06090031U);
  EXPECT_EQ(t.write({0x1A00, 0}, 2, 1), 0U);
}

TEST(CanopenNodeSim, EveryNthSyncFromTheStartValue) {
  Fixture t;
  EXPECT_EQ(t.write({0x1800, 1}, 0x80000185U, 4), 0U);
  EXPECT_EQ(t.write({0x1800, 2}, 3, 1), 0U);  // every 3rd SYNC
  EXPECT_EQ(t.write({0x1800, 6}, 2, 1), 0U);  // starting on counter 2
  EXPECT_EQ(t.write({0x1800, 1}, 0x185U, 4), 0U);
  t.start();
  std::vector<int> sent_on;
  std::uint8_t counter = 0;
  for (int k = 0; k < 12; ++k) {
    counter = counter == 0 ? 1 : next_sync_counter(counter, 6);
    if (!t.sync(encode_sync(counter)).empty()) sent_on.push_back(counter);
  }
  EXPECT_EQ(sent_on, (std::vector<int>{2, 5, 2, 5}));
}

TEST(CanopenNodeSim, ResetNodeRebootsWithDefaults) {
  Fixture t;
  EXPECT_EQ(t.write({0x1017, 0}, 20, 2), 0U);
  t.start();
  t.exchange(encode_nmt(NmtCommand::kResetNode, 0));
  EXPECT_FALSE(t.node->booted());
  t.rx.clear();
  t.bus.run_until(t.bus.now() + 5 * kMs, &t.rx);
  ASSERT_FALSE(t.rx.empty());
  EXPECT_EQ(t.rx[0].id, 0x705U);
  EXPECT_EQ(t.rx[0].data[0], 0x00);
  EXPECT_EQ(t.node->state(), NmtState::kPreOperational);
  EXPECT_EQ(t.read({0x1017, 0}), 100U);
}

TEST(CanopenNodeSim, FaultEmcySetAndCleared) {
  Fixture t;
  t.node->set_fault(SimFault::kEmcy, true, t.bus.now());
  std::vector<CanFrame> rx;
  t.bus.run_until(t.bus.now() + kMs, &rx);
  ASSERT_EQ(rx.size(), 1U);
  Decoded d = decode_frame(rx[0]);
  ASSERT_EQ(d.kind, FrameKind::kEmcy);
  EXPECT_EQ(d.emcy.error_code, emcy_code::kDeviceHardware);
  EXPECT_EQ(d.emcy.error_register, error_register::kGeneric);
  EXPECT_EQ(t.read({0x1001, 0}), error_register::kGeneric);
  t.node->set_fault(SimFault::kEmcy, false, t.bus.now());
  rx.clear();
  t.bus.run_until(t.bus.now() + kMs, &rx);
  ASSERT_EQ(rx.size(), 1U);
  d = decode_frame(rx[0]);
  EXPECT_EQ(d.emcy.error_code, emcy_code::kNoError);
  EXPECT_EQ(d.emcy.error_register, 0);
}

TEST(CanopenNodeSim, FaultsOnTpdos) {
  Fixture t;
  t.start();
  t.node->set_fault(SimFault::kTpdoMissing, true, t.bus.now());
  EXPECT_TRUE(t.sync().empty());
  t.node->set_fault(SimFault::kTpdoMissing, false, t.bus.now());
  t.node->set_fault(SimFault::kWrongPdoLength, true, t.bus.now());
  std::vector<CanFrame> tpdo = t.sync();
  ASSERT_EQ(tpdo.size(), 1U);
  EXPECT_EQ(tpdo[0].dlc, 3);
  t.node->set_fault(SimFault::kWrongPdoLength, false, t.bus.now());
  t.node->set_fault(SimFault::kTpdoLate, true, t.bus.now());
  const std::int64_t sync_at = t.bus.now();
  t.bus.send(encode_sync(), sync_at);
  std::vector<CanFrame> rx;
  t.bus.run_until(sync_at + 3 * kMs, &rx);
  ASSERT_EQ(rx.size(), 1U);
  EXPECT_EQ(rx[0].mono_ns, sync_at + 700'000);
}

TEST(CanopenNodeSim, FaultHeartbeatStopsAndNeverBoots) {
  Fixture t;
  t.node->set_fault(SimFault::kHeartbeatStops, true, t.bus.now());
  std::vector<CanFrame> rx;
  t.bus.run_until(t.bus.now() + 500 * kMs, &rx);
  EXPECT_TRUE(rx.empty());
  EXPECT_EQ(t.read({0x1018, 1}), 0x00000A5EU);  // the rest still works

  SimBus bus;
  NodeSimConfig c;
  c.node = kNode;
  EncoderNodeSim& mute = bus.add(c, [](std::int64_t) { return SimPosition{}; });
  mute.set_fault(SimFault::kNeverBoots, true, 0);
  bus.power_on(0);
  rx.clear();
  bus.run_until(500 * kMs, &rx);
  bus.send(encode_nmt(NmtCommand::kResetCommunication, kNode), bus.now());
  bus.send(encode_sdo_upload_request(kNode, {0x1018, 1}), bus.now());
  bus.run_until(600 * kMs, &rx);
  EXPECT_TRUE(rx.empty());
  mute.set_fault(SimFault::kNeverBoots, false, bus.now());  // power returns: it boots
  bus.run_until(700 * kMs, &rx);
  ASSERT_FALSE(rx.empty());
  EXPECT_EQ(rx[0].data[0], 0x00);
}

TEST(CanopenNodeSim, SyncProducerCountsAndFaultSkipsACounter) {
  NodeSimConfig c;
  c.sync_producer = true;
  c.sync_period_ns = kMs;
  c.sync_overflow = 4;
  c.heartbeat_ms = 0;
  Fixture t(c);  // booted at 2 ms, runs to 10 ms: SYNCs at 3..10 ms
  std::vector<int> counters;
  for (const CanFrame& f : t.rx) {
    const Decoded d = decode_frame(f);
    if (d.kind == FrameKind::kSync) counters.push_back(d.sync.counter);
  }
  EXPECT_EQ(counters, (std::vector<int>{1, 2, 3, 4, 1, 2, 3, 4}));
  t.start();
  t.node->set_fault(SimFault::kSyncCounterMismatch, true, t.bus.now());
  std::vector<CanFrame> rx;
  t.bus.run_until(t.bus.now() + 2 * kMs + kMs / 2, &rx);  // SYNCs at 12 and 13 ms
  counters.clear();
  int tpdos = 0;
  for (const CanFrame& f : rx) {
    const Decoded d = decode_frame(f);
    if (d.kind == FrameKind::kSync) counters.push_back(d.sync.counter);
    if (d.kind == FrameKind::kTpdo) ++tpdos;
  }
  EXPECT_EQ(counters, (std::vector<int>{3, 1}));  // after 1 (at 11 ms): 2 and 4 skipped
  EXPECT_EQ(tpdos, 3);  // its own SYNCs trigger its TPDO: answers to 11, 12 and 13 ms
}

}  // namespace
}  // namespace exodaq::drivers::canopen
