// The simulated board's own clock (SimOptions::board_clock): a free-running
// board samples at phase + k · period · (1 + drift) whatever the reader does,
// so a reader that comes late finds the cycles it missed queued, as in a
// socket, and takes them oldest first; its config keys and their errors.
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "alloc_counter.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/sim_source.hpp"

namespace sim = exodaq::drivers::sim;
using exodaq::drivers::CycleTime;
using exodaq::drivers::EncoderSample;
using exodaq::drivers::ReadStatus;
using exodaq::drivers::SimOptions;
using exodaq::drivers::SimSource;

namespace {
constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kStart = 2'000'000'000;

SimOptions free_running(double drift_ppm, std::int64_t phase_ns) {
  SimOptions o;
  o.start_mono_ns = kStart;
  o.wall_offset_ns = 7;
  o.board_clock.free_running = true;
  o.board_clock.drift_ppm = drift_ppm;
  o.board_clock.phase_ns = phase_ns;
  return o;
}

CycleTime at(std::int64_t deadline, std::int64_t now) {
  CycleTime t;
  t.deadline_mono_ns = deadline;
  t.now_mono_ns = now;
  t.period_ns = kMs;
  return t;
}

std::shared_ptr<const exodaq::drivers::SimSourceSettings> parse(const std::string& yaml) {
  exodaq::MapReader src("cfg.yaml", exodaq::load_yaml_text(yaml, "cfg.yaml"), "source");
  exodaq::MapReader s = src.map("sim");
  return std::dynamic_pointer_cast<const exodaq::drivers::SimSourceSettings>(
      exodaq::drivers::sim_backend().parse(&s, src, true));
}
}  // namespace

TEST(SimBoardClock, AFreeRunningBoardSamplesOnItsOwnDriftingClock) {
  sim::SimRig drifting(free_running(100.0, 250'000));
  // 100 ppm slow: cycle k at 250 µs + k · 1.0001 ms.
  EXPECT_EQ(drifting.sample_offset_ns(0), 250'000);
  EXPECT_EQ(drifting.sample_offset_ns(1), 250'000 + 1'000'100);
  EXPECT_EQ(drifting.sample_offset_ns(10'000), 250'000 + 10'000 * kMs + 1'000'000);
  sim::SimRig fast(free_running(-50.0, 0));
  EXPECT_EQ(fast.sample_offset_ns(20'000), 20'000 * kMs - 1'000'000);
  // The default board samples at the reader's deadlines: no drift, no phase.
  SimOptions aligned = free_running(100.0, 250'000);
  aligned.board_clock.free_running = false;
  EXPECT_EQ(sim::SimRig(aligned).sample_offset_ns(10'000), 10'000 * kMs);
  SimOptions bad = free_running(1500.0, 0);
  EXPECT_THROW(sim::SimRig{bad}, std::invalid_argument);
  bad = free_running(0.0, kMs);
  EXPECT_THROW(sim::SimRig{bad}, std::invalid_argument);
}

// In step with the reader (no drift, no phase) a free-running board gives the
// reader exactly what the default board gives: the same samples, stamps, flags.
TEST(SimBoardClock, InStepWithTheReaderItIsTheDefaultBoard) {
  SimSource aligned([] {
    SimOptions o = free_running(0.0, 0);
    o.board_clock.free_running = false;
    return o;
  }());
  SimSource own(free_running(0.0, 0));
  aligned.start();
  own.start();
  EXPECT_TRUE(own.free_running());
  EXPECT_FALSE(aligned.free_running());
  EncoderSample a;
  EncoderSample b;
  for (std::int64_t k = 0; k < 3000; ++k) {
    CycleTime t = at(kStart + k * kMs, kStart + k * kMs + 20'000);
    t.cycle = k;
    ASSERT_EQ(aligned.read(t, a), ReadStatus::kSample);
    ASSERT_EQ(own.read(t, b), ReadStatus::kSample);
    ASSERT_EQ(a.mono_ns, b.mono_ns) << k;
    ASSERT_EQ(a.seq, b.seq);
    ASSERT_EQ(a.position, b.position) << k;
    ASSERT_EQ(a.index_position, b.index_position) << k;
    ASSERT_EQ(a.flags, b.flags) << k;
    ASSERT_EQ(own.backlog(), 0);
  }
}

// A reader that comes 10 ms late finds the eleven cycles sampled meanwhile
// queued: the first read gives the oldest, backlog() says more wait, the
// catch-up reads give the rest in order, then nothing. Nothing superseded.
TEST(SimBoardClock, ALateReaderFindsEveryCycleQueuedAndTakesThemOldestFirst) {
  SimSource src(free_running(0.0, 300'000));
  src.start();
  EncoderSample s;
  // Cycle 0 at 300 µs: the reader waits (half a period at most) for it.
  ASSERT_EQ(src.read(at(kStart, kStart + 20'000), s), ReadStatus::kSample);
  EXPECT_EQ(s.seq, 0);
  EXPECT_EQ(s.mono_ns, kStart + 300'000);
  EXPECT_EQ(src.backlog(), 0);
  // The reader is back 10 ms after deadline 1: cycles 1 .. 10 are there (cycle
  // 11 comes at 11.3 ms).
  CycleTime t = at(kStart + kMs, kStart + 11 * kMs);
  for (std::int64_t k = 1; k <= 10; ++k) {
    ASSERT_EQ(src.read(t, s), ReadStatus::kSample) << k;
    EXPECT_EQ(s.seq, k);
    EXPECT_EQ(s.mono_ns, kStart + k * kMs + 300'000);
    EXPECT_EQ(s.wall_ns, s.mono_ns + 7);
    EXPECT_EQ(s.flags, 0U) << k;
    EXPECT_EQ(src.backlog() > 0, k < 10) << k;
    t.catch_up = true;
  }
  EXPECT_EQ(src.read(t, s), ReadStatus::kNothingDue);
  EXPECT_EQ(src.stats().superseded_samples, 0);
  EXPECT_EQ(src.stats().missing_samples, 0);
  EXPECT_EQ(src.stats().seq_gaps, 0);
}

// The scripted stall holds the reader off (real time) and its now moves on by
// as much: the samples of those 20 ms are queued behind it.
TEST(SimBoardClock, AStallLeavesTheCyclesOfItsDurationQueued) {
  SimOptions o = free_running(0.0, 0);
  sim::SimFault stall;
  stall.kind = sim::SimFault::Kind::kStall;
  stall.start_s = 0.0105;
  stall.duration_s = 0.02;
  o.faults.push_back(stall);
  SimSource src(o);
  src.start();
  EncoderSample s;
  std::int64_t delivered = 0;
  std::chrono::steady_clock::duration longest{};
  for (std::int64_t k = 0; k < 40; ++k) {
    CycleTime t = at(kStart + k * kMs, kStart + k * kMs + 20'000);
    const auto t0 = std::chrono::steady_clock::now();
    ReadStatus r = src.read(t, s);
    longest = std::max(longest, std::chrono::steady_clock::now() - t0);
    int in_this_read = 0;
    while (r == ReadStatus::kSample) {
      ASSERT_EQ(s.seq, delivered % 256);
      ++delivered;
      ++in_this_read;
      if (src.backlog() == 0) break;
      t.catch_up = true;
      r = src.read(t, s);
    }
    // The read at deadline 11 stalled until 31.02 ms: cycles 11 .. 31.
    EXPECT_EQ(in_this_read, k == 11 ? 21 : (k > 11 && k <= 31 ? 0 : 1)) << k;
  }
  EXPECT_GE(longest, std::chrono::milliseconds(20));
  EXPECT_EQ(delivered, 40);
  EXPECT_EQ(src.stats().superseded_samples, 0);
}

// A board 1000 ppm slow, read at every deadline: now and then a read finds
// nothing due (its clock slipped past the wake) and the next one two; never a
// MISSING, every board cycle once.
TEST(SimBoardClock, ASlowBoardClockGivesReadsWithNothingDueNeverMissing) {
  SimSource src(free_running(1000.0, 400'000));
  src.start();
  EncoderSample s;
  std::int64_t delivered = 0;
  int nothing_due = 0;
  for (std::int64_t k = 0; k < 3000; ++k) {
    CycleTime t = at(kStart + k * kMs, kStart + k * kMs + 20'000);
    ReadStatus r = src.read(t, s);
    if (r == ReadStatus::kNothingDue) ++nothing_due;
    while (r == ReadStatus::kSample) {
      ASSERT_EQ(s.seq, delivered % 256) << k;
      ++delivered;
      if (src.backlog() == 0) break;
      t.catch_up = true;
      r = src.read(t, s);
    }
  }
  // 3000 ms at 1000 ppm slow: 3 periods slipped, from 400 µs past the deadline.
  EXPECT_EQ(nothing_due, 3);
  EXPECT_EQ(delivered, 3000 - 3);
  EXPECT_EQ(src.stats().missing_samples, 0);
  EXPECT_EQ(src.stats().superseded_samples, 0);
}

// Reading a free-running board, catch-ups included, allocates nothing.
TEST(SimBoardClock, ReadingAllocatesNothing) {
  SimSource src(free_running(-300.0, 100'000));
  src.start();
  EncoderSample s;
  std::int64_t delivered = 0;
  exodaq::test::AllocationScope scope;
  for (std::int64_t k = 0; k < 5000; ++k) {
    const std::int64_t late = k % 500 == 250 ? 30 * kMs : 20'000;  // now and then 30 ms late
    CycleTime t = at(kStart + k * kMs, kStart + k * kMs + late);
    while (src.read(t, s) == ReadStatus::kSample) {
      ++delivered;
      if (src.backlog() == 0) break;
      t.catch_up = true;
    }
  }
  EXPECT_EQ(scope.count(), 0U);
  EXPECT_GT(delivered, 5000);
  EXPECT_EQ(src.stats().superseded_samples, 0);
  EXPECT_EQ(src.stats().missing_samples, 0);
}

TEST(SimBoardClock, ConfigKeysAndTheirErrors) {
  const auto s = parse("sim: {board_clock: {free_running: true, drift_ppm: -40, phase: 0.25}}");
  ASSERT_TRUE(s);
  EXPECT_TRUE(s->free_running);
  EXPECT_DOUBLE_EQ(s->drift_ppm, -40.0);
  EXPECT_DOUBLE_EQ(s->phase, 0.25);
  EXPECT_NE(s->describe().find("board_clock: {free_running: true, drift_ppm: -40, phase: 0.25}"),
            std::string::npos)
      << s->describe();
  exodaq::drivers::SourceContext ctx;
  ctx.period_ns = 2 * kMs;
  const SimOptions o = exodaq::drivers::sim_options_from(*s, ctx);
  EXPECT_TRUE(o.board_clock.free_running);
  EXPECT_EQ(o.board_clock.phase_ns, 500'000);  // a quarter of the 2 ms period
  EXPECT_FALSE(parse("sim: {seed: 3}")->free_running);
  const auto error_of = [](const std::string& yaml) {
    try {
      parse(yaml);
    } catch (const exodaq::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error_of("sim: {board_clock: {free_running: true, drift_ppm: 2000}}")
                .find("drift_ppm must be within ±1000"),
            std::string::npos);
  EXPECT_NE(
      error_of("sim: {board_clock: {free_running: true, phase: 1}}").find("must be in [0, 1)"),
      std::string::npos);
  EXPECT_NE(error_of("sim: {board_clock: {drift_ppm: 5}}").find("not free_running"),
            std::string::npos);
  EXPECT_NE(error_of("sim: {board_clock: {free_running: true, skew: 5}}").find("skew"),
            std::string::npos);
  EXPECT_EQ(error_of("sim: {board_clock: {free_running: true}}"), "no error");
}
