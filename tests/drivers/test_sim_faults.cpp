// The one fault vocabulary of the simulators (sim_rig.hpp SimFault, parsed by
// the sim backend for source.sim.faults and exodaq-board-sim --fault): every
// kind named once, parameters a kind does not take refused, and the kinds the
// board simulator brought in (every-Nth windows, delays, error frames, a stuck
// channel's quadrature error) acting on exactly the cycles they should,
// through the real decode path.
#include <gtest/gtest.h>

#include <set>
#include <string>

#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/sim_source.hpp"

namespace sim = exodaq::drivers::sim;
namespace can = exodaq::drivers::can;
namespace flag = exodaq::drivers::sample_flag;
using exodaq::drivers::CycleTime;
using exodaq::drivers::EncoderSample;
using exodaq::drivers::ReadStatus;
using exodaq::drivers::SimSource;
using Kind = sim::SimFault::Kind;

namespace {

sim::SimFault parse(const std::string& yaml) {
  exodaq::MapReader m("fault", exodaq::load_yaml_text(yaml, "fault"), "fault");
  return exodaq::drivers::parse_sim_fault(m);
}

sim::SimFault window(Kind kind, std::int64_t first_k, std::int64_t cycles, int every = 1) {
  sim::SimFault f;
  f.kind = kind;
  f.start_s = (static_cast<double>(first_k) - 0.5) * 1e-3;  // 1 kHz: cycles first_k ...
  f.duration_s = static_cast<double>(cycles) * 1e-3;
  f.every = every;
  return f;
}

sim::SimOptions options_with(const sim::SimFault& f) {
  sim::SimOptions o;
  o.start_mono_ns = 1'000'000'000;
  o.wall_offset_ns = 1;
  o.faults.push_back(f);
  return o;
}

TEST(SimFaultVocabulary, EveryKindHasOneNameAndTheNamesAreUnique) {
  std::set<std::string> names;
  for (const auto& n : sim::sim_fault_names()) {
    EXPECT_TRUE(names.insert(std::string(n.name)).second) << n.name;
    EXPECT_EQ(sim::find_sim_fault(n.name), &n);
    EXPECT_EQ(sim::sim_fault_name(n.kind), n.name);
  }
  for (int k = 0; k <= static_cast<int>(Kind::kErrorFrame); ++k) {
    EXPECT_NE(sim::sim_fault_name(static_cast<Kind>(k)), "?") << k;
  }
  EXPECT_EQ(sim::find_sim_fault("nonsense"), nullptr);
  EXPECT_EQ(sim::fault_bit(Kind::kDelay), 1U << static_cast<int>(Kind::kDelay));
}

TEST(SimFaultVocabulary, ParsesTheBoardSimulatorKindsAndRefusesForeignParameters) {
  const auto d = parse("{kind: delay, delay_us: 900, at_s: 16, for_s: 0.3}");
  EXPECT_EQ(d.kind, Kind::kDelay);
  EXPECT_DOUBLE_EQ(d.delay_us, 900.0);
  EXPECT_DOUBLE_EQ(d.duration_s, 0.3);
  const auto e = parse("{kind: error_frame, every: 10, at_s: 1}");
  EXPECT_EQ(e.kind, Kind::kErrorFrame);
  EXPECT_EQ(e.every, 10);
  const auto s = parse("{kind: stuck, joint: 3, error_bits: 1, at_s: 2}");
  EXPECT_EQ(s.joint, 2);
  EXPECT_EQ(s.error_bits, 1);
  try {
    parse("{kind: drop, percent: 10, joint: 2, at_s: 1}");
    FAIL() << "a drop with a joint was accepted";
  } catch (const exodaq::ConfigError& err) {
    EXPECT_NE(std::string(err.what()).find("a drop fault takes no joint"), std::string::npos)
        << err.what();
  }
  EXPECT_THROW(parse("{kind: glitch, every: 3, at_s: 1}"), exodaq::ConfigError);
  EXPECT_THROW(parse("{kind: bad_seq, every: 0, at_s: 1}"), exodaq::ConfigError);
  EXPECT_THROW(parse("{kind: delay, delay_us: -1, at_s: 1}"), exodaq::ConfigError);
  EXPECT_THROW(parse("{kind: jitter, at_s: 1}"), exodaq::ConfigError);
  // A delay of four periods or more is refused by the rig.
  sim::SimFault too_late = window(Kind::kDelay, 10, 10);
  too_late.delay_us = 4000;
  EXPECT_THROW(sim::SimRig{options_with(too_late)}, std::invalid_argument);
}

TEST(SimFaults, EveryNthKindsChangeEveryNthCycleOfTheirWindowOnly) {
  sim::SimRig rig(options_with(window(Kind::kBadSeq, 100, 100, 10)));
  sim::SimBoard::Frames out{};
  const std::uint32_t id_a = rig.options().board.ids.counts_a_id();
  std::vector<std::int64_t> hit;
  for (std::int64_t k = 0; k < 300; ++k) {
    const int n = rig.step(k, out, 0, 0);
    const bool applied = (rig.last_cycle().applied & sim::fault_bit(Kind::kBadSeq)) != 0;
    for (int i = 0; i < n; ++i) {
      if (out[static_cast<std::size_t>(i)].id != id_a) continue;
      const auto seq = can::decode(out[static_cast<std::size_t>(i)]).counts.seq;
      EXPECT_EQ(seq, static_cast<std::uint8_t>(k + (applied ? 128 : 0))) << k;
    }
    if (applied) hit.push_back(k);
  }
  EXPECT_EQ(hit, (std::vector<std::int64_t>{100, 110, 120, 130, 140, 150, 160, 170, 180, 190}));
  EXPECT_EQ(rig.applied_counts()[static_cast<std::size_t>(Kind::kBadSeq)], 10);
}

TEST(SimFaults, AnErrorFrameGoesThroughTheCodecIntoTheDecoderAsABusError) {
  SimSource src(options_with(window(Kind::kErrorFrame, 1000, 50, 5)));
  src.start();
  EncoderSample s;
  std::int64_t flagged = 0;
  for (std::int64_t k = 0; k < 1100; ++k) {
    ASSERT_EQ(src.read(CycleTime{.cycle = k}, s), ReadStatus::kSample);
    if ((s.flags & flag::kBusError) != 0) {
      ++flagged;
      EXPECT_EQ((k - 1001) % 5, 0) << k;  // the sample after each error frame
    }
  }
  EXPECT_EQ(src.stats().bus_errors, 10);
  EXPECT_EQ(flagged, 10);
  EXPECT_EQ(src.stats().bad_frames, 0);
  EXPECT_EQ(src.stats().bus_state, exodaq::drivers::BusState::kActive);
}

TEST(SimFaults, DelayedFramesReachTheReaderOneCycleLateStampedWhenTheyArrived) {
  sim::SimFault f = window(Kind::kDelay, 1000, 100);
  f.delay_us = 700;  // past the sim reader's half-period wait
  const auto o = options_with(f);
  SimSource src(o);
  src.start();
  EncoderSample s;
  for (std::int64_t k = 0; k < 1200; ++k) {
    const ReadStatus st = src.read(CycleTime{.cycle = k}, s);
    if (k == 1000) {  // its own frames are still on the way
      EXPECT_EQ(st, ReadStatus::kNoSample);
      EXPECT_TRUE(s.flags & flag::kMissing);
      continue;
    }
    ASSERT_EQ(st, ReadStatus::kSample) << k;
    const bool late = k > 1000 && k < 1100;
    const std::int64_t seq = late ? k - 1 : k;
    EXPECT_EQ(s.seq, seq & 0xFF) << k;
    EXPECT_EQ(s.mono_ns, o.start_mono_ns + seq * 1'000'000 + (late ? 700'000 : 0)) << k;
  }
  EXPECT_EQ(src.stats().missing_samples, 1);
  EXPECT_EQ(src.stats().seq_gaps, 0);
  // Every cycle was assembled; 1099 arrived with 1100 at read 1100 and was superseded.
  EXPECT_EQ(src.decoder().detail().samples, 1200);
  EXPECT_EQ(src.rig().applied_counts()[static_cast<std::size_t>(Kind::kDelay)], 100);
}

TEST(SimFaults, AStuckChannelWithQuadratureErrorBitsIsReportedForItsChannel) {
  sim::SimFault f = window(Kind::kStuck, 1000, 500);
  f.joint = 2;
  f.error_bits = can::board_error::kQuadrature;
  auto o = options_with(f);
  o.encoders[2].channel = 4;  // joint 3 on channel 4, joint 5 on channel 2
  o.encoders[4].channel = 2;
  SimSource src(o);
  src.start();
  EncoderSample s;
  std::int64_t reported = 0;
  for (std::int64_t k = 0; k < 2000; ++k) {
    src.read(CycleTime{.cycle = k}, s);
    if (s.board_errors != 0) {
      ++reported;
      EXPECT_EQ(s.board_errors, can::board_error::kQuadrature | (1U << 4) << 8) << k;
      EXPECT_TRUE(s.flags & flag::kBoardError);
    }
  }
  EXPECT_EQ(reported, 500);  // from the heartbeat at 1000 to the one at 1500
}

TEST(SimFaults, DropMarksExactlyTheCyclesItDropped) {
  sim::SimFault f = window(Kind::kDrop, 100, 1000);
  f.percent = 30;
  sim::SimRig rig(options_with(f));
  sim::SimBoard::Frames out{};
  std::int64_t empty = 0;
  std::int64_t marked = 0;
  for (std::int64_t k = 0; k < 1200; ++k) {
    const int n = rig.step(k, out, 0, 0);
    const bool dropped = (rig.last_cycle().applied & sim::fault_bit(Kind::kDrop)) != 0;
    EXPECT_EQ(n == 0, dropped) << k;
    empty += n == 0 ? 1 : 0;
    marked += dropped ? 1 : 0;
  }
  EXPECT_EQ(marked, empty);
  EXPECT_GT(marked, 250);
  EXPECT_LT(marked, 350);
}

}  // namespace
