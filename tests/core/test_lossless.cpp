// Lossless delivery (issue 15): the threaded loop on a simulated loop clock
// (core::LoopClock) that wakes late on purpose. A free-running board (the sim's
// board_clock, or a board on the in-memory CAN port) keeps sampling while the
// loop is held off; the loop then publishes every sample, once, in order, each
// with its own board sequence and stamp, LATE exactly where it went out more
// than one period after its stamp. As sync master a late SYNC moves the sample
// instant: stamped truthfully, counted.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <thread>
#include <vector>

#include "alloc_counter.hpp"
#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/builder.hpp"
#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/drivers/socketcan_backend.hpp"
#include "exodaq/drivers/socketcan_source.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/settings/service_config.hpp"
#include "memory_can_port.hpp"

using namespace exodaq;

namespace {
constexpr std::int64_t kMs = 1'000'000;
constexpr std::int64_t kT0 = 1000 * 1'000'000'000LL;  // the simulated clock at start
constexpr std::int64_t kWakeLatency = 20'000;         // every wake, 20 µs after its deadline

// A loop clock that only moves when the loop sleeps: each wake comes
// kWakeLatency after its deadline, and the first wake at or after `stall_at`
// comes `stall_ns` later still (a host that held the loop off). Each wake is
// logged with the number of cycles published before it, so a test knows when
// each cycle went out. A short real pause per wake lets the publisher thread
// keep up with a loop that otherwise runs flat out.
class SteppedClock : public core::LoopClock {
 public:
  explicit SteppedClock(std::int64_t start) : now_(start) { wakes.reserve(1 << 16); }
  std::int64_t now_ns() noexcept override { return now_.load(std::memory_order_relaxed); }
  void sleep_until(std::int64_t deadline) noexcept override {
    std::int64_t t = std::max(now_ns(), deadline) + kWakeLatency;
    if (!stalled_ && stall_ns > 0 && t >= stall_at) {
      stalled_ = true;
      t += stall_ns;
    }
    set_now(t);
    if (wakes.size() < wakes.capacity()) wakes.push_back({t, acq != nullptr ? acq->cycles() : 0});
    std::this_thread::sleep_for(std::chrono::microseconds(50));
  }
  std::int64_t stall_at = 0;
  std::int64_t stall_ns = 0;
  const core::Acquisition* acq = nullptr;
  struct Wake {
    std::int64_t at;
    std::int64_t first_seq;  // cycles published before this wake
  };
  std::vector<Wake> wakes;

  // When cycle `seq` went out: the time of the wake that published it.
  std::int64_t published_at(std::int64_t seq) const {
    const auto it = std::upper_bound(wakes.begin(), wakes.end(), seq,
                                     [](std::int64_t s, const Wake& w) { return s < w.first_seq; });
    return it == wakes.begin() ? -1 : std::prev(it)->at;
  }

 protected:
  virtual void set_now(std::int64_t t) { now_.store(t, std::memory_order_relaxed); }

 private:
  std::atomic<std::int64_t> now_;
  bool stalled_ = false;
};

// The same clock driving an in-memory CAN port's clock (its frames arrive on it).
class PortClock final : public SteppedClock {
 public:
  explicit PortClock(test::MemoryCanPort& port) : SteppedClock(port.mono), port_(port) {}
  std::int64_t now_ns() noexcept override { return port_.mono; }
  void sleep_until(std::int64_t deadline) noexcept override {
    SteppedClock::set_now(port_.mono);
    SteppedClock::sleep_until(deadline);
  }

 protected:
  void set_now(std::int64_t t) override {
    SteppedClock::set_now(t);
    port_.advance_to(t);
  }

 private:
  test::MemoryCanPort& port_;
};

class KeepingSink final : public core::MessageSink {
 public:
  std::mutex mutex;
  std::vector<exodaq::joint_state_t> joints;
  std::vector<exodaq::encoder_raw_t> raws;
  bool publish(const std::string&, const core::OutgoingMessage& m) noexcept override {
    try {
      std::lock_guard<std::mutex> lock(mutex);
      if (m.channel == messages::Kind::kJointState) {
        joints.emplace_back();
        joints.back().decode(m.bytes.data(), 0, static_cast<int>(m.size));
      } else if (m.channel == messages::Kind::kEncoderRaw) {
        raws.emplace_back();
        raws.back().decode(m.bytes.data(), 0, static_cast<int>(m.size));
      }
    } catch (...) {
      return false;
    }
    return true;
  }
};

// Counts, allocation-free.
class CountingSink final : public core::MessageSink {
 public:
  std::int64_t messages = 0;
  bool publish(const std::string&, const core::OutgoingMessage&) noexcept override {
    ++messages;
    return true;
  }
};

settings::ServiceConfig sim_config() {
  return settings::load_service_config(std::string(EXODAQ_SOURCE_DIR) + "/config/sim.yaml");
}

struct LoopRun {
  std::unique_ptr<core::Acquisition> acq;
  KeepingSink* sink = nullptr;
};

// Runs the threaded loop until `cycles` cycles are out, then stops it.
LoopRun run_loop(std::unique_ptr<drivers::EncoderSource> source,
                 std::unique_ptr<core::LoopClock> clock, SteppedClock& clock_ref,
                 std::int64_t cycles) {
  LoopRun r;
  auto sink = std::make_unique<KeepingSink>();
  r.sink = sink.get();
  core::AcquisitionOptions wiring;
  wiring.source = std::move(source);
  wiring.sink = std::move(sink);
  wiring.channel_prefix = "";
  wiring.realtime = false;
  wiring.loop_clock = std::move(clock);
  settings::ServiceConfig c = sim_config();
  c.clock.require_sync = core::RequireSync::kIgnore;
  r.acq = core::build_acquisition(c, std::move(wiring));
  clock_ref.acq = r.acq.get();
  r.acq->start();
  while (r.acq->cycles() < cycles) std::this_thread::sleep_for(std::chrono::milliseconds(2));
  r.acq->stop();
  return r;
}

std::unique_ptr<drivers::SimSource> free_running_sim(double drift_ppm, double phase) {
  const settings::ServiceConfig c = sim_config();
  drivers::sim::SimOptions o =
      drivers::sim_options_from(c.source, settings::make_source_context(c));
  o.board_clock.free_running = true;
  o.board_clock.drift_ppm = drift_ppm;
  o.board_clock.phase_ns = static_cast<std::int64_t>(phase * static_cast<double>(kMs));
  return std::make_unique<drivers::SimSource>(o);
}

// What every free-running run must show: seq 0, 1, 2, … without a hole; cycle
// s is board sample s (its board seq, its own sampling instant), present,
// never MISSING; LATE exactly where it went out more than a period after its
// stamp. Returns the number of LATE cycles.
std::int64_t expect_every_board_sample_once(const LoopRun& r, const SteppedClock& clock,
                                            const drivers::sim::SimRig* rig,
                                            std::int64_t start_mono) {
  const auto& js = r.sink->joints;
  const auto& raw = r.sink->raws;
  EXPECT_EQ(r.acq->publisher().ring_drops(), 0);
  EXPECT_EQ(static_cast<std::int64_t>(js.size()), r.acq->cycles());
  EXPECT_EQ(raw.size(), js.size());
  std::int64_t late = 0;
  for (std::size_t i = 0; i < js.size() && i < raw.size(); ++i) {
    const auto s = static_cast<std::int64_t>(i);
    EXPECT_EQ(js[i].seq, s);
    EXPECT_EQ(raw[i].seq, s);
    EXPECT_TRUE(raw[i].present) << s;
    EXPECT_EQ(raw[i].source_seq, s % 256) << s;
    EXPECT_EQ(js[i].sample_flags & joint_state_t::SAMPLE_MISSING, 0) << s;
    if (rig != nullptr) {
      EXPECT_EQ(js[i].mono_ns, start_mono + rig->sample_offset_ns(s)) << s;
    }
    const std::int64_t out_at = clock.published_at(s);
    const bool should_be_late = out_at - js[i].mono_ns > kMs;
    const bool is_late = (js[i].sample_flags & joint_state_t::SAMPLE_LATE) != 0;
    EXPECT_EQ(is_late, should_be_late) << "seq " << s << " out " << out_at - js[i].mono_ns;
    if (i > 0) {
      EXPECT_GT(js[i].mono_ns, js[i - 1].mono_ns) << s;
    }
    late += is_late ? 1 : 0;
  }
  EXPECT_EQ(late, r.acq->late_samples());
  return late;
}

// The sim's free-running board (drift, phase as free_running_sim) and the loop
// held off for `stall_ns` at its first wake `stall_at_ms` in, run for `cycles`
// cycles and checked with expect_every_board_sample_once.
struct SimStall {
  LoopRun run;
  drivers::SimSource* sim = nullptr;
  SteppedClock* clock = nullptr;
  std::int64_t late = 0;  // LATE cycles
};

SimStall run_sim_stall(double drift_ppm, double phase, std::int64_t stall_at_ms,
                       std::int64_t stall_ns, std::int64_t cycles) {
  SimStall s;
  auto src = free_running_sim(drift_ppm, phase);
  s.sim = src.get();
  auto clock = std::make_unique<SteppedClock>(kT0);
  s.clock = clock.get();
  s.clock->stall_at = kT0 + stall_at_ms * kMs;
  s.clock->stall_ns = stall_ns;
  s.run = run_loop(std::move(src), std::move(clock), *s.clock, cycles);
  s.late = expect_every_board_sample_once(s.run, *s.clock, &s.sim->rig(), s.sim->start_mono_ns());
  return s;
}

}  // namespace

// The loop held off for 1, 5 and 50 ms while a free-running board (the sim's
// own clock, in step with the loop's deadlines) keeps sampling: the wake after
// the stall publishes the stall's samples, oldest first; nothing superseded,
// nothing missing, no seq hole, and exactly the samples published more than a
// period after their instant are LATE: 1, 5 and 50 of them.
TEST(Lossless, AFreeRunningBoardsSamplesAreAllPublishedAfterALoopStall) {
  for (const std::int64_t stall_ms : {1, 5, 50}) {
    SCOPED_TRACE(stall_ms);
    const SimStall s = run_sim_stall(0.0, 0.0, 300, stall_ms * kMs, 800);
    // The stall's wake comes stall + 20 µs after its deadline: its own sample
    // and the stall_ms the board took meanwhile are waiting; all but the
    // newest are more than a period old.
    std::printf(
        "LOSSLESS sim stall %lld ms: %lld cycles, %lld caught up in one wake, %lld LATE, %lld "
        "overruns, superseded %lld, missing %lld\n",
        static_cast<long long>(stall_ms), static_cast<long long>(s.run.acq->cycles()),
        static_cast<long long>(s.run.acq->caught_up_samples()), static_cast<long long>(s.late),
        static_cast<long long>(s.run.acq->overruns()),
        static_cast<long long>(s.sim->stats().superseded_samples),
        static_cast<long long>(s.sim->stats().missing_samples));
    EXPECT_EQ(s.late, stall_ms);
    EXPECT_EQ(s.run.acq->caught_up_samples(), stall_ms);
    EXPECT_EQ(s.run.acq->backlog_wakes(), 0);
    EXPECT_GE(s.run.acq->overruns(), 1);
    EXPECT_EQ(s.sim->stats().superseded_samples, 0);
    EXPECT_EQ(s.sim->stats().missing_samples, 0);
    EXPECT_EQ(s.sim->stats().seq_gaps, 0);
  }
}

// A stall longer than the catch-up bound (64 samples per wake): 200 ms of
// samples come out over the following wakes, bounded per wake, still every one
// of them once and in order, and the wakes that left a backlog are counted.
TEST(Lossless, ABacklogBeyondTheCatchUpBoundIsCarriedToTheNextWakes) {
  const SimStall s = run_sim_stall(0.0, 0.0, 300, 200 * kMs, 900);
  std::printf(
      "LOSSLESS sim stall 200 ms: %lld cycles, %lld caught up, %lld wakes left a backlog, %lld "
      "LATE, superseded %lld, missing %lld\n",
      static_cast<long long>(s.run.acq->cycles()),
      static_cast<long long>(s.run.acq->caught_up_samples()),
      static_cast<long long>(s.run.acq->backlog_wakes()), static_cast<long long>(s.late),
      static_cast<long long>(s.sim->stats().superseded_samples),
      static_cast<long long>(s.sim->stats().missing_samples));
  EXPECT_GE(s.late, 200);
  // 201 samples at 64 a wake: the stall's wake and 3 more.
  EXPECT_GE(s.run.acq->backlog_wakes(), 3);
  EXPECT_EQ(s.sim->stats().superseded_samples, 0);
  EXPECT_EQ(s.sim->stats().missing_samples, 0);
}

// A board whose clock runs 500 ppm slow or fast against the loop's, a third of
// a period out of phase, with a 5 ms stall: the slow one leaves a wake now and
// then with nothing due (nothing published, no MISSING), the fast one a wake
// with two samples; either way every sample once, in order, nothing lost.
TEST(Lossless, ADriftingBoardClockLosesNothingAndInventsNothing) {
  for (const double drift : {500.0, -500.0}) {
    SCOPED_TRACE(drift);
    // The stall's samples went out late (the slow board's lag behind the loop
    // leaves four of them over a period old, the fast board's five or more).
    const SimStall s = run_sim_stall(drift, 0.3, 1500, 5 * kMs, 3500);
    EXPECT_GE(s.late, 4);
    EXPECT_EQ(s.sim->stats().superseded_samples, 0);
    EXPECT_EQ(s.sim->stats().missing_samples, 0);
    EXPECT_EQ(s.sim->stats().seq_gaps, 0);
    std::printf(
        "LOSSLESS sim drift %+.0f ppm, stall 5 ms: %lld cycles in %zu wakes, %lld caught "
        "up, %lld LATE, superseded %lld, missing %lld\n",
        drift, static_cast<long long>(s.run.acq->cycles()), s.clock->wakes.size(),
        static_cast<long long>(s.run.acq->caught_up_samples()), static_cast<long long>(s.late),
        static_cast<long long>(s.sim->stats().superseded_samples),
        static_cast<long long>(s.sim->stats().missing_samples));
    // 3500 samples at 500 ppm: the phase slips by 1.75 periods, so some wake
    // went without a sample (slow) or with two (fast, beyond the stall's five).
    std::int64_t empty_wakes = 0;
    for (std::size_t w = 0; w + 1 < s.clock->wakes.size(); ++w)
      empty_wakes += s.clock->wakes[w + 1].first_seq == s.clock->wakes[w].first_seq ? 1 : 0;
    if (drift > 0) {
      EXPECT_GE(empty_wakes, 1);
      EXPECT_EQ(s.run.acq->caught_up_samples(), s.late);  // only the stall's wake had more than one
    } else {
      EXPECT_EQ(empty_wakes, 0);
      EXPECT_GT(s.run.acq->caught_up_samples(), 5);
    }
  }
}

// The catch-up path allocates nothing: wakes driven by hand on a free-running
// sim board, every 250th of them 30 ms late (31 samples in one wake).
TEST(Lossless, CatchingUpAllocatesNothing) {
  auto src = free_running_sim(0.0, 0.0);
  drivers::SimSource* sim = src.get();
  core::AcquisitionOptions wiring;
  wiring.source = std::move(src);
  wiring.sink = std::make_unique<CountingSink>();
  wiring.realtime = false;
  auto acq = core::build_acquisition(sim_config(), std::move(wiring));
  acq->prepare_for_manual_cycles();
  acq->run_cycle(kT0, kT0 + kWakeLatency);  // the first wake outside the scope
  acq->publisher().drain();
  std::int64_t k = 1;
  {
    test::AllocationScope scope;
    for (int wake = 1; wake < 3000; ++wake, ++k) {
      const bool late = wake % 250 == 0;
      acq->run_cycle(kT0 + k * kMs, kT0 + k * kMs + (late ? 30 * kMs : kWakeLatency));
      if (late) k += 30;  // the deadlines it overran are skipped
      acq->publisher().drain();
    }
    EXPECT_EQ(scope.count(), 0U);
  }
  EXPECT_EQ(acq->caught_up_samples(), 11 * 30);
  // Of the 31 samples of a wake 30 ms late, the newest two are not over a
  // period old (0 and exactly 1 ms): 29 LATE.
  EXPECT_EQ(acq->late_samples(), 11 * 29);
  EXPECT_EQ(acq->cycles(), k);  // one cycle per board sample, none skipped
  EXPECT_EQ(sim->stats().superseded_samples, 0);
}

namespace {

// A board on the in-memory port: answers each SYNC with the simulated rig's
// next cycle (COUNTS_A 100 µs, COUNTS_B 150 µs after it), or, free-running,
// has its frames put on the port in advance at its own instants.
struct PortBoard {
  explicit PortBoard(test::MemoryCanPort& port) : rig(drivers::sim::SimOptions{}) {
    port.on_send = [this](const drivers::can::CanFrame& f, test::MemoryCanPort& p) {
      if (f.id != 0x080) return;
      sync_at.push_back(p.mono);
      const int n = rig.step(next++, frames, 0, 0);
      for (int i = 0; i < n; ++i) {
        const auto& fr = frames[static_cast<std::size_t>(i)];
        p.push(fr, p.mono + (fr.id == 0x182 ? 150'000 : 100'000));
      }
    };
    sync_at.reserve(1 << 16);
  }
  void free_run(test::MemoryCanPort& port, std::int64_t first, std::int64_t cycles) {
    port.on_send = nullptr;
    for (std::int64_t k = 0; k < cycles; ++k) {
      const int n = rig.step(k, frames, 0, 0);
      for (int i = 0; i < n; ++i) {
        port.push(frames[static_cast<std::size_t>(i)], first + k * kMs + 200'000 + i * 1000);
      }
    }
  }
  drivers::sim::SimRig rig;
  drivers::sim::SimBoard::Frames frames{};
  std::int64_t next = 0;
  std::vector<std::int64_t> sync_at;
};

std::unique_ptr<drivers::SocketCanSource> port_source(std::unique_ptr<test::MemoryCanPort> port,
                                                      bool sync_master) {
  drivers::SocketCanSettings s;
  s.interface = "vcan0";
  s.sync_master = sync_master;
  return std::make_unique<drivers::SocketCanSource>(
      drivers::socketcan_config_from(s, drivers::SourceContext{}), std::move(port));
}

}  // namespace

// Sync master: the loop wakes 3.3 ms late, so the SYNC leaves late and the
// board samples then. The sample is stamped with the true instant (the
// receive stamp of its COUNTS_B, 150 µs after that SYNC), not the missed
// deadline; the late SYNC is counted; the deadlines skipped are counted seq
// holes, as always as sync master; nothing is LATE or MISSING.
TEST(Lossless, AsSyncMasterALateSyncIsStampedAtTheTrueInstantAndCounted) {
  auto p = std::make_unique<test::MemoryCanPort>();
  test::MemoryCanPort* port = p.get();
  PortBoard board(*port);
  auto clock = std::make_unique<PortClock>(*port);
  PortClock* c = clock.get();
  const std::int64_t start = port->mono;
  c->stall_at = start + 200 * kMs;
  c->stall_ns = 3'300'000;
  auto src = port_source(std::move(p), true);
  drivers::SocketCanSource* can = src.get();
  const LoopRun r = run_loop(std::move(src), std::move(clock), *c, 400);

  const auto& js = r.sink->joints;
  const auto& raw = r.sink->raws;
  ASSERT_EQ(js.size(), raw.size());
  std::int64_t holes = 0;
  int stamped_late = 0;
  for (std::size_t i = 0; i < js.size(); ++i) {
    EXPECT_TRUE(raw[i].present) << js[i].seq;
    const std::int32_t missing_or_late =
        std::int32_t{joint_state_t::SAMPLE_MISSING} | joint_state_t::SAMPLE_LATE;
    EXPECT_EQ(js[i].sample_flags & missing_or_late, 0) << js[i].seq;
    // Every sample: 150 µs after the SYNC that asked for it (i-th SYNC, i-th sample).
    ASSERT_LT(i, board.sync_at.size());
    EXPECT_EQ(js[i].mono_ns, board.sync_at[i] + 150'000) << js[i].seq;
    EXPECT_EQ(raw[i].wall_ns, board.sync_at[i] + 150'000 + test::MemoryCanPort::kWallOffsetNs);
    if (i > 0) holes += js[i].seq - js[i - 1].seq - 1;
    // The deadline of its seq is start + (seq + 1) * period (the first deadline is a period in).
    const std::int64_t deadline = start + (js[i].seq + 1) * kMs;
    if (board.sync_at[i] - deadline > kMs / 10) ++stamped_late;
  }
  std::printf(
      "LOSSLESS sync master, a wake 3.3 ms late: late SYNCs %lld, overruns %lld, seq holes %lld, "
      "missing %lld, superseded %lld\n",
      static_cast<long long>(can->detail().late_syncs), static_cast<long long>(r.acq->overruns()),
      static_cast<long long>(holes), static_cast<long long>(can->stats().missing_samples),
      static_cast<long long>(can->detail().superseded_samples));
  EXPECT_EQ(stamped_late, 1);
  EXPECT_EQ(can->detail().late_syncs, 1);
  EXPECT_EQ(can->stats().late_syncs, 1);  // what the daemon reports
  EXPECT_EQ(can->detail().superseded_samples, 0);
  EXPECT_EQ(can->stats().missing_samples, 0);
  // 3.3 ms late + 150 µs waiting for the answer: deadlines +1 .. +3 skipped.
  EXPECT_EQ(r.acq->overruns(), 3);
  EXPECT_EQ(holes, 3);
}

// Following a free-running board on the in-memory port, the loop held off for
// 50 ms: the socket holds the frames, the loop publishes every cycle once, in
// order, LATE where it went out over a period after its receive stamp.
TEST(Lossless, FollowingAFreeRunningBoardOnSocketCanAStallLosesNothing) {
  auto p = std::make_unique<test::MemoryCanPort>();
  test::MemoryCanPort* port = p.get();
  PortBoard board(*port);
  const std::int64_t start = port->mono;
  // The board's cycle k: its frames arrive 200 µs after the loop's deadline k.
  board.free_run(*port, start + kMs, 1200);
  auto clock = std::make_unique<PortClock>(*port);
  PortClock* c = clock.get();
  c->stall_at = start + 300 * kMs;
  c->stall_ns = 50 * kMs;
  auto src = port_source(std::move(p), false);
  drivers::SocketCanSource* can = src.get();
  const LoopRun r = run_loop(std::move(src), std::move(clock), *c, 1000);
  const std::int64_t late = expect_every_board_sample_once(r, *c, nullptr, 0);
  for (std::size_t i = 0; i < r.sink->joints.size(); ++i) {
    // Stamped when COUNTS_B (the second frame after the INDEX frames) arrived.
    const std::int64_t k = static_cast<std::int64_t>(i);
    EXPECT_GE(r.sink->joints[i].mono_ns, start + (k + 1) * kMs + 201'000);
    EXPECT_LE(r.sink->joints[i].mono_ns, start + (k + 1) * kMs + 210'000);
  }
  // Cycles arrive 0.2 ms into their period: of the 50 waiting after the
  // stall, the newest is 0.8 ms old, the other 49 over a period.
  std::printf(
      "LOSSLESS socketcan free-running, stall 50 ms: %lld cycles, %lld caught up, %lld LATE, "
      "superseded %lld, missing %lld, queue overflows %lld\n",
      static_cast<long long>(r.acq->cycles()), static_cast<long long>(r.acq->caught_up_samples()),
      static_cast<long long>(late), static_cast<long long>(can->stats().superseded_samples),
      static_cast<long long>(can->stats().missing_samples),
      static_cast<long long>(can->decoder().detail().queue_overflows));
  EXPECT_EQ(late, 49);
  EXPECT_EQ(can->detail().superseded_samples, 0);
  EXPECT_EQ(can->stats().superseded_samples, 0);
  EXPECT_EQ(can->stats().missing_samples, 0);
  EXPECT_EQ(can->stats().seq_gaps, 0);
  EXPECT_EQ(can->decoder().detail().queue_overflows, 0);
}
