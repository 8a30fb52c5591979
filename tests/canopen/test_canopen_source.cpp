// The `canopen` backend: CanopenSource on the in-memory CanPort with six
// simulated CiA 406 encoder nodes answering its NMT, SDO and SYNC frames, and
// the parsing of its config section. Every sample is checked against the
// nodes' truth: start-up, positions with their modulus, the absolute and
// index bits, each node fault, interface loss and recovery, and read()
// allocating nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "alloc_counter.hpp"
#include "exodaq/common/config_error.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/drivers/canopen/canopen_backend.hpp"
#include "exodaq/drivers/canopen/canopen_source.hpp"
#include "exodaq/drivers/canopen/node_sim.hpp"
#include "exodaq/drivers/replay_source.hpp"
#include "exodaq/drivers/source_factory.hpp"
#include "memory_can_port.hpp"

namespace exodaq::drivers::canopen {
namespace {

using exodaq::test::MemoryCanPort;
namespace flag = sample_flag;

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kUs = 1'000;
constexpr int kNodes = kChannelCount;
constexpr NodeId kFirstNode = 11;
constexpr std::uint32_t kRange = 1U << 25;  // the simulated encoders' total measuring range
constexpr Multiplexer kReference{0x2100, 1};
constexpr std::uint32_t kVendor = 0x00000A5E;
constexpr std::uint32_t kProduct = 0x00000406;
constexpr int kIndexFrom = 4;  // joints 4 and 5: encoder-interface modules with a latched reference
constexpr std::int64_t kReferenceMovesAt = 600 * kMs;

NodeId node_id(int i) {
  return static_cast<NodeId>(kFirstNode + i);
}

// The raw count of node i at `now`: 3 counts per ms; node 5 starts 900
// counts below the range and wraps after 300 ms. The latched reference of
// nodes 4 and 5 moves once, at 600 ms.
SimPosition truth(int i, std::int64_t now) {
  const auto ms = static_cast<std::uint32_t>(now / kMs);
  const std::uint32_t base = i == 5 ? kRange - 900 : 1000U * static_cast<std::uint32_t>(i);
  const std::uint32_t reference =
      (now < kReferenceMovesAt ? 500U : 7000U) + static_cast<std::uint32_t>(i);
  return {base + 3 * ms, reference};
}

CanopenSourceConfig source_config() {
  CanopenSourceConfig c;
  c.interface = "vcan0";
  c.boot_timeout_ns = 100 * kMs;
  c.heartbeat_timeout_ns = 150 * kMs;  // producer time written: 100 ms
  c.reopen_interval_ns = 50 * kMs;
  c.sdo_timeout_ns = 20 * kMs;
  for (int i = 0; i < kNodes; ++i) {
    CanopenJoint& j = c.joints[static_cast<std::size_t>(i)];
    j.node = node_id(i);
    j.vendor_id = kVendor;
    j.product_code = kProduct;
    j.total_range = kRange;
    j.tpdo = position_tpdo(1);
    if (i >= kIndexFrom) {
      j.reference = ReferenceKind::kIndex;
      j.tpdo.mapping.add({kReference.index, kReference.sub, 32});
      j.values.has_reference = true;
      j.values.reference = kReference;
    }
  }
  return c;
}

// The source, its in-memory port and six nodes on one simulated bus, in
// lockstep with the port's clock: before each read the nodes run to the
// port's time; a frame the source sends reaches every node at the port's
// time; after a SYNC the nodes run ahead to the latest poll deadline, their
// frames queued to arrive at their stamps. Allocation-free once built.
class Rig {
 public:
  explicit Rig(const CanopenSourceConfig& config = source_config()) : config_(config) {
    for (int i = 0; i < kNodes; ++i) {
      NodeSimConfig c;
      c.node = node_id(i);
      c.identity = {kVendor, kProduct, 0x00010000, 100U + static_cast<std::uint32_t>(i)};
      c.has_reference_object = true;
      c.reference_object = kReference;
      c.boot_delay_ns = (2 + i) * kMs;
      nodes_[static_cast<std::size_t>(i)] =
          std::make_unique<EncoderNodeSim>(c, [i](std::int64_t now) { return truth(i, now); });
    }
    auto port = std::make_unique<MemoryCanPort>();
    port_ = port.get();
    port_->mono = 0;
    const can::CanIdFilterSet filters = port_config(config_).filters;
    port_->admit = [filters](const can::CanFrame& f) {
      return (f.flags & can::frame_flag::kError) != 0 || filters.passes(f.id);
    };
    port_->on_send = [this](const can::CanFrame& f, MemoryCanPort& p) { on_send(f, p.mono); };
    source_ = std::make_unique<CanopenSource>(config_, std::move(port));
  }

  CanopenSource& source() { return *source_; }
  MemoryCanPort& port() { return *port_; }
  EncoderNodeSim& node(int i) { return *nodes_[static_cast<std::size_t>(i)]; }
  std::int64_t now() const { return t_; }
  std::int64_t last_sync() const { return last_sync_; }

  void power_on() {
    for (auto& n : nodes_) n->power_on(0);
    source_->start();
  }

  // One loop cycle: the deadline 1 ms after the previous one, woken on time.
  ReadStatus cycle(EncoderSample& out) {
    t_ += kMs;
    port_->advance_to(t_);
    run_nodes(t_);
    CycleTime time;
    time.deadline_mono_ns = t_;
    time.now_mono_ns = t_;
    time.period_ns = kMs;
    time.cycle = ++cycles_;
    return source_->read(time, out);
  }

  // Cycles until the source runs its SYNC cycles; every sample before is MISSING.
  int start_up(int max_cycles = 5000) {
    power_on();
    EncoderSample s;
    for (int k = 0; k < max_cycles; ++k) {
      if (source_->cycling()) return k;
      const ReadStatus r = cycle(s);
      if (source_->cycling()) return k;
      EXPECT_EQ(r, ReadStatus::kNoSample) << k;
      EXPECT_FALSE(s.present) << k;
      EXPECT_EQ(s.flags & flag::kMissing, flag::kMissing) << k;
      EXPECT_EQ(s.channel_fresh, 0U) << k;
      if (s.present) break;
    }
    return -1;
  }

  // What node i's TPDO of the last SYNC carries.
  std::uint32_t expected_position(int i) const { return truth(i, last_sync_).position % kRange; }

  // From now on every frame on the bus, both ways, stamped (as candump on the
  // same bus would log it); null: none (allocation-free).
  void log_bus(std::vector<can::CanFrame>* log) { bus_log_ = log; }

  // A frame some other device sends, arriving `after` the next SYNC.
  void inject_after_sync(const can::CanFrame& f, std::int64_t after) {
    inject_ = f;
    inject_after_ = after;
    inject_pending_ = true;
  }

 private:
  static constexpr int kMaxBatch = 128;

  void on_send(const can::CanFrame& f, std::int64_t at) {
    if (bus_log_ != nullptr) {
      can::CanFrame stamped = f;
      stamped.mono_ns = at;
      bus_log_->push_back(stamped);
    }
    for (auto& n : nodes_) n->on_frame(f, at);
    if (f.id == cob::kSync) {
      last_sync_ = at;
      if (inject_pending_) {
        inject_pending_ = false;
        pending_extra_ = true;
        extra_at_ = at + inject_after_;
      }
      run_nodes(at + 900 * kUs);
    }
  }

  // The nodes run to `until`; their frames are queued in stamp order (the
  // kernel's receive filter applies; nothing is queued while the port is closed).
  void run_nodes(std::int64_t until) {
    if (until < bus_now_) return;
    bus_now_ = until;
    int n = 0;
    for (int i = 0; i < kNodes; ++i) {
      EncoderNodeSim& node = *nodes_[static_cast<std::size_t>(i)];
      node.advance(until);
      can::CanFrame f;
      while (n < kMaxBatch && node.next_frame(f)) batch_[static_cast<std::size_t>(n++)] = f;
    }
    if (pending_extra_ && extra_at_ <= until && n < kMaxBatch) {
      pending_extra_ = false;
      inject_.mono_ns = extra_at_;
      batch_[static_cast<std::size_t>(n++)] = inject_;
    }
    // Insertion sort by stamp (stable: equal stamps keep the nodes' order).
    for (int a = 1; a < n; ++a) {
      const can::CanFrame f = batch_[static_cast<std::size_t>(a)];
      int b = a - 1;
      while (b >= 0 && batch_[static_cast<std::size_t>(b)].mono_ns > f.mono_ns) {
        batch_[static_cast<std::size_t>(b + 1)] = batch_[static_cast<std::size_t>(b)];
        --b;
      }
      batch_[static_cast<std::size_t>(b + 1)] = f;
    }
    for (int k = 0; k < n; ++k) {
      const can::CanFrame& f = batch_[static_cast<std::size_t>(k)];
      if (bus_log_ != nullptr) bus_log_->push_back(f);
      if (port_->is_open()) port_->push(f, f.mono_ns);
    }
  }

  CanopenSourceConfig config_;
  std::vector<can::CanFrame>* bus_log_ = nullptr;
  std::array<std::unique_ptr<EncoderNodeSim>, kNodes> nodes_;
  MemoryCanPort* port_ = nullptr;
  std::unique_ptr<CanopenSource> source_;
  std::array<can::CanFrame, kMaxBatch> batch_{};
  std::int64_t t_ = 0;
  std::int64_t bus_now_ = 0;
  std::int64_t cycles_ = 0;
  std::int64_t last_sync_ = 0;
  can::CanFrame inject_{};
  std::int64_t inject_after_ = 0;
  bool inject_pending_ = false;
  bool pending_extra_ = false;
  std::int64_t extra_at_ = 0;
};

std::uint32_t bit(int j) {
  return 1U << j;
}

// --- start-up and the main path ------------------------------------------------

TEST(CanopenSource, StartUpReachesOperationalWithMissingSamplesMeanwhile) {
  Rig r;
  const int cycles = r.start_up();
  ASSERT_GT(cycles, 5);  // boot-up (2..7 ms), identity, configuration, NMT start, heartbeat
  ASSERT_LT(cycles, 500);
  EXPECT_TRUE(r.source().startup().all_operational());
  for (int i = 0; i < kNodes; ++i) {
    EXPECT_EQ(r.node(i).state(), NmtState::kOperational) << i;
    EXPECT_EQ(r.source().startup().progress(i).identity.serial_number,
              100U + static_cast<std::uint32_t>(i));
    std::uint32_t v = 0;
    ASSERT_TRUE(r.node(i).read({od::kProducerHeartbeatTime, 0}, v));
    EXPECT_EQ(v, 100U) << i;  // two thirds of the 150 ms consumer time
    ASSERT_TRUE(r.node(i).read({0x1A00, 0}, v));
    EXPECT_EQ(v, i >= kIndexFrom ? 2U : 1U) << i;  // the mapping written at start-up
  }
  // No SYNC before every node was operational: the one sent is the first cycle's.
  int syncs = 0;
  for (const can::CanFrame& f : r.port().sent) syncs += f.id == cob::kSync;
  EXPECT_EQ(syncs, 1);
  EXPECT_EQ(r.port().sent.back().id, cob::kSync);
  EXPECT_EQ(r.source().stats().missing_samples, cycles);
  SourceDiagnostics d;
  r.source().diagnose(d);
  EXPECT_EQ(d.state(), "vcan0 open, 6/6 operational");
}

TEST(CanopenSource, EveryCycleCarriesEveryNodesPositionWithItsModulus) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  EncoderSample s;
  int wraps = 0;
  int index_samples = 0;
  std::int64_t last5 = -1;
  std::int64_t seq = -1;
  for (int k = 0; k < 1000; ++k) {
    ASSERT_EQ(r.cycle(s), ReadStatus::kSample) << k;
    ASSERT_TRUE(s.present) << k;
    ASSERT_EQ(s.flags, 0U) << k;
    ASSERT_EQ(s.channel_fresh, kAllChannels) << k;
    ASSERT_EQ(s.board_errors, 0U) << k;
    ASSERT_EQ(s.board_state, kAllChannels) << k;  // every node operational
    ASSERT_EQ(s.mono_ns, r.now()) << k;           // the SYNC's send time
    ASSERT_EQ(s.mono_ns, r.last_sync()) << k;
    ASSERT_EQ(s.wall_ns, s.mono_ns + MemoryCanPort::kWallOffsetNs) << k;
    ASSERT_EQ(s.seq_modulus, 0);
    if (seq >= 0) {
      ASSERT_EQ(s.seq, seq + 1) << k;
    }
    seq = s.seq;
    ASSERT_EQ(s.absolute, 0x0FU) << k;  // joints 0..3 absolute, 4 and 5 on their index
    for (int j = 0; j < kNodes; ++j) {
      ASSERT_EQ(s.position[static_cast<std::size_t>(j)], r.expected_position(j)) << k << " " << j;
      ASSERT_EQ(s.modulus[static_cast<std::size_t>(j)], kRange) << j;
    }
    for (int j = kIndexFrom; j < kNodes; ++j) {
      const std::int64_t expected_reference = truth(j, r.last_sync()).reference;
      ASSERT_EQ(s.index_position[static_cast<std::size_t>(j)], expected_reference) << k;
    }
    if (s.index_count_valid != 0) {
      ++index_samples;
      EXPECT_EQ(s.index_count_valid, bit(4) | bit(5));
      EXPECT_EQ(s.index_latched, bit(4) | bit(5));
      EXPECT_EQ(s.index_position[4], 7004);
      EXPECT_GE(r.last_sync(), kReferenceMovesAt);
    }
    wraps += last5 >= 0 && s.position[5] < last5;
    last5 = s.position[5];
  }
  EXPECT_EQ(wraps, 1);          // node 5 crossed its total measuring range
  EXPECT_EQ(index_samples, 1);  // the reference moved once
  const SourceStats st = r.source().stats();
  EXPECT_EQ(st.bus_state, BusState::kActive);
  EXPECT_EQ(st.bad_frames, 0);
  EXPECT_EQ(st.seq_gaps, 0);
  EXPECT_EQ(st.late_syncs, 0);
  EXPECT_EQ(r.source().detail().sync_sent, 1001);  // with start_up()'s first cycle
  EXPECT_EQ(r.source().assembler().stats().tpdos, 1001 * kNodes);
  // Each cycle ended as soon as its six TPDOs were in (0.1 ms after SYNC),
  // not at the 0.4 ms poll deadline.
  EXPECT_EQ(r.port().mono, r.now() + 100 * kUs);
}

TEST(CanopenSource, TheSampleInstantIsItsSyncReadBackFromTheBus) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  // Each SYNC goes out 30 us after the clock reading before it.
  r.port().send_delay_ns = 30 * kUs;
  EncoderSample s;
  ASSERT_EQ(r.cycle(s), ReadStatus::kSample);
  EXPECT_EQ(s.mono_ns, r.now());  // not read back: the clock reading
  EXPECT_EQ(r.last_sync(), r.now() + 30 * kUs);
  r.port().receive_own = true;
  for (int k = 0; k < 10; ++k) {
    ASSERT_EQ(r.cycle(s), ReadStatus::kSample) << k;
    ASSERT_EQ(s.channel_fresh, kAllChannels) << k;
    ASSERT_EQ(s.mono_ns, r.last_sync()) << k;  // when the nodes latched
    ASSERT_EQ(s.mono_ns, r.now() + 30 * kUs) << k;
    for (int j = 0; j < kNodes; ++j) {
      ASSERT_EQ(s.position[static_cast<std::size_t>(j)], r.expected_position(j)) << k;
    }
  }
  EXPECT_EQ(r.source().assembler().stats().syncs_read_back, 10);
  EXPECT_EQ(r.source().assembler().stats().late, 0);
}

TEST(CanopenSource, CatchUpReadDeliversNothing) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  EncoderSample s;
  ASSERT_EQ(r.cycle(s), ReadStatus::kSample);
  CycleTime time;
  time.deadline_mono_ns = r.now();
  time.now_mono_ns = r.now();
  time.catch_up = true;
  EncoderSample other;
  other.seq = 12345;
  EXPECT_EQ(r.source().read(time, other), ReadStatus::kNothingDue);
  EXPECT_EQ(other.seq, 12345);
}

// --- node faults -------------------------------------------------------------------

// Runs `n` cycles; `check` sees each sample.
template <typename Check>
void run(Rig& r, int n, Check&& check) {
  EncoderSample s;
  for (int k = 0; k < n; ++k) {
    const ReadStatus status = r.cycle(s);
    check(k, status, s);
  }
}

TEST(CanopenSource, EmcyIsABoardErrorOnItsJointOnly) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  run(r, 20, [](int, ReadStatus, const EncoderSample& s) { ASSERT_EQ(s.flags, 0U); });
  r.node(2).set_fault(SimFault::kEmcy, true, r.now());
  int flagged = 0;
  run(r, 50, [&](int k, ReadStatus status, const EncoderSample& s) {
    ASSERT_EQ(status, ReadStatus::kSample);
    ASSERT_EQ(s.channel_fresh, kAllChannels) << k;  // its positions still come
    ASSERT_EQ(s.position[2], r.expected_position(2));
    if (s.flags == 0) return;
    ASSERT_EQ(s.flags, flag::kBoardError) << k;
    ASSERT_EQ(s.board_errors, bit(2) | board_error::kEmcy) << k;
    ++flagged;
  });
  EXPECT_GE(flagged, 48);  // from the EMCY's arrival on, every cycle
  EXPECT_EQ(r.source().stats().board_errors, bit(2) | board_error::kEmcy);
  r.node(2).set_fault(SimFault::kEmcy, false, r.now());  // error reset (code 0)
  run(r, 3, [](int, ReadStatus, const EncoderSample&) {});
  run(r, 10, [](int k, ReadStatus, const EncoderSample& s) {
    ASSERT_EQ(s.flags, 0U) << k;
    ASSERT_EQ(s.board_errors, 0U) << k;
  });
}

TEST(CanopenSource, MissingTpdoLeavesItsChannelStaleAndTheSamplePartial) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  EncoderSample s;
  ASSERT_EQ(r.cycle(s), ReadStatus::kSample);
  const std::int64_t held = s.position[3];
  r.node(3).set_fault(SimFault::kTpdoMissing, true, r.now());
  run(r, 30, [&](int k, ReadStatus status, const EncoderSample& x) {
    ASSERT_EQ(status, ReadStatus::kSample) << k;
    ASSERT_TRUE(x.present);
    ASSERT_EQ(x.flags, flag::kPartial) << k;
    ASSERT_EQ(x.channel_fresh, kAllChannels & ~bit(3)) << k;
    ASSERT_EQ(x.position[3], held) << k;  // the last fresh position, repeated
    ASSERT_EQ(x.position[2], r.expected_position(2)) << k;
  });
  EXPECT_EQ(r.source().assembler().stats().missing, 30);
  // The cycle waited for the missing TPDO until its poll deadline: 0.4 ms.
  EXPECT_EQ(r.port().mono, r.now() + 400 * kUs);
  r.node(3).set_fault(SimFault::kTpdoMissing, false, r.now());
  run(r, 5, [&](int k, ReadStatus, const EncoderSample& x) {
    ASSERT_EQ(x.flags, 0U) << k;
    ASSERT_EQ(x.position[3], r.expected_position(3)) << k;
  });
}

TEST(CanopenSource, EveryTpdoMissingIsAMissingSample) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  for (int i = 0; i < kNodes; ++i) r.node(i).set_fault(SimFault::kTpdoMissing, true, r.now());
  const std::int64_t missing_before = r.source().stats().missing_samples;
  run(r, 10, [](int k, ReadStatus status, const EncoderSample& s) {
    ASSERT_EQ(status, ReadStatus::kNoSample) << k;
    ASSERT_FALSE(s.present);
    ASSERT_EQ(s.flags, flag::kMissing) << k;
    ASSERT_EQ(s.channel_fresh, 0U);
  });
  EXPECT_EQ(r.source().stats().missing_samples, missing_before + 10);
}

TEST(CanopenSource, WrongPdoLengthIsCountedAndNeverPublished) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  r.node(5).set_fault(SimFault::kWrongPdoLength, true, r.now());
  run(r, 20, [&](int k, ReadStatus, const EncoderSample& s) {
    ASSERT_EQ(s.flags, flag::kPartial) << k;
    ASSERT_EQ(s.channel_fresh, kAllChannels & ~bit(5)) << k;
    ASSERT_EQ(s.index_count_valid, 0U);
  });
  EXPECT_EQ(r.source().stats().bad_frames, 20);
  EXPECT_EQ(r.source().assembler().stats().wrong_length, 20);
}

TEST(CanopenSource, DuplicateTpdoFlagsTheSampleAndStalesTheChannel) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  run(r, 3, [](int, ReadStatus, const EncoderSample&) {});
  // A second TPDO of node 12 (joint 1), 50 us after the next SYNC: before its own.
  std::array<std::uint8_t, 8> data{0x11, 0x22, 0x33, 0x00};
  r.inject_after_sync(encode_tpdo(1, node_id(1), data, 4), 50 * kUs);
  EncoderSample s;
  ASSERT_EQ(r.cycle(s), ReadStatus::kSample);
  EXPECT_EQ(s.flags, flag::kDuplicate | flag::kPartial);
  EXPECT_EQ(s.channel_fresh, kAllChannels & ~bit(1));
  EXPECT_NE(s.position[1], 0x332211);
  EXPECT_EQ(r.source().stats().duplicates, 1);
  ASSERT_EQ(r.cycle(s), ReadStatus::kSample);
  EXPECT_EQ(s.flags, 0U);
  EXPECT_EQ(s.position[1], r.expected_position(1));
}

TEST(CanopenSource, LateTpdoIsNeverPublished) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  r.node(4).set_fault(SimFault::kTpdoLate, true, r.now());  // 0.7 ms after its SYNC
  run(r, 20, [&](int k, ReadStatus, const EncoderSample& s) {
    ASSERT_EQ(s.flags, flag::kPartial) << k;
    ASSERT_EQ(s.channel_fresh, kAllChannels & ~bit(4)) << k;
  });
  // Missing in its own cycle (poll deadline 0.4 ms), late in the next.
  EXPECT_EQ(r.source().assembler().stats().late, 19);
}

TEST(CanopenSource, ForeignSyncIsABusError) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  r.inject_after_sync(encode_sync(), 300 * kUs);  // SYNC from another producer
  EncoderSample s;
  ASSERT_EQ(r.cycle(s), ReadStatus::kSample);
  EXPECT_EQ(s.flags, 0U);  // the cycle ended with its TPDOs, 0.1 ms after SYNC
  ASSERT_EQ(r.cycle(s), ReadStatus::kSample);
  EXPECT_EQ(s.flags, flag::kBusError);  // received before the next SYNC: flags that cycle
  EXPECT_EQ(s.channel_fresh, kAllChannels);
  ASSERT_EQ(r.cycle(s), ReadStatus::kSample);
  EXPECT_EQ(s.flags, 0U);
  EXPECT_EQ(r.source().assembler().stats().foreign_syncs, 1);
  EXPECT_EQ(r.source().stats().bus_errors, 1);
}

TEST(CanopenSource, LostHeartbeatIsABoardError) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  r.node(1).set_fault(SimFault::kHeartbeatStops, true, r.now());
  int flagged = 0;
  run(r, 400, [&](int k, ReadStatus, const EncoderSample& s) {
    ASSERT_EQ(s.channel_fresh, kAllChannels) << k;  // TPDOs keep coming
    if (s.flags == 0) return;
    ASSERT_EQ(s.flags, flag::kBoardError) << k;
    ASSERT_EQ(s.board_errors, bit(1) | board_error::kHeartbeatLost) << k;
    ++flagged;
  });
  // Lost 150 ms after its last heartbeat (every 100 ms, the last one 0..100 ms
  // before the fault): the last 250..350 cycles.
  EXPECT_GE(flagged, 250);
  EXPECT_LE(flagged, 350);
  EXPECT_EQ(r.source().assembler().stats().heartbeat_losses, 1);
}

TEST(CanopenSource, NodeNeverBootingFailsStartUpAndIsFlaggedEveryCycle) {
  Rig r;
  r.node(0).set_fault(SimFault::kNeverBoots, true, 0);
  const int cycles = r.start_up();
  ASSERT_GE(cycles, 299);  // three boot waits of 100 ms (two NMT resets)
  const NodeProgress& p = r.source().startup().progress(0);
  EXPECT_EQ(p.phase, StartupPhase::kFailed);
  EXPECT_EQ(p.failure, StartupFailure::kNeverBooted);
  EXPECT_EQ(p.boot_resets, 2);
  SourceDiagnostics d;
  r.source().diagnose(d);
  EXPECT_EQ(d.state(), "vcan0 open, 5/6 operational, node 11 failed: never booted");
  EXPECT_EQ(d.find("boot_resets")->value, 2);
  run(r, 20, [&](int k, ReadStatus status, const EncoderSample& s) {
    ASSERT_EQ(status, ReadStatus::kSample) << k;
    ASSERT_EQ(s.flags, flag::kPartial | flag::kBoardError) << k;
    ASSERT_EQ(s.channel_fresh, kAllChannels & ~bit(0)) << k;
    ASSERT_EQ(s.board_errors, bit(0) | board_error::kNeverBooted) << k;
    ASSERT_EQ(s.board_state, kAllChannels & ~bit(0)) << k;
    ASSERT_EQ(s.position[1], r.expected_position(1)) << k;
  });
  // The cycle does not wait for the failed node: it ends with the others' TPDOs.
  EXPECT_EQ(r.port().mono, r.now() + 100 * kUs);
}

TEST(CanopenSource, WrongIdentityFailsItsNodeWhichStaysUnstarted) {
  CanopenSourceConfig c = source_config();
  c.joints[3].product_code = 0x999;
  Rig r(c);
  ASSERT_GE(r.start_up(), 0);
  EXPECT_EQ(r.source().startup().progress(3).failure, StartupFailure::kIdentityMismatch);
  EncoderSample s;
  r.cycle(s);
  EXPECT_EQ(s.flags, flag::kPartial | flag::kBoardError);
  EXPECT_EQ(s.channel_fresh, kAllChannels & ~bit(3));
  EXPECT_EQ(s.board_errors, bit(3) | board_error::kNotOperational);  // pre-operational
}

TEST(CanopenSource, RebootedNodeIsConfiguredAgainWhileFlagged) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  run(r, 5, [](int, ReadStatus, const EncoderSample&) {});
  r.node(3).on_frame(encode_nmt(NmtCommand::kResetNode, node_id(3)), r.now());
  bool rebooted = false;
  int back = -1;
  run(r, 400, [&](int k, ReadStatus, const EncoderSample& s) {
    if ((s.board_errors & board_error::kRebooted) != 0) {
      rebooted = true;
      EXPECT_NE(s.board_errors & bit(3), 0U);
    }
    if (rebooted && back < 0 && s.flags == 0) back = k;
  });
  EXPECT_TRUE(rebooted);
  ASSERT_GE(back, 0);
  EXPECT_EQ(r.source().startup().progress(3).reboots, 1);
  EXPECT_EQ(r.node(3).state(), NmtState::kOperational);
}

// --- interface loss ----------------------------------------------------------------

TEST(CanopenSource, InterfaceDownIsMissingWithBusErrorThenRecovers) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  run(r, 10, [](int, ReadStatus, const EncoderSample& s) { ASSERT_EQ(s.flags, 0U); });
  EncoderSample last;
  r.cycle(last);
  r.port().take_down();
  run(r, 30, [&](int k, ReadStatus status, const EncoderSample& s) {
    ASSERT_EQ(status, ReadStatus::kNoSample) << k;
    ASSERT_FALSE(s.present);
    ASSERT_EQ(s.flags, flag::kMissing | flag::kBusError) << k;
    ASSERT_EQ(s.position, last.position);  // positions repeat the last sample
    ASSERT_EQ(s.mono_ns, r.now());
  });
  EXPECT_EQ(r.source().stats().bus_state, BusState::kDown);
  EXPECT_EQ(r.source().link().stats().interface_losses, 1);
  SourceDiagnostics d;
  r.source().diagnose(d);
  EXPECT_EQ(d.state().substr(0, 17), "vcan0 down: ENETD");
  r.port().bring_up();
  // Re-opened within the reopen interval (50 ms); then the start-up again.
  int missing = 0;
  int valid = 0;
  run(r, 600, [&](int k, ReadStatus status, const EncoderSample& s) {
    if (valid == 0) {
      if (status == ReadStatus::kSample) {
        ++valid;
      } else {
        ++missing;
        ASSERT_FALSE(s.present) << k;
      }
      return;
    }
    ASSERT_EQ(status, ReadStatus::kSample) << k;
    ASSERT_EQ(s.flags, 0U) << k;
    ASSERT_EQ(s.position[0], r.expected_position(0)) << k;
    ++valid;
  });
  EXPECT_GT(missing, 50);
  EXPECT_GT(valid, 100);
  EXPECT_EQ(r.source().detail().startup_restarts, 1);
  EXPECT_EQ(r.source().link().stats().reopens, 1);
  EXPECT_EQ(r.source().stats().bus_state, BusState::kActive);
}

TEST(CanopenSource, MissingInterfaceAtStartIsNotAnErrorAndIsRetried) {
  Rig r;
  r.port().remove();
  r.power_on();  // does not throw
  EncoderSample s;
  for (int k = 0; k < 20; ++k) {
    ASSERT_EQ(r.cycle(s), ReadStatus::kNoSample);
    ASSERT_EQ(s.flags, flag::kMissing | flag::kBusError) << k;
  }
  EXPECT_EQ(r.source().stats().bus_state, BusState::kDown);
  r.port().bring_up();
  for (int k = 0; k < 1000 && !r.source().cycling(); ++k) r.cycle(s);
  ASSERT_TRUE(r.source().cycling());
  ASSERT_EQ(r.cycle(s), ReadStatus::kSample);
  EXPECT_EQ(s.flags, 0U);
  EXPECT_EQ(s.position[4], r.expected_position(4));
}

TEST(CanopenSource, NoCanInTheKernelThrowsAtStart) {
  Rig r;
  r.port().open_error = EAFNOSUPPORT;
  EXPECT_THROW(r.power_on(), std::runtime_error);
}

TEST(CanopenSource, BusOffErrorFrameIsABusError) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  can::ErrorPayload e;
  e.classes = can::err_class::kBusOff;
  r.port().push(can::encode_error(e), r.now() + kMs);
  EncoderSample s;
  r.cycle(s);
  EXPECT_NE(s.flags & flag::kBusError, 0U);
  EXPECT_EQ(r.source().stats().bus_state, BusState::kOff);
  EXPECT_EQ(r.source().stats().bus_errors, 1);
}

// --- no allocation ---------------------------------------------------------------

TEST(CanopenSource, ReadAllocatesNothing) {
  Rig r;
  ASSERT_GE(r.start_up(), 0);
  EncoderSample s;
  r.cycle(s);
  SourceDiagnostics d;
  exodaq::test::AllocationScope scope;
  for (int k = 0; k < 500; ++k) {
    r.cycle(s);
    if (k == 100) r.node(2).set_fault(SimFault::kTpdoMissing, true, r.now());
    if (k == 200) r.node(2).set_fault(SimFault::kTpdoMissing, false, r.now());
    if (k == 300) r.port().take_down();  // down, missing, re-opened, start-up again
    if (k == 310) r.port().bring_up();
    if (k % 100 == 0) {
      d.clear();
      r.source().diagnose(d);
      (void)r.source().stats();
    }
  }
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_EQ(r.source().detail().startup_restarts, 1);
}

// --- configuration -------------------------------------------------------------------

const char* const kGood = R"(source:
  backend: canopen
  canopen:
    interface: can1
    sync: producer
    sync_overflow: 0
    read_deadline_us: 500
    reopen_interval_ms: 200
    rcvbuf_bytes: 65536
    boot_timeout_ms: 2000
    heartbeat_timeout_ms: 300
    joints:
      - {node: 1, reference: absolute}
      - {node: 2, vendor_id: 0x0000005A, product_code: 0x406, configure: false}
      - {node: 3, pdo: 2, total_range: 33554432}
      - {node: 4, cob_id: 0x1A4, bits: 24}
      - {node: 5, reference: index, object: 0x2000, sub_index: 1, reference_object: 0x2001, reference_sub_index: 1}
      - {node: 6}
)";

// Parses the `source:` section of `text` as the service config does.
std::shared_ptr<const BackendSettings> parse(const std::string& text) {
  const YAML::Node root = exodaq::load_yaml_text(text, "canopen.yaml");
  exodaq::MapReader source("canopen.yaml", root["source"], "config.source");
  source.allow("backend");
  std::optional<exodaq::MapReader> section = source.optional_map("canopen");
  return canopen_backend().parse(section ? &*section : nullptr, source, true);
}

TEST(CanopenConfig, GoodSectionIsParsedAndDescribed) {
  const auto parsed = parse(kGood);
  const auto* s = dynamic_cast<const CanopenSettings*>(parsed.get());
  ASSERT_NE(s, nullptr);
  const CanopenSourceConfig& c = s->config;
  EXPECT_EQ(c.interface, "can1");
  EXPECT_EQ(c.read_deadline_ns, 500'000);
  EXPECT_EQ(c.reopen_interval_ns, 200 * kMs);
  EXPECT_EQ(c.rcvbuf_bytes, 65536);
  EXPECT_EQ(c.boot_timeout_ns, 2000 * kMs);
  EXPECT_EQ(c.heartbeat_timeout_ns, 300 * kMs);
  EXPECT_EQ(heartbeat_producer_ms(c), 200);
  ASSERT_EQ(c.joint_count, 6);
  EXPECT_EQ(c.joints[0].reference, ReferenceKind::kAbsolute);
  EXPECT_EQ(tpdo_cob_id(c.joints[0].node, c.joints[0].tpdo), 0x181U);
  EXPECT_EQ(c.joints[1].vendor_id, 0x5AU);
  EXPECT_EQ(c.joints[1].product_code, 0x406U);
  EXPECT_FALSE(c.joints[1].configure);
  EXPECT_EQ(tpdo_cob_id(c.joints[2].node, c.joints[2].tpdo), 0x283U);  // TPDO2 of node 3
  EXPECT_EQ(c.joints[2].total_range, 1U << 25);
  EXPECT_EQ(tpdo_cob_id(c.joints[3].node, c.joints[3].tpdo), 0x1A4U);
  EXPECT_EQ(c.joints[3].tpdo.mapping.entries[0], (MappedObject{0x6004, 0, 24}));
  EXPECT_EQ(c.joints[4].reference, ReferenceKind::kIndex);
  ASSERT_EQ(c.joints[4].tpdo.mapping.count, 2);
  EXPECT_EQ(c.joints[4].tpdo.mapping.entries[0], (MappedObject{0x2000, 1, 32}));
  EXPECT_EQ(c.joints[4].tpdo.mapping.entries[1], (MappedObject{0x2001, 1, 32}));
  EXPECT_TRUE(c.joints[4].values.has_reference);
  const std::string d = s->describe();
  EXPECT_NE(d.find("{interface: can1, sync: producer, sync_overflow: 0, read_deadline_us: 500, "
                   "reopen_interval_ms: 200, rcvbuf_bytes: 65536, boot_timeout_ms: 2000, "
                   "heartbeat_timeout_ms: 300, joints: [{node: 1, reference: absolute, pdo: 1, "
                   "cob_id: 0x181, object: 0x6004, sub_index: 0, bits: 32, total_range: 0, "
                   "vendor_id: 0x0, product_code: 0x0, configure: true}"),
            std::string::npos)
      << d;
  EXPECT_NE(d.find("reference_object: 0x2001, reference_sub_index: 1"), std::string::npos) << d;
  // The port asks the kernel for SYNC and each node's EMCY, TPDO, SDO response and heartbeat.
  const CanPortConfig p = port_config(c);
  EXPECT_EQ(p.interface, "can1");
  EXPECT_EQ(p.filters.count, 1 + 4 * 6);
  EXPECT_TRUE(p.filters.passes(0x1A4));
  EXPECT_TRUE(p.filters.passes(0x585));
  EXPECT_TRUE(p.filters.passes(0x706));
  EXPECT_FALSE(p.filters.passes(0x184));  // node 4's TPDO is on 0x1A4
  EXPECT_FALSE(p.filters.passes(0x605));  // SDO requests: ours
}

// Up to nine tenths of the longest period (10 Hz): the source caps the wait
// at nine tenths of its own period whatever the setting.
TEST(CanopenConfig, ReadDeadlineUpToNineTenthsOfTheLongestPeriod) {
  std::string text = kGood;
  text.replace(text.find("read_deadline_us: 500"), 21, "read_deadline_us: 90000");
  const auto parsed = parse(text);
  const auto* s = dynamic_cast<const CanopenSettings*>(parsed.get());
  ASSERT_NE(s, nullptr);
  EXPECT_EQ(s->config.read_deadline_ns, 90 * kMs);
}

TEST(CanopenConfig, RegisteredAndBuildsItsSource) {
  const Backend* b = find_backend("canopen");
  ASSERT_NE(b, nullptr);
  const auto parsed = parse(kGood);
  const auto source = b->make(*parsed, SourceContext{});
  ASSERT_NE(source, nullptr);
  EXPECT_EQ(source->name(), "canopen");  // nothing opened before start()
}

struct BadCase {
  const char* name;
  std::string from;  // replaced in kGood...
  std::string to;    // ...by this
  int line;          // the line the error names
  std::string message;
};

void PrintTo(const BadCase& c, std::ostream* os) {
  *os << c.name;
}

class CanopenBadConfig : public ::testing::TestWithParam<BadCase> {};

TEST_P(CanopenBadConfig, RefusedNamingTheKeyAndLine) {
  const BadCase& c = GetParam();
  std::string text = kGood;
  const std::size_t at = text.find(c.from);
  ASSERT_NE(at, std::string::npos) << c.from;
  text.replace(at, c.from.size(), c.to);
  try {
    parse(text);
    FAIL() << "accepted: " << text;
  } catch (const exodaq::ConfigError& e) {
    EXPECT_EQ(e.line(), c.line) << e.what();
    EXPECT_NE(std::string(e.what()).find(c.message), std::string::npos) << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(
    EveryKey, CanopenBadConfig,
    ::testing::Values(
        BadCase{"interface_too_long", "can1", "can0123456789abcd", 4,
                "source.canopen.interface must be a network interface name (1-15 characters)"},
        BadCase{"sync_unknown", "sync: producer", "sync: both", 5,
                "'sync' must be one of producer, consumer"},
        BadCase{"sync_overflow_reserved", "sync_overflow: 0", "sync_overflow: 1", 6,
                "source.canopen.sync_overflow must be 0 or 2..240"},
        BadCase{"read_deadline_zero", "read_deadline_us: 500", "read_deadline_us: 0", 7,
                "source.canopen.read_deadline_us must be in (0, 90000]"},
        BadCase{"read_deadline_too_long", "read_deadline_us: 500", "read_deadline_us: 90001", 7,
                "source.canopen.read_deadline_us must be in (0, 90000]"},
        BadCase{"reopen_too_short", "reopen_interval_ms: 200", "reopen_interval_ms: 5", 8,
                "source.canopen.reopen_interval_ms must be between 10 and 60000"},
        BadCase{"rcvbuf_too_small", "rcvbuf_bytes: 65536", "rcvbuf_bytes: 100", 9,
                "source.canopen.rcvbuf_bytes must be >= 4096"},
        BadCase{"boot_timeout_too_short", "boot_timeout_ms: 2000", "boot_timeout_ms: 5", 10,
                "source.canopen.boot_timeout_ms must be 10..60000"},
        BadCase{"heartbeat_timeout_too_short", "heartbeat_timeout_ms: 300",
                "heartbeat_timeout_ms: 5", 11,
                "source.canopen.heartbeat_timeout_ms must be 0 (not monitored) or 10..60000"},
        BadCase{"unknown_key", "rcvbuf_bytes: 65536", "rcvbuf_bytes: 65536\n    rcvbuf: 1", 10,
                "unknown key 'rcvbuf' in config.source.canopen"},
        BadCase{"five_joints", "      - {node: 6}\n", "", 13,
                "source.canopen.joints must be a list of 6 joints (one per channel, in channel "
                "order), has 5"},
        BadCase{"node_missing", "{node: 6}", "{pdo: 1}", 18,
                "source.canopen.joints[5].node is required (1..127)"},
        BadCase{"node_zero", "{node: 6}", "{node: 0}", 18,
                "source.canopen.joints[5].node must be 1..127"},
        BadCase{"node_128", "{node: 6}", "{node: 128}", 18,
                "source.canopen.joints[5].node must be 1..127"},
        BadCase{"node_twice", "{node: 6}", "{node: 2}", 18,
                "source.canopen.joints[5].node 2 is another joint's: node ids must be unique"},
        BadCase{"reference_unknown", "{node: 1, reference: absolute}",
                "{node: 1, reference: incremental}", 13,
                "'reference' must be one of absolute, index"},
        BadCase{"index_without_reference_object", "{node: 1, reference: absolute}",
                "{node: 1, reference: index}", 13,
                "source.canopen.joints[0].reference: index needs reference_object"},
        BadCase{"reference_object_on_absolute", "{node: 6}", "{node: 6, reference_object: 0x2001}",
                18, "source.canopen.joints[5].reference_object needs reference: index"},
        BadCase{"pdo_five", "{node: 6}", "{node: 6, pdo: 5}", 18,
                "source.canopen.joints[5].pdo must be 1..4"},
        BadCase{"bits_twenty", "{node: 6}", "{node: 6, bits: 20}", 18,
                "source.canopen.joints[5].bits must be 16, 24 or 32"},
        BadCase{"total_range_too_big", "{node: 6}", "{node: 6, bits: 16, total_range: 70000}", 18,
                "source.canopen.joints[5].total_range must be 0..65536"},
        BadCase{"cob_id_shared", "{node: 6}", "{node: 6, cob_id: 0x1A4}", 16,
                "source.canopen.joints[3]: two joints share a TPDO COB-ID"},
        BadCase{"cob_id_is_a_heartbeat", "{node: 6}", "{node: 6, cob_id: 0x702}", 18,
                "source.canopen.joints[5]: TPDO COB-ID collides with a node's EMCY, SDO or "
                "heartbeat"},
        BadCase{"unknown_joint_key", "{node: 6}", "{node: 6, nod: 7}", 18,
                "unknown key 'nod' in source.canopen.joints[5]"},
        BadCase{"no_section", "  canopen:\n", "  other:\n", 2,
                "source.backend canopen needs source.canopen"}),
    [](const ::testing::TestParamInfo<BadCase>& info) { return std::string(info.param.name); });

// --- candump replay ---------------------------------------------------------------

// The bus as `candump -l` logs it: "(seconds.micros) can0 ID#DATA", sorted by
// stamp, the stamps moved to a wall-clock epoch.
std::string write_candump(const std::vector<can::CanFrame>& frames, const std::string& path,
                          std::int64_t epoch_ns) {
  std::vector<can::CanFrame> sorted = frames;
  std::stable_sort(
      sorted.begin(), sorted.end(),
      [](const can::CanFrame& a, const can::CanFrame& b) { return a.mono_ns < b.mono_ns; });
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return "";
  for (const can::CanFrame& c : sorted) {
    const std::int64_t us = (epoch_ns + c.mono_ns) / 1000;
    std::fprintf(f, "(%lld.%06lld) can0 %03X#", static_cast<long long>(us / 1'000'000),
                 static_cast<long long>(us % 1'000'000), static_cast<unsigned>(c.id));
    for (int b = 0; b < c.dlc; ++b) std::fprintf(f, "%02X", c.data[static_cast<std::size_t>(b)]);
    std::fprintf(f, "\n");
  }
  std::fclose(f);
  return path;
}

// Issue 27.6: a candump log of a CANopen session replays, through the same
// conversion, to the samples the live source delivered: positions, moduli,
// fresh channels, references, flags (the replay mark aside) and seq, every
// cycle, with a node's EMCY and a missing TPDO in it.
TEST(CanopenReplay, ACandumpOfTheBusReplaysToTheLiveSamples) {
  Rig r;
  std::vector<can::CanFrame> bus;
  r.log_bus(&bus);
  ASSERT_GT(r.start_up(), 0);
  std::vector<EncoderSample> live;
  EncoderSample s;
  for (int k = 0; k < 1500; ++k) {
    if (k == 300) r.node(2).set_fault(SimFault::kEmcy, true, r.now());
    if (k == 400) r.node(2).set_fault(SimFault::kEmcy, false, r.now());
    if (k == 700) r.node(4).set_fault(SimFault::kTpdoMissing, true, r.now());
    if (k == 720) r.node(4).set_fault(SimFault::kTpdoMissing, false, r.now());
    r.cycle(s);
    live.push_back(s);
  }
  // The last cycle's TPDOs were logged, but its closing SYNC never came.
  constexpr std::int64_t kEpoch = 1'700'000'000'000'000'000;
  const std::string path = write_candump(bus, ::testing::TempDir() + "canopen-bus.log", kEpoch);
  ASSERT_FALSE(path.empty());

  ReplaySettings settings;
  settings.path = path;
  settings.format = "candump";
  settings.protocol = "canopen";
  SourceContext context;
  const CanopenSourceConfig config = source_config();
  context.frame_assembler = [&config](std::string_view name) -> std::unique_ptr<FrameAssembler> {
    return name == "canopen" ? make_frame_assembler(config, kMs) : nullptr;
  };
  ReplaySource replay(settings, context);
  replay.start();
  std::vector<EncoderSample> replayed;
  for (;;) {
    EncoderSample x;
    const ReadStatus st = replay.read(CycleTime{}, x);
    if (st == ReadStatus::kEndOfStream) break;
    replayed.push_back(x);
  }
  // The first cycle ran inside start_up(): the replay has it, `live` not.
  ASSERT_EQ(replayed.size(), live.size() + 1);
  EXPECT_EQ(replayed.front().seq, 0);
  int emcy = 0;
  int partial = 0;
  for (std::size_t k = 0; k < live.size(); ++k) {
    const EncoderSample& l = live[k];
    const EncoderSample& p = replayed[k + 1];
    ASSERT_EQ(p.seq, l.seq) << k;
    EXPECT_EQ(p.present, l.present) << k;
    EXPECT_EQ(p.position, l.position) << k;
    EXPECT_EQ(p.modulus, l.modulus) << k;
    EXPECT_EQ(p.index_position, l.index_position) << k;
    EXPECT_EQ(p.index_count_valid, l.index_count_valid) << k;
    EXPECT_EQ(p.absolute, l.absolute) << k;
    EXPECT_EQ(p.channel_fresh, l.channel_fresh) << k;
    EXPECT_EQ(p.board_errors, l.board_errors) << k;
    EXPECT_EQ(p.flags & ~flag::kReplay, l.flags) << k;
    EXPECT_EQ(p.mono_ns / 1000, (kEpoch + l.mono_ns) / 1000) << k;  // the logged SYNC, in us
    emcy += (l.flags & flag::kBoardError) != 0;
    partial += (l.flags & flag::kPartial) != 0;
  }
  EXPECT_GE(emcy, 90);  // the EMCY's cycles are in the comparison
  EXPECT_GE(partial, 15);
}

}  // namespace
}  // namespace exodaq::drivers::canopen
