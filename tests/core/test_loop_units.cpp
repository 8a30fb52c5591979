// The loop's parts on their own: the time bases, the state machine's
// hysteresis, the message encoder, the status assembler, the event ring and
// the reload hand-over. Each allocates nothing where the loop calls it.
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "alloc_counter.hpp"
#include "exodaq/core/builder.hpp"
#include "exodaq/core/config_handover.hpp"
#include "exodaq/core/health.hpp"
#include "exodaq/core/loop_events.hpp"
#include "exodaq/core/message_encoder.hpp"
#include "exodaq/core/status_assembler.hpp"
#include "exodaq/core/time_base.hpp"
#include "exodaq/settings/service_config.hpp"

using namespace exodaq;
namespace flag = drivers::sample_flag;

namespace {
constexpr std::int64_t kMs = 1'000'000;

settings::ServiceConfig sim_config() {
  return settings::load_service_config(std::string(EXODAQ_SOURCE_DIR) + "/config/sim.yaml");
}

// A source that only carries a recording's speed and seq.
class Recording final : public drivers::EncoderSource {
 public:
  std::optional<double> speed = 1.0;
  std::int64_t seq = -1;
  std::string_view name() const noexcept override { return "recording"; }
  void start() override {}
  drivers::ReadStatus read(const drivers::CycleTime&, drivers::EncoderSample&) noexcept override {
    return drivers::ReadStatus::kEndOfStream;
  }
  std::optional<double> recording_speed() const noexcept override { return speed; }
  std::int64_t recorded_seq() const noexcept override { return seq; }
  drivers::SourceStats stats() const noexcept override { return {}; }
};

class Live final : public drivers::EncoderSource {
 public:
  std::string_view name() const noexcept override { return "live"; }
  void start() override {}
  drivers::ReadStatus read(const drivers::CycleTime&, drivers::EncoderSample&) noexcept override {
    return drivers::ReadStatus::kNoSample;
  }
  drivers::SourceStats stats() const noexcept override { return {}; }
};

// Keeps every message handed over, in order.
class KeepingSink final : public core::MessageSink {
 public:
  std::vector<core::OutgoingMessage> kept;
  bool publish(const std::string&, const core::OutgoingMessage& m) noexcept override {
    kept.push_back(m);
    return true;
  }
};

template <typename Msg>
Msg decode(const core::OutgoingMessage& m) {
  Msg out;
  EXPECT_GT(out.decode(m.bytes.data(), 0, static_cast<int>(m.size)), 0);
  return out;
}

core::WindowFacts clean_window() {
  core::WindowFacts f;
  f.cycles = 100;
  f.samples_present = 100;
  f.valid_poses = 100;
  f.all_homed = true;
  return f;
}
}  // namespace

TEST(TimeBase, TheSourceChoosesLiveOrRecordedTime) {
  core::ClockShared clock;
  Live live;
  Recording recording;
  const auto loop_clock = core::make_monotonic_loop_clock();
  EXPECT_FALSE(core::make_time_base(live, clock, {}, kMs, *loop_clock)->recorded());
  EXPECT_TRUE(core::make_time_base(recording, clock, {}, kMs, *loop_clock)->recorded());
}

TEST(TimeBase, LiveSkipsTheDeadlinesACycleOverran) {
  core::ClockShared clock;
  const auto loop_clock = core::make_monotonic_loop_clock();
  core::LiveTimeBase live(clock, {}, kMs, *loop_clock);
  const std::int64_t next = 50 * kMs;
  EXPECT_EQ(live.overrun(next - 1, next), 0);
  EXPECT_EQ(live.overrun(next, next), 0);
  EXPECT_EQ(live.overrun(next + 1, next), 1);
  EXPECT_EQ(live.overrun(next + kMs, next), 2);
  EXPECT_EQ(live.overrun(next + 5 * kMs / 2, next), 3);
  EXPECT_EQ(live.seq(41), 41);
}

TEST(TimeBase, LiveStampsWallTimeAndFlagsAnUnsynchronisedClockByPolicy) {
  core::ClockShared clock;
  clock.offset_ns = 1'700'000'000'000'000'000LL;
  clock.offset_generation = 1;
  clock.synchronised = false;
  settings::ClockPolicy policy;
  policy.require_sync = settings::RequireSync::kMark;
  const auto loop_clock = core::make_monotonic_loop_clock();
  core::LiveTimeBase live(clock, policy, kMs, *loop_clock);
  drivers::EncoderSample s;
  s.mono_ns = 5'000 * kMs + 123'456;
  core::SampleTime t = live.stamp(s);
  EXPECT_EQ(t.utime_us, (s.mono_ns + clock.offset_ns) / 1000);
  EXPECT_EQ(t.flags, flag::kClockUnsync);
  EXPECT_FALSE(t.clock_invalid);
  EXPECT_FALSE(t.clock_hold);
  policy.require_sync = settings::RequireSync::kHold;
  live.set_policy(policy);
  s.mono_ns += kMs;
  t = live.stamp(s);
  EXPECT_EQ(t.flags, flag::kClockUnsync);
  EXPECT_TRUE(t.clock_invalid);
  EXPECT_TRUE(t.clock_hold);
  policy.require_sync = settings::RequireSync::kIgnore;
  live.set_policy(policy);
  s.mono_ns += kMs;
  t = live.stamp(s);
  EXPECT_EQ(t.flags, 0U);
  EXPECT_FALSE(t.clock_invalid);
  // A 1 s step of the wall clock: detected once, flagged while it is slewed out.
  clock.offset_ns = clock.offset_ns + 1'000'000'000;
  clock.offset_generation = 2;
  s.mono_ns += kMs;
  t = live.stamp(s);
  EXPECT_TRUE(t.new_step);
  EXPECT_EQ(t.flags, flag::kClockStep);
  EXPECT_TRUE(t.clock_invalid);
  EXPECT_EQ(live.clock_steps(), 1);
  EXPECT_LT(live.utime_correction_ns(), -900'000'000);
  s.mono_ns += kMs;
  t = live.stamp(s);
  EXPECT_FALSE(t.new_step);
  EXPECT_EQ(t.flags, flag::kClockStep);
}

TEST(TimeBase, RecordedKeepsTheRecordingsTimeSeqAndClockVerdict) {
  Recording recording;
  settings::ClockPolicy policy;
  policy.require_sync = settings::RequireSync::kMark;
  const auto loop_clock = core::make_monotonic_loop_clock();
  core::RecordedTimeBase recorded(recording, 0.0, policy, *loop_clock);
  EXPECT_EQ(recorded.seq(7), 7);  // no recorded seq: the loop's count
  recording.seq = 1234;
  EXPECT_EQ(recorded.seq(7), 1234);
  EXPECT_EQ(recorded.overrun(100 * kMs, kMs), 0);  // a recording never skips

  drivers::EncoderSample s;
  s.mono_ns = 42;
  s.wall_ns = 1'700'000'000'123'456'789LL;
  core::SampleTime t = recorded.stamp(s);
  EXPECT_EQ(t.utime_us, 1'700'000'000'123'456LL);
  EXPECT_EQ(t.flags, flag::kReplay);
  EXPECT_FALSE(t.clock_invalid);
  s.flags = flag::kClockStep;
  EXPECT_TRUE(recorded.stamp(s).clock_invalid);
  s.flags = flag::kClockUnsync;
  EXPECT_FALSE(recorded.stamp(s).clock_invalid);
  policy.require_sync = settings::RequireSync::kHold;
  recorded.set_policy(policy);
  EXPECT_TRUE(recorded.stamp(s).clock_invalid);
  EXPECT_FALSE(recorded.stamp(s).clock_hold);
  EXPECT_EQ(recorded.clock_steps(), 0);
  EXPECT_EQ(recorded.utime_correction_ns(), 0);
}

TEST(ServiceStateMachine, DegradedRecoversOnlyAfterTenCleanWindows) {
  core::ServiceStateMachine machine({});
  using S = core::ServiceState;
  S s = machine.next(S::kHoming, clean_window(), 0);
  EXPECT_EQ(s, S::kRunning);
  core::WindowFacts dirty = clean_window();
  dirty.overruns = 1;
  s = machine.next(s, dirty, 0);
  EXPECT_EQ(s, S::kDegraded);
  for (int i = 1; i < 10; ++i) {
    s = machine.next(s, clean_window(), 0);
    ASSERT_EQ(s, S::kDegraded) << "clean window " << i;
  }
  EXPECT_EQ(machine.next(s, clean_window(), 0), S::kRunning);
  EXPECT_EQ(machine.next(S::kStopping, dirty, 10'000), S::kStopping);
}

TEST(ServiceStateMachine, ARecordingsWindowWithSamplesIsNeverAFault) {
  core::WindowFacts bus_off = clean_window();
  bus_off.bus_state = drivers::BusState::kOff;
  core::ServiceStateMachine live({});
  EXPECT_EQ(live.next(core::ServiceState::kRunning, bus_off, 0), core::ServiceState::kFault);
  core::ServiceStateMachine recorded({.hold_fault_while_samples = true});
  EXPECT_EQ(recorded.next(core::ServiceState::kRunning, bus_off, 0), core::ServiceState::kRunning);
  bus_off.samples_present = 0;
  EXPECT_EQ(recorded.next(core::ServiceState::kRunning, bus_off, 0), core::ServiceState::kFault);
}

TEST(ServiceStateMachine, AForeignRunDegradesEvenWhileHomingButNotAFault) {
  using S = core::ServiceState;
  core::WindowFacts foreign = clean_window();
  foreign.sample_flags_or |= drivers::sample_flag::kForeignRun;
  EXPECT_EQ(core::next_state(S::kRunning, foreign, 0, 500), S::kDegraded);
  foreign.all_homed = false;
  EXPECT_EQ(core::next_state(S::kHoming, foreign, 0, 500), S::kDegraded);
  EXPECT_EQ(core::next_state(S::kStarting, foreign, 0, 500), S::kDegraded);
  EXPECT_EQ(core::next_state(S::kHoming, foreign, 501, 500), S::kFault);
  EXPECT_EQ(core::next_state(S::kStopping, foreign, 0, 500), S::kStopping);
}

// Every degraded or fault state carries its reason, with the value that
// crossed and the threshold; the window's other reasons ride along.
TEST(ServiceStateMachine, EveryDegradedOrFaultStateCarriesItsReasonAndThreshold) {
  using S = core::ServiceState;
  using R = core::StateReason;
  const auto bit = [](R r) { return 1U << static_cast<unsigned>(r); };
  core::WindowFacts f = clean_window();
  EXPECT_EQ(core::judge(S::kRunning, f, 0, 500).cause.reason, R::kNone);
  f.overruns = 60;
  f.publish_failures = 2;
  core::Verdict v = core::judge(S::kRunning, f, 0, 500);
  EXPECT_EQ(v.state, S::kDegraded);
  EXPECT_EQ(v.cause.reason, R::kOverruns);
  EXPECT_EQ(v.cause.value, 60);
  EXPECT_EQ(v.cause.threshold, 0);
  EXPECT_EQ(v.cause.also, bit(R::kPublishFailures));
  // The overrun comes first: the seq gaps and stale joints follow from it.
  f.joint_flags_or[4] = core::joint_flag::kStale | core::joint_flag::kHeld;
  f.joint_flags_or[5] = core::joint_flag::kGlitch;
  f.sample_flags_or = flag::kSeqGap | flag::kLate;
  v = core::judge(S::kRunning, f, 0, 500);
  EXPECT_EQ(v.cause.reason, R::kOverruns);
  EXPECT_EQ(v.cause.also, bit(R::kJointFault) | bit(R::kSampleFlags) | bit(R::kPublishFailures));
  // Without it, the joint fault names the first joint with one.
  f.overruns = 0;
  v = core::judge(S::kRunning, f, 0, 500);
  EXPECT_EQ(v.cause.reason, R::kJointFault);
  EXPECT_EQ(v.cause.joint, 4);
  EXPECT_EQ(v.cause.flags, core::joint_flag::kStale | core::joint_flag::kHeld);
  EXPECT_EQ(v.cause.value, 2);  // joints with a fault
  f = clean_window();
  f.sample_flags_or = flag::kMissing | flag::kLate;  // LATE alone does not degrade
  v = core::judge(S::kRunning, f, 0, 500);
  EXPECT_EQ(v.cause.reason, R::kSampleFlags);
  EXPECT_EQ(v.cause.flags, flag::kMissing);
  f = clean_window();
  f.clock_hold = true;
  EXPECT_EQ(core::judge(S::kRunning, f, 0, 500).cause.reason, R::kClockHold);
  v = core::judge(S::kRunning, clean_window(), 612, 500);
  EXPECT_EQ(v.state, S::kFault);
  EXPECT_EQ(v.cause.reason, R::kNoSamples);
  EXPECT_EQ(v.cause.value, 612);
  EXPECT_EQ(v.cause.threshold, 500);
  f = clean_window();
  f.bus_state = drivers::BusState::kOff;
  v = core::judge(S::kRunning, f, 0, 500);
  EXPECT_EQ(v.cause.reason, R::kBusDown);
  EXPECT_EQ(v.cause.value, static_cast<std::int64_t>(drivers::BusState::kOff));
  f = clean_window();
  f.all_homed = false;  // homing: the homed count says it
  v = core::judge(S::kRunning, f, 0, 500);
  EXPECT_EQ(v.state, S::kHoming);
  EXPECT_EQ(v.cause.reason, R::kNone);
}

// Held in degraded by the hysteresis, the state says it is recovering, how
// far, and from what.
TEST(ServiceStateMachine, AHeldDegradedStateSaysItIsRecoveringAndFromWhat) {
  using S = core::ServiceState;
  core::ServiceStateMachine machine({});
  core::WindowFacts dirty = clean_window();
  dirty.overruns = 4;
  S s = machine.next(S::kRunning, dirty, 0);
  ASSERT_EQ(s, S::kDegraded);
  EXPECT_EQ(machine.cause().reason, core::StateReason::kOverruns);
  for (int i = 1; i <= 3; ++i) s = machine.next(s, clean_window(), 0);
  ASSERT_EQ(s, S::kDegraded);
  EXPECT_EQ(machine.cause().reason, core::StateReason::kRecovering);
  EXPECT_EQ(machine.cause().value, 3);
  EXPECT_EQ(machine.cause().threshold, 10);
  EXPECT_EQ(machine.cause().was, core::StateReason::kOverruns);
}

// The cause for people, with flags by name; allocation-free (the loop writes it).
TEST(StateCause, IsDescribedWithItsThresholdAndFlagNamesWithoutAllocating) {
  using R = core::StateReason;
  const auto cause = [](R r, std::int64_t value, std::int64_t threshold) {
    core::StateCause c;
    c.reason = r;
    c.value = value;
    c.threshold = threshold;
    c.window_ns = 100 * kMs;
    return c;
  };
  core::StateCause overruns = cause(R::kOverruns, 60, 0);
  overruns.also = 1U << static_cast<unsigned>(R::kPublishFailures);
  core::StateCause joint = cause(R::kJointFault, 2, 0);
  joint.joint = 4;
  joint.flags = core::joint_flag::kStale | core::joint_flag::kHeld;
  core::StateCause samples = cause(R::kSampleFlags, 0, 0);
  samples.flags = flag::kMissing | flag::kSeqGap;
  core::StateCause recovering = cause(R::kRecovering, 3, 10);
  recovering.was = R::kOverruns;
  core::StateCause bus = cause(R::kBusDown, static_cast<std::int64_t>(drivers::BusState::kOff), 0);
  const std::pair<core::StateCause, std::string> expected[] = {
      {overruns,
       "60 overruns in the last 0.1 s window (threshold: more than 0) (also PUBLISH_FAILURES)"},
      {joint,
       "joint elbow_flexion STALE|HELD and 1 more joint(s) in the last 0.1 s window (threshold: "
       "any fault flag)"},
      {samples, "samples flagged MISSING|SEQ_GAP in the last 0.1 s window (threshold: any)"},
      {cause(R::kPublishFailures, 7, 0),
       "7 messages not published in the last 0.1 s window (threshold: more than 0)"},
      {cause(R::kOverruns, 1, 0), "1 overrun in the last 0.1 s window (threshold: more than 0)"},
      {cause(R::kNoSamples, 612, 500), "no sample for 612 ms (threshold 500 ms)"},
      {bus, "bus OFF: no frame can arrive"},
      {cause(R::kForeignRun, 0, 0),
       "another run publishes on these channels (threshold: any status heard)"},
      {cause(R::kClockHold, 0, 0), "clock unsynchronised under clock.require_sync: hold"},
      {recovering, "recovering from OVERRUNS: 3 of 10 clean windows in a row"},
      {cause(R::kNone, 0, 0), ""},
  };
  for (const auto& [c, text] : expected) {
    char out[256];
    std::size_t n = 0;
    {
      test::AllocationScope scope;
      n = core::describe_cause(c, "elbow_flexion", out, sizeof out);
      EXPECT_EQ(scope.count(), 0u);
    }
    EXPECT_EQ(std::string(out), text);
    EXPECT_EQ(n, text.size());
  }
  char small[16];
  EXPECT_EQ(core::describe_cause(overruns, "", small, sizeof small), 15u);
  EXPECT_EQ(std::string(small), "60 overruns in ");
  EXPECT_EQ(core::reason_name(R::kJointFault), "JOINT_FAULT");
}

TEST(MessageEncoder, PalmFirstThenJointsThenRawAllocatingNothing) {
  const auto cfg = sim_config();
  const auto acq_config = core::make_acquisition_config(cfg);
  auto sink = std::make_unique<KeepingSink>();
  KeepingSink* kept = sink.get();
  core::Publisher publisher(std::move(sink), "P_");
  for (const bool raw : {true, false}) {
    core::MessageEncoder encoder(acq_config.joint_names, 77, raw);
    encoder.warm_up();
    core::CycleResult r;
    r.seq = 9;
    r.mono_ns = 123 * kMs;
    r.utime_us = 1'700'000'000'000'000LL;
    r.valid = true;
    r.pose.palm_position = {0.1, 0.2, 0.3};
    r.joints[2].position_rad = 0.5;
    r.joints[2].flags = core::joint_flag::kStale;
    drivers::EncoderSample sample;
    sample.present = true;
    sample.position[4] = 4321;
    kept->kept.clear();
    kept->kept.reserve(8);
    {
      test::AllocationScope scope;
      encoder.publish(r, sample, publisher);
      EXPECT_EQ(scope.count(), 0u);
    }
    publisher.drain();
    ASSERT_EQ(kept->kept.size(), raw ? 3U : 2U);
    EXPECT_EQ(kept->kept[0].channel, messages::Kind::kPalmPose);
    EXPECT_EQ(kept->kept[1].channel, messages::Kind::kJointState);
    const auto palm = decode<exodaq::palm_pose_t>(kept->kept[0]);
    EXPECT_EQ(palm.seq, 9);
    EXPECT_EQ(palm.run_id, 77);
    EXPECT_TRUE(palm.valid);
    EXPECT_DOUBLE_EQ(palm.position[2], 0.3);
    const auto js = decode<exodaq::joint_state_t>(kept->kept[1]);
    EXPECT_EQ(js.utime, r.utime_us);
    EXPECT_EQ(js.mono_ns, r.mono_ns);
    EXPECT_EQ(js.name[2], acq_config.joint_names[2]);
    EXPECT_DOUBLE_EQ(js.position[2], 0.5);
    EXPECT_EQ(js.flags[2], static_cast<std::int32_t>(core::joint_flag::kStale));
    for (const auto& m : kept->kept) EXPECT_EQ(m.utime_us, r.utime_us);
    if (raw) {
      EXPECT_EQ(kept->kept[2].channel, messages::Kind::kEncoderRaw);
      const auto er = decode<exodaq::encoder_raw_t>(kept->kept[2]);
      EXPECT_EQ(er.seq, 9);
      EXPECT_EQ(er.position[4], 4321);
    }
  }
}

TEST(StatusAssembler, AWindowBecomesAStatusAndTheNextWindowStartsEmpty) {
  const auto cfg = sim_config();
  const auto pipeline_config = core::make_pipeline_config(cfg);
  const core::Pipeline pipeline(*pipeline_config);
  core::ClockShared clock;
  clock.synchronised = true;
  clock.est_error_us = 12.5;
  core::StatusSettings settings;
  settings.rig = "rig-a";
  settings.source = "src";
  settings.joint_names = core::make_acquisition_config(cfg).joint_names;
  settings.run_id = 5;
  core::StatusAssembler status(settings, pipeline, clock);
  status.warm_up();
  core::CycleResult r;
  r.joints[1].flags = core::joint_flag::kGlitch;
  core::WindowEnd end;
  end.now_mono_ns = 1000 * kMs;
  end.seq = 99;
  end.utime_us = 77;
  end.overruns = 3;
  end.cycles = 100;
  end.source.missing_samples = 4;
  end.utime_correction_ns = 2500;
  end.clock_steps = 1;
  {
    test::AllocationScope scope;
    for (int k = 0; k < 100; ++k) {
      const std::int64_t deadline = 900 * kMs + k * kMs;
      status.count_cycle(r, k % 10 != 0, false, deadline, deadline + 20'000);
      status.count_work(7'000);
    }
    EXPECT_EQ(status.close_window(core::ServiceState::kStarting, end), core::ServiceState::kHoming);
    EXPECT_EQ(scope.count(), 0u);
  }
  const exodaq::status_t& s = status.message();
  EXPECT_EQ(s.rig, "rig-a");
  EXPECT_EQ(s.source, "src");
  EXPECT_EQ(s.run_id, 5);
  EXPECT_EQ(s.seq, 99);
  EXPECT_EQ(s.utime, 77);
  EXPECT_EQ(s.window_cycles, 100);
  EXPECT_EQ(s.state, static_cast<std::int8_t>(core::ServiceState::kHoming));
  EXPECT_DOUBLE_EQ(s.lateness_p50_us, 20.0);
  EXPECT_DOUBLE_EQ(s.period_p50_us, 1000.0);
  EXPECT_DOUBLE_EQ(s.work_max_us, 7.0);
  EXPECT_EQ(s.overruns, 3);
  EXPECT_EQ(s.missing_samples, 4);
  EXPECT_TRUE(s.clock_synchronised);
  EXPECT_DOUBLE_EQ(s.clock_est_error_us, 12.5);
  EXPECT_DOUBLE_EQ(s.utime_correction_us, 2.5);
  EXPECT_EQ(s.clock_steps, 1);
  EXPECT_EQ(s.joint_flags[1], static_cast<std::int32_t>(core::joint_flag::kGlitch));
  EXPECT_EQ(s.message, "HOMING: 0/6 homed, 0.0% valid, 3 overruns since start; joint " +
                           settings.joint_names[1] + " GLITCH");
  // The next window: only its own cycles and its own overruns.
  status.count_cycle(core::CycleResult{}, true, false, 0, 1);
  end.overruns = 3;
  status.close_window(core::ServiceState::kHoming, end);
  EXPECT_EQ(status.message().window_cycles, 1);
  EXPECT_EQ(status.message().joint_flags[1], static_cast<std::int32_t>(core::joint_flag::kUnhomed));
  EXPECT_EQ(status.message().foreign_run_id, 0);
  // Another run heard: named in the status and in its message.
  end.foreign_run_id = 0x0123456789abcdef;
  status.count_cycle(core::CycleResult{}, true, false, 0, 1);
  status.close_window(core::ServiceState::kHoming, end);
  EXPECT_EQ(status.message().foreign_run_id, 0x0123456789abcdef);
  EXPECT_NE(status.message().message.find("ANOTHER RUN 0123456789abcdef"), std::string::npos)
      << status.message().message;
  // Its samples flagged: degraded, the reason first, the other one along.
  core::CycleResult foreign;
  foreign.sample_flags = flag::kForeignRun;
  end.overruns = 5;
  end.now_mono_ns = 1100 * kMs;
  {
    test::AllocationScope scope;
    status.count_cycle(foreign, true, false, 1050 * kMs, 1050 * kMs);
    EXPECT_EQ(status.close_window(core::ServiceState::kHoming, end), core::ServiceState::kDegraded);
    EXPECT_EQ(scope.count(), 0u);
  }
  EXPECT_EQ(status.cause().reason, core::StateReason::kForeignRun);
  EXPECT_EQ(status.message().message,
            "DEGRADED: another run publishes on these channels (threshold: any status heard) (also "
            "OVERRUNS); 0/6 homed, 0.0% valid, 5 overruns since start; ANOTHER RUN "
            "0123456789abcdef on these channels");
}

TEST(EventRing, AFullRingDropsAndCounts) {
  core::EventRing ring;
  for (std::size_t i = 0; i < core::EventRing::kCapacity + 3; ++i) {
    core::LogEvent e;
    e.seq = static_cast<std::int64_t>(i);
    ring.push(e);
  }
  EXPECT_EQ(ring.dropped(), 3);
  core::LogEvent e;
  std::int64_t expected = 0;
  while (ring.pop(e)) EXPECT_EQ(e.seq, expected++);
  EXPECT_EQ(expected, static_cast<std::int64_t>(core::EventRing::kCapacity));
}

TEST(ConfigHandover, TheLoopTakesTheLatestStagedConfiguration) {
  auto first = std::make_unique<core::PipelineConfig>();
  first->rig.singularity_threshold = 1.0;
  core::ConfigHandover handover(std::move(first));
  EXPECT_EQ(handover.take_staged(), nullptr);
  for (const double v : {2.0, 3.0}) {
    auto next = std::make_unique<core::PipelineConfig>();
    next->rig.singularity_threshold = v;
    handover.stage(std::move(next));
  }
  const core::PipelineConfig* taken = handover.take_staged();
  ASSERT_NE(taken, nullptr);
  EXPECT_EQ(taken, &handover.active());
  EXPECT_DOUBLE_EQ(handover.active().rig.singularity_threshold, 3.0);
  EXPECT_EQ(handover.take_staged(), nullptr);
}

// A configuration staged and replaced before the loop took it: the loop goes
// straight from the active one to the latest, which starts the new segment
// the skipped one would have.
TEST(ConfigHandover, ASkippedConfigurationHandsOnItsNewSegment) {
  core::ConfigHandover handover(std::make_unique<core::PipelineConfig>());
  auto marked = std::make_unique<core::PipelineConfig>();
  marked->new_segment = true;
  handover.stage(std::move(marked));
  handover.stage(std::make_unique<core::PipelineConfig>());
  const core::PipelineConfig* taken = handover.take_staged();
  ASSERT_NE(taken, nullptr);
  EXPECT_TRUE(taken->new_segment);
  handover.stage(std::make_unique<core::PipelineConfig>());
  taken = handover.take_staged();
  ASSERT_NE(taken, nullptr);
  EXPECT_FALSE(taken->new_segment);
}

// status_t names the files in effect: cut to its limits by
// make_pipeline_config, switched by a reload without allocating.
TEST(StatusAssembler, TheFilesInEffectFollowAReloadWithoutAllocating) {
  auto cfg = sim_config();
  const auto first = core::make_pipeline_config(cfg);
  const core::Pipeline pipeline(*first);
  core::ClockShared clock;
  core::StatusSettings settings;
  settings.joint_names = core::make_acquisition_config(cfg).joint_names;
  core::StatusAssembler status(settings, pipeline, clock);
  status.warm_up();
  EXPECT_EQ(status.message().config_path, cfg.file);
  EXPECT_EQ(status.message().config_sha256, cfg.config_sha256);
  EXPECT_EQ(status.message().config_sha256.size(), 64u);
  EXPECT_EQ(status.message().calibration_sha256, cfg.calibration_sha256);
  EXPECT_EQ(status.message().reloads, 0);

  // A long path keeps its end; a long provenance its start, cut between
  // UTF-8 characters ("é" is 2 bytes and would straddle byte 77).
  cfg.file = "/" + std::string(150, 'd') + "/exodaqd.yaml";
  cfg.calibration.provenance = {};
  cfg.calibration.provenance.created_by = std::string(76, 'x') + "\xc3\xa9" + std::string(20, 'y');
  cfg.config_sha256 = std::string(64, 'a');
  const auto next = core::make_pipeline_config(cfg);
  ASSERT_EQ(next->files.config_path.size(), core::ConfigFiles::kMaxPathBytes);
  EXPECT_EQ(next->files.config_path.substr(0, 3), "...");
  EXPECT_TRUE(next->files.config_path.ends_with("ddd/exodaqd.yaml"));
  EXPECT_EQ(next->files.calibration_provenance, std::string(76, 'x') + "...");
  {
    test::AllocationScope scope;
    status.use_files(next->files, 1);
    EXPECT_EQ(scope.count(), 0u);
  }
  EXPECT_EQ(status.message().config_path, next->files.config_path);
  EXPECT_EQ(status.message().config_sha256, std::string(64, 'a'));
  EXPECT_EQ(status.message().calibration_provenance, next->files.calibration_provenance);
  EXPECT_EQ(status.message().reloads, 1);
}
