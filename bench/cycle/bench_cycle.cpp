// One whole acquisition cycle on the simulated rig, without threads:
// Acquisition::run_cycle() = sim source read (simulate the rig, encode its CAN
// frames, decode them with the real BoardDecoder) -> unwrap -> homing/offsets
// -> FK -> Jacobian -> manipulability -> encode joint_state, palm_pose,
// encoder_raw (and status every 100th cycle) into the publisher's ring. The
// ring is drained into a counting sink between timed cycles (the publisher
// thread's work is not the loop's).
//
//   bench_cycle [benchmark flags]        Google Benchmark (means): BM_Cycle, BM_SimSourceRead
//   bench_cycle --harness [--cycles N] [--paced N] [--json FILE]
//        times every cycle with clock_gettime (p50/p99/p99.9/max) and counts
//        heap allocations (operator new + malloc, tests/support/alloc_counter)
//        over the timed cycles, back to back (hot caches). Then N cycles
//        paced at the config's period on CLOCK_MONOTONIC deadlines, as the
//        loop runs them: first with the ring drained inline after each timed
//        cycle, then with the publisher thread running (each commit's
//        sem_post then wakes it, as in exodaqd). Used by bench/run.
#include <benchmark/benchmark.h>
#include <time.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "alloc_counter.hpp"
#include "exodaq/common/clock_now.hpp"
#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/builder.hpp"
#include "exodaq/drivers/source_factory.hpp"
#include "exodaq/settings/service_config.hpp"

using namespace exodaq;

namespace {

// Counts what the publisher hands over; allocates nothing.
class CountingSink final : public core::MessageSink {
 public:
  std::array<std::int64_t, exodaq::messages::kKindCount> counts{};
  std::int64_t bytes = 0;
  bool publish(const std::string&, const core::OutgoingMessage& msg) noexcept override {
    ++counts[static_cast<std::size_t>(msg.channel)];
    bytes += msg.size;
    return true;
  }
};

settings::ServiceConfig sim_config() {
  return settings::load_service_config(std::string(EXODAQ_SOURCE_DIR) + "/config/sim.yaml");
}

// The daemon's wiring (build_acquisition) with a counting sink instead of LCM.
struct Rig {
  settings::ServiceConfig cfg = sim_config();
  CountingSink* sink = nullptr;
  std::unique_ptr<core::Acquisition> acq;
  std::int64_t period_ns = 0;
  std::int64_t t0 = 0;
  std::int64_t k = 0;  // cycles run

  Rig() {
    period_ns = static_cast<std::int64_t>(1e9 / cfg.loop.rate_hz);
    auto s = std::make_unique<CountingSink>();
    sink = s.get();
    core::AcquisitionOptions wiring;
    wiring.sink = std::move(s);
    wiring.channel_prefix = "BENCH_";
    wiring.realtime = false;
    acq = core::build_acquisition(cfg, std::move(wiring));
    acq->prepare_for_manual_cycles();
    t0 = mono_now_ns();
  }

  // One cycle, 5 us after its deadline (the deadlines are simulated time).
  bool cycle() noexcept {
    const std::int64_t deadline = t0 + k * period_ns;
    ++k;
    return acq->run_cycle(deadline, deadline + 5'000);
  }

  // Runs until every joint is homed and the service is running (the simulated
  // operator homes joint by joint over ~10 s of simulated time).
  void warm_up(std::int64_t at_least, std::int64_t at_most) {
    while (k < at_most && (k < at_least || acq->state() != core::ServiceState::kRunning)) {
      cycle();
      if (k % 256 == 0) acq->publisher().drain();
    }
    acq->publisher().drain();
  }
};

Rig& shared_rig() {
  static Rig rig = [] {
    Rig r;
    r.warm_up(15'000, 60'000);
    return r;
  }();
  return rig;
}

void BM_Cycle(benchmark::State& state) {
  Rig& rig = shared_rig();
  const std::uint64_t a0 = test::thread_allocations();
  std::int64_t n = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(rig.cycle());
    if ((++n & 255) == 0) {
      state.PauseTiming();
      rig.acq->publisher().drain();
      state.ResumeTiming();
    }
  }
  rig.acq->publisher().drain();
  state.counters["allocs_per_cycle"] = static_cast<double>(test::thread_allocations() - a0) /
                                       static_cast<double>(std::max<std::int64_t>(n, 1));
}
BENCHMARK(BM_Cycle);

// The sim source alone (simulating the rig and its CAN frames, decoding them):
// part of BM_Cycle that a real rig replaces with reading SocketCAN.
void BM_SimSourceRead(benchmark::State& state) {
  const auto cfg = sim_config();
  auto src = drivers::make_source(cfg.source, settings::make_source_context(cfg));
  src->start();
  drivers::EncoderSample sample;
  drivers::CycleTime t;
  t.period_ns = static_cast<std::int64_t>(1e9 / cfg.loop.rate_hz);
  const std::int64_t t0 = mono_now_ns();
  for (auto _ : state) {
    t.deadline_mono_ns = t0 + t.cycle * t.period_ns;
    t.now_mono_ns = t.deadline_mono_ns + 5'000;
    benchmark::DoNotOptimize(src->read(t, sample));
    ++t.cycle;
  }
}
BENCHMARK(BM_SimSourceRead);

struct Stats {
  std::size_t n = 0;
  double mean = 0, p50 = 0, p90 = 0, p99 = 0, p999 = 0, max = 0;
};

Stats stats_of(std::vector<std::int64_t> v) {
  Stats s;
  s.n = v.size();
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  const auto at = [&v](double q) {
    const auto i = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5);
    return static_cast<double>(v[std::min(i, v.size() - 1)]);
  };
  double sum = 0;
  for (const auto x : v) sum += static_cast<double>(x);
  s.mean = sum / static_cast<double>(v.size());
  s.p50 = at(0.5);
  s.p90 = at(0.9);
  s.p99 = at(0.99);
  s.p999 = at(0.999);
  s.max = static_cast<double>(v.back());
  return s;
}

std::string json_of(const Stats& s) {
  char buf[256];
  std::snprintf(buf, sizeof buf,
                "{\"n\": %zu, \"mean_ns\": %.1f, \"p50_ns\": %.0f, \"p90_ns\": %.0f, \"p99_ns\": "
                "%.0f, \"p999_ns\": %.0f, \"max_ns\": %.0f}",
                s.n, s.mean, s.p50, s.p90, s.p99, s.p999, s.max);
  return buf;
}

// `n` cycles, one per period on real deadlines (caches and predictors go cold
// between them, as in the daemon). With `publisher_thread`, the publisher
// thread hands the messages over (the sink counts them) and the loop's
// sem_posts wake it.
std::vector<std::int64_t> paced(std::int64_t n, bool publisher_thread) {
  Rig rig;
  rig.warm_up(15'000, 60'000);
  if (publisher_thread) rig.acq->publisher().start();
  std::vector<std::int64_t> d;
  d.reserve(static_cast<std::size_t>(n));
  std::int64_t deadline = mono_now_ns() + rig.period_ns;
  for (std::int64_t i = 0; i < n; ++i, deadline += rig.period_ns) {
    exodaq::sleep_until_mono(deadline);
    const std::int64_t a = mono_now_ns();
    rig.cycle();
    d.push_back(mono_now_ns() - a);
    if (!publisher_thread) rig.acq->publisher().drain();
  }
  if (publisher_thread) rig.acq->publisher().stop();
  return d;
}

// The sim source alone over the rig's cycles after its warm-up (what a real
// rig replaces).
std::vector<std::int64_t> time_source_reads(const Rig& rig, std::int64_t warmup,
                                            std::int64_t cycles) {
  std::vector<std::int64_t> source_read;
  source_read.reserve(static_cast<std::size_t>(cycles));
  auto src = drivers::make_source(rig.cfg.source, settings::make_source_context(rig.cfg));
  src->start();
  drivers::EncoderSample sample;
  drivers::CycleTime t;
  t.period_ns = rig.period_ns;
  for (std::int64_t i = 0; i < warmup + cycles; ++i) {
    t.cycle = i;
    t.deadline_mono_ns = rig.t0 + i * t.period_ns;
    t.now_mono_ns = t.deadline_mono_ns + 5'000;
    const std::int64_t a = mono_now_ns();
    src->read(t, sample);
    const std::int64_t d = mono_now_ns() - a;
    if (i >= warmup) source_read.push_back(d);
  }
  return source_read;
}

// The cost of the timer itself.
std::vector<std::int64_t> time_the_timer() {
  std::vector<std::int64_t> timer;
  timer.reserve(10'000);
  for (int i = 0; i < 10'000; ++i) {
    const std::int64_t a = mono_now_ns();
    timer.push_back(mono_now_ns() - a);
  }
  return timer;
}

// To stdout for "" or "-".
bool write_json(const std::string& j, const std::string& json_path) {
  if (json_path.empty() || json_path == "-") {
    std::fputs(j.c_str(), stdout);
    return true;
  }
  FILE* f = std::fopen(json_path.c_str(), "w");
  if (f == nullptr) {
    std::perror(json_path.c_str());
    return false;
  }
  std::fputs(j.c_str(), f);
  std::fclose(f);
  return true;
}

int harness(std::int64_t cycles, std::int64_t paced_cycles, const std::string& json_path) {
  Rig rig;
  rig.warm_up(15'000, 60'000);
  const bool running = rig.acq->state() == core::ServiceState::kRunning;
  const std::int64_t warmup = rig.k;
  const int status_every =
      std::max(1, static_cast<int>(rig.cfg.loop.rate_hz / rig.cfg.loop.status_rate_hz + 0.5));

  std::vector<std::int64_t> all, regular, status;
  all.reserve(static_cast<std::size_t>(cycles));
  regular.reserve(static_cast<std::size_t>(cycles));
  status.reserve(static_cast<std::size_t>(cycles / status_every + 1));
  const auto published_before = rig.acq->publisher().published();
  const std::uint64_t proc_before = test::process_allocations();
  std::uint64_t thread_allocs = 0;
  {
    test::AllocationScope scope;
    for (std::int64_t i = 0; i < cycles; ++i) {
      const bool is_status = (rig.k + 1) % status_every == 0;
      const std::int64_t a = mono_now_ns();
      rig.cycle();
      const std::int64_t d = mono_now_ns() - a;
      all.push_back(d);
      (is_status ? status : regular).push_back(d);
      if ((i & 255) == 255) rig.acq->publisher().drain();
    }
    rig.acq->publisher().drain();
    thread_allocs = scope.count();
  }
  const std::uint64_t proc_allocs = test::process_allocations() - proc_before;
  const auto published = rig.acq->publisher().published() - published_before;

  const auto source_read = time_source_reads(rig, warmup, cycles);
  const auto timer = time_the_timer();

  const auto paced_inline = paced(paced_cycles, false);
  const auto paced_thread = paced(paced_cycles, true);

  std::string j = "{\n";
  j += "  \"cycles\": " + std::to_string(cycles) + ",\n";
  j += "  \"warmup_cycles\": " + std::to_string(warmup) + ",\n";
  j += std::string("  \"homed_and_running\": ") + (running ? "true" : "false") + ",\n";
  j += "  \"status_every_cycles\": " + std::to_string(status_every) + ",\n";
  j += "  \"messages_published\": " + std::to_string(published) + ",\n";
  j += "  \"cycle\": " + json_of(stats_of(all)) + ",\n";
  j += "  \"cycle_without_status\": " + json_of(stats_of(regular)) + ",\n";
  j += "  \"cycle_with_status\": " + json_of(stats_of(status)) + ",\n";
  j += "  \"sim_source_read\": " + json_of(stats_of(source_read)) + ",\n";
  j += "  \"clock_gettime_pair\": " + json_of(stats_of(timer)) + ",\n";
  j += "  \"paced_cycle\": " + json_of(stats_of(paced_inline)) + ",\n";
  j += "  \"paced_cycle_publisher_thread\": " + json_of(stats_of(paced_thread)) + ",\n";
  j += "  \"allocations_loop_thread\": " + std::to_string(thread_allocs) + ",\n";
  j += "  \"allocations_process\": " + std::to_string(proc_allocs) + ",\n";
  j += "  \"allocations_per_cycle\": " +
       std::to_string(static_cast<double>(thread_allocs) / static_cast<double>(cycles)) + "\n";
  j += "}\n";
  if (!write_json(j, json_path)) return 1;
  return thread_allocs == 0 ? 0 : 3;
}

}  // namespace

int main(int argc, char** argv) {
  bool run_harness = false;
  std::int64_t cycles = 100'000;
  std::int64_t paced_cycles = 5'000;
  std::string json_path;
  std::vector<char*> rest{argv[0]};
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--harness") {
      run_harness = true;
    } else if (a == "--cycles" && i + 1 < argc) {
      cycles = std::atoll(argv[++i]);
    } else if (a == "--paced" && i + 1 < argc) {
      paced_cycles = std::atoll(argv[++i]);
    } else if (a == "--json" && i + 1 < argc) {
      json_path = argv[++i];
    } else {
      rest.push_back(argv[i]);
    }
  }
  if (run_harness)
    return harness(std::max<std::int64_t>(cycles, 1), std::max<std::int64_t>(paced_cycles, 1),
                   json_path);
  int n = static_cast<int>(rest.size());
  benchmark::Initialize(&n, rest.data());
  if (benchmark::ReportUnrecognizedArguments(n, rest.data())) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
