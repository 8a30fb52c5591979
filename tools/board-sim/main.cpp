// exodaq-board-sim: the encoder interface board (CAN protocol v1), or six
// CANopen encoder nodes (CiA 406, --protocol canopen), on a CAN interface
// (vcan0 in tests, can0 with a real adapter), built from the daemon's own
// config so both sides describe one rig. The board answers each SYNC with the
// cycle's frames or free-runs at the config's rate; the nodes are started by
// the manager and answer its SYNC with TPDOs. Faults come from the config's
// source.sim.faults and --fault, in the one vocabulary of the sim backend
// (CANopen: the node faults it maps to). docs/can-protocol.md ("The board
// simulator", "CANopen nodes"), docs/simulator.md.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "board_sim.hpp"
#include "canopen_sim.hpp"
#include "exodaq/common/clock_now.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/drivers/canopen/canopen_backend.hpp"
#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/socketcan_backend.hpp"
#include "exodaq/settings/service_config.hpp"

namespace {

namespace can = exodaq::drivers::can;
namespace sim = exodaq::drivers::sim;
using exodaq::board_sim::BoardSim;
using exodaq::board_sim::CanopenSim;
using exodaq::board_sim::CanopenSimOptions;
using exodaq::drivers::CanPort;

std::atomic<bool> g_stop{false};
void on_signal(int) {
  g_stop.store(true);
}

struct Cli {
  std::string protocol = "v1";
  std::string iface;
  std::string config_path;
  std::string truth_path;
  std::string answers_path;
  bool free_run = false;
  std::int64_t seed = -1;
  int board = -1;
  double duration_s = 0.0;
  std::vector<std::string> faults;
  // canopen
  std::vector<int> nodes;
  bool sync_producer = false;
  int sync_overflow = 0;
  std::int64_t total_range = 0;
};

std::string canopen_fault_help() {
  std::string s;
  for (const auto& f : exodaq::board_sim::canopen_fault_names()) {
    s += (s.empty() ? "" : ", ") + std::string(f.name);
    if (!f.v1_name.empty()) s += " (" + std::string(f.v1_name) + ")";
  }
  return s;
}

void add_options(CLI::App& app, Cli& c) {
  app.add_option("--protocol", c.protocol,
                 "v1: the encoder interface board; canopen: six CiA 406 encoder nodes")
      ->check(CLI::IsMember({"v1", "canopen"}))
      ->capture_default_str();
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
  app.add_option("--answers", c.answers_path,
                 "canopen: write one line per TPDO sent: k channel mono_ns (the SYNC it "
                 "answers, its node's channel, CLOCK_MONOTONIC once the frame was sent)");
  app.add_option("--fault", c.faults,
                 "one more fault, as an entry of source.sim.faults: "
                 "'{kind: drop, percent: 10, at_s: 12.5, for_s: 1}' (docs/simulator.md); "
                 "canopen: '{kind: emcy, joint: 3, at_s: 2, for_s: 1}', kind one of " +
                     canopen_fault_help() + " (the v1 kind it maps)")
      ->allow_extra_args(false);
  app.add_option("--nodes", c.nodes,
                 "canopen: node ids of channels 0..5 (default: source.canopen.joints, or "
                 "1,2,3,4,5,6)")
      ->delimiter(',')
      ->expected(exodaq::board_sim::kCanopenNodes)
      ->check(CLI::Range(1, 127));
  app.add_flag("--sync-producer", c.sync_producer,
               "canopen: the first node produces SYNC at the config's rate (default: the manager)");
  app.add_option("--sync-overflow", c.sync_overflow,
                 "canopen: SYNC counter overflow of the producing node, 0 or 2..240")
      ->check(CLI::Range(0, 240));
  app.add_option("--total-range", c.total_range,
                 "canopen: every node's total measuring range, 0x6002 (default: the joint's "
                 "total_range in source.canopen, or 2^25)")
      ->check(CLI::Range(std::int64_t{2}, std::int64_t{0xFFFFFFFF}));
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
  if (cli.protocol == "v1") {
    for (std::size_t i = 0; i < cli.faults.size(); ++i)
      options.faults.push_back(parse_fault(cli.faults[i], i));
  }
  return options;
}

// The nodes from the config's source.canopen (when it has one), the options,
// and the faults: the config's source.sim.faults (moved out of the rig's
// options) and --fault.
CanopenSimOptions canopen_options(const Cli& cli, sim::SimOptions& rig) {
  namespace co = exodaq::drivers::canopen;
  CanopenSimOptions o;
  if (!cli.config_path.empty()) {
    const auto cfg = exodaq::settings::load_service_config(cli.config_path);
    if (const auto* s = cfg.source.section_as<co::CanopenSettings>("canopen")) {
      const co::CanopenSourceConfig& c = s->config;
      for (int i = 0; i < std::min(c.joint_count, exodaq::board_sim::kCanopenNodes); ++i) {
        const co::CanopenJoint& j = c.joints[static_cast<std::size_t>(i)];
        auto& n = o.nodes[static_cast<std::size_t>(i)];
        n.node = j.node;
        if (j.total_range != 0) n.total_range = j.total_range;
        n.index_module = j.values.has_reference;
        if (j.values.has_reference) {
          n.count_object = j.values.position;
          n.reference_object = j.values.reference;
        }
      }
      o.sync_overflow = c.sync_overflow;
    }
  }
  for (std::size_t i = 0; i < cli.nodes.size(); ++i) {
    o.nodes[i].node = static_cast<co::NodeId>(cli.nodes[i]);
  }
  if (cli.total_range > 0) {
    for (auto& n : o.nodes) n.total_range = static_cast<std::uint32_t>(cli.total_range);
  }
  o.sync_producer = cli.sync_producer;
  o.sync_period_ns = rig.period_ns;
  if (cli.sync_overflow != 0) o.sync_overflow = static_cast<std::uint8_t>(cli.sync_overflow);
  for (const sim::SimFault& f : rig.faults) {
    if (f.kind == sim::SimFault::Kind::kExcursion) continue;  // real motion: the rig's
    o.faults.push_back(exodaq::board_sim::canopen_fault_from(f));
  }
  std::erase_if(rig.faults,
                [](const sim::SimFault& f) { return f.kind != sim::SimFault::Kind::kExcursion; });
  rig.loss_percent = 0.0;
  rig.partial_percent = 0.0;
  for (std::size_t i = 0; i < cli.faults.size(); ++i) {
    const std::string name = "--fault #" + std::to_string(i + 1);
    exodaq::MapReader m(name, exodaq::load_yaml_text(cli.faults[i], name), "--fault");
    o.faults.push_back(exodaq::board_sim::parse_canopen_fault(m));
  }
  return o;
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

// The nodes poll the port every 100 us at most: a TPDO leaves within its
// node's response time (100 us) plus that of its SYNC's arrival.
void run_canopen(const Cli& cli, CanPort& port, CanopenSim& nodes) {
  Link link(port);
  const std::int64_t start = port.now_mono_ns();
  const std::int64_t end =
      cli.duration_s > 0 ? start + static_cast<std::int64_t>(cli.duration_s * 1e9) : INT64_MAX;
  link.up();
  nodes.power_on(start);
  while (!g_stop.load() && port.now_mono_ns() < end) {
    if (link.up()) {
      port.wait_readable(port.now_mono_ns() + 100'000);
    } else {
      exodaq::sleep_until_mono(port.now_mono_ns() + 1'000'000);
    }
    nodes.poll(port.now_mono_ns());
  }
}

struct FileCloser {
  void operator()(std::FILE* f) const { std::fclose(f); }
};

int run_main(int argc, char** argv) {
  CLI::App app{
      "exodaq-board-sim: the encoder interface board (CAN protocol v1) or six CANopen "
      "encoder nodes (CiA 406) on a CAN interface"};
  Cli cli;
  add_options(app, cli);
  CLI11_PARSE(app, argc, argv);
  try {
    sim::SimOptions options = rig_options(cli);
    const bool canopen = cli.protocol == "canopen";
    CanopenSimOptions co_options;
    if (canopen) co_options = canopen_options(cli, options);
    std::unique_ptr<std::FILE, FileCloser> truth;
    if (!cli.truth_path.empty()) {
      truth.reset(std::fopen(cli.truth_path.c_str(), "w"));
      if (!truth) throw std::runtime_error("cannot write " + cli.truth_path);
      exodaq::board_sim::write_truth_header(truth.get());
    }
    std::unique_ptr<std::FILE, FileCloser> answers;
    if (!cli.answers_path.empty()) {
      if (!canopen) throw std::runtime_error("--answers is for --protocol canopen");
      answers.reset(std::fopen(cli.answers_path.c_str(), "w"));
      if (!answers) throw std::runtime_error("cannot write " + cli.answers_path);
      std::fprintf(answers.get(), "# k channel sent_mono_ns\n");
    }
    std::signal(SIGTERM, on_signal);
    std::signal(SIGINT, on_signal);
    exodaq::drivers::CanPortConfig pc;
    pc.interface = cli.iface;
    pc.filters = canopen ? exodaq::board_sim::canopen_port_filters(co_options)
                         : exodaq::drivers::can::port_filters(options.board.ids, true);
    const auto port = exodaq::drivers::make_socketcan_port(pc);
    if (canopen) {
      CanopenSim nodes(options, co_options, *port, truth.get(), answers.get());
      std::string ids;
      for (const auto& n : co_options.nodes)
        ids += (ids.empty() ? "" : ",") + std::to_string(n.node);
      std::fprintf(stderr, "exodaq-board-sim: CANopen nodes %s on %s, SYNC from %s, %zu faults\n",
                   ids.c_str(), cli.iface.c_str(),
                   co_options.sync_producer ? "the first node" : "the manager",
                   co_options.faults.size());
      run_canopen(cli, *port, nodes);
      truth.reset();
      answers.reset();
      std::fprintf(stderr, "%s\n", nodes.summary().c_str());
      return 0;
    }
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
