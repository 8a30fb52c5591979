// Writes an LCM log (the format lcm-logger writes) holding N cycles of
// <prefix>EXO_ENCODER_RAW as exodaqd on the simulated rig would publish
// them, for the replay throughput benchmark:
//   bench_replay_gen --config config/sim.yaml --cycles 600000 --out big.lcm
#include <lcm/lcm.h>

#include <CLI/CLI.hpp>
#include <cstdio>
#include <vector>

#include "exodaq/config/service_config.hpp"
#include "exodaq/drivers/sim_options.hpp"
#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/encoder_raw_t.hpp"

int main(int argc, char** argv) {
  CLI::App app{"bench_replay_gen: a simulated lcm-logger log for the replay benchmark"};
  std::string config;
  std::string out;
  std::int64_t cycles = 600'000;
  app.add_option("--config", config, "service config (the sim rig's)")->required();
  app.add_option("--out", out, "LCM log to write")->required();
  app.add_option("--cycles", cycles, "cycles (1 kHz: 600000 = 10 min)");
  CLI11_PARSE(app, argc, argv);

  const exodaq::config::ServiceConfig cfg = exodaq::config::load_service_config(config);
  const auto ctx = exodaq::config::make_source_context(cfg);
  exodaq::drivers::sim::SimOptions opt = exodaq::drivers::sim_options_from(cfg.source, ctx);
  opt.start_mono_ns = 1'000'000'000;
  opt.wall_offset_ns = 1'700'000'000'000'000'000LL;
  exodaq::drivers::SimSource sim(opt);
  sim.start();

  lcm_eventlog_t* log = lcm_eventlog_create(out.c_str(), "w");
  if (log == nullptr) {
    std::fprintf(stderr, "cannot create %s\n", out.c_str());
    return 1;
  }
  const std::string channel = cfg.lcm.prefix + "EXO_ENCODER_RAW";
  exodaq::encoder_raw_t raw{};
  raw.run_id = 0x5eed;
  std::vector<std::uint8_t> buf(4096);
  exodaq::drivers::EncoderSample s;
  for (std::int64_t k = 0; k < cycles; ++k) {
    exodaq::drivers::CycleTime t;
    t.cycle = k;
    sim.read(t, s);
    raw.utime = s.wall_ns / 1000;
    raw.mono_ns = s.mono_ns;
    raw.seq = k;
    raw.present = s.present;
    raw.board_seq = s.board_seq;
    for (int c = 0; c < 6; ++c) {
      raw.count16[c] = static_cast<std::int16_t>(s.count16[static_cast<std::size_t>(c)]);
      raw.index_count16[c] =
          static_cast<std::int16_t>(s.index_count16[static_cast<std::size_t>(c)]);
    }
    raw.index_latched = static_cast<std::int32_t>(s.index_latched);
    raw.index_count_valid = static_cast<std::int32_t>(s.index_count_valid);
    raw.board_state = static_cast<std::int32_t>(s.board_state);
    raw.board_errors = static_cast<std::int32_t>(s.board_errors);
    raw.source_flags = static_cast<std::int32_t>(s.flags);
    raw.wall_ns = s.wall_ns;
    const int n = raw.encode(buf.data(), 0, static_cast<int>(buf.size()));
    lcm_eventlog_event_t ev{};
    ev.timestamp = raw.utime;
    ev.channellen = static_cast<std::int32_t>(channel.size());
    ev.datalen = n;
    ev.channel = const_cast<char*>(channel.c_str());
    ev.data = buf.data();
    if (lcm_eventlog_write_event(log, &ev) != 0) {
      std::fprintf(stderr, "error writing %s\n", out.c_str());
      return 1;
    }
  }
  lcm_eventlog_destroy(log);
  std::printf("%s: %lld cycles on %s\n", out.c_str(), static_cast<long long>(cycles),
              channel.c_str());
  return 0;
}
