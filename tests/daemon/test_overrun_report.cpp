// The daemon's overrun lines (daemon/src/overrun_report.hpp): the first
// overrun at once, the rest summed up at most once per interval, nothing
// lost from the counts, the latest wake and the longest work apart.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "overrun_report.hpp"

using exodaq::core::LogEvent;
using exodaq::daemon::OverrunLine;
using exodaq::daemon::OverrunReport;

namespace {

constexpr std::int64_t kS = 1'000'000'000;

LogEvent overrun(std::int64_t seq, std::int64_t skipped, double lateness_us, double work_us) {
  LogEvent e;
  e.kind = LogEvent::Kind::kOverrun;
  e.seq = seq;
  e.count = skipped;
  e.value = lateness_us;
  e.work_us = work_us;
  return e;
}

}  // namespace

TEST(OverrunReport, TheFirstIsSaidAtOnceTheRestSummedUpOncePerInterval) {
  OverrunReport report;  // 10 s
  const auto first = report.add(overrun(311, 4, 4012.31, 49.3), 100 * kS);
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(first->text(),
            "loop overrun at seq 311: the wake was 4012.3 us late, the cycle's work 49.3 us; 4 "
            "deadline(s) skipped in 1 late wake");
  // One overrun a 10 ms for just under 10 s: not a line until the interval passed.
  std::int64_t now = 100 * kS;
  std::int64_t skipped = 0;
  for (int k = 0; k < 999; ++k) {
    now += kS / 100;
    const double late = k == 500 ? 9000.0 : 1500.0;
    const double work = k == 700 ? 300.0 : 40.0;
    EXPECT_FALSE(report.add(overrun(400 + 10 * k, 2, late, work), now).has_value()) << k;
    EXPECT_FALSE(report.due(now).has_value());
    skipped += 2;
  }
  const auto summary = report.due(110 * kS);
  ASSERT_TRUE(summary.has_value());
  EXPECT_EQ(summary->late_wakes, 999);
  EXPECT_EQ(summary->skipped, skipped);
  EXPECT_EQ(summary->first_seq, 400);
  EXPECT_EQ(summary->last_seq, 400 + 10 * 998);
  EXPECT_DOUBLE_EQ(summary->worst_lateness_us, 9000.0);
  EXPECT_EQ(summary->worst_seq, 400 + 10 * 500);
  EXPECT_DOUBLE_EQ(summary->longest_work_us, 300.0);
  EXPECT_EQ(summary->text(),
            "loop overruns from seq 400 to 10380 (10.0 s): 1998 deadline(s) skipped in 999 late "
            "wakes; the latest wake 9000.0 us late (seq 5400), the longest cycle's work 300.0 us");
  // Nothing pending: nothing due, however long.
  EXPECT_FALSE(report.due(200 * kS).has_value());
}

TEST(OverrunReport, AtStopWhatIsPendingIsSaidAndAQuietIntervalStartsOver) {
  OverrunReport report(10 * kS);
  ASSERT_TRUE(report.add(overrun(10, 1, 2000.0, 30.0), 5 * kS).has_value());
  EXPECT_FALSE(report.add(overrun(20, 3, 1000.0, 30.0), 6 * kS).has_value());
  EXPECT_FALSE(report.due(7 * kS).has_value());
  const auto at_stop = report.due(7 * kS, true);
  ASSERT_TRUE(at_stop.has_value());
  EXPECT_EQ(at_stop->late_wakes, 1);
  EXPECT_EQ(at_stop->skipped, 3);
  // After a quiet interval the next overrun is said at once again.
  const auto again = report.add(overrun(90, 1, 1200.0, 25.0), 30 * kS);
  ASSERT_TRUE(again.has_value());
  EXPECT_EQ(again->late_wakes, 1);
  EXPECT_EQ(again->last_seq, 90);
}
