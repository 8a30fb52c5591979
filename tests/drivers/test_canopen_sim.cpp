// exodaq-board-sim's CANopen nodes (CanopenSim) on the in-memory CanPort,
// the manager played by the CANopen start-up and cycle assembler on a
// simulated clock: six nodes boot and are started, every SYNC's TPDOs carry
// the rig's counts at the SYNC (the truth file's), and each scripted fault
// shows on its joint in the assembler.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "board_sim.hpp"
#include "canopen_sim.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/drivers/canopen/assembler.hpp"
#include "exodaq/drivers/canopen/canopen_source.hpp"
#include "exodaq/drivers/canopen/startup.hpp"
#include "memory_can_port.hpp"

namespace exodaq::board_sim {
namespace {

using namespace drivers::canopen;
namespace sim = drivers::sim;

constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kUs = 1'000;
constexpr std::int64_t kStep = 50 * kUs;  // the simulator's poll granularity here
constexpr std::int64_t kDeadline = 400 * kUs;
constexpr std::uint32_t kRange = 1U << 25;
constexpr Multiplexer kCount{0x2000, 1};
constexpr Multiplexer kRef{0x2001, 1};

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

struct BenchSetup {
  std::vector<CanopenFault> faults;
  bool sync_producer = false;  // node 0 produces SYNC (counter 1..10), the manager consumes it
  bool index_module = false;   // node 5 maps its count and reference objects
};

// The simulator on a memory port, and the manager on the other side of it.
class Bench {
 public:
  explicit Bench(const BenchSetup& s = {})
      : setup_(s), truth_(std::tmpfile()), answers_(std::tmpfile()) {
    CanopenSimOptions o;
    for (int i = 0; i < kCanopenNodes; ++i) {
      o.nodes[static_cast<std::size_t>(i)].node = static_cast<NodeId>(21 + i);
    }
    o.nodes[5].index_module = s.index_module;
    o.faults = s.faults;
    o.sync_producer = s.sync_producer;
    o.sync_overflow = s.sync_producer ? 10 : 0;
    const drivers::can::CanIdFilterSet filters = canopen_port_filters(o);
    port_.admit = [filters](const drivers::can::CanFrame& f) { return filters.passes(f.id); };
    EXPECT_EQ(port_.open(), 0);
    write_truth_header(truth_.get());
    sim_ = std::make_unique<CanopenSim>(sim::SimOptions{}, o, port_, truth_.get(), answers_.get());
    build_manager();
  }

  CanopenSim& sim() { return *sim_; }
  Startup& startup() { return startup_; }
  Assembler& assembler() { return assembler_; }
  test::MemoryCanPort& port() { return port_; }
  std::int64_t now() const { return port_.mono; }

  // One step of kStep: the simulator polls, the manager reads what it sent
  // and sends what the start-up wants.
  void step() {
    port_.mono += kStep;
    sim_->poll(port_.mono);
    for (; read_ < port_.sent.size(); ++read_) {
      drivers::can::CanFrame f = port_.sent[read_];
      f.mono_ns = port_.mono;
      startup_.on_frame(f, f.mono_ns);
      if (cycling_) assembler_.on_frame(f);
      if (setup_.sync_producer && decode_frame(f).kind == FrameKind::kSync) last_sync_ = f.mono_ns;
    }
    if (cycling_ && setup_.sync_producer && assembler_.cycle_open() &&
        port_.mono >= last_sync_ + kDeadline) {
      assembler_.end_cycle(port_.mono);
    }
    startup_.advance(port_.mono);
    drivers::can::CanFrame out;
    while (startup_.next_frame(out)) port_.push(out, port_.mono);
  }

  void run_for(std::int64_t ns) {
    const std::int64_t end = port_.mono + ns;
    while (port_.mono < end) step();
  }

  // Start-up until done (every node operational or failed).
  void start() {
    startup_.begin(port_.mono);
    sim_->poll(port_.mono);  // power-on: simulated time 0
    const std::int64_t end = port_.mono + 5000 * kMs;
    while (!startup_.done() && port_.mono < end) step();
    ASSERT_TRUE(startup_.done());
    assembler_.reset(port_.mono);
    cycling_ = true;
  }

  // One 1 ms cycle: (producer) SYNC at its start, closed at the deadline.
  CycleSample cycle() {
    if (!setup_.sync_producer) {
      last_sync_ = port_.mono;
      port_.push(assembler_.begin_cycle(port_.mono), port_.mono);
      run_for(kDeadline);
      assembler_.end_cycle(port_.mono);
      run_for(kMs - kDeadline);
      CycleSample s;
      EXPECT_TRUE(assembler_.poll(s)) << now();
      return s;
    }
    CycleSample s;
    const std::int64_t end = port_.mono + 10 * kMs;
    while (!assembler_.poll(s) && port_.mono < end) step();
    EXPECT_LT(port_.mono, end);
    return s;
  }

  std::int64_t last_sync() const { return last_sync_; }

  // The truth file's and the answers file's lines.
  std::vector<std::string> truth_lines() { return lines_of(truth_.get()); }
  std::vector<std::string> answer_lines() { return lines_of(answers_.get()); }

 private:
  void build_manager() {
    StartupConfig sc;
    sc.node_count = kCanopenNodes;
    sc.boot_timeout_ns = 100 * kMs;
    sc.sdo_timeout_ns = 20 * kMs;
    sc.operational_timeout_ns = 300 * kMs;
    AssemblerConfig ac;
    ac.joint_count = kCanopenNodes;
    ac.sync_role = setup_.sync_producer ? SyncRole::kConsumer : SyncRole::kProducer;
    ac.sync_overflow = setup_.sync_producer ? 10 : 0;
    ac.boot_timeout_ns = 200 * kMs;
    ac.tpdo_deadline_ns = kDeadline;
    for (int i = 0; i < kCanopenNodes; ++i) {
      const auto node = static_cast<NodeId>(21 + i);
      TpdoSetup tpdo = position_tpdo(1);
      ValueObjects values;
      if (setup_.index_module && i == 5) {
        tpdo.mapping = {};
        tpdo.mapping.add({kCount.index, kCount.sub, 32});
        tpdo.mapping.add({kRef.index, kRef.sub, 32});
        values = {kCount, true, kRef};
      }
      NodeSetup& n = sc.nodes[static_cast<std::size_t>(i)];
      n.node = node;
      EXPECT_TRUE(n.add_tpdo(tpdo));
      EXPECT_TRUE(n.add({{od::kProducerHeartbeatTime, 0}, 100, 2}));
      JointConfig& j = ac.joints[static_cast<std::size_t>(i)];
      j.node = node;
      j.tpdo = tpdo;
      j.values = values;
      j.total_range = kRange;
      j.heartbeat_timeout_ns = 150 * kMs;
    }
    EXPECT_EQ(validate(ac).what, nullptr);
    startup_ = Startup(sc);
    assembler_ = Assembler(ac);
  }

  BenchSetup setup_;
  test::MemoryCanPort port_;
  static std::vector<std::string> lines_of(std::FILE* f) {
    std::fflush(f);
    std::rewind(f);
    std::vector<std::string> lines;
    char buf[1024];
    while (std::fgets(buf, sizeof buf, f) != nullptr) lines.emplace_back(buf);
    std::fseek(f, 0, SEEK_END);
    return lines;
  }

  std::unique_ptr<std::FILE, FileCloser> truth_;
  std::unique_ptr<std::FILE, FileCloser> answers_;
  std::unique_ptr<CanopenSim> sim_;
  Startup startup_{StartupConfig{}};
  Assembler assembler_{AssemblerConfig{}};
  std::size_t read_ = 0;
  bool cycling_ = false;
  std::int64_t last_sync_ = 0;
};

std::uint32_t wrapped(std::int64_t count) {
  std::int64_t v = count % kRange;
  return static_cast<std::uint32_t>(v < 0 ? v + kRange : v);
}

// --- options -----------------------------------------------------------------

TEST(CanopenSimOptions, FiltersTakeNmtSyncAndEachSdoRequest) {
  CanopenSimOptions o;
  const drivers::can::CanIdFilterSet f = canopen_port_filters(o);
  EXPECT_EQ(f.count, 8);
  for (std::uint32_t id : {0x000U, 0x080U, 0x601U, 0x606U}) EXPECT_TRUE(f.passes(id)) << id;
  for (std::uint32_t id : {0x181U, 0x581U, 0x701U, 0x081U, 0x607U})
    EXPECT_FALSE(f.passes(id)) << id;
}

TEST(CanopenSimOptions, RefusesDuplicateNodesAndFaultsOnNoNode) {
  test::MemoryCanPort port;
  CanopenSimOptions o;
  o.nodes[3].node = 1;
  EXPECT_THROW(CanopenSim(sim::SimOptions{}, o, port, nullptr), std::invalid_argument);
  o = {};
  o.nodes[3].node = 0;
  EXPECT_THROW(CanopenSim(sim::SimOptions{}, o, port, nullptr), std::invalid_argument);
  o = {};
  o.faults.push_back({SimFault::kEmcy, 6, 0.0, 0.0});
  EXPECT_THROW(CanopenSim(sim::SimOptions{}, o, port, nullptr), std::invalid_argument);
}

TEST(CanopenSimFaults, ParsedByNameOrByTheirV1Kind) {
  const auto parse = [](const std::string& text) {
    MapReader m("--fault", load_yaml_text(text, "--fault"), "--fault");
    return parse_canopen_fault(m);
  };
  const CanopenFault a = parse("{kind: tpdo_missing, joint: 4, at_s: 2.5, for_s: 0.5}");
  EXPECT_EQ(a.kind, SimFault::kTpdoMissing);
  EXPECT_EQ(a.joint, 3);
  EXPECT_DOUBLE_EQ(a.start_s, 2.5);
  EXPECT_DOUBLE_EQ(a.duration_s, 0.5);
  EXPECT_EQ(parse("{kind: silence, at_s: 0}").kind, SimFault::kNeverBoots);
  EXPECT_EQ(parse("{kind: board_error, at_s: 1, joint: 6}").kind, SimFault::kEmcy);
  EXPECT_EQ(parse("{kind: delay, at_s: 1, delay_us: 700}").kind, SimFault::kTpdoLate);
  EXPECT_EQ(parse("{kind: wrong_dlc, at_s: 1}").kind, SimFault::kWrongPdoLength);
  EXPECT_EQ(parse("{kind: bad_seq, at_s: 1}").kind, SimFault::kSyncCounterMismatch);
  EXPECT_EQ(parse("{kind: heartbeat_stops, at_s: 1}").kind, SimFault::kHeartbeatStops);
  EXPECT_THROW(parse("{kind: glitch, at_s: 1}"), std::exception);
  EXPECT_THROW(parse("{kind: emcy, at_s: 1, joint: 7}"), std::exception);
  EXPECT_THROW(parse("{kind: emcy, at_s: 1, colour: red}"), std::exception);

  sim::SimFault v1;
  v1.kind = sim::SimFault::Kind::kDrop;
  v1.joint = 2;
  v1.start_s = 3;
  v1.duration_s = 1;
  const CanopenFault d = canopen_fault_from(v1);
  EXPECT_EQ(d.kind, SimFault::kTpdoMissing);
  EXPECT_EQ(d.joint, 2);
  v1.kind = sim::SimFault::Kind::kStall;
  EXPECT_THROW(canopen_fault_from(v1), std::invalid_argument);
}

// --- start-up and cycles -----------------------------------------------------

TEST(CanopenSim, SixNodesBootAndAreStarted) {
  Bench b;
  b.start();
  ASSERT_TRUE(b.startup().all_operational());
  for (int i = 0; i < kCanopenNodes; ++i) {
    EXPECT_EQ(b.sim().node(i).state(), NmtState::kOperational) << i;
    EXPECT_EQ(b.startup().progress(i).identity.serial_number, 1000U + static_cast<unsigned>(i));
    std::uint32_t v = 0;
    ASSERT_TRUE(b.sim().node(i).read({od::kMeasuringUnitsPerRevolution, 0}, v));
    EXPECT_EQ(v, 10000U);  // the rig's counts per revolution
    ASSERT_TRUE(b.sim().node(i).read({od::kTotalMeasuringRange, 0}, v));
    EXPECT_EQ(v, kRange);
  }
  EXPECT_LT(b.now() - 5'000 * kMs, 500 * kMs);
  EXPECT_EQ(b.sim().counters().send_failures, 0);
}

TEST(CanopenSim, EveryJointCarriesTheRigsCountAtItsSync) {
  Bench b;
  b.start();
  constexpr int kCycles = 1500;  // through the start hold into the homing sweeps
  std::array<std::int64_t, kCanopenNodes> first{};
  std::array<std::int64_t, kCanopenNodes> last{};
  bool wrapped_seen = false;
  for (int k = 0; k < kCycles; ++k) {
    const CycleSample s = b.cycle();
    ASSERT_EQ(s.flags, 0U) << k;
    ASSERT_EQ(s.sync_mono_ns, b.last_sync()) << k;
    const sim::SimCycle& truth = b.sim().rig().last_cycle();
    ASSERT_EQ(truth.k, k);
    ASSERT_NEAR(truth.t_s, b.sim().sim_time_s(b.last_sync()), 1e-9);
    for (int i = 0; i < kCanopenNodes; ++i) {
      const JointReading& j = s.joints[static_cast<std::size_t>(i)];
      ASSERT_TRUE(j.present) << k << " " << i;
      ASSERT_EQ(j.faults, 0U) << k << " " << i;
      ASSERT_EQ(j.modulus, kRange);
      const std::int64_t count = b.sim().reported(i, truth.count[static_cast<std::size_t>(i)]);
      ASSERT_EQ(j.position, wrapped(count)) << k << " " << i;
      if (k == 0) first[static_cast<std::size_t>(i)] = count;
      last[static_cast<std::size_t>(i)] = count;
      wrapped_seen = wrapped_seen || count < 0;
    }
  }
  int moved = 0;
  for (int i = 0; i < kCanopenNodes; ++i) moved += first[i] != last[i];
  EXPECT_GT(moved, 0);        // the homing sweeps began
  EXPECT_TRUE(wrapped_seen);  // joint 5 powers up at −5: sent as 2^25 − 5
  EXPECT_EQ(b.sim().counters().syncs, kCycles);
  EXPECT_EQ(b.assembler().stats().tpdos, kCycles * kCanopenNodes);

  // The truth file: BoardSim's header and format, the simulator's start on
  // CLOCK_MONOTONIC, one line per SYNC.
  const std::vector<std::string> lines = b.truth_lines();
  ASSERT_EQ(lines.size(), static_cast<std::size_t>(kCycles + 2));
  EXPECT_EQ(lines[0], "# k seq t_s q0 q1 q2 q3 q4 q5 c0 c1 c2 c3 c4 c5 fault_bits\n");
  EXPECT_EQ(lines[1].rfind("# origin_mono_ns ", 0), 0U) << lines[1];
  std::istringstream last_line(lines.back());
  long long k = 0;
  unsigned seq = 0;
  double t = 0;
  last_line >> k >> seq >> t;
  EXPECT_EQ(k, kCycles - 1);
  EXPECT_EQ(seq, static_cast<unsigned>((kCycles - 1) & 0xFF));
  double q = 0;
  for (int i = 0; i < 6; ++i) last_line >> q;
  for (int i = 0; i < 6; ++i) {
    long long c = 0;
    last_line >> c;
    EXPECT_EQ(c, last[static_cast<std::size_t>(i)]) << i;
  }
  unsigned bits = 1;
  last_line >> bits;
  EXPECT_EQ(bits, 0U);

  // The answers: every TPDO once, with the SYNC it answered, sent after it.
  const std::int64_t origin = std::stoll(lines[1].substr(17));
  std::vector<int> answered(static_cast<std::size_t>(kCycles) * kCanopenNodes, 0);
  for (const std::string& line : b.answer_lines()) {
    std::istringstream a(line);
    long long ak = -1, sent = 0;
    int channel = -1;
    ASSERT_TRUE(a >> ak >> channel >> sent) << line;
    ASSERT_TRUE(ak >= 0 && ak < kCycles && channel >= 0 && channel < kCanopenNodes) << line;
    std::istringstream truth_line(lines[static_cast<std::size_t>(ak) + 2]);
    long long tk = 0;
    unsigned tseq = 0;
    double ts = 0;
    truth_line >> tk >> tseq >> ts;
    EXPECT_GE(sent, origin + std::llround(ts * 1e9)) << line;
    ++answered[static_cast<std::size_t>(ak * kCanopenNodes + channel)];
  }
  for (int n : answered) ASSERT_EQ(n, 1);
}

TEST(CanopenSim, IndexModuleSendsItsCountAndLatchedReference) {
  BenchSetup s;
  s.index_module = true;
  Bench b(s);
  b.start();
  ASSERT_TRUE(b.startup().all_operational());
  // Joint 5's homing sweep crosses its index after about 10 s.
  bool changed = false;
  for (int k = 0; k < 12000 && !changed; ++k) {
    const CycleSample c = b.cycle();
    const JointReading& j = c.joints[5];
    ASSERT_TRUE(j.present) << k;
    ASSERT_EQ(j.position, wrapped(b.sim().rig().last_cycle().count[5])) << k;
    ASSERT_TRUE(j.has_reference);
    if (j.reference_changed) {
      changed = true;
      EXPECT_GT(k, 9000);  // at about 10.4 s of the homing
      EXPECT_EQ(j.reference, wrapped(b.sim().rig().encoders().latched_count(5)));
    }
  }
  EXPECT_TRUE(changed);
}

// --- faults ------------------------------------------------------------------

// The joint_fault bits seen on each joint over `cycles` cycles.
std::array<std::uint32_t, kCanopenNodes> faults_over(Bench& b, int cycles,
                                                     std::array<int, kCanopenNodes>* present) {
  std::array<std::uint32_t, kCanopenNodes> seen{};
  for (int k = 0; k < cycles; ++k) {
    const CycleSample s = b.cycle();
    for (int i = 0; i < kCanopenNodes; ++i) {
      seen[static_cast<std::size_t>(i)] |= s.joints[static_cast<std::size_t>(i)].faults;
      if (present)
        (*present)[static_cast<std::size_t>(i)] += s.joints[static_cast<std::size_t>(i)].present;
    }
  }
  return seen;
}

TEST(CanopenSim, EmcyAndMissingTpdosShowOnTheirJointsOnly) {
  BenchSetup s;
  // Simulated time 0 is power-on; start-up is over by 0.3 s.
  s.faults = {{SimFault::kEmcy, 2, 0.6, 0.2}, {SimFault::kTpdoMissing, 4, 0.6, 0.1}};
  Bench b(s);
  b.start();
  ASSERT_LT(b.sim().sim_time_s(b.now()), 0.5);
  while (b.sim().sim_time_s(b.now()) < 0.55) {
    const CycleSample c = b.cycle();
    for (const JointReading& j : c.joints) ASSERT_EQ(j.faults, 0U);
  }
  std::array<int, kCanopenNodes> present{};
  const auto seen = faults_over(b, 400, &present);  // 0.55 .. 0.95 s
  EXPECT_EQ(seen[2], joint_fault::kEmcy);
  EXPECT_EQ(seen[4], joint_fault::kMissing);
  for (int i : {0, 1, 3, 5}) EXPECT_EQ(seen[static_cast<std::size_t>(i)], 0U) << i;
  EXPECT_NEAR(present[4], 400 - 100, 2);  // missing for 0.1 s
  EXPECT_EQ(present[2], 400);             // an EMCY does not stop its TPDOs
  // Both cleared: clean again.
  const auto after = faults_over(b, 50, nullptr);
  for (std::uint32_t f : after) EXPECT_EQ(f, 0U);
  EXPECT_EQ(b.assembler().stats().emcys, 2);  // the error and its reset
  EXPECT_GE(b.sim().counters().fault_cycles[static_cast<std::size_t>(SimFault::kEmcy)], 195);
  EXPECT_NE(b.sim().summary().find(" emcy=2"), std::string::npos) << b.sim().summary();
  // The truth file marks the cycles.
  int marked = 0;
  for (const std::string& line : b.truth_lines()) {
    if (line[0] == '#') continue;
    const unsigned long bits = std::stoul(line.substr(line.rfind(' ') + 1));
    marked += (bits & canopen_fault_bit(SimFault::kTpdoMissing)) != 0;
  }
  EXPECT_NEAR(marked, 100, 2);
}

TEST(CanopenSim, NodeThatNeverBootsFailsItsStartUpAndIsFlagged) {
  BenchSetup s;
  s.faults = {{SimFault::kNeverBoots, 1, 0.0, 0.0}};
  Bench b(s);
  b.start();
  EXPECT_EQ(b.startup().progress(1).failure, StartupFailure::kNeverBooted);
  for (int i : {0, 2, 3, 4, 5}) {
    EXPECT_EQ(b.startup().progress(i).phase, StartupPhase::kOperational) << i;
  }
  std::array<int, kCanopenNodes> present{};
  const auto seen = faults_over(b, 300, &present);
  EXPECT_NE(seen[1] & joint_fault::kNeverBooted, 0U);
  EXPECT_EQ(present[1], 0);
  for (int i : {0, 2, 3, 4, 5}) {
    EXPECT_EQ(seen[static_cast<std::size_t>(i)], 0U) << i;
    EXPECT_EQ(present[static_cast<std::size_t>(i)], 300) << i;
  }
}

TEST(CanopenSim, LateAndShortTpdosAndALostHeartbeat) {
  BenchSetup s;
  s.faults = {{SimFault::kTpdoLate, 0, 0.6, 0.1},
              {SimFault::kWrongPdoLength, 3, 0.6, 0.1},
              {SimFault::kHeartbeatStops, 5, 0.6, 0.0}};
  Bench b(s);
  b.start();
  while (b.sim().sim_time_s(b.now()) < 0.55) b.cycle();
  const std::int64_t late_before = b.assembler().stats().late;
  const auto seen = faults_over(b, 400, nullptr);
  // 0.7 ms after its SYNC, past the deadline: its cycle's channel missing,
  // the answer counted late.
  EXPECT_NE(seen[0] & joint_fault::kMissing, 0U);
  EXPECT_GE(b.assembler().stats().late - late_before, 95);
  EXPECT_NE(seen[3] & joint_fault::kWrongLength, 0U);
  EXPECT_NE(seen[5] & joint_fault::kHeartbeatLost, 0U);
  for (int i : {1, 2, 4}) EXPECT_EQ(seen[static_cast<std::size_t>(i)], 0U) << i;
}

TEST(CanopenSim, NodeProducingSyncAndItsCounterMismatch) {
  BenchSetup s;
  s.sync_producer = true;
  s.faults = {{SimFault::kSyncCounterMismatch, 0, 0.6, 0.05}};
  Bench b(s);
  b.start();
  ASSERT_TRUE(b.startup().all_operational());
  int mismatches = 0;
  while (b.sim().sim_time_s(b.now()) < 0.7) {
    const CycleSample c = b.cycle();
    mismatches += (c.flags & cycle_flag::kSyncCounterMismatch) != 0;
    ASSERT_TRUE(c.has_sync_counter);
    // The cycle's TPDOs carry the counts at its SYNC, the node producing it included.
    const sim::SimCycle& truth = b.sim().rig().last_cycle();
    for (int i = 0; i < kCanopenNodes; ++i) {
      const JointReading& j = c.joints[static_cast<std::size_t>(i)];
      ASSERT_TRUE(j.present) << i;
      ASSERT_EQ(j.position, wrapped(b.sim().reported(i, truth.count[static_cast<std::size_t>(i)])))
          << i;
    }
  }
  EXPECT_GT(mismatches, 0);
  EXPECT_GT(b.sim().counters().syncs, 300);
}

// --- the daemon's canopen source as SYNC consumer ------------------------------

using drivers::CycleTime;
using drivers::EncoderSample;
using drivers::ReadStatus;
namespace sample_flag = drivers::sample_flag;

// CanopenSource (sync: consumer) on one in-memory port, the simulator with
// node 1 producing SYNC on another, the two wired as one bus. The simulator
// runs in 10 us steps up to each clock reading of the source, so its frames
// carry the stamps of their due instants.
class ConsumerBench {
 public:
  static constexpr std::int64_t kSimStep = 10 * kUs;

  explicit ConsumerBench(std::int64_t sync_period_ns, std::vector<CanopenFault> faults = {}) {
    CanopenSimOptions o;  // nodes 1..6, absolute, total range 2^25
    o.faults = std::move(faults);
    o.sync_producer = true;
    o.sync_period_ns = sync_period_ns;
    const drivers::can::CanIdFilterSet sim_filters = canopen_port_filters(o);
    sim_port_.admit = [sim_filters](const drivers::can::CanFrame& f) {
      return sim_filters.passes(f.id);
    };
    EXPECT_EQ(sim_port_.open(), 0);
    sim_ = std::make_unique<CanopenSim>(sim::SimOptions{}, o, sim_port_, nullptr);

    CanopenSourceConfig c;
    c.interface = "vcan0";
    c.sync = SyncRole::kConsumer;
    c.boot_timeout_ns = 100 * kMs;
    c.sdo_timeout_ns = 20 * kMs;
    for (int i = 0; i < kCanopenNodes; ++i) {
      CanopenJoint& j = c.joints[static_cast<std::size_t>(i)];
      j.node = static_cast<NodeId>(i + 1);
      j.total_range = kRange;
    }
    const drivers::can::CanIdFilterSet filters = port_config(c).filters;
    auto port = std::make_unique<test::MemoryCanPort>();
    port_ = port.get();
    port_->admit = [filters](const drivers::can::CanFrame& f) { return filters.passes(f.id); };
    port_->on_send = [this](const drivers::can::CanFrame& f, test::MemoryCanPort& p) {
      sim_port_.push(f, p.mono);
    };
    sim_port_.on_send = [this](const drivers::can::CanFrame& f, test::MemoryCanPort& p) {
      port_->push(f, p.mono);
    };
    port_->on_now = [this](test::MemoryCanPort& p) { run_sim_to(p.mono); };
    port_->on_wait = [this](test::MemoryCanPort& p, std::int64_t deadline) {
      // The simulator runs on until it sends something or the wait ends.
      while (p.queued() == 0 && sim_t_ + kSimStep <= deadline) run_sim_to(sim_t_ + kSimStep);
    };
    sim_t_ = port_->mono;
    source_ = std::make_unique<CanopenSource>(c, std::move(port));
    source_->start();
  }

  CanopenSource& source() { return *source_; }
  CanopenSim& sim() { return *sim_; }
  std::int64_t now() const { return t_; }  // the last wake

  // One loop wake (and its catch-up reads), 1 ms after the last; the
  // samples delivered are appended to `out`.
  ReadStatus wake(std::vector<EncoderSample>& out) {
    t_ += kMs;
    port_->advance_to(t_);
    CycleTime time{t_, t_, kMs, cycle_++, false};
    EncoderSample s;
    const ReadStatus r = source_->read(time, s);
    if (r == ReadStatus::kSample || r == ReadStatus::kNoSample) out.push_back(s);
    for (int k = 0; k < 16 && source_->backlog() > 0; ++k) {
      time.catch_up = true;
      if (source_->read(time, s) == ReadStatus::kSample) out.push_back(s);
    }
    return r;
  }

 private:
  void run_sim_to(std::int64_t t) {
    while (sim_t_ + kSimStep <= t) {
      sim_t_ += kSimStep;
      sim_port_.mono = sim_t_;
      sim_->poll(sim_t_);
    }
  }

  test::MemoryCanPort sim_port_;
  test::MemoryCanPort* port_ = nullptr;
  std::unique_ptr<CanopenSim> sim_;
  std::unique_ptr<CanopenSource> source_;
  std::int64_t sim_t_ = 0;
  std::int64_t t_ = 5'000'000'000;
  std::int64_t cycle_ = 0;
};

// Every SYNC the producer sent after the start-up is one sample, once, in
// order, at the SYNC's instant, with every node's position at that instant;
// a wake that finds no cycle closed publishes nothing (never MISSING).
void expect_every_sync_once(std::int64_t sync_period_ns, bool expect_idle_wakes,
                            bool expect_two_in_a_wake) {
  ConsumerBench b(sync_period_ns);
  std::vector<EncoderSample> samples;
  for (int k = 0; k < 3000 && !b.source().cycling(); ++k) b.wake(samples);
  ASSERT_TRUE(b.source().cycling());
  samples.clear();
  int idle = 0, two = 0;
  for (int k = 0; k < 1000; ++k) {
    const std::size_t before = samples.size();
    const ReadStatus r = b.wake(samples);
    ASSERT_NE(r, ReadStatus::kNoSample) << k;
    idle += r == ReadStatus::kNothingDue;
    two += samples.size() - before >= 2;
  }
  ASSERT_GT(samples.size(), 900U);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const EncoderSample& s = samples[i];
    ASSERT_EQ(s.flags, 0U) << i;
    ASSERT_EQ(s.channel_fresh, 0x3FU) << i;
    if (i > 0) {
      ASSERT_EQ(s.seq, samples[i - 1].seq + 1) << i;
      ASSERT_EQ(s.mono_ns - samples[i - 1].mono_ns, sync_period_ns) << i;
    }
    const double t = b.sim().sim_time_s(s.mono_ns);
    for (int c = 0; c < kCanopenNodes; ++c) {
      ASSERT_EQ(s.position[static_cast<std::size_t>(c)], b.sim().position_value(c, t))
          << i << " " << c;
    }
  }
  EXPECT_EQ(idle > 0, expect_idle_wakes) << idle;
  EXPECT_EQ(two > 0, expect_two_in_a_wake) << two;
  EXPECT_EQ(b.source().assembler().stats().queue_overflows, 0);
  EXPECT_EQ(b.source().detail().sync_sent, 0);  // the consumer sends none
}

TEST(CanopenConsumer, ProducerAtTheLoopRate) {
  expect_every_sync_once(kMs, false, false);
}

TEST(CanopenConsumer, ProducerSlowerThanTheLoop) {
  expect_every_sync_once(kMs + 10 * kUs, true, false);
}

TEST(CanopenConsumer, ProducerFasterThanTheLoop) {
  expect_every_sync_once(kMs - 10 * kUs, false, true);
}

TEST(CanopenConsumer, NoSyncForOneAndAHalfPeriodsIsMissing) {
  // At 2 s the producing node falls silent (its SYNC with it).
  ConsumerBench b(kMs, {{SimFault::kNeverBoots, 0, 2.0, 0.0}});
  std::vector<EncoderSample> samples;
  for (int k = 0; k < 3000 && !b.source().cycling(); ++k) b.wake(samples);
  ASSERT_TRUE(b.source().cycling());
  std::int64_t last_sync = 0;
  while (b.sim().sim_time_s(last_sync) < 1.95) {
    samples.clear();
    ASSERT_NE(b.wake(samples), ReadStatus::kNoSample);
    if (!samples.empty()) last_sync = samples.back().mono_ns;
  }
  // Once no SYNC came for one and a half periods, every wake is MISSING;
  // never before.
  int missing = 0;
  for (int k = 0; k < 100; ++k) {
    samples.clear();
    const ReadStatus r = b.wake(samples);
    if (r != ReadStatus::kNoSample && !samples.empty()) last_sync = samples.back().mono_ns;
    const bool overdue = b.now() - last_sync > kMs + kMs / 2;
    ASSERT_EQ(r == ReadStatus::kNoSample, overdue) << k;
    if (r == ReadStatus::kNoSample) {
      ++missing;
      ASSERT_EQ(samples.size(), 1U);
      EXPECT_NE(samples[0].flags & sample_flag::kMissing, 0U);
      EXPECT_FALSE(samples[0].present);
      EXPECT_EQ(samples[0].mono_ns, b.now());
    }
  }
  EXPECT_LT(b.sim().sim_time_s(last_sync), 2.0);
  EXPECT_GE(missing, 40);
}

}  // namespace
}  // namespace exodaq::board_sim
