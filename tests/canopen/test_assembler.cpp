// The CANopen cycle assembler on hand-made frames: configuration checks,
// normal cycles, every fault it detects, SYNC roles, and a per-cycle path
// that allocates nothing.
#include <gtest/gtest.h>

#include <cstdint>

#include "alloc_counter.hpp"
#include "exodaq/drivers/canopen/assembler.hpp"

namespace exodaq::drivers::canopen {
namespace {

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kUs = 1'000;
constexpr std::int64_t kDeadline = 500 * kUs;  // after the SYNC
constexpr std::uint32_t kRange = 1U << 25;

AssemblerConfig config_for(int joints) {
  AssemblerConfig c;
  c.joint_count = joints;
  for (int j = 0; j < joints; ++j) {
    JointConfig& joint = c.joints[static_cast<std::size_t>(j)];
    joint.node = static_cast<NodeId>(j + 1);
    joint.tpdo = position_tpdo(1);
    joint.total_range = kRange;
    joint.heartbeat_timeout_ns = 150 * kMs;
  }
  c.boot_timeout_ns = 200 * kMs;
  return c;
}

CanFrame at(CanFrame f, std::int64_t t) {
  f.mono_ns = t;
  return f;
}

CanFrame tpdo(NodeId node, std::uint32_t position, std::int64_t t, std::uint8_t length = 4) {
  std::array<std::uint8_t, 8> d{};
  for (std::size_t i = 0; i < 4; ++i) d[i] = static_cast<std::uint8_t>(position >> (8 * i));
  return at(encode_tpdo(1, node, d, length), t);
}

// A started assembler whose nodes all said "operational" at time 0.
struct Rig {
  Assembler a;
  std::int64_t t = 0;
  explicit Rig(const AssemblerConfig& c) : a(c) {
    EXPECT_EQ(validate(c).what, nullptr);
    a.reset(0);
    for (int j = 0; j < c.joint_count; ++j) {
      a.on_frame(at(
          encode_heartbeat(c.joints[static_cast<std::size_t>(j)].node, NmtState::kOperational), 0));
    }
    t = kMs;
  }
  // One producer cycle at t: SYNC, the frames (stamped t + their offset),
  // close at the deadline; t moves one period on.
  CycleSample cycle(std::initializer_list<CanFrame> frames) {
    a.begin_cycle(t);
    for (CanFrame f : frames) a.on_frame(at(f, t + f.mono_ns));
    a.end_cycle(t + kDeadline);
    t += kMs;
    CycleSample s;
    EXPECT_TRUE(a.poll(s));
    return s;
  }
  // All joints answer with position `base + j`.
  CycleSample all(std::uint32_t base) {
    a.begin_cycle(t);
    for (int j = 0; j < a.config().joint_count; ++j) {
      a.on_frame(
          tpdo(static_cast<NodeId>(j + 1), base + static_cast<std::uint32_t>(j), t + 100 * kUs));
    }
    a.end_cycle(t + kDeadline);
    t += kMs;
    CycleSample s;
    EXPECT_TRUE(a.poll(s));
    return s;
  }
};

// --- configuration -----------------------------------------------------------

TEST(CanopenAssemblerConfig, AcceptsTheRigAndNamesWhatIsWrong) {
  EXPECT_EQ(validate(config_for(6)).what, nullptr);
  struct Case {
    const char* name;
    void (*edit)(AssemblerConfig&);
    int joint;
  };
  const Case cases[] = {
      {"no joints", [](AssemblerConfig& c) { c.joint_count = 0; }, -1},
      {"17 joints", [](AssemblerConfig& c) { c.joint_count = 17; }, -1},
      {"overflow 1", [](AssemblerConfig& c) { c.sync_overflow = 1; }, -1},
      {"boot timeout 0", [](AssemblerConfig& c) { c.boot_timeout_ns = 0; }, -1},
      {"node 0", [](AssemblerConfig& c) { c.joints[2].node = 0; }, 2},
      {"node 128", [](AssemblerConfig& c) { c.joints[2].node = 128; }, 2},
      {"same node", [](AssemblerConfig& c) { c.joints[3].node = 1; }, 0},
      {"TPDO5", [](AssemblerConfig& c) { c.joints[1].tpdo.pdo = 5; }, 1},
      {"COB-ID flag bits", [](AssemblerConfig& c) { c.joints[1].tpdo.cob_id = 0x80000182; }, 1},
      {"COB-ID on a heartbeat", [](AssemblerConfig& c) { c.joints[1].tpdo.cob_id = 0x703; }, 1},
      {"COB-ID on SYNC", [](AssemblerConfig& c) { c.joints[1].tpdo.cob_id = 0x080; }, 1},
      {"shared COB-ID", [](AssemblerConfig& c) { c.joints[1].tpdo.cob_id = 0x181; }, 0},
      {"event driven", [](AssemblerConfig& c) { c.joints[4].tpdo.transmission_type = 254; }, 4},
      {"acyclic", [](AssemblerConfig& c) { c.joints[4].tpdo.transmission_type = 0; }, 4},
      {"every 2nd without counter",
       [](AssemblerConfig& c) {
         c.joints[4].tpdo.transmission_type = 2;
         c.joints[4].tpdo.sync_start = 1;
       },
       4},
      {"every 4th, overflow 6",
       [](AssemblerConfig& c) {
         c.sync_overflow = 6;
         c.joints[4].tpdo.transmission_type = 4;
         c.joints[4].tpdo.sync_start = 1;
       },
       4},
      {"start value without counter", [](AssemblerConfig& c) { c.joints[4].tpdo.sync_start = 1; },
       4},
      {"range beyond 16 bits",
       [](AssemblerConfig& c) {
         c.joints[5].tpdo.mapping.entries[0].bits = 16;
         c.joints[5].total_range = 70000;
       },
       5},
      {"heartbeat timeout < 0", [](AssemblerConfig& c) { c.joints[5].heartbeat_timeout_ns = -1; },
       5},
  };
  for (const Case& k : cases) {
    AssemblerConfig c = config_for(6);
    k.edit(c);
    const ConfigError e = validate(c);
    EXPECT_NE(e.what, nullptr) << k.name;
    EXPECT_EQ(e.joint, k.joint) << k.name << ": " << (e.what ? e.what : "");
  }
}

TEST(CanopenAssemblerConfig, MappingErrorsArePassedOn) {
  AssemblerConfig c = config_for(2);
  c.joints[1].values.has_reference = true;
  c.joints[1].values.reference = {0x2100, 1};
  const ConfigError e = validate(c);
  EXPECT_EQ(e.joint, 1);
  EXPECT_EQ(e.mapping, MappingError::kReferenceNotMapped);
}

// --- cycles ------------------------------------------------------------------

TEST(CanopenAssembler, ProducerCycleDeliversEveryJoint) {
  Rig r(config_for(3));
  const CycleSample s = r.all(1000);
  EXPECT_EQ(s.cycle, 0U);
  EXPECT_EQ(s.sync_mono_ns, kMs);
  EXPECT_FALSE(s.has_sync_counter);
  EXPECT_EQ(s.flags, 0U);
  ASSERT_EQ(s.joint_count, 3);
  for (int j = 0; j < 3; ++j) {
    const JointReading& jr = s.joints[static_cast<std::size_t>(j)];
    EXPECT_TRUE(jr.present);
    EXPECT_TRUE(jr.due);
    EXPECT_EQ(jr.position, 1000U + static_cast<std::uint32_t>(j));
    EXPECT_EQ(jr.modulus, kRange);
    EXPECT_EQ(jr.faults, 0U) << j;
    EXPECT_EQ(jr.state, NmtState::kOperational);
    EXPECT_EQ(jr.rx_mono_ns, kMs + 100 * kUs);
  }
  EXPECT_EQ(r.a.stats().tpdos, 3);
  EXPECT_EQ(r.a.stats().cycles, 1);
  EXPECT_EQ(r.all(2000).cycle, 1U);
}

TEST(CanopenAssembler, ProducerSyncCarriesTheCounter) {
  AssemblerConfig c = config_for(1);
  c.sync_overflow = 3;
  Assembler a(c);
  a.reset(0);
  int expected[] = {1, 2, 3, 1, 2};
  for (int k = 0; k < 5; ++k) {
    const CanFrame sync = a.begin_cycle(k * kMs);
    ASSERT_EQ(sync.id, 0x080U);
    ASSERT_EQ(sync.dlc, 1);
    EXPECT_EQ(sync.data[0], expected[k]);
  }
  const CanFrame plain = Assembler(config_for(1)).begin_cycle(0);
  EXPECT_EQ(plain.dlc, 0);
}

TEST(CanopenAssembler, MissingTpdoHoldsTheLastPosition) {
  Rig r(config_for(2));
  r.all(500);
  const CycleSample s = r.cycle({tpdo(1, 600, 100 * kUs)});
  EXPECT_TRUE(s.joints[0].present);
  EXPECT_FALSE(s.joints[1].present);
  EXPECT_EQ(s.joints[1].faults, joint_fault::kMissing);
  EXPECT_EQ(s.joints[1].position, 501U);
  EXPECT_EQ(s.joints[1].rx_mono_ns, 0);
  EXPECT_EQ(r.a.stats().missing, 1);
}

TEST(CanopenAssembler, TpdoOfAnEarlierCycleIsLateNotData) {
  Rig r(config_for(1));
  r.all(10);
  // Cycle k: nothing by the deadline.
  CycleSample s = r.cycle({});
  EXPECT_EQ(s.joints[0].faults, joint_fault::kMissing);
  // Its TPDO arrives 1.5 periods after its SYNC, stamped before cycle k+1's
  // SYNC was sent but read after it.
  const std::int64_t late_stamp = r.t - kMs / 2;
  r.a.begin_cycle(r.t);
  r.a.on_frame(tpdo(1, 11, late_stamp));
  r.a.on_frame(tpdo(1, 12, r.t + 100 * kUs));
  r.a.end_cycle(r.t + kDeadline);
  ASSERT_TRUE(r.a.poll(s));
  EXPECT_TRUE(s.joints[0].present);
  EXPECT_EQ(s.joints[0].position, 12U);
  EXPECT_EQ(s.joints[0].faults, 0U);  // cycle k's answer: counted, not charged to k + 1
  EXPECT_EQ(r.a.stats().late, 1);
  // Between a deadline and the next SYNC no cycle is open: late as well.
  r.a.on_frame(tpdo(1, 13, r.t + 600 * kUs));
  r.t += kMs;
  s = r.all(14);
  EXPECT_EQ(s.joints[0].faults, 0U);
  EXPECT_EQ(s.joints[0].position, 14U);
  EXPECT_EQ(r.a.stats().late, 2);
}

TEST(CanopenAssembler, ItsOwnSyncReadBackIsTheCycleInstantAndEarlierAnswersLate) {
  Rig r(config_for(2));
  r.all(10);
  // The clock read at t, the SYNC on the bus 80 us later (the sender was
  // preempted in between); node 1's answer to the previous SYNC is stamped
  // in between and read first.
  CanFrame sync = r.a.begin_cycle(r.t);
  sync.flags |= can::frame_flag::kOwn;
  r.a.on_frame(tpdo(1, 11, r.t + 50 * kUs));
  EXPECT_EQ(r.a.answered(), 1U);
  r.a.on_frame(at(sync, r.t + 80 * kUs));
  EXPECT_EQ(r.a.answered(), 0U);
  r.a.on_frame(tpdo(2, 12, r.t + 150 * kUs));
  EXPECT_EQ(r.a.answered(), 2U);
  r.a.end_cycle(r.t + kDeadline);
  CycleSample s;
  ASSERT_TRUE(r.a.poll(s));
  EXPECT_EQ(s.sync_mono_ns, r.t + 80 * kUs);
  EXPECT_FALSE(s.joints[0].present);
  EXPECT_EQ(s.joints[0].faults, joint_fault::kMissing);  // the late answer was the last cycle's
  EXPECT_TRUE(s.joints[1].present);
  EXPECT_EQ(s.joints[1].position, 12U);
  EXPECT_EQ(r.a.stats().syncs_read_back, 1);
  EXPECT_EQ(r.a.stats().late, 1);
  EXPECT_EQ(r.a.stats().tpdos, 2 + 1);
  EXPECT_EQ(r.a.stats().frames, 2 + 2 + 2);  // heartbeats, TPDOs: own frames are not traffic
  EXPECT_EQ(r.a.stats().foreign_syncs, 0);
  // A SYNC read back from before the next cycle began (an older one's, read
  // late) leaves that cycle at its clock reading; a second read back of the
  // cycle changes nothing.
  r.t += kMs;
  r.a.begin_cycle(r.t);
  r.a.on_frame(at(sync, r.t - 500 * kUs));
  r.a.on_frame(at(sync, r.t + 10 * kUs));
  r.a.on_frame(at(sync, r.t + 20 * kUs));
  r.a.end_cycle(r.t + kDeadline);
  ASSERT_TRUE(r.a.poll(s));
  EXPECT_EQ(s.sync_mono_ns, r.t + 10 * kUs);
  EXPECT_EQ(r.a.stats().syncs_read_back, 2);
}

TEST(CanopenAssembler, TpdoStampedAfterTheDeadlineIsLateEvenIfReadInTime) {
  AssemblerConfig c = config_for(2);
  c.tpdo_deadline_ns = 400 * kUs;
  Rig r(c);
  const CycleSample s = r.cycle({tpdo(1, 5, 400 * kUs), tpdo(2, 6, 401 * kUs)});
  EXPECT_TRUE(s.joints[0].present);  // at the deadline: in time
  EXPECT_EQ(s.joints[0].faults, 0U);
  EXPECT_FALSE(s.joints[1].present);
  EXPECT_EQ(s.joints[1].faults, joint_fault::kLate | joint_fault::kMissing);
}

TEST(CanopenAssembler, UnstampedFramesBelongToTheOpenCycle) {
  Rig r(config_for(1));
  const CycleSample s = r.cycle({tpdo(1, 77, -kMs)});  // stamp 0 after the offset
  EXPECT_TRUE(s.joints[0].present);
  EXPECT_EQ(s.joints[0].position, 77U);
}

TEST(CanopenAssembler, DuplicateWrongLengthAndOutOfRangeAreDropped) {
  Rig r(config_for(3));
  r.all(0);
  const CycleSample s = r.cycle({tpdo(1, 5, 100 * kUs), tpdo(1, 6, 150 * kUs),
                                 tpdo(2, 5, 100 * kUs, 3), tpdo(3, kRange, 100 * kUs)});
  EXPECT_TRUE(s.joints[0].present);
  EXPECT_EQ(s.joints[0].position, 5U);
  EXPECT_EQ(s.joints[0].faults, joint_fault::kDuplicate);
  EXPECT_FALSE(s.joints[1].present);
  EXPECT_EQ(s.joints[1].faults, joint_fault::kWrongLength | joint_fault::kMissing);
  EXPECT_FALSE(s.joints[2].present);
  EXPECT_EQ(s.joints[2].faults, joint_fault::kOutOfRange | joint_fault::kMissing);
  EXPECT_EQ(s.joints[2].position, 2U);  // held
  EXPECT_EQ(r.a.stats().duplicates, 1);
  EXPECT_EQ(r.a.stats().wrong_length, 1);
  EXPECT_EQ(r.a.stats().out_of_range, 1);
}

TEST(CanopenAssembler, HeartbeatLostAfterTheConsumerTimeAndBack) {
  Rig r(config_for(2));
  CycleSample s;
  // Node 1 keeps its heartbeat (every 100 ms), node 2 falls silent after 0.
  for (int k = 0; k < 200; ++k) {
    std::int64_t now = r.t;
    if (k % 100 == 99) r.a.on_frame(at(encode_heartbeat(1, NmtState::kOperational), now));
    s = r.all(static_cast<std::uint32_t>(k));
    const bool lost = now + kDeadline > 150 * kMs;
    EXPECT_EQ(s.joints[1].faults, lost ? joint_fault::kHeartbeatLost : 0U) << k;
    EXPECT_EQ(s.joints[0].faults, 0U) << k;
  }
  EXPECT_EQ(r.a.stats().heartbeat_losses, 1);
  r.a.on_frame(at(encode_heartbeat(2, NmtState::kOperational), r.t));
  s = r.all(0);
  EXPECT_EQ(s.joints[1].faults, 0U);
}

TEST(CanopenAssembler, NodeNeverHeardIsNeverBooted) {
  AssemblerConfig c = config_for(2);
  Assembler a(c);
  a.reset(0);
  CycleSample s;
  for (int k = 0; k < 300; ++k) {
    const std::int64_t t = k * kMs;
    a.on_frame(at(encode_heartbeat(1, NmtState::kOperational), t));
    a.begin_cycle(t);
    a.on_frame(tpdo(1, 1, t + 100 * kUs));
    a.end_cycle(t + kDeadline);
    ASSERT_TRUE(a.poll(s));
    const std::uint32_t want = t + kDeadline > 200 * kMs
                                   ? joint_fault::kNeverBooted | joint_fault::kMissing
                                   : joint_fault::kMissing;
    ASSERT_EQ(s.joints[1].faults, want) << k;
    ASSERT_FALSE(s.joints[1].state_known);
  }
}

TEST(CanopenAssembler, NmtStateRebootAndEmcy) {
  Rig r(config_for(1));
  r.a.on_frame(at(encode_heartbeat(1, NmtState::kPreOperational), r.t));
  CycleSample s = r.all(1);
  EXPECT_EQ(s.joints[0].faults, joint_fault::kNotOperational);
  EXPECT_EQ(s.joints[0].state, NmtState::kPreOperational);

  EmcyPayload e{0x7300, error_register::kGeneric | error_register::kManufacturer, {}};
  r.a.on_frame(at(encode_heartbeat(1, NmtState::kOperational), r.t));
  r.a.on_frame(at(encode_emcy(1, e), r.t));
  s = r.all(2);
  EXPECT_EQ(s.joints[0].faults, joint_fault::kEmcy);
  EXPECT_EQ(s.joints[0].emcy_code, 0x7300);
  EXPECT_EQ(s.joints[0].error_register, 0x81);
  EXPECT_TRUE(s.joints[0].present);  // an emergency flags the value, the caller decides
  s = r.all(3);
  EXPECT_EQ(s.joints[0].faults, joint_fault::kEmcy);  // until the error reset
  r.a.on_frame(at(encode_emcy(1, EmcyPayload{}), r.t));
  s = r.all(4);
  EXPECT_EQ(s.joints[0].faults, 0U);

  r.a.on_frame(at(encode_boot_up(1), r.t));
  s = r.all(5);
  EXPECT_EQ(s.joints[0].faults, joint_fault::kRebooted | joint_fault::kNotOperational);
  EXPECT_EQ(s.joints[0].state, NmtState::kPreOperational);
  EXPECT_EQ(r.a.stats().boot_ups, 1);
  EXPECT_EQ(r.a.stats().emcys, 2);
}

TEST(CanopenAssembler, BootUpOfANodeHeardOnlyByItsTpdosIsAReboot) {
  Assembler a(config_for(1));
  a.reset(0);
  a.on_frame(tpdo(1, 9, 50 * kUs));  // answers a SYNC from before reset()
  EXPECT_EQ(a.stats().before_first_cycle, 1);
  EXPECT_EQ(a.stats().late, 0);
  a.begin_cycle(kMs);
  a.on_frame(tpdo(1, 10, kMs + 100 * kUs));
  a.on_frame(at(encode_boot_up(1), kMs + 200 * kUs));
  a.end_cycle(kMs + kDeadline);
  CycleSample s;
  ASSERT_TRUE(a.poll(s));
  EXPECT_EQ(s.joints[0].faults, joint_fault::kRebooted | joint_fault::kNotOperational);
  EXPECT_TRUE(s.joints[0].present);  // the TPDO came before the reset
}

TEST(CanopenAssembler, MalformedFrameFromANodeIsFlaggedAndCounted) {
  Rig r(config_for(2));
  CanFrame bad = encode_heartbeat(2, NmtState::kOperational);
  bad.data[0] = 0x01;  // no such state
  CanFrame foreign = encode_heartbeat(9, NmtState::kOperational);
  const CycleSample s = r.cycle({tpdo(1, 1, 100 * kUs), tpdo(2, 2, 100 * kUs), at(bad, 50 * kUs),
                                 at(foreign, 60 * kUs), tpdo(9, 1, 70 * kUs)});
  EXPECT_EQ(s.joints[0].faults, 0U);
  EXPECT_EQ(s.joints[1].faults, joint_fault::kBadFrame);
  EXPECT_EQ(r.a.stats().rejected[static_cast<std::size_t>(Reject::kUnknownState)], 1);
  EXPECT_EQ(r.a.stats().foreign, 2);
}

TEST(CanopenAssembler, ProducerFlagsASecondSyncProducer) {
  Rig r(config_for(1));
  const CycleSample s = r.cycle({tpdo(1, 1, 100 * kUs), at(encode_sync(), 200 * kUs)});
  EXPECT_EQ(s.flags, cycle_flag::kForeignSync);
  EXPECT_EQ(r.a.stats().foreign_syncs, 1);
  EXPECT_EQ(r.all(2).flags, 0U);
}

TEST(CanopenAssembler, ConsumerChecksTheSyncCounter) {
  AssemblerConfig c = config_for(1);
  c.sync_role = SyncRole::kConsumer;
  c.sync_overflow = 8;
  Assembler a(c);
  a.reset(0);
  const int counters[] = {3, 4, 5, 7, 8, 1};
  const bool mismatch[] = {false, false, false, true, false, false};
  for (int k = 0; k < 6; ++k) {
    const std::int64_t t = (k + 1) * kMs;
    a.on_frame(at(encode_sync(static_cast<std::uint8_t>(counters[k])), t));
    a.on_frame(tpdo(1, 1, t + 100 * kUs));
    a.end_cycle(t + kDeadline);
    CycleSample s;
    ASSERT_TRUE(a.poll(s));
    EXPECT_EQ(s.sync_counter, counters[k]);
    EXPECT_EQ(s.sync_mono_ns, t);
    EXPECT_EQ((s.flags & cycle_flag::kSyncCounterMismatch) != 0, mismatch[k]) << k;
    EXPECT_TRUE(s.joints[0].present);
  }
  // A SYNC without its counter, and one beyond the overflow value.
  a.on_frame(at(encode_sync(), 10 * kMs));
  a.on_frame(at(encode_sync(9), 11 * kMs));  // also closes the previous cycle
  a.end_cycle(11 * kMs + kDeadline);
  CycleSample s;
  ASSERT_TRUE(a.poll(s));
  EXPECT_NE(s.flags & cycle_flag::kSyncCounterMismatch, 0U);
  ASSERT_TRUE(a.poll(s));
  EXPECT_NE(s.flags & cycle_flag::kSyncCounterMismatch, 0U);
  EXPECT_EQ(a.stats().sync_counter_mismatches, 3);
  // A malformed SYNC (counter 0) opens no cycle; the next one carries the flag.
  CanFrame broken = encode_sync(1);
  broken.data[0] = 0;
  a.on_frame(at(broken, 12 * kMs));
  a.on_frame(at(encode_sync(1), 13 * kMs));
  a.end_cycle(13 * kMs + kDeadline);
  ASSERT_TRUE(a.poll(s));
  EXPECT_EQ(s.sync_mono_ns, 13 * kMs);
  EXPECT_NE(s.flags & cycle_flag::kSyncCounterMismatch, 0U);
  EXPECT_FALSE(a.poll(s));
  EXPECT_EQ(a.stats().rejected[static_cast<std::size_t>(Reject::kBadSyncCounter)], 1);
}

TEST(CanopenAssembler, EverySecondSyncIsDueOnItsPhase) {
  AssemblerConfig c = config_for(2);
  c.sync_overflow = 4;
  c.joints[1].tpdo.transmission_type = 2;
  c.joints[1].tpdo.sync_start = 2;
  ASSERT_EQ(validate(c).what, nullptr);
  Rig r(c);
  for (int k = 0; k < 8; ++k) {
    const int counter = k % 4 + 1;  // 1, 2, 3, 4, 1, ...
    const bool due = counter % 2 == 0;
    CycleSample s = due ? r.all(0) : r.cycle({tpdo(1, 0, 100 * kUs)});
    EXPECT_EQ(s.sync_counter, counter);
    EXPECT_EQ(s.joints[1].due, due) << k;
    EXPECT_EQ(s.joints[1].present, due) << k;
    EXPECT_EQ(s.joints[1].faults, 0U) << k;  // not due and absent is not missing
  }
}

TEST(CanopenAssembler, LatchedReferenceAndItsChange) {
  AssemblerConfig c = config_for(1);
  c.joints[0].tpdo.mapping.add({0x2100, 1, 32});
  c.joints[0].values.has_reference = true;
  c.joints[0].values.reference = {0x2100, 1};
  Rig r(c);
  auto with_ref = [](std::uint32_t pos, std::uint32_t ref) {
    std::array<std::uint8_t, 8> d{};
    for (std::size_t i = 0; i < 4; ++i) {
      d[i] = static_cast<std::uint8_t>(pos >> (8 * i));
      d[4 + i] = static_cast<std::uint8_t>(ref >> (8 * i));
    }
    return at(encode_tpdo(1, 1, d, 8), 100 * kUs);
  };
  CycleSample s = r.cycle({with_ref(100, 40)});
  EXPECT_TRUE(s.joints[0].has_reference);
  EXPECT_EQ(s.joints[0].reference, 40U);
  EXPECT_FALSE(s.joints[0].reference_changed);  // the first is the baseline
  s = r.cycle({with_ref(110, 40)});
  EXPECT_FALSE(s.joints[0].reference_changed);
  s = r.cycle({with_ref(120, 117)});
  EXPECT_TRUE(s.joints[0].reference_changed);
  EXPECT_EQ(s.joints[0].reference, 117U);
  s = r.cycle({});
  EXPECT_FALSE(s.joints[0].reference_changed);
  EXPECT_EQ(s.joints[0].reference, 117U);  // held
  s = r.cycle({tpdo(1, 1, 100 * kUs)});    // a 4-byte TPDO: wrong length for this mapping
  EXPECT_EQ(s.joints[0].faults, joint_fault::kWrongLength | joint_fault::kMissing);
}

TEST(CanopenAssembler, QueueKeepsTheNewestAndFlagsTheOverrun) {
  Assembler a(config_for(1));
  a.reset(0);
  for (int k = 0; k < Assembler::kQueueCapacity + 1; ++k) {
    a.begin_cycle(k * kMs);
    a.end_cycle(k * kMs + kDeadline);
  }
  EXPECT_EQ(a.stats().queue_overflows, 1);
  CycleSample s;
  ASSERT_TRUE(a.poll(s));
  EXPECT_EQ(s.cycle, 1U);
  EXPECT_EQ(s.flags, cycle_flag::kOverrun);
  int left = 0;
  while (a.poll(s)) ++left;
  EXPECT_EQ(left, Assembler::kQueueCapacity - 1);
  EXPECT_EQ(s.cycle, static_cast<std::uint64_t>(Assembler::kQueueCapacity));
}

TEST(CanopenAssembler, WantedIdentifiers) {
  AssemblerConfig c = config_for(2);
  c.joints[1].tpdo.pdo = 3;
  const WantedIds w = Assembler(c).wanted_ids();
  ASSERT_EQ(w.count, 9);
  const std::uint32_t want[] = {0x080, 0x081, 0x181, 0x581, 0x701, 0x082, 0x382, 0x582, 0x702};
  for (int i = 0; i < 9; ++i) EXPECT_EQ(w.ids[static_cast<std::size_t>(i)], want[i]) << i;
}

TEST(CanopenAssembler, CustomTpdoCobIdIsRecognised) {
  AssemblerConfig c = config_for(1);
  c.joints[0].tpdo.cob_id = 0x1F0;
  Rig r(c);
  std::array<std::uint8_t, 8> d{42, 0, 0, 0};
  CanFrame f = encode_tpdo(1, 1, d, 4);
  f.id = 0x1F0;
  const CycleSample s = r.cycle({at(f, 100 * kUs)});
  EXPECT_TRUE(s.joints[0].present);
  EXPECT_EQ(s.joints[0].position, 42U);
}

// The per-cycle path — SYNC, TPDOs, heartbeats, an EMCY, a malformed frame,
// closing and polling — allocates nothing.
TEST(CanopenAssembler, CyclePathAllocatesNothing) {
  constexpr int kJoints = 6;
  AssemblerConfig c = config_for(kJoints);
  c.sync_overflow = 240;
  Rig r(c);
  r.all(0);  // warm-up
  CanFrame bad = encode_heartbeat(3, NmtState::kOperational);
  bad.dlc = 2;
  std::int64_t present = 0;
  const exodaq::test::AllocationScope scope;
  for (int k = 0; k < 2000; ++k) {
    const CanFrame sync = r.a.begin_cycle(r.t);
    ASSERT_EQ(sync.dlc, 1);
    for (int j = 0; j < kJoints; ++j) {
      if (k % 7 == j) continue;  // one joint missing now and then
      r.a.on_frame(
          tpdo(static_cast<NodeId>(j + 1), static_cast<std::uint32_t>(k), r.t + 100 * kUs));
    }
    if (k % 100 == 0) {
      for (int j = 0; j < kJoints; ++j) {
        r.a.on_frame(at(encode_heartbeat(static_cast<NodeId>(j + 1), NmtState::kOperational), r.t));
      }
    }
    if (k % 500 == 1) r.a.on_frame(at(encode_emcy(2, {0x5000, 1, {}}), r.t));
    if (k % 500 == 2) r.a.on_frame(at(bad, r.t));
    r.a.end_cycle(r.t + kDeadline);
    r.t += kMs;
    CycleSample s;
    ASSERT_TRUE(r.a.poll(s));
    for (int j = 0; j < kJoints; ++j) present += s.joints[static_cast<std::size_t>(j)].present;
  }
  EXPECT_EQ(scope.count(), 0U);
  // A joint is missing when k % 7 < 6: 1715 of the 2000 cycles.
  EXPECT_EQ(present, 2000 * kJoints - 1715);
}

}  // namespace
}  // namespace exodaq::drivers::canopen
