// The `sim` backend end to end through the real decode path: 20 000 cycles
// whose unwrapped counts match the simulator's truth within one count, exact
// loss/partial/gap counters, index latches, determinism, no allocation in
// read().
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <vector>

#include "alloc_counter.hpp"
#include "exodaq/drivers/sim_source.hpp"

namespace sim = exodaq::drivers::sim;
namespace flag = exodaq::drivers::sample_flag;
using exodaq::drivers::CycleTime;
using exodaq::drivers::EncoderSample;
using exodaq::drivers::ReadStatus;
using exodaq::drivers::SimOptions;
using exodaq::drivers::SimSource;

namespace {

SimOptions lossy_options() {
  SimOptions o;
  o.seed = 42;
  o.loss_percent = 1.0;
  o.partial_percent = 0.5;
  o.jitter_ns = 80'000;
  o.start_mono_ns = 5'000'000'000;
  o.wall_offset_ns = 1'700'000'000'000'000'000LL;
  // Joint 1 on channel 5 and joint 6 on channel 0; odd directions and gears.
  o.encoders[0].channel = 5;
  o.encoders[5].channel = 0;
  o.encoders[1].direction = -1;
  o.encoders[3].gear_ratio = 2.5;
  o.encoders[5].gear_ratio = 3.0;
  o.encoders[5].direction = -1;
  return o;
}

TEST(SimSource, TwentyThousandCyclesMatchTruthWithinOneCountAndAllocateNothing) {
  const SimOptions o = lossy_options();
  SimSource src(o);
  src.start();
  EXPECT_EQ(src.name(), "sim");
  EXPECT_EQ(src.start_mono_ns(), o.start_mono_ns);

  constexpr std::int64_t kCycles = 20'000;
  std::array<std::int64_t, 6> unwrapped{};  // by joint
  for (std::size_t j = 0; j < 6; ++j) unwrapped[j] = o.encoders[j].power_up_count;

  std::int64_t allocations = 0;
  std::int64_t samples = 0;
  std::int64_t missing = 0;
  std::int64_t partial = 0;
  std::int64_t gap_flags = 0;
  std::int64_t expected_gaps = 0;
  double worst = 0.0;
  std::array<int, 6> index_seen{};
  bool previous_lost = false;
  EncoderSample s;
  CycleTime ct;
  for (std::int64_t k = 0; k < kCycles; ++k) {
    ct.cycle = k;
    ReadStatus st;
    {
      exodaq::test::AllocationScope scope;
      st = src.read(ct, s);
      allocations += static_cast<std::int64_t>(scope.count());
    }
    const bool lost = src.rig().cycle_lost(k);
    const std::int64_t t_ns = src.rig().sample_offset_ns(k);
    ASSERT_EQ(s.mono_ns, o.start_mono_ns + t_ns);
    ASSERT_EQ(s.wall_ns, s.mono_ns + o.wall_offset_ns);
    if (lost) {
      ASSERT_EQ(st, ReadStatus::kNoSample);
      ASSERT_FALSE(s.present);
      ASSERT_TRUE(s.flags & flag::kMissing);
      ++missing;
      previous_lost = true;
      continue;
    }
    ASSERT_EQ(st, ReadStatus::kSample);
    ASSERT_TRUE(s.present);
    ASSERT_EQ(s.seq, k & 0xFF);
    ++samples;
    if (previous_lost) ++expected_gaps;
    ASSERT_EQ((s.flags & flag::kSeqGap) != 0, previous_lost) << k;
    if (s.flags & flag::kSeqGap) ++gap_flags;
    previous_lost = false;
    const bool part = src.rig().cycle_partial(k);
    ASSERT_EQ((s.flags & flag::kPartial) != 0, part);
    ASSERT_EQ(s.channel_fresh, part ? 0x07U : 0x3FU);
    if (part) ++partial;

    const auto truth = src.rig().motion().truth(src.sim_time_s(s.mono_ns));
    for (std::size_t j = 0; j < 6; ++j) {
      const auto ch = static_cast<std::size_t>(o.encoders[j].channel);
      if ((s.channel_fresh & (1U << ch)) == 0) continue;  // held from an older cycle
      unwrapped[j] = exodaq::unwrap(unwrapped[j], s.position[ch], exodaq::kCount16Modulus);
      // The count the floor formula gives at the true angle, exactly...
      ASSERT_EQ(unwrapped[j], src.rig().encoders().count_at(static_cast<int>(j), truth.position[j]))
          << "k " << k << " joint " << j;
      // ...and within one count of the continuous encoder position.
      const double exact = o.encoders[j].direction * src.rig().encoders().encoder_position(
                                                         static_cast<int>(j), truth.position[j]) +
                           static_cast<double>(src.rig().encoders().offset(static_cast<int>(j)));
      worst = std::max(worst, std::abs(static_cast<double>(unwrapped[j]) - exact));
      if (s.index_count_valid & (1U << ch)) {
        ++index_seen[j];
        EXPECT_TRUE(s.index_latched & (1U << ch));
        // Homing crosses the index instance n = 0.
        EXPECT_EQ(s.index_position[ch],
                  static_cast<std::uint16_t>(
                      src.rig().encoders().count_at_index(static_cast<int>(j), 0) & 0xFFFF));
      }
    }
  }
  EXPECT_EQ(allocations, 0);
  {  // the counter is live in this binary
    exodaq::test::AllocationScope scope;
    auto* p = new std::vector<int>(100);
    EXPECT_GE(scope.count(), 1U);
    delete p;
  }
  EXPECT_LE(worst, 1.0);
  const auto st = src.stats();
  const auto& d = src.decoder().detail();
  EXPECT_EQ(st.missing_samples, missing);
  EXPECT_EQ(d.samples, samples);
  EXPECT_EQ(d.partial_samples, partial);
  EXPECT_EQ(st.seq_gaps, expected_gaps);
  EXPECT_EQ(gap_flags, expected_gaps);
  EXPECT_EQ(st.bad_frames, 0);
  EXPECT_EQ(st.duplicates, 0);
  EXPECT_EQ(st.out_of_order, 0);
  EXPECT_EQ(st.bus_errors, 0);
  EXPECT_EQ(samples + missing, kCycles);
  EXPECT_GT(missing, 100);  // ~1 %
  EXPECT_LT(missing, 320);
  EXPECT_GT(partial, 40);  // ~0.5 %
  EXPECT_GT(d.heartbeats, 150);
  for (std::size_t j = 0; j < 6; ++j) EXPECT_GE(index_seen[j], 1) << "joint " << j;
  EXPECT_EQ(src.cycles(), kCycles);
}

TEST(SimSource, DeterministicForASeedAndRestartable) {
  SimOptions o = lossy_options();
  SimSource a(o);
  SimSource b(o);
  a.start();
  b.start();
  EncoderSample sa;
  EncoderSample sb;
  std::vector<std::uint16_t> first;
  for (int k = 0; k < 3000; ++k) {
    ASSERT_EQ(a.read({}, sa), b.read({}, sb));
    ASSERT_EQ(sa.position, sb.position);
    ASSERT_EQ(sa.flags, sb.flags);
    ASSERT_EQ(sa.mono_ns, sb.mono_ns);
    first.push_back(sa.position[3]);
  }
  a.start();  // rewinds to power-up
  for (int k = 0; k < 3000; ++k) {
    a.read({}, sa);
    ASSERT_EQ(sa.position[3], first[static_cast<std::size_t>(k)]);
  }
  o.seed = 43;
  SimSource c(o);
  c.start();
  bool differs = false;
  for (int k = 0; k < 3000; ++k) {
    c.read({}, sb);
    if (sb.flags != 0) differs = true;  // different loss pattern
  }
  EXPECT_TRUE(differs);
}

TEST(SimSource, CleanRunHasNoFlagsAndWallClockFromStart) {
  SimOptions o;  // no loss, no jitter, time base from the clocks
  SimSource src(o);
  src.start();
  EXPECT_GT(src.start_mono_ns(), 0);
  EXPECT_GT(src.wall_offset_ns(), 0);
  EncoderSample s;
  for (int k = 0; k < 2000; ++k) {
    ASSERT_EQ(src.read({}, s), ReadStatus::kSample);
    ASSERT_EQ(s.flags, 0U);
    ASSERT_EQ(s.mono_ns, src.start_mono_ns() + k * 1'000'000LL);
  }
  EXPECT_EQ(src.stats().frames, 2000 * 2 + 20 + src.decoder().detail().index_frames);
}

// A scripted stall (a host held off): the read that reaches at_s blocks for
// for_s of real time; the samples are those of the same run without it.
TEST(SimSource, StallBlocksTheReadThatReachesItsStart) {
  SimOptions o;
  o.start_mono_ns = 1'000'000'000;
  SimSource reference(o);
  sim::SimFault stall;
  stall.kind = sim::SimFault::Kind::kStall;
  stall.start_s = 0.0105;  // cycle 11 (t = 11 ms) is the first at or after it
  stall.duration_s = 0.2;
  o.faults.push_back(stall);
  SimSource src(o);
  src.start();
  reference.start();
  EncoderSample s;
  EncoderSample r;
  std::chrono::steady_clock::duration cycle_11{};
  for (int k = 0; k < 40; ++k) {
    const auto t0 = std::chrono::steady_clock::now();
    ASSERT_EQ(src.read({}, s), ReadStatus::kSample);
    if (k == 11) cycle_11 = std::chrono::steady_clock::now() - t0;
    ASSERT_EQ(reference.read({}, r), ReadStatus::kSample);
    ASSERT_EQ(s.mono_ns, r.mono_ns);
    ASSERT_EQ(s.position, r.position);
    ASSERT_EQ(s.flags, r.flags);
  }
  EXPECT_GE(cycle_11, std::chrono::milliseconds(200));
}

TEST(SimSource, BadOptionsThrow) {
  SimOptions o;
  o.encoders[2].channel = 0;  // two joints on channel 0
  EXPECT_THROW(SimSource{o}, std::invalid_argument);
  o = SimOptions{};
  o.encoders[4].direction = 0;
  EXPECT_THROW(SimSource{o}, std::invalid_argument);
  o = SimOptions{};
  o.loss_percent = 150;
  EXPECT_THROW(SimSource{o}, std::invalid_argument);
  o = SimOptions{};
  o.board.ids.counts_b = o.board.ids.counts_a;
  EXPECT_THROW(SimSource{o}, std::invalid_argument);
  o = SimOptions{};
  o.faults.push_back(sim::SimFault{});
  o.faults.back().kind = sim::SimFault::Kind::kStall;  // no duration: would block for ever
  EXPECT_THROW(SimSource{o}, std::invalid_argument);
}

}  // namespace
