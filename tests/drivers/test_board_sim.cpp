// exodaq-board-sim's core (tools/board-sim/board_sim.hpp) on the in-memory
// CanPort: it sends exactly the shared SimRig's frames, faults included (the
// sim's own vocabulary), and its truth file marks each cycle with the bits of
// the faults that changed it.
#include <gtest/gtest.h>

#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "board_sim.hpp"
#include "memory_can_port.hpp"

namespace sim = exodaq::drivers::sim;
using exodaq::board_sim::BoardSim;
using exodaq::test::MemoryCanPort;
using Kind = sim::SimFault::Kind;

namespace {

sim::SimFault fault(Kind kind, double at_s, double for_s) {
  sim::SimFault f;
  f.kind = kind;
  f.start_s = at_s;
  f.duration_s = for_s;
  return f;
}

struct TruthLine {
  std::int64_t k = 0;
  std::uint32_t bits = 0;
};

std::vector<TruthLine> read_truth(std::FILE* f) {
  std::rewind(f);
  std::vector<TruthLine> out;
  char line[512];
  while (std::fgets(line, sizeof line, f) != nullptr) {
    if (line[0] == '#') continue;
    std::istringstream s(line);
    TruthLine t;
    s >> t.k;
    std::string field;
    for (int i = 0; i < 1 + 1 + 6 + 6; ++i) s >> field;  // seq t q0..q5 c0..c5
    s >> t.bits;
    out.push_back(t);
  }
  return out;
}

TEST(BoardSim, SendsTheSharedRigsFramesThroughTheCanPortAndMarksTheTruth) {
  sim::SimOptions o;
  o.faults.push_back(fault(Kind::kWrongDlc, 0.0995, 0.1));
  o.faults.back().every = 10;
  o.faults.push_back(fault(Kind::kCountOffset, 0.2995, 0.0));
  o.faults.back().joint = 1;
  o.faults.back().counts = 1000;
  MemoryCanPort port;
  ASSERT_EQ(port.open(), 0);
  std::FILE* truth = std::tmpfile();
  ASSERT_NE(truth, nullptr);
  exodaq::board_sim::write_truth_header(truth);
  BoardSim board(o, port, truth);
  sim::SimRig reference(o);
  sim::SimBoard::Frames expected{};
  std::size_t sent = 0;
  for (std::int64_t k = 0; k < 500; ++k) {
    board.cycle(k, port.mono - board.rig().sample_offset_ns(k));
    const int n = reference.step(k, expected, 0, 0);
    ASSERT_EQ(port.sent.size(), sent + static_cast<std::size_t>(n)) << k;
    for (int i = 0; i < n; ++i) {
      const auto& a = port.sent[sent + static_cast<std::size_t>(i)];
      const auto& b = expected[static_cast<std::size_t>(i)];
      EXPECT_EQ(a.id, b.id);
      EXPECT_EQ(a.dlc, b.dlc);
      EXPECT_EQ(a.data, b.data);
    }
    sent = port.sent.size();
  }
  const auto lines = read_truth(truth);
  std::fclose(truth);
  ASSERT_EQ(lines.size(), 500U);
  int wrong_dlc = 0;
  for (const TruthLine& t : lines) {
    if ((t.bits & sim::fault_bit(Kind::kWrongDlc)) != 0) {
      ++wrong_dlc;
      EXPECT_EQ((t.k - 100) % 10, 0) << t.k;
    }
    EXPECT_EQ((t.bits & sim::fault_bit(Kind::kCountOffset)) != 0, t.k >= 300) << t.k;
  }
  EXPECT_EQ(wrong_dlc, 10);
  EXPECT_EQ(board.counters().cycles, 500);
  EXPECT_EQ(board.counters().frames, static_cast<std::int64_t>(port.sent.size()));
  EXPECT_EQ(board.counters().send_failures, 0);
  const std::string summary = board.summary();
  EXPECT_NE(summary.find(" wrong_dlc=10 "), std::string::npos) << summary;
  EXPECT_NE(summary.find(" glitch=200 "), std::string::npos) << summary;
}

// A board answering SYNC latches its counts when the SYNC reaches it. Answers
// at irregular instants (every fifth 12 ms late, at 50 Hz) must carry the
// motion of the instant the SYNC was read, go out at that instant, and name
// it in the truth file; counts of k periods would look like a glitch to the
// daemon (docs/simulator.md, "The board simulator").
TEST(BoardSim, AnsweringSyncTakesTheMotionAtTheInstantTheSyncIsRead) {
  sim::SimOptions o;
  o.period_ns = 20'000'000;
  MemoryCanPort port;
  ASSERT_EQ(port.open(), 0);
  std::FILE* truth = std::tmpfile();
  ASSERT_NE(truth, nullptr);
  BoardSim board(o, port, truth);
  sim::SimRig at_instant(o);
  sim::SimRig at_k_periods(o);
  sim::SimBoard::Frames expected{};
  sim::SimBoard::Frames nominal{};
  const std::int64_t origin = port.mono;
  std::vector<std::int64_t> t_ns;
  std::size_t sent = 0;
  int late_and_moved = 0;
  for (std::int64_t k = 0; k < 1000; ++k) {
    const std::int64_t t = k * o.period_ns + (k % 5 == 4 ? 12'000'000 : 0);
    port.mono = origin + t;
    board.cycle_now(k, port.mono, origin);
    t_ns.push_back(t);
    const int n = at_instant.step_at(k, t, expected, origin, 0);
    at_k_periods.step(k, nominal, origin, 0);
    ASSERT_EQ(port.sent.size(), sent + static_cast<std::size_t>(n)) << k;
    bool moved = false;
    for (int i = 0; i < n; ++i) {
      const auto& a = port.sent[sent + static_cast<std::size_t>(i)];
      const auto& b = expected[static_cast<std::size_t>(i)];
      EXPECT_EQ(a.id, b.id) << k;
      EXPECT_EQ(a.data, b.data) << k;
      EXPECT_EQ(b.mono_ns, origin + t) << k;  // sent at once
      moved = moved || a.data != nominal[static_cast<std::size_t>(i)].data;
    }
    if (k % 5 == 4 && moved) ++late_and_moved;
    const auto& position = board.rig().last_cycle().position;
    EXPECT_EQ(position, at_instant.last_cycle().position) << k;
    if (k % 5 !=
        4) {  // on time: the motion of k periods (index latches may differ after a late one)
      EXPECT_EQ(position, at_k_periods.last_cycle().position) << k;
    }
    sent = port.sent.size();
  }
  EXPECT_GT(late_and_moved, 100);  // the rig moves: a late answer has other counts
  std::rewind(truth);
  char line[512];
  std::size_t i = 0;
  while (std::fgets(line, sizeof line, truth) != nullptr) {
    long long k = -1;
    unsigned seq = 0;
    double t_s = -1;
    ASSERT_EQ(std::sscanf(line, "%lld %u %lf", &k, &seq, &t_s), 3) << line;
    ASSERT_LT(i, t_ns.size());
    EXPECT_EQ(k, static_cast<long long>(i));
    EXPECT_NEAR(t_s, static_cast<double>(t_ns[i]) * 1e-9, 1e-9) << k;
    ++i;
  }
  std::fclose(truth);
  EXPECT_EQ(i, t_ns.size());
}

TEST(BoardSim, AFrameThatCannotBeSentIsCountedAndMarked) {
  MemoryCanPort port;
  ASSERT_EQ(port.open(), 0);
  std::FILE* truth = std::tmpfile();
  BoardSim board(sim::SimOptions{}, port, truth);
  board.cycle(0, port.mono);
  port.take_down();
  port.close();
  board.cycle(1, port.mono - board.rig().sample_offset_ns(1));
  const auto lines = read_truth(truth);
  std::fclose(truth);
  ASSERT_EQ(lines.size(), 2U);
  EXPECT_EQ(lines[0].bits & exodaq::board_sim::kSendFailedBit, 0U);
  EXPECT_NE(lines[1].bits & exodaq::board_sim::kSendFailedBit, 0U);
  EXPECT_EQ(board.counters().send_failures, 1);  // the first failure ends the cycle
}

}  // namespace
