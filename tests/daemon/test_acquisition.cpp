// The acquisition loop driven with an injected source and sink: what it
// publishes, and that a cycle allocates nothing.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <map>
#include <mutex>
#include <thread>
#include <vector>

#include "alloc_counter.hpp"
#include "exodaq/config/service_config.hpp"
#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/builder.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"

using namespace exodaq;

namespace {
constexpr std::int64_t kMs = 1'000'000;

// A board whose six counters ramp slowly; every channel passes its index at
// cycle 5. Optionally skips every `drop_every`-th sample.
class RampSource final : public drivers::EncoderSource {
 public:
  int drop_every = 0;
  std::string_view name() const noexcept override { return "ramp"; }
  void start() override {}
  drivers::ReadStatus read(const drivers::CycleTime& t,
                           drivers::EncoderSample& out) noexcept override {
    const std::int64_t k = t.cycle;
    if (drop_every > 0 && k > 10 && k % drop_every == 0) {
      out.present = false;
      ++stats_.missing_samples;
      return drivers::ReadStatus::kNoSample;
    }
    out = drivers::EncoderSample{};
    out.present = true;
    out.mono_ns = t.deadline_mono_ns;
    out.board_seq = static_cast<std::int16_t>(k & 0xFF);
    for (int c = 0; c < 6; ++c) {
      out.count16[static_cast<std::size_t>(c)] = static_cast<std::uint16_t>(1000 + k / 4);
      if (k == 5)
        out.index_count16[static_cast<std::size_t>(c)] = static_cast<std::uint16_t>(1000 + k / 4);
    }
    if (k == 5) out.index_count_valid = out.index_latched = 0x3F;
    ++stats_.frames;
    return drivers::ReadStatus::kSample;
  }
  drivers::SourceStats stats() const noexcept override { return stats_; }

 private:
  drivers::SourceStats stats_;
};

// Counts messages per channel; decodes the last of each. Allocation-free
// unless `keep` is set.
class MemorySink final : public core::MessageSink {
 public:
  bool keep = false;
  std::array<std::int64_t, 4> counts{};
  std::mutex mutex;
  std::vector<std::pair<exodaq::msg::Kind, std::vector<std::uint8_t>>> kept;
  bool publish(const std::string&, const core::OutgoingMessage& msg) noexcept override {
    ++counts[static_cast<std::size_t>(msg.channel)];
    if (keep) {
      std::lock_guard<std::mutex> lock(mutex);
      kept.emplace_back(msg.channel,
                        std::vector<std::uint8_t>(msg.bytes.begin(), msg.bytes.begin() + msg.size));
    }
    return true;
  }
};

config::ServiceConfig sim_config() {
  return config::load_service_config(std::string(EXODAQ_SOURCE_DIR) + "/config/sim.yaml");
}

std::unique_ptr<core::Acquisition> make_acquisition(std::unique_ptr<drivers::EncoderSource> src,
                                                    MemorySink*& sink_out) {
  const auto cfg = sim_config();
  core::AcquisitionConfig ac;
  ac.rig = cfg.rig;
  ac.clock = cfg.clock;
  for (int i = 0; i < 6; ++i)
    ac.joint_names[static_cast<std::size_t>(i)] =
        cfg.model.chain.joints()[static_cast<std::size_t>(i)].name;
  auto sink = std::make_unique<MemorySink>();
  sink_out = sink.get();
  return std::make_unique<core::Acquisition>(ac, core::make_pipeline_config(cfg), std::move(src),
                                             std::move(sink), "TEST_", nullptr);
}

template <typename Msg>
Msg decode(const std::vector<std::uint8_t>& bytes) {
  Msg m;
  EXPECT_GT(m.decode(bytes.data(), 0, static_cast<int>(bytes.size())), 0);
  return m;
}
}  // namespace

TEST(Acquisition, PublishesEveryChannelEachCycleAndStatusAtTenHertz) {
  MemorySink* sink = nullptr;
  auto acq = make_acquisition(std::make_unique<RampSource>(), sink);
  sink->keep = true;
  acq->prepare_for_manual_cycles();
  const std::int64_t t0 = 100 * 1'000'000'000LL;
  for (int k = 0; k < 1000; ++k) {
    ASSERT_TRUE(acq->run_cycle(t0 + k * kMs, t0 + k * kMs + 20'000));
    acq->publisher().drain();
  }
  // Exactly one of each per cycle, status every 100 cycles; nothing before the first cycle.
  EXPECT_EQ(sink->counts[0], 1000);
  EXPECT_EQ(sink->counts[1], 1000);
  EXPECT_EQ(sink->counts[2], 1000);
  EXPECT_EQ(sink->counts[3], 10);

  std::int64_t expected_seq = 0;
  for (const auto& [channel, bytes] : sink->kept) {
    if (channel == exodaq::msg::Kind::kJointState) {
      const auto js = decode<exodaq::joint_state_t>(bytes);
      EXPECT_EQ(js.seq, expected_seq++);
      EXPECT_EQ(js.run_id, acq->run_id());
      EXPECT_EQ(js.mono_ns, t0 + js.seq * kMs);
      if (js.seq >= 5) {
        for (int j = 0; j < 6; ++j) ASSERT_TRUE(js.homed[j]) << "joint " << j << " seq " << js.seq;
      } else {
        EXPECT_FALSE(js.homed[0]);
        EXPECT_TRUE(js.flags[0] & exodaq::joint_state_t::JOINT_UNHOMED);
      }
    }
    if (channel == exodaq::msg::Kind::kStatus) {
      const auto st = decode<exodaq::status_t>(bytes);
      EXPECT_EQ(st.rig, "sim-macaque");
      EXPECT_EQ(st.window_cycles, 100);
      EXPECT_EQ(st.run_id, acq->run_id());
      EXPECT_DOUBLE_EQ(st.lateness_p50_us, 20.0);
      EXPECT_EQ(st.source, "ramp");
    }
  }
  EXPECT_EQ(expected_seq, 1000);
}

TEST(Acquisition, PalmIsValidOnlyWhenHomedAndTheSampleIsPresent) {
  MemorySink* sink = nullptr;
  auto src = std::make_unique<RampSource>();
  src->drop_every = 50;
  auto acq = make_acquisition(std::move(src), sink);
  sink->keep = true;
  acq->prepare_for_manual_cycles();
  const std::int64_t t0 = 100 * 1'000'000'000LL;
  for (int k = 0; k < 300; ++k) {
    acq->run_cycle(t0 + k * kMs, t0 + k * kMs + 10'000);
    acq->publisher().drain();
  }
  int valid = 0;
  int checked = 0;
  for (const auto& [channel, bytes] : sink->kept) {
    if (channel != exodaq::msg::Kind::kPalmPose) continue;
    const auto p = decode<exodaq::palm_pose_t>(bytes);
    ++checked;
    const bool missing = p.seq > 10 && p.seq % 50 == 0;
    if (p.seq < 5) {
      EXPECT_FALSE(p.valid);
      EXPECT_TRUE(p.invalid_reason & exodaq::palm_pose_t::INVALID_UNHOMED);
    } else if (missing) {
      EXPECT_FALSE(p.valid) << p.seq;
      EXPECT_TRUE(p.invalid_reason & exodaq::palm_pose_t::INVALID_SAMPLE);
    } else {
      EXPECT_TRUE(p.valid) << p.seq << " reason " << p.invalid_reason;
      ++valid;
    }
    const double qn =
        std::sqrt(p.orientation[0] * p.orientation[0] + p.orientation[1] * p.orientation[1] +
                  p.orientation[2] * p.orientation[2] + p.orientation[3] * p.orientation[3]);
    EXPECT_NEAR(qn, 1.0, 1e-12);
  }
  EXPECT_EQ(checked, 300);
  EXPECT_EQ(valid, 300 - 5 - 5);
}

TEST(Acquisition, ACycleAllocatesNothingOverTenThousandCycles) {
  MemorySink* sink = nullptr;
  auto src = std::make_unique<RampSource>();
  src->drop_every = 97;  // exercise the missing-sample path too
  auto acq = make_acquisition(std::move(src), sink);
  acq->prepare_for_manual_cycles();
  const std::int64_t t0 = 100 * 1'000'000'000LL;
  acq->run_cycle(t0, t0);  // first cycle outside the scope
  acq->publisher().drain();
  test::AllocationScope scope;
  for (int k = 1; k <= 12'000; ++k) {
    acq->run_cycle(t0 + k * kMs, t0 + k * kMs + 5'000);
    if (k % 256 == 0) acq->publisher().drain();  // the sink counts without allocating
  }
  EXPECT_EQ(scope.count(), 0u);
  acq->publisher().drain();
  EXPECT_EQ(sink->counts[0], 12'001);
}

TEST(Acquisition, ThreadedLoopAllocatesNothingAfterStartUp) {
  MemorySink* sink = nullptr;
  auto acq = make_acquisition(std::make_unique<RampSource>(), sink);
  acq->start();
  while (acq->cycles() < 500) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  // Only the loop, publisher and clock-monitor threads run now; none may allocate.
  const std::uint64_t before = test::process_allocations();
  const std::int64_t c0 = acq->cycles();
  while (acq->cycles() < c0 + 10'000) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const std::uint64_t after = test::process_allocations();
  acq->stop();
  EXPECT_EQ(after - before, 0u);
  EXPECT_GE(sink->counts[0], 10'000);
}
