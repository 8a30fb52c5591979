// Writes an LCM log (the format lcm-logger writes) holding N cycles of
// <prefix>EXO_ENCODER_RAW as exodaqd on the simulated rig would publish
// them, for the replay throughput benchmark:
//   bench_replay_gen --config config/sim.yaml --cycles 600000 --out big.lcm

#include <CLI/CLI.hpp>
#include <cstdio>
#include <vector>

#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/raw_sample.hpp"
#include "exodaq/settings/service_config.hpp"

int main(int argc, char** argv) {
  CLI::App app{"bench_replay_gen: a simulated lcm-logger log for the replay benchmark"};
  std::string config;
  std::string out;
  std::int64_t cycles = 600'000;
  app.add_option("--config", config, "service config (the sim rig's)")->required();
  app.add_option("--out", out, "LCM log to write")->required();
  app.add_option("--cycles", cycles, "cycles (1 kHz: 600000 = 10 min)");
  CLI11_PARSE(app, argc, argv);

  const exodaq::settings::ServiceConfig cfg = exodaq::settings::load_service_config(config);
  const auto ctx = exodaq::settings::make_source_context(cfg);
  exodaq::drivers::sim::SimOptions opt = exodaq::drivers::sim_options_from(cfg.source, ctx);
  opt.start_mono_ns = 1'000'000'000;
  opt.wall_offset_ns = 1'700'000'000'000'000'000LL;
  exodaq::drivers::SimSource sim(opt);
  sim.start();

  namespace messages = exodaq::messages;
  messages::LogWriter log(out);
  const std::string channel = messages::channel_name(cfg.lcm.prefix, messages::Kind::kEncoderRaw);
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
    messages::to_encoder_raw(s, raw);
    const int n = raw.encode(buf.data(), 0, static_cast<int>(buf.size()));
    log.write(channel, raw.utime, buf.data(), static_cast<std::size_t>(n));
  }
  log.close();
  std::printf("%s: %lld cycles on %s\n", out.c_str(), static_cast<long long>(cycles),
              channel.c_str());
  return 0;
}
