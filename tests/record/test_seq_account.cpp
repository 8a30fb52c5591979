// messages::RunAccount: seq holes split into the daemon's own (its status
// counters, window by window) and those lost on the way; repeats and late
// arrivals (issue 25 items 1, 5 and 10).
#include <gtest/gtest.h>

#include "exodaq/messages/seq_account.hpp"
#include "rate_meter.hpp"

namespace exodaq::messages {
namespace {

constexpr Kind kJoint = Kind::kJointState;

DaemonCounts status(std::int64_t seq, std::int64_t cycles, std::int64_t failures = 0) {
  status_t s{};
  s.seq = seq;
  s.cycles = cycles;
  s.publish_failures = failures;
  return daemon_counts(s);
}

TEST(SeqAccount, AnUnbrokenStreamHasNothingMissing) {
  RunAccount a;
  EXPECT_EQ(a.add(kJoint, 0), SeqStep::kFirst);
  for (int s = 1; s < 100; ++s) EXPECT_EQ(a.add(kJoint, s), SeqStep::kNext);
  a.add_status(status(99, 100));
  const SeqTally t = a.tally(kJoint);
  EXPECT_EQ(t.received, 100);
  EXPECT_EQ(t.missing, 0);
  EXPECT_EQ(t.lost, 0);
  EXPECT_EQ(describe(t), "100 cycles (seq 0..99), none missing");
}

// Sync master: the daemon skipped seq 50..52 (status: seq 99, 97 cycles);
// the receiver also lost 70: 3 skipped, 1 lost.
TEST(SeqAccount, HolesTheDaemonSkippedAreItsOwnTheRestIsLost) {
  RunAccount a;
  for (int s = 0; s < 100; ++s) {
    if ((s >= 50 && s <= 52) || s == 70) continue;
    a.add(kJoint, s);
  }
  a.add_status(status(99, 97));
  const SeqTally t = a.tally(kJoint);
  EXPECT_EQ(t.missing, 4);
  EXPECT_EQ(t.holes, 2);
  EXPECT_EQ(t.unpublished, 3);
  EXPECT_EQ(t.lost, 1);
  EXPECT_EQ(t.widest_from, 50);
  EXPECT_EQ(t.widest, 3);
  EXPECT_EQ(describe(t),
            "96 cycles (seq 0..99), 4 missing in 2 holes: 3 skipped by the daemon, 1 lost");
}

// The daemon's skips explain only holes in their own window: 3 skipped in
// 0..99 do not excuse 3 lost in 100..199.
TEST(SeqAccount, SkipsExplainOnlyTheirOwnWindow) {
  RunAccount a;
  for (int s = 0; s < 200; ++s) {
    if ((s >= 20 && s <= 22) || (s >= 150 && s <= 152)) continue;
    a.add(kJoint, s);
    if (s == 99) a.add_status(status(99, 100));    // window 0..99: no skip, so 20..22 were lost
    if (s == 199) a.add_status(status(199, 197));  // window 100..199: 3 skipped
  }
  const SeqTally t = a.tally(kJoint);
  EXPECT_EQ(t.missing, 6);
  EXPECT_EQ(t.unpublished, 3);
  EXPECT_EQ(t.lost, 3);
}

// A free-running board: overruns make no holes (cycles = seq + 1), so a hole
// is a loss even in a window with overruns.
TEST(SeqAccount, AFreeRunningBoardsOverrunsExplainNoHole) {
  RunAccount a;
  for (int s = 0; s < 100; ++s) {
    if (s != 40) a.add(kJoint, s);
  }
  a.add_status(status(99, 100));
  EXPECT_EQ(a.tally(kJoint).lost, 1);
}

TEST(SeqAccount, PublishFailuresAreTheDaemonsAndHolesAfterTheLastStatusUnconfirmed) {
  RunAccount a;
  for (int s = 0; s < 300; ++s) {
    if (s == 10 || s == 250) continue;
    a.add(kJoint, s);
  }
  a.add_status(status(199, 200, 1));
  const SeqTally t = a.tally(kJoint);
  EXPECT_EQ(t.failed, 1);
  EXPECT_EQ(t.lost, 1);
  EXPECT_EQ(t.unconfirmed, 1);
}

// Two streams with one run id (replay --live of the live run: 8066, 0,
// 8067, 1, ...) and a log holding its run twice: repeats, not cycles.
TEST(SeqAccount, InterleavedOrRepeatedSeqIsCountedAsRepeated) {
  RunAccount a;
  for (int s = 0; s <= 8066; ++s) a.add(kJoint, s);
  for (int k = 0; k < 10; ++k) {
    EXPECT_EQ(a.add(kJoint, k), SeqStep::kRepeat);
    EXPECT_EQ(a.add(kJoint, 8067 + k), SeqStep::kNext);
  }
  const SeqTally t = a.tally(kJoint);
  EXPECT_EQ(t.received, 8077);
  EXPECT_EQ(t.repeated, 10);
  EXPECT_EQ(t.missing, 0);
}

TEST(SeqAccount, ALateArrivalFillsItsHole) {
  RunAccount a;
  a.add(kJoint, 0);
  a.add(kJoint, 1);
  EXPECT_EQ(a.add(kJoint, 5), SeqStep::kGap);
  EXPECT_EQ(a.add(kJoint, 3), SeqStep::kLate);
  EXPECT_EQ(a.add(kJoint, 3), SeqStep::kRepeat);
  const SeqTally t = a.tally(kJoint);
  EXPECT_EQ(t.received, 4);
  EXPECT_EQ(t.missing, 2);  // 2 and 4
  EXPECT_EQ(t.holes, 2);
  EXPECT_EQ(t.late, 1);
  EXPECT_EQ(t.repeated, 1);
}

TEST(SeqAccount, AStatusOlderThanTheLastIsIgnored) {
  RunAccount a;
  for (int s = 0; s < 50; ++s) {
    if (s != 30) a.add(kJoint, s);
  }
  a.add_status(status(49, 49));
  a.add_status(status(20, 21));  // another stream's, or out of order
  EXPECT_EQ(a.last_status()->seq, 49);
  EXPECT_EQ(a.tally(kJoint).unpublished, 1);
}

}  // namespace
}  // namespace exodaq::messages

namespace exodaq::tools {
namespace {

// echo's "received %": of the cycles the daemon published, not of the seq
// span (a sync master's skipped deadlines are no loss).
TEST(RateMeter, TheDaemonsSkippedSeqAreNotCountedAsMissing) {
  RateMeter m;
  std::int64_t t = 0;
  for (std::int64_t s = 0; s < 500; ++s) {
    if (s >= 100 && s < 110) continue;  // the daemon skipped 10
    m.add(messages::Stamp{0, s * 1'000'000, s, 7}, t += 1'000'000);
    if (s % 100 == 99) m.add_status(7, s, s < 100 ? 0 : 10);
  }
  EXPECT_EQ(m.skipped_in_window(), 10);
  EXPECT_DOUBLE_EQ(*m.received_fraction(), 1.0);
  RateMeter without;  // no statuses: the holes count as missing
  t = 0;
  for (std::int64_t s = 0; s < 500; ++s) {
    if (s < 100 || s >= 110) without.add(messages::Stamp{0, s * 1'000'000, s, 7}, t += 1'000'000);
  }
  EXPECT_DOUBLE_EQ(*without.received_fraction(), 490.0 / 500.0);
}

}  // namespace
}  // namespace exodaq::tools
