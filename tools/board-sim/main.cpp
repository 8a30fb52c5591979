// exodaq-board-sim: behaves as the encoder interface board on a CAN interface
// (vcan0 in tests, can0 with a real adapter). The counts come from the same
// simulated rig (drivers/sim_rig.hpp) the `sim` backend runs, built from the
// daemon's own config (--config) so both sides agree on channels, directions,
// gearing and index angles. Answers each SYNC with the cycle's frames (INDEX,
// COUNTS_A, COUNTS_B, HEARTBEAT every 100 cycles) or free-runs at the config's
// rate on absolute CLOCK_MONOTONIC deadlines. Fault switches corrupt the
// stream in documented, counted ways; --truth writes the true joint angles of
// every cycle for tests. See docs/can-protocol.md ("Board simulator").
#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>
#include <exception>

#include <CLI/CLI.hpp>
#include <array>
#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "exodaq/config/service_config.hpp"
#include "exodaq/drivers/can_codec.hpp"
#include "exodaq/drivers/sim_backend.hpp"
#include "exodaq/drivers/sim_rig.hpp"
#include "exodaq/drivers/socketcan_backend.hpp"

namespace {

using exodaq::drivers::can::CanFrame;
namespace can = exodaq::drivers::can;
namespace sim = exodaq::drivers::sim;

std::atomic<bool> g_stop{false};
void on_signal(int) {
  g_stop.store(true);
}

std::int64_t mono_ns() {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// A fault's time window in simulated seconds: "VALUE[@T[+D]]".
struct Window {
  double start_s = 0.0;
  double duration_s = std::numeric_limits<double>::infinity();
  bool contains(double t) const { return t >= start_s && t < start_s + duration_s; }
};

// Splits "VALUE@T+D" into VALUE and the window.
std::string split_window(const std::string& spec, Window& w) {
  const auto at = spec.find('@');
  if (at == std::string::npos) return spec;
  const std::string rest = spec.substr(at + 1);
  const auto plus = rest.find('+');
  w.start_s = std::stod(rest.substr(0, plus));
  if (plus != std::string::npos) w.duration_s = std::stod(rest.substr(plus + 1));
  return spec.substr(0, at);
}

struct Glitch {
  int channel = 0;
  std::int64_t counts = 0;
  double at_s = 0.0;
};

struct Faults {
  double drop_percent = 0.0;
  Window drop;
  std::int64_t delay_us = 0;
  Window delay;
  std::vector<Window> silences;  // burst silence
  int stuck_channel = -1;
  Window stuck;
  int bad_seq_every = 0;
  Window bad_seq;
  int error_frames = 0;
  Window errors;
  std::vector<Glitch> glitches;
  int drift_channel = -1;
  std::int64_t drift_counts = 0;
  Window drift;
  int wrong_dlc_every = 0;
  Window wrong_dlc;
  int duplicate_every = 0;
  Window duplicate;
  int board_error_bits = 0;
  Window board_error;
};

// Truth-file fault bits (per cycle).
namespace truth_flag {
constexpr unsigned kDropped = 1U << 0;
constexpr unsigned kSilent = 1U << 1;
constexpr unsigned kStuck = 1U << 2;
constexpr unsigned kBadSeq = 1U << 3;
constexpr unsigned kWrongDlc = 1U << 4;
constexpr unsigned kDuplicate = 1U << 5;
constexpr unsigned kErrorFrame = 1U << 6;
constexpr unsigned kGlitched = 1U << 7;  // some channel carries a glitch offset
constexpr unsigned kDrift = 1U << 8;     // some channel's counter has slipped (index drift)
constexpr unsigned kBoardError = 1U << 9;
constexpr unsigned kDelayed = 1U << 10;
constexpr unsigned kSimLoss = 1U << 11;  // source.sim.loss_percent of the config
constexpr unsigned kSendFailed = 1U << 12;
}  // namespace truth_flag

struct Counters {
  std::int64_t cycles = 0;
  std::int64_t frames = 0;
  std::int64_t send_failures = 0;
  std::int64_t dropped = 0;
  std::int64_t silent = 0;
  std::int64_t delayed = 0;
  std::int64_t stuck = 0;
  std::int64_t bad_seq = 0;
  std::int64_t wrong_dlc = 0;
  std::int64_t duplicates = 0;
  std::int64_t error_frames = 0;
  std::int64_t glitches = 0;
  std::int64_t drifted_index = 0;
  std::int64_t board_error_cycles = 0;
  std::int64_t sim_lost = 0;
};

class Bus {
 public:
  explicit Bus(std::string iface) : iface_(std::move(iface)) {}
  ~Bus() {
    if (fd_ >= 0) ::close(fd_);
  }
  bool open(std::uint32_t sync_id) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    const unsigned index = if_nametoindex(iface_.c_str());
    if (index == 0) return false;
    const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
    if (fd < 0) throw std::runtime_error(std::string("socket(PF_CAN): ") + std::strerror(errno));
    can_filter f{};
    f.can_id = sync_id;
    f.can_mask = CAN_SFF_MASK | CAN_EFF_FLAG | CAN_RTR_FLAG;
    setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, &f, sizeof f);
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = static_cast<int>(index);
    if (bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) {
      ::close(fd);
      return false;
    }
    fd_ = fd;
    return true;
  }
  int fd() const { return fd_; }
  // 0 or errno.
  int send(const CanFrame& frame) {
    can_frame cf{};
    if ((frame.flags & can::frame_flag::kError) != 0) {
      cf.can_id = (frame.id & CAN_ERR_MASK) | CAN_ERR_FLAG;
    } else {
      cf.can_id = frame.id & CAN_SFF_MASK;
    }
    cf.can_dlc = frame.dlc;
    std::memcpy(cf.data, frame.data.data(), 8);
    for (int attempt = 0; attempt < 3; ++attempt) {
      if (::send(fd_, &cf, sizeof cf, MSG_DONTWAIT) == static_cast<ssize_t>(sizeof cf)) return 0;
      if (errno != EAGAIN && errno != ENOBUFS) return errno;
      pollfd p{fd_, POLLOUT, 0};
      ::poll(&p, 1, 1);
    }
    return errno;
  }

 private:
  std::string iface_;
  int fd_ = -1;
};

class BoardSim {
 public:
  BoardSim(const sim::SimOptions& options, Faults faults, Bus& bus, std::FILE* truth)
      : rig_(options), faults_(std::move(faults)), bus_(bus), truth_(truth) {
    base_errors_ = rig_.board().options().errors;
  }

  void cycle(std::int64_t k) {
    using namespace truth_flag;
    ++c_.cycles;
    const double t = rig_.sample_time_s(k);
    sim::SimBoard::Frames scratch{};
    rig_.step(k, scratch, 0, 0);  // advances the motion and the encoders
    const auto& enc = rig_.encoders();
    sim::BoardCycle bc;
    std::array<std::int64_t, 6> true_count{};
    for (int j = 0; j < sim::kJoints; ++j) {
      const auto ch = static_cast<std::size_t>(enc.params(j).channel);
      bc.count[ch] = enc.count(j);
      true_count[ch] = enc.count(j);
      if (enc.latched(j)) {
        bc.index_latched |= 1U << ch;
        bc.index_count[ch] = enc.latched_count(j);
      }
    }
    unsigned flags = 0;
    // Glitch: a permanent jump of the channel's counter from T on.
    for (const Glitch& g : faults_.glitches) {
      if (t >= g.at_s) {
        bc.count[static_cast<std::size_t>(g.channel)] += g.counts;
        if (bc.index_latched & (1U << g.channel)) {
          bc.index_count[static_cast<std::size_t>(g.channel)] += g.counts;
        }
        flags |= kGlitched;
        if (!glitch_applied_) ++c_.glitches;
      }
    }
    glitch_applied_ = (flags & kGlitched) != 0;
    // Stuck channel: its counter freezes and it latches no index; the board
    // notices the dead encoder and reports a quadrature error on it.
    auto& bopt = rig_.board().options();
    bopt.errors = base_errors_;
    bopt.channel_quadrature_errors = 0;
    if (faults_.stuck_channel >= 0 && faults_.stuck.contains(t)) {
      const auto ch = static_cast<std::size_t>(faults_.stuck_channel);
      if (!stuck_valid_) {
        stuck_value_ = bc.count[ch];
        stuck_valid_ = true;
      }
      bc.count[ch] = stuck_value_;
      bc.index_latched &= ~(1U << ch);
      bopt.errors |= can::board_error::kQuadrature;
      bopt.channel_quadrature_errors = static_cast<std::uint8_t>(1U << ch);
      flags |= kStuck;
      ++c_.stuck;
    }
    // Index drift: from T on, channel C's counter has slipped by N counts
    // (lost or extra counts too slow for the speed check): only the next index
    // crossing can reveal it (JOINT_LOST_COUNTS).
    if (faults_.drift_channel >= 0 && t >= faults_.drift.start_s) {
      const auto ch = static_cast<std::size_t>(faults_.drift_channel);
      bc.count[ch] += faults_.drift_counts;
      if (bc.index_latched & (1U << faults_.drift_channel)) {
        bc.index_count[ch] += faults_.drift_counts;
        ++c_.drifted_index;  // index crossings that can reveal the slip
      }
      flags |= kDrift;
    }
    if (faults_.board_error_bits != 0 && faults_.board_error.contains(t)) {
      bopt.errors |= static_cast<std::uint8_t>(faults_.board_error_bits);
      flags |= kBoardError;
      ++c_.board_error_cycles;
    }

    std::array<CanFrame, 16> out{};
    sim::SimBoard::Frames made{};
    int n = rig_.board().make_cycle(k, bc, made);
    for (int i = 0; i < n; ++i)
      out[static_cast<std::size_t>(i)] = made[static_cast<std::size_t>(i)];
    const std::uint32_t id_a = bopt.ids.counts_a_id();
    const std::uint32_t id_b = bopt.ids.counts_b_id();
    if (rig_.cycle_lost(k)) {
      n = 0;
      flags |= kSimLoss;
      ++c_.sim_lost;
    }
    if (n > 0 && faults_.drop_percent > 0 && faults_.drop.contains(t) &&
        sim::unit_random(rig_.options().seed, 0xD409, static_cast<std::uint64_t>(k)) * 100.0 <
            faults_.drop_percent) {
      n = 0;
      flags |= kDropped;
      ++c_.dropped;
    }
    for (const Window& s : faults_.silences) {
      if (n > 0 && s.contains(t)) {
        n = 0;
        flags |= kSilent;
        ++c_.silent;
      }
    }
    if (n > 0 && faults_.bad_seq_every > 0 && faults_.bad_seq.contains(t) &&
        k % faults_.bad_seq_every == faults_.bad_seq_every - 1) {
      for (int i = 0; i < n; ++i) {
        CanFrame& f = out[static_cast<std::size_t>(i)];
        if (f.id == id_a || f.id == id_b) f.data[7] = static_cast<std::uint8_t>(f.data[7] + 128);
      }
      flags |= kBadSeq;
      ++c_.bad_seq;
    }
    if (n > 0 && faults_.wrong_dlc_every > 0 && faults_.wrong_dlc.contains(t) &&
        k % faults_.wrong_dlc_every == faults_.wrong_dlc_every - 1) {
      for (int i = 0; i < n; ++i) {
        if (out[static_cast<std::size_t>(i)].id == id_b) out[static_cast<std::size_t>(i)].dlc = 6;
      }
      flags |= kWrongDlc;
      ++c_.wrong_dlc;
    }
    if (n > 0 && faults_.duplicate_every > 0 && faults_.duplicate.contains(t) &&
        k % faults_.duplicate_every == faults_.duplicate_every - 1) {
      for (int i = 0; i < n; ++i) {
        if (out[static_cast<std::size_t>(i)].id == id_a) {
          out[static_cast<std::size_t>(n++)] = out[static_cast<std::size_t>(i)];
          break;
        }
      }
      flags |= kDuplicate;
      ++c_.duplicates;
    }
    if (faults_.error_frames > c_.error_frames && faults_.errors.contains(t) && k % 10 == 0) {
      // A protocol error (bit error) as a controller reports it.
      can::ErrorPayload e;
      e.classes = can::err_class::kProt | can::err_class::kBusError;
      e.protocol_type = CAN_ERR_PROT_BIT;
      out[static_cast<std::size_t>(n++)] = can::encode_error(e);
      flags |= kErrorFrame;
      ++c_.error_frames;
    }
    if (n > 0 && faults_.delay_us > 0 && faults_.delay.contains(t)) {
      const timespec d{0, static_cast<long>(faults_.delay_us * 1000)};
      clock_nanosleep(CLOCK_MONOTONIC, 0, &d, nullptr);
      flags |= kDelayed;
      ++c_.delayed;
    }
    for (int i = 0; i < n; ++i) {
      const int err = bus_.fd() >= 0 ? bus_.send(out[static_cast<std::size_t>(i)]) : ENODEV;
      if (err == 0) {
        ++c_.frames;
      } else {
        ++c_.send_failures;
        flags |= kSendFailed;
        if (err == ENETDOWN || err == ENODEV || err == ENXIO) break;
      }
    }
    if (truth_ != nullptr) {
      const sim::Vec6 q = rig_.motion().position(t);
      std::fprintf(truth_, "%lld %u %.9f", static_cast<long long>(k),
                   static_cast<unsigned>((bopt.first_seq + k) & 0xFF), t);
      for (double v : q) std::fprintf(truth_, " %.12f", v);
      for (std::int64_t c : true_count) std::fprintf(truth_, " %lld", static_cast<long long>(c));
      std::fprintf(truth_, " %u\n", flags);
    }
  }

  const Counters& counters() const { return c_; }
  const sim::SimRig& rig() const { return rig_; }

 private:
  sim::SimRig rig_;
  Faults faults_;
  Bus& bus_;
  std::FILE* truth_;
  Counters c_{};
  std::uint8_t base_errors_ = 0;
  bool stuck_valid_ = false;
  std::int64_t stuck_value_ = 0;
  bool glitch_applied_ = false;
};

void print_counters(const Counters& c) {
  std::fprintf(stderr,
               "BOARD-SIM: cycles=%lld frames=%lld send_failures=%lld dropped=%lld silent=%lld "
               "delayed=%lld stuck=%lld bad_seq=%lld wrong_dlc=%lld duplicates=%lld "
               "error_frames=%lld glitches=%lld drift_index_crossings=%lld board_error_cycles=%lld "
               "sim_lost=%lld\n",
               static_cast<long long>(c.cycles), static_cast<long long>(c.frames),
               static_cast<long long>(c.send_failures), static_cast<long long>(c.dropped),
               static_cast<long long>(c.silent), static_cast<long long>(c.delayed),
               static_cast<long long>(c.stuck), static_cast<long long>(c.bad_seq),
               static_cast<long long>(c.wrong_dlc), static_cast<long long>(c.duplicates),
               static_cast<long long>(c.error_frames), static_cast<long long>(c.glitches),
               static_cast<long long>(c.drifted_index),
               static_cast<long long>(c.board_error_cycles), static_cast<long long>(c.sim_lost));
}

}  // namespace

static int run_main(int argc, char** argv) {
  CLI::App app{
      "exodaq-board-sim: the encoder interface board (CAN protocol v1) on a CAN interface"};
  std::string iface;
  std::string config_path;
  std::string truth_path;
  bool free_run = false;
  std::int64_t seed = -1;
  int board = -1;
  double duration_s = 0.0;
  std::string drop, delay, stuck, bad_seq, errors, drift, wrong_dlc, duplicate, board_error;
  std::vector<std::string> silences, glitches;
  app.add_option("--iface", iface, "CAN interface (vcan0, can0)")->required();
  app.add_option("--config", config_path,
                 "the daemon's YAML config: rig, encoders, model and calibration (and "
                 "source.sim.seed, source.socketcan.board) are taken from it");
  app.add_flag("--free-run", free_run, "sample on an own 1 kHz timer instead of answering SYNC");
  app.add_option("--seed", seed,
                 "motion/fault seed (default: source.sim.seed of the config, or 1)");
  app.add_option("--board", board, "board number (IDs + board * 0x20)");
  app.add_option("--duration", duration_s, "stop after this many seconds (0: until SIGTERM)");
  app.add_option(
      "--truth", truth_path,
      "write one line per cycle: k seq t_s q0..q5 count0..count5(by channel) fault_bits");
  const char* w = " (optional @T[+D]: only from simulated second T, for D seconds)";
  app.add_option("--drop-percent", drop, std::string("drop whole cycles at random, P %") + w);
  app.add_option("--delay-us", delay, std::string("answer each cycle U µs late") + w);
  app.add_option("--burst-silence-ms", silences, "send nothing for M ms from second T: M@T")
      ->allow_extra_args(false);
  app.add_option("--stuck-channel", stuck,
                 std::string("freeze channel C (and report a quadrature error on it)") + w);
  app.add_option("--bad-seq-every", bad_seq,
                 std::string("every Nth cycle's COUNTS carry a corrupted sequence byte") + w);
  app.add_option("--error-frames", errors,
                 std::string("send N error frames (protocol/bit error), one per 10 cycles") + w);
  app.add_option("--glitch", glitches,
                 "counter of channel C jumps by COUNTS at second T: C:COUNTS@T")
      ->allow_extra_args(false);
  app.add_option("--index-drift", drift,
                 "channel C's counter slips by COUNTS from second T (seen at its next index): "
                 "C:COUNTS[@T]");
  app.add_option("--wrong-dlc-every", wrong_dlc,
                 std::string("every Nth cycle's COUNTS_B is sent with DLC 6") + w);
  app.add_option("--duplicate-every", duplicate,
                 std::string("every Nth cycle's COUNTS_A is sent twice") + w);
  app.add_option("--board-error", board_error,
                 std::string("heartbeat error bits (board_error::*) to report") + w);
  CLI11_PARSE(app, argc, argv);

  sim::SimOptions options;
  exodaq::drivers::SourceOptions source;
  try {
    if (!config_path.empty()) {
      const auto cfg = exodaq::config::load_service_config(config_path);
      source = cfg.source;
      options =
          exodaq::drivers::sim_options_from(cfg.source, exodaq::config::make_source_context(cfg));
      options.board.ids.board =
          static_cast<std::uint32_t>(exodaq::drivers::socketcan_board(cfg.source));
    }
    if (seed >= 0) options.seed = static_cast<std::uint64_t>(seed);
    if (board >= 0) options.board.ids.board = static_cast<std::uint32_t>(board);
    options.board.state = static_cast<std::uint8_t>(free_run ? can::BoardState::kFreeRun
                                                             : can::BoardState::kSyncSlave);

    Faults f;
    if (!drop.empty()) f.drop_percent = std::stod(split_window(drop, f.drop));
    if (!delay.empty()) f.delay_us = std::stoll(split_window(delay, f.delay));
    for (const std::string& s : silences) {
      Window win;
      const double ms = std::stod(split_window(s, win));
      win.duration_s = ms / 1000.0;
      f.silences.push_back(win);
    }
    if (!stuck.empty()) f.stuck_channel = std::stoi(split_window(stuck, f.stuck));
    if (!bad_seq.empty()) f.bad_seq_every = std::stoi(split_window(bad_seq, f.bad_seq));
    if (!errors.empty()) f.error_frames = std::stoi(split_window(errors, f.errors));
    for (const std::string& g : glitches) {
      Window win;
      const std::string v = split_window(g, win);
      const auto colon = v.find(':');
      if (colon == std::string::npos) throw std::invalid_argument("--glitch C:COUNTS@T");
      f.glitches.push_back(
          {std::stoi(v.substr(0, colon)), std::stoll(v.substr(colon + 1)), win.start_s});
    }
    if (!drift.empty()) {
      drift = split_window(drift, f.drift);
      const auto colon = drift.find(':');
      if (colon == std::string::npos) throw std::invalid_argument("--index-drift C:COUNTS");
      f.drift_channel = std::stoi(drift.substr(0, colon));
      f.drift_counts = std::stoll(drift.substr(colon + 1));
    }
    if (!wrong_dlc.empty()) f.wrong_dlc_every = std::stoi(split_window(wrong_dlc, f.wrong_dlc));
    if (!duplicate.empty()) f.duplicate_every = std::stoi(split_window(duplicate, f.duplicate));
    if (!board_error.empty()) {
      f.board_error_bits = std::stoi(split_window(board_error, f.board_error), nullptr, 0);
    }
    for (int c : {f.stuck_channel, f.drift_channel}) {
      if (c >= 6) throw std::invalid_argument("channel must be 0..5");
    }
    for (const Glitch& g : f.glitches) {
      if (g.channel < 0 || g.channel >= 6) throw std::invalid_argument("channel must be 0..5");
    }

    std::FILE* truth = nullptr;
    if (!truth_path.empty()) {
      truth = std::fopen(truth_path.c_str(), "w");
      if (truth == nullptr) throw std::runtime_error("cannot write " + truth_path);
      std::fprintf(truth, "# k seq t_s q0 q1 q2 q3 q4 q5 c0 c1 c2 c3 c4 c5 fault_bits\n");
    }
    std::signal(SIGTERM, on_signal);
    std::signal(SIGINT, on_signal);

    Bus bus(iface);
    const std::uint32_t sync_id = options.board.ids.sync_id();
    if (!bus.open(sync_id)) {
      std::fprintf(stderr, "exodaq-board-sim: interface %s not available (retrying)\n",
                   iface.c_str());
    }
    BoardSim sim(options, f, bus, truth);
    const std::int64_t period = options.period_ns;
    const std::int64_t start = mono_ns();
    const std::int64_t end =
        duration_s > 0 ? start + static_cast<std::int64_t>(duration_s * 1e9) : INT64_MAX;
    std::int64_t k = 0;
    std::int64_t next = start;
    std::int64_t last_reopen = start;
    std::fprintf(stderr, "exodaq-board-sim: %s on %s, board %u, period %lld ns\n",
                 free_run ? "free-running" : "answering SYNC", iface.c_str(),
                 options.board.ids.board, static_cast<long long>(period));
    while (!g_stop.load() && mono_ns() < end) {
      if (bus.fd() < 0) {
        // The interface is missing: retry once a second.
        const timespec d{0, 100'000'000};
        clock_nanosleep(CLOCK_MONOTONIC, 0, &d, nullptr);
        if (mono_ns() - last_reopen > 1'000'000'000) {
          last_reopen = mono_ns();
          bus.open(sync_id);
        }
        if (free_run) sim.cycle(k++);
        continue;
      }
      if (free_run) {
        next += period;
        const timespec ts{static_cast<time_t>(next / 1'000'000'000),
                          static_cast<long>(next % 1'000'000'000)};
        clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr);
        sim.cycle(k++);
        continue;
      }
      pollfd p{bus.fd(), POLLIN, 0};
      const int r = ::poll(&p, 1, 100);
      if (r <= 0) continue;
      can_frame cf{};
      const ssize_t got = ::recv(bus.fd(), &cf, sizeof cf, MSG_DONTWAIT);
      if (got < 0) {
        if (errno == ENODEV) bus.open(sync_id);  // interface deleted: re-create the socket
        if (errno == ENETDOWN || errno == ENODEV) {
          const timespec d{0, 10'000'000};
          clock_nanosleep(CLOCK_MONOTONIC, 0, &d, nullptr);
        }
        continue;
      }
      if (got == sizeof cf && (cf.can_id & CAN_SFF_MASK) == sync_id && cf.can_dlc == 0) {
        sim.cycle(k++);
      }
    }
    if (truth != nullptr) std::fclose(truth);
    print_counters(sim.counters());
  } catch (const std::exception& e) {
    std::fprintf(stderr, "exodaq-board-sim: %s\n", e.what());
    return 2;
  }
  return 0;
}

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
