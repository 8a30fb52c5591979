// Start-up and assembly against six simulated CANopen encoder nodes on the
// in-memory bus: the manager's sequence (boot-up, identity, configuration,
// NMT start) and its failures, then the cycle assembler with every simulator
// fault injected on one node at a time, each detected with its own reason
// and no other joint flagged.
#include <gtest/gtest.h>

#include <cstdint>
#include <functional>
#include <ostream>
#include <string>
#include <vector>

#include "exodaq/drivers/canopen/assembler.hpp"
#include "exodaq/drivers/canopen/startup.hpp"
#include "sim_bus.hpp"

namespace exodaq::drivers::canopen {
namespace {

using test::SimBus;

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kDeadline = 500'000;
constexpr int kNodes = 6;
constexpr NodeId kFirstNode = 11;
constexpr std::uint32_t kRange = 1U << 25;
constexpr Multiplexer kReference{0x2100, 1};
constexpr std::uint32_t kVendor = 0x00000A5E;
constexpr std::uint32_t kProduct = 0x00000406;

NodeId node_id(int i) {
  return static_cast<NodeId>(kFirstNode + i);
}

TpdoSetup position_and_reference() {
  TpdoSetup t = position_tpdo(1);
  t.mapping.add({kReference.index, kReference.sub, 32});
  return t;
}

struct Options {
  bool consumer = false;  // node 0 produces SYNC (counter 1..10), the assembler consumes it
  std::function<void(NodeSimConfig&, int)> node_config;
  std::function<void(NodeSetup&, int)> setup;
};

// Six nodes, the manager's start-up and assembler, and the truth.
class Rig {
 public:
  explicit Rig(const Options& o = {}) : options_(o) {
    for (int i = 0; i < kNodes; ++i) {
      NodeSimConfig c;
      c.node = node_id(i);
      c.identity = {kVendor, kProduct, 0x00010000, 100U + static_cast<std::uint32_t>(i)};
      c.has_reference_object = true;
      c.reference_object = kReference;
      c.boot_delay_ns = (2 + i) * kMs;
      if (o.consumer && i == 0) {
        c.sync_producer = true;
        c.sync_period_ns = kMs;
        c.sync_overflow = 10;
      }
      if (o.node_config) o.node_config(c, i);
      bus_.add(c, [i](std::int64_t now) { return truth(i, now); });
    }
    build_startup();
    build_assembler();
  }

  SimBus& bus() { return bus_; }
  EncoderNodeSim& node(int i) { return bus_.node(i); }
  Startup& startup() { return startup_; }
  Assembler& assembler() { return assembler_; }
  std::int64_t now() const { return t_; }

  // The encoder's raw count at `now`: 3 counts per ms, across the range's
  // wrap (at 300 ms) for node 5; the reference is a fixed latch per node.
  static SimPosition truth(int i, std::int64_t now) {
    const auto ms = static_cast<std::uint32_t>(now / kMs);
    const std::uint32_t base = i == 5 ? kRange - 900 : 1000U * static_cast<std::uint32_t>(i);
    return {base + 3 * ms, 500U + static_cast<std::uint32_t>(i)};
  }

  // Power-on at 0 and the manager's start-up, 1 ms per step, until done.
  void start(const std::function<void(std::int64_t)>& each_ms = {}) {
    bus_.power_on(0);
    startup_.begin(0);
    while (!startup_.done() && t_ < 10'000 * kMs) {
      t_ += kMs;
      if (each_ms) each_ms(t_);
      step_startup();
    }
    ASSERT_TRUE(startup_.done());
    assembler_.reset(t_);
  }

  void step_startup() {
    std::vector<CanFrame> rx;
    bus_.run_until(t_, &rx);
    for (const CanFrame& f : rx) startup_.on_frame(f, f.mono_ns);
    startup_.advance(t_);
    CanFrame out;
    while (startup_.next_frame(out)) bus_.send(out, t_);
  }

  // One loop cycle of 1 ms: (producer) SYNC at its start, deadline 0.5 ms
  // later; the start-up machine keeps following the nodes.
  CycleSample cycle() {
    t_ += kMs;
    std::vector<CanFrame> rx;
    bus_.run_until(t_, &rx);
    feed(rx);
    if (!options_.consumer) {
      last_sync_ = t_;
      bus_.send(assembler_.begin_cycle(t_), t_);
    }
    rx.clear();
    bus_.run_until(t_ + kDeadline, &rx);
    feed(rx);
    assembler_.end_cycle(t_ + kDeadline);
    CycleSample s;
    EXPECT_TRUE(assembler_.poll(s)) << t_;
    return s;
  }

  // The position node i's TPDO of the last SYNC carries.
  std::uint32_t expected_position(int i) const { return truth(i, last_sync_).position % kRange; }

 private:
  void feed(const std::vector<CanFrame>& frames) {
    for (const CanFrame& f : frames) {
      assembler_.on_frame(f);
      startup_.on_frame(f, f.mono_ns);
      if (options_.consumer && decode_frame(f).kind == FrameKind::kSync) last_sync_ = f.mono_ns;
    }
  }

  void build_startup() {
    StartupConfig sc;
    sc.node_count = kNodes;
    sc.boot_timeout_ns = 100 * kMs;
    sc.sdo_timeout_ns = 20 * kMs;
    sc.operational_timeout_ns = 300 * kMs;
    for (int i = 0; i < kNodes; ++i) {
      NodeSetup& n = sc.nodes[static_cast<std::size_t>(i)];
      n.node = node_id(i);
      n.expected_vendor_id = kVendor;
      n.expected_product_code = kProduct;
      EXPECT_TRUE(n.add_tpdo(position_and_reference()));
      EXPECT_TRUE(n.add({{od::kProducerHeartbeatTime, 0}, 100, 2}));
      EXPECT_TRUE(n.add({{od::kOperatingParameters, 0}, operating_parameter::kScaling, 2}));
      EXPECT_TRUE(n.add({{od::kMeasuringUnitsPerRevolution, 0}, 1U << 13, 4}));
      EXPECT_TRUE(n.add({{od::kTotalMeasuringRange, 0}, kRange, 4}));
      if (options_.setup) options_.setup(n, i);
    }
    startup_ = Startup(sc);
  }

  void build_assembler() {
    AssemblerConfig ac;
    ac.joint_count = kNodes;
    ac.sync_role = options_.consumer ? SyncRole::kConsumer : SyncRole::kProducer;
    ac.sync_overflow = options_.consumer ? 10 : 0;
    ac.boot_timeout_ns = 200 * kMs;
    ac.tpdo_deadline_ns = kDeadline;
    for (int i = 0; i < kNodes; ++i) {
      JointConfig& j = ac.joints[static_cast<std::size_t>(i)];
      j.node = node_id(i);
      j.tpdo = position_and_reference();
      j.values.has_reference = true;
      j.values.reference = kReference;
      j.total_range = kRange;
      j.heartbeat_timeout_ns = 150 * kMs;
    }
    EXPECT_EQ(validate(ac).what, nullptr);
    assembler_ = Assembler(ac);
  }

  Options options_;
  SimBus bus_;
  Startup startup_{StartupConfig{}};
  Assembler assembler_{AssemblerConfig{}};
  std::int64_t t_ = 0;
  std::int64_t last_sync_ = 0;
};

// --- start-up ----------------------------------------------------------------

TEST(CanopenStartup, SixNodesReadConfiguredAndStarted) {
  Rig r;
  r.start();
  ASSERT_TRUE(r.startup().all_operational());
  for (int i = 0; i < kNodes; ++i) {
    const NodeProgress& p = r.startup().progress(i);
    EXPECT_EQ(p.failure, StartupFailure::kNone);
    EXPECT_EQ(p.identity.vendor_id, kVendor);
    EXPECT_EQ(p.identity.product_code, kProduct);
    EXPECT_EQ(p.identity.serial_number, 100U + static_cast<std::uint32_t>(i));
    EXPECT_EQ(p.sdo_retries, 0);
    EXPECT_EQ(p.boot_resets, 0);
    EXPECT_EQ(r.node(i).state(), NmtState::kOperational);
    std::uint32_t v = 0;
    ASSERT_TRUE(r.node(i).read({0x1A00, 0}, v));
    EXPECT_EQ(v, 2U);
    ASSERT_TRUE(r.node(i).read({0x1A00, 2}, v));
    EXPECT_EQ(v, 0x21000120U);  // the reference object, written by the start-up
  }
  // Operational is confirmed by a heartbeat (every 100 ms): within 0.5 s.
  EXPECT_LT(r.now(), 500 * kMs);
  EXPECT_EQ(r.startup().stats().unexpected_sdo, 0);
}

TEST(CanopenStartup, ThenEveryCycleCarriesEveryJoint) {
  Rig r;
  r.start();
  int wraps = 0;
  std::uint32_t last5 = 0;
  for (int k = 0; k < 400; ++k) {
    const CycleSample s = r.cycle();
    ASSERT_EQ(s.flags, 0U) << k;
    for (int i = 0; i < kNodes; ++i) {
      const JointReading& j = s.joints[static_cast<std::size_t>(i)];
      ASSERT_TRUE(j.present) << k << " " << i;
      ASSERT_EQ(j.faults, 0U) << k << " " << i;
      ASSERT_EQ(j.position, r.expected_position(i)) << k << " " << i;
      ASSERT_EQ(j.reference, 500U + static_cast<std::uint32_t>(i));
      ASSERT_EQ(j.modulus, kRange);
    }
    wraps += k > 0 && s.joints[5].position < last5;
    last5 = s.joints[5].position;
  }
  EXPECT_EQ(wraps, 1);  // node 5 crossed the total measuring range
  EXPECT_EQ(r.assembler().stats().tpdos, 400 * kNodes);
  EXPECT_GT(r.assembler().stats().heartbeats, 0);
}

TEST(CanopenStartup, NodeNeverBootingFailsAfterItsResets) {
  Rig r;
  r.node(2).set_fault(SimFault::kNeverBoots, true, 0);
  r.start();
  const NodeProgress& p = r.startup().progress(2);
  EXPECT_EQ(p.phase, StartupPhase::kFailed);
  EXPECT_EQ(p.failure, StartupFailure::kNeverBooted);
  EXPECT_EQ(p.boot_resets, 2);  // two NMT reset communication, then given up
  for (int i = 0; i < kNodes; ++i) {
    if (i == 2) continue;
    EXPECT_EQ(r.startup().progress(i).phase, StartupPhase::kOperational) << i;
  }
}

TEST(CanopenStartup, WrongIdentityIsRefused) {
  Options o;
  o.node_config = [](NodeSimConfig& c, int i) {
    if (i == 4) c.identity.product_code = 0x999;
  };
  Rig r(o);
  r.start();
  const NodeProgress& p = r.startup().progress(4);
  EXPECT_EQ(p.failure, StartupFailure::kIdentityMismatch);
  EXPECT_EQ(p.identity.product_code, 0x999U);
  EXPECT_EQ(r.node(4).state(), NmtState::kPreOperational);  // never started
}

TEST(CanopenStartup, AbortedWriteFailsWithItsCodeAndObject) {
  Options o;
  o.setup = [](NodeSetup& n, int i) {
    if (i == 1) n.writes[3].value = 0x22000120;  // map an object the node does not have
  };
  Rig r(o);
  r.start();
  const NodeProgress& p = r.startup().progress(1);
  EXPECT_EQ(p.failure, StartupFailure::kSdoAbort);
  EXPECT_EQ(p.abort_code, 0x06040041U);
  EXPECT_EQ(p.at, (Multiplexer{0x1A00, 2}));
  EXPECT_EQ(abort_name(p.abort_code), "object cannot be mapped to the PDO");
}

TEST(CanopenStartup, NodeGoingMuteTimesOutItsSdoAfterRetries) {
  Rig r;
  // Node 0 falls silent as soon as the manager reads its identity.
  r.start([&](std::int64_t t) {
    if (r.startup().progress(0).phase == StartupPhase::kReadIdentity) {
      r.node(0).set_fault(SimFault::kNeverBoots, true, t);
    }
  });
  const NodeProgress& p = r.startup().progress(0);
  EXPECT_EQ(p.failure, StartupFailure::kSdoTimeout);
  EXPECT_EQ(p.at, (Multiplexer{0x1018, 1}));
  EXPECT_EQ(p.sdo_retries, 2);
  EXPECT_EQ(r.startup().progress(1).phase, StartupPhase::kOperational);
}

TEST(CanopenStartup, RunningNodeIsTakenBackToPreOperational) {
  Rig r;
  r.bus().power_on(0);
  r.bus().run_until(50 * kMs);
  r.bus().send(encode_nmt(NmtCommand::kStart, kAllNodes), 50 * kMs);
  r.bus().run_until(150 * kMs);
  for (int i = 0; i < kNodes; ++i) ASSERT_EQ(r.node(i).state(), NmtState::kOperational);
  // The manager starts now: no boot-up to see, only operational heartbeats.
  Startup& s = r.startup();
  s.begin(150 * kMs);
  std::int64_t t = 150 * kMs;
  while (!s.done() && t < 2000 * kMs) {
    t += kMs;
    std::vector<CanFrame> rx;
    r.bus().run_until(t, &rx);
    for (const CanFrame& f : rx) s.on_frame(f, f.mono_ns);
    s.advance(t);
    CanFrame out;
    while (s.next_frame(out)) r.bus().send(out, t);
  }
  ASSERT_TRUE(s.all_operational());
  std::uint32_t v = 0;
  ASSERT_TRUE(r.node(0).read({0x1A00, 0}, v));
  EXPECT_EQ(v, 2U);  // reconfigured: it went through pre-operational
}

TEST(CanopenStartup, RebootedNodeIsConfiguredAgainAndFlagged) {
  Rig r;
  r.start();
  for (int k = 0; k < 5; ++k) r.cycle();
  r.bus().send(encode_nmt(NmtCommand::kResetNode, node_id(3)), r.now());
  bool rebooted = false;
  int back = -1;
  for (int k = 0; k < 400 && back < 0; ++k) {
    const CycleSample s = r.cycle();
    r.step_startup();
    const JointReading& j = s.joints[3];
    rebooted = rebooted || (j.faults & joint_fault::kRebooted) != 0;
    if (rebooted && j.present && j.faults == 0) back = k;
  }
  EXPECT_TRUE(rebooted);
  EXPECT_GE(back, 0);
  EXPECT_EQ(r.startup().progress(3).reboots, 1);
  EXPECT_EQ(r.startup().progress(3).phase, StartupPhase::kOperational);
  std::uint32_t v = 0;
  ASSERT_TRUE(r.node(3).read({0x1A00, 2}, v));
  EXPECT_EQ(v, 0x21000120U);  // its reset lost the mapping; the start-up wrote it again
}

// --- every fault, one node at a time ------------------------------------------

struct FaultCase {
  SimFault fault;
  int node;                 // which of the six
  std::uint32_t joint_bit;  // joint_fault bit that must show on that joint (0: none)
  std::uint32_t allowed;    // every bit that may show on it
  std::uint32_t cycle_bit;  // cycle_flag bit that must show (0: none)
  bool consumer;            // node 0 produces the SYNC
};

void PrintTo(const FaultCase& c, std::ostream* os) {
  *os << to_string(c.fault) << " on joint " << c.node;
}

class CanopenSixNodeFault : public ::testing::TestWithParam<FaultCase> {};

TEST_P(CanopenSixNodeFault, DetectedWithItsReasonAndNowhereElse) {
  const FaultCase& fc = GetParam();
  Options o;
  o.consumer = fc.consumer;
  Rig r(o);
  const bool at_boot = fc.fault == SimFault::kNeverBoots;
  if (at_boot) r.node(fc.node).set_fault(fc.fault, true, 0);
  r.start();
  for (int k = 0; k < 50; ++k) {  // clean before the fault
    const CycleSample s = r.cycle();
    ASSERT_EQ(s.flags, 0U) << k;
    for (int i = 0; i < kNodes; ++i) {
      if (at_boot && i == fc.node) continue;
      ASSERT_EQ(s.joints[static_cast<std::size_t>(i)].faults, 0U) << k << " " << i;
    }
  }
  if (!at_boot) r.node(fc.node).set_fault(fc.fault, true, r.now());
  int joint_seen = 0;
  int cycle_seen = 0;
  for (int k = 0; k < 400; ++k) {
    const CycleSample s = r.cycle();
    cycle_seen += (s.flags & fc.cycle_bit) != 0;
    ASSERT_EQ(s.flags & ~fc.cycle_bit, 0U) << k;
    for (int i = 0; i < kNodes; ++i) {
      const JointReading& j = s.joints[static_cast<std::size_t>(i)];
      if (i != fc.node) {
        ASSERT_EQ(j.faults, 0U) << "joint " << i << " cycle " << k;
        ASSERT_TRUE(j.present) << "joint " << i << " cycle " << k;
        continue;
      }
      ASSERT_EQ(j.faults & ~fc.allowed, 0U) << "cycle " << k << ": " << j.faults;
      joint_seen += (j.faults & fc.joint_bit) != 0;
      // A joint whose TPDO is missing, late or malformed is never present.
      if ((j.faults & (joint_fault::kMissing | joint_fault::kWrongLength)) != 0) {
        ASSERT_FALSE(j.present);
      }
    }
  }
  EXPECT_EQ(joint_seen > 0, fc.joint_bit != 0) << to_string(fc.fault);
  EXPECT_EQ(cycle_seen > 0, fc.cycle_bit != 0) << to_string(fc.fault);
}

using namespace joint_fault;

INSTANTIATE_TEST_SUITE_P(
    EveryFault, CanopenSixNodeFault,
    ::testing::Values(
        // Never answers: missing from the first cycle, never booted after 200 ms.
        FaultCase{SimFault::kNeverBoots, 0, kNeverBooted, kNeverBooted | kMissing, 0, false},
        // Heartbeat every 100 ms, consumer time 150 ms.
        FaultCase{SimFault::kHeartbeatStops, 1, kHeartbeatLost, kHeartbeatLost, 0, false},
        FaultCase{SimFault::kEmcy, 2, kEmcy, kEmcy, 0, false},
        FaultCase{SimFault::kTpdoMissing, 3, kMissing, kMissing, 0, false},
        // 0.7 ms after its SYNC, past the 0.5 ms deadline: missing in its own
        // cycle (the answer, read after the cycle closed, is counted late).
        FaultCase{SimFault::kTpdoLate, 4, kMissing, kLate | kMissing, 0, false},
        FaultCase{SimFault::kWrongPdoLength, 5, kWrongLength, kWrongLength | kMissing, 0, false},
        FaultCase{SimFault::kSyncCounterMismatch, 0, 0, 0, cycle_flag::kSyncCounterMismatch, true}),
    [](const ::testing::TestParamInfo<FaultCase>& info) {
      std::string name(to_string(info.param.fault));
      for (char& c : name) c = c == ' ' ? '_' : c;
      return name;
    });

}  // namespace
}  // namespace exodaq::drivers::canopen
