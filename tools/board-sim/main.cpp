// exodaq-board-sim: the encoder interface board (CAN protocol v1) on a CAN
// interface (vcan0 in tests, can0 with a real adapter), built from the
// daemon's own config so both sides describe one rig. Answers each SYNC with
// the cycle's frames or free-runs at the config's rate; faults come from the
// config's source.sim.faults and --fault, in the one vocabulary of the sim
// backend. docs/can-protocol.md ("Board simulator"), docs/simulator.md.
#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "board_sim.hpp"
#include "exodaq/common/clock_now.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/socketcan_backend.hpp"
#include "exodaq/settings/service_config.hpp"

namespace {

namespace can = exodaq::drivers::can;
namespace sim = exodaq::drivers::sim;
using exodaq::board_sim::BoardSim;
using exodaq::drivers::CanPort;

std::atomic<bool> g_stop{false};
void on_signal(int) {
  g_stop.store(true);
}

struct Cli {
  std::string iface;
  std::string config_path;
  std::string truth_path;
  bool free_run = false;
  std::int64_t seed = -1;
  int board = -1;
  double duration_s = 0.0;
  std::vector<std::string> faults;
};

void add_options(CLI::App& app, Cli& c) {
  app.add_option("--iface", c.iface, "CAN interface (vcan0, can0)")->required();
  app.add_option("--config", c.config_path,
                 "the daemon's YAML config: rig, encoders, model and calibration (and "
                 "source.sim: seed, loss, jitter, faults; source.socketcan.board) come from it");
  app.add_flag("--free-run", c.free_run, "sample on an own timer instead of answering SYNC");
  app.add_option("--seed", c.seed, "motion/fault seed (default: source.sim.seed, or 1)");
  app.add_option("--board", c.board, "board number (IDs + board * 0x20)");
  app.add_option("--duration", c.duration_s, "stop after this many seconds (0: until SIGTERM)");
  app.add_option("--truth", c.truth_path,
                 "write one line per cycle: k seq t_s q0..q5 count0..count5 (by channel) "
                 "fault_bits");
  app.add_option("--fault", c.faults,
                 "one more fault, as an entry of source.sim.faults: "
                 "'{kind: drop, percent: 10, at_s: 12.5, for_s: 1}' (docs/simulator.md)")
      ->allow_extra_args(false);
}

sim::SimFault parse_fault(const std::string& spec, std::size_t i) {
  const std::string name = "--fault #" + std::to_string(i + 1);
  exodaq::MapReader m(name, exodaq::load_yaml_text(spec, name), "--fault");
  return exodaq::drivers::parse_sim_fault(m);
}

sim::SimOptions rig_options(const Cli& cli) {
  sim::SimOptions options;
  if (!cli.config_path.empty()) {
    const auto cfg = exodaq::settings::load_service_config(cli.config_path);
    options =
        exodaq::drivers::sim_options_from(cfg.source, exodaq::settings::make_source_context(cfg));
    options.board.ids.board =
        static_cast<std::uint32_t>(exodaq::drivers::socketcan_board(cfg.source));
  }
  if (cli.seed >= 0) options.seed = static_cast<std::uint64_t>(cli.seed);
  if (cli.board >= 0) options.board.ids.board = static_cast<std::uint32_t>(cli.board);
  options.board.state = static_cast<std::uint8_t>(cli.free_run ? can::BoardState::kFreeRun
                                                               : can::BoardState::kSyncSlave);
  for (std::size_t i = 0; i < cli.faults.size(); ++i)
    options.faults.push_back(parse_fault(cli.faults[i], i));
  return options;
}

// Keeps the port open: re-open attempts at most every 200 ms while it is not.
class Link {
 public:
  explicit Link(CanPort& port) : port_(port) {}
  bool up() {
    if (port_.is_open()) return true;
    const std::int64_t now = port_.now_mono_ns();
    if (tried_ && now - last_try_ < 200'000'000) return false;
    tried_ = true;
    last_try_ = now;
    return port_.open() == 0;
  }

 private:
  CanPort& port_;
  bool tried_ = false;
  std::int64_t last_try_ = 0;
};

// Waits up to 100 ms for SYNC frames; returns how many arrived (the port is
// closed when the interface went away).
int receive_syncs(CanPort& port, const can::ProtocolIds& ids) {
  const int r = port.wait_readable(port.now_mono_ns() + 100'000'000);
  if (r <= 0) return 0;
  std::array<can::CanFrame, 32> rx{};
  exodaq::drivers::CanRxInfo info;
  const int n = port.receive(rx.data(), static_cast<int>(rx.size()), info);
  if (n < 0 && exodaq::drivers::is_interface_loss(-n)) port.close();
  int syncs = 0;
  for (int i = 0; i < n; ++i) {
    const can::CanFrame& f = rx[static_cast<std::size_t>(i)];
    if (f.flags == 0 && f.id == ids.sync_id() && f.dlc == 0) ++syncs;
  }
  return syncs;
}

void run(const Cli& cli, const sim::SimOptions& options, CanPort& port, BoardSim& board) {
  Link link(port);
  const std::int64_t start = port.now_mono_ns();
  const std::int64_t end =
      cli.duration_s > 0 ? start + static_cast<std::int64_t>(cli.duration_s * 1e9) : INT64_MAX;
  std::int64_t k = 0;
  std::int64_t origin = 0;  // answering SYNC: the first SYNC's instant is t = 0
  while (!g_stop.load() && port.now_mono_ns() < end) {
    if (cli.free_run) {  // absolute deadlines: start + k * period
      exodaq::sleep_until_mono(start + k * options.period_ns);
      link.up();
      board.cycle(k++, start);
      continue;
    }
    if (!link.up()) {
      exodaq::sleep_until_mono(port.now_mono_ns() + 50'000'000);
      continue;
    }
    for (int s = receive_syncs(port, options.board.ids); s > 0; --s) {
      const std::int64_t now = port.now_mono_ns();
      if (k == 0) origin = now;
      board.cycle_now(k++, now, origin);  // sampled on the SYNC's arrival, sent at once
    }
  }
}

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

int run_main(int argc, char** argv) {
  CLI::App app{
      "exodaq-board-sim: the encoder interface board (CAN protocol v1) on a CAN interface"};
  Cli cli;
  add_options(app, cli);
  CLI11_PARSE(app, argc, argv);
  try {
    const sim::SimOptions options = rig_options(cli);
    std::unique_ptr<std::FILE, FileCloser> truth;
    if (!cli.truth_path.empty()) {
      truth.reset(std::fopen(cli.truth_path.c_str(), "w"));
      if (!truth) throw std::runtime_error("cannot write " + cli.truth_path);
      exodaq::board_sim::write_truth_header(truth.get());
    }
    std::signal(SIGTERM, on_signal);
    std::signal(SIGINT, on_signal);
    exodaq::drivers::CanPortConfig pc;
    pc.interface = cli.iface;
    pc.filters = exodaq::drivers::can::port_filters(options.board.ids, true);
    const auto port = exodaq::drivers::make_socketcan_port(pc);
    BoardSim board(options, *port, truth.get());
    std::fprintf(stderr, "exodaq-board-sim: %s on %s, board %u, period %lld ns, %zu faults\n",
                 cli.free_run ? "free-running" : "answering SYNC", cli.iface.c_str(),
                 options.board.ids.board, static_cast<long long>(options.period_ns),
                 options.faults.size());
    run(cli, options, *port, board);
    truth.reset();
    std::fprintf(stderr, "%s\n", board.summary().c_str());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "exodaq-board-sim: %s\n", e.what());
    return 2;
  }
  return 0;
}

}  // namespace

// Nothing escapes main: an unexpected exception is reported and exits 1.
int main(int argc, char** argv) {
  try {
    return run_main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", argv[0], e.what());
  } catch (...) {
    std::fprintf(stderr, "%s: unknown error\n", argv[0]);
  }
  return 1;
}
