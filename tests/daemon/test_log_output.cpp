// The daemon's log output (daemon/src/log_output.hpp): a stalled output
// fills the queue and further lines are dropped and counted, never waited
// for; stop() is bounded whether the output gives up when asked (stderr) or
// stays blocked (a journald that does not read). The real-process
// reproductions are in tests/integration/test_signals.cpp (LogStall).
#include "log_output.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <future>
#include <mutex>
#include <string>
#include <vector>

using exodaq::daemon::LogOutput;
using exodaq::daemon::LogRecord;
using exodaq::daemon::StderrWriter;
using namespace std::chrono_literals;

namespace {

// An output that takes nothing until opened; records what it wrote.
struct Gate {
  std::atomic<bool> open{false};
  std::atomic<bool> honour_give_up{true};
  std::mutex mutex;
  std::vector<std::string> written;
  std::promise<void> release;  // for an output that ignores give_up()
  std::shared_future<void> released = release.get_future().share();
};

LogOutput::Write writer(const std::shared_ptr<Gate>& gate) {
  return [gate](const LogRecord& r, const std::function<bool()>& give_up) {
    while (!gate->open.load()) {
      if (!gate->honour_give_up.load()) {
        gate->released.wait();  // blocked in the output: cannot be asked
        return StderrWriter::Result::kFailed;
      }
      if (give_up()) return StderrWriter::Result::kGaveUp;
      std::this_thread::sleep_for(1ms);
    }
    std::lock_guard lock(gate->mutex);
    gate->written.push_back(r.text);
    return StderrWriter::Result::kWritten;
  };
}

LogRecord line(int i) {
  return {2, "line " + std::to_string(i) + "\n"};
}

}  // namespace

TEST(LogOutput, AStalledOutputDropsAndCountsWhatDoesNotFitAndNeverWaits) {
  auto gate = std::make_shared<Gate>();
  LogOutput out(writer(gate));
  const int pushed = static_cast<int>(LogOutput::kMaxLines) + 500;
  int accepted = 0;
  std::vector<std::string> kept;  // the accepted lines, in order
  for (int i = 0; i < pushed; ++i) {
    if (!out.push(line(i))) continue;
    ++accepted;
    kept.push_back(line(i).text);
  }
  // The writer holds one line (waiting for the output), the queue the next
  // kMaxLines. Which lines: the first kMaxLines, and one more pushed after the
  // writer took its line, whenever that was (a slow writer thread takes it
  // after the queue filled: then a later line fills the slot).
  EXPECT_GE(accepted, static_cast<int>(LogOutput::kMaxLines));
  EXPECT_LE(accepted, static_cast<int>(LogOutput::kMaxLines) + 1);
  EXPECT_EQ(out.counts().dropped, pushed - accepted);
  EXPECT_EQ(out.unreported_drops(), pushed - accepted);
  out.note_reported(10);
  EXPECT_EQ(out.unreported_drops(), pushed - accepted - 10);

  gate->open.store(true);  // the output takes lines again: everything kept is written, in order
  const LogOutput::Counts c = out.stop(10s);
  EXPECT_EQ(c.written, accepted);
  EXPECT_EQ(c.dropped, pushed - accepted);
  EXPECT_EQ(c.unwritten, 0);
  ASSERT_EQ(gate->written.size(), static_cast<std::size_t>(accepted));
  EXPECT_EQ(gate->written, kept);
  for (int i = 0; i < static_cast<int>(LogOutput::kMaxLines); ++i)
    EXPECT_EQ(gate->written[static_cast<std::size_t>(i)], line(i).text);
  EXPECT_FALSE(out.push(line(0)));  // after stop(): counted, not queued
}

TEST(LogOutput, StopGivesUpOnAStalledOutputAndCountsWhatWasLeft) {
  auto gate = std::make_shared<Gate>();
  LogOutput out(writer(gate));
  for (int i = 0; i < 100; ++i) ASSERT_TRUE(out.push(line(i)));
  const auto t0 = std::chrono::steady_clock::now();
  const LogOutput::Counts c = out.stop(100ms);
  // Bounded: the drain, then the writer's next look at give_up() (50 ms at
  // most for stderr); generous for a loaded machine.
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 5s);
  EXPECT_EQ(c.written, 0);
  EXPECT_EQ(c.unwritten, 100);
}

TEST(LogOutput, StopLeavesAWriterBlockedInItsOutputBehind) {
  auto gate = std::make_shared<Gate>();
  gate->honour_give_up.store(false);
  {
    LogOutput out(writer(gate));
    for (int i = 0; i < 10; ++i) ASSERT_TRUE(out.push(line(i)));
    const auto t0 = std::chrono::steady_clock::now();
    const LogOutput::Counts c = out.stop(100ms);
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 5s);
    EXPECT_EQ(c.written, 0);
    EXPECT_EQ(c.unwritten, 10);  // nine queued, one in the blocked writer's hands
  }
  // The LogOutput is gone; the detached writer still owns what it uses.
  gate->release.set_value();
  std::this_thread::sleep_for(50ms);
}
