// exodaq-vcan-replay-check: the host side of the vcan VM test (CTest
// vm_vcan_replay, after vm_vcan). Issue 7 point 4: the candump file recorded
// inside the VM replays to the same angles as the live VM run.
//
// Inputs, both left in --work by run-vm-tests:
//   vcan-run.candump   the bus as `candump -l` recorded it inside the VM;
//   vcan-run-live.txt  every cycle exodaq-vcan-check received live from the
//                      daemon (joint_state_t joined with encoder_raw_t by seq).
// Runs `exodaq replay vcan-run.candump --config <vcan.yaml at the VM's loop
// rate> --speed max`, reads the replay's LCM log and pairs the cycles by the
// board's cycle, not by the daemon's seq (a candump replay numbers its cycles
// from 0 at the first frame, the live daemon from its own start, and the live
// loop skips seqs when it overruns): a live and a replayed sample are the same
// board cycle when they carry the same board_seq and the same receive instant
// (utime, the kernel RX stamp of the COUNTS frame that completed the cycle;
// candump logs that stamp to the microsecond, the daemon maps it to utime
// within 1 us). For every cycle present in both, exactly:
//   - the raw counts are the same (count16 of each channel whose joint is
//     HELD on neither side: a held joint repeats what its side last read),
//   - every joint position (not HELD on either side) is the same to 1e-9 rad,
//   - every joint's `homed` is the same;
// and every live sample pairs with a replayed one, some of them with every
// joint homed compared whole (how many the live loop cut at its read deadline
// is the emulated machine's speed, not the replay's: those are compared on
// their fresh joints). Cycles that cannot pair are counted by cause. Exit 0
// pass, 1 fail, 77 skip (the VM did not run: no recording in --work).
//
// --protocol canopen (CTest vm_vcan_canopen_replay): the VM's canopen stage
// (canopen-run.candump, canopen-run-live.txt from exodaq-canopen-check, and
// canopen-run.yaml, the config the daemon ran) replayed with that config. The
// replay numbers its cycles from the log's first SYNC, the live source from
// its first SYNC, and candump ran before the daemon: a live and a replayed
// cycle pair by source_seq, verified by their instants (the SYNC's send time
// live, its logged kernel stamp replayed: within half a period). For every pair: the
// raw position of each channel fresh on both sides equal, each joint's angle
// not HELD on either side equal to 1e-9 rad, `homed` the same; a channel fresh
// on one side only is counted and printed: its TPDO was stamped in the wait
// but queued to the live socket after it (the kernel stamps a vcan frame as
// it is sent and delivers it later, under TCG more than a wait later). From
// such a cycle on, the joint may home one cycle apart on the two sides: a
// `homed` (and angle) difference on a joint is a failure only if no fresh
// difference on it came first.
#include <lcm/lcm-cpp.hpp>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "process.hpp"

namespace {

struct Cycle {
  std::int64_t seq = -1;
  std::int64_t utime = 0;
  bool present = false;
  int board_seq = -1;
  std::uint32_t sample_flags = 0;
  std::array<std::int16_t, 6> count16{};
  std::array<bool, 6> homed{};
  std::array<std::uint32_t, 6> flags{};
  std::array<double, 6> pos{};
  bool all_homed() const {
    return std::all_of(homed.begin(), homed.end(), [](bool h) { return h; });
  }
};

int g_failures = 0;
void check(bool ok, const std::string& what) {
  std::printf("VCAN-REPLAY: %s %s\n", ok ? "ok  " : "FAIL", what.c_str());
  if (!ok) ++g_failures;
}

// The end of a live-cycles line: homed[6] flags[6] angle[6] (angles in
// %.17g text, which strtod reads back as the same double).
template <typename CycleT>
void read_joints(std::istringstream& s, CycleT& c) {
  for (auto& h : c.homed) {
    int x = 0;
    s >> x;
    h = x != 0;
  }
  for (auto& f : c.flags) s >> f;
  for (auto& q : c.pos) {
    std::string t;
    s >> t;
    q = std::strtod(t.c_str(), nullptr);
  }
}

bool read_live(const std::string& path, std::vector<Cycle>& out, double& rate_hz) {
  std::ifstream in(path);
  if (!in) return false;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    if (line[0] == '#') {
      const auto p = line.find("rate_hz ");
      if (p != std::string::npos) rate_hz = std::strtod(line.c_str() + p + 8, nullptr);
      continue;
    }
    std::istringstream s(line);
    Cycle c;
    int present = 0, valid = 0;
    long long wall_ns = 0;
    std::uint32_t source_flags = 0;
    s >> c.seq >> c.utime >> present >> c.board_seq >> wall_ns >> c.sample_flags >> source_flags >>
        valid;
    for (auto& v : c.count16) s >> v;
    read_joints(s, c);
    if (!s) {
      std::printf("VCAN-REPLAY: FAIL %s: unreadable line \"%s\"\n", path.c_str(), line.c_str());
      return false;
    }
    c.present = present != 0;
    out.push_back(c);
  }
  return true;
}

// The replay's joint_state_t and encoder_raw_t, joined by seq.
bool read_replay(const std::string& path, std::vector<Cycle>& out) {
  lcm::LogFile log(path, "r");
  if (!log.good()) return false;
  std::map<std::int64_t, Cycle> by_seq;
  std::map<std::int64_t, int> parts;
  while (const lcm::LogEvent* ev = log.readNextEvent()) {
    const bool js = ev->channel.ends_with("EXO_JOINT_STATE");
    const bool raw = ev->channel.ends_with("EXO_ENCODER_RAW");
    if (js) {
      exodaq::joint_state_t m;
      if (m.decode(ev->data, 0, static_cast<int>(ev->datalen)) < 0) return false;
      Cycle& c = by_seq[m.seq];
      c.seq = m.seq;
      c.utime = m.utime;
      c.sample_flags = static_cast<std::uint32_t>(m.sample_flags);
      for (std::size_t j = 0; j < 6; ++j) {
        c.homed[j] = m.homed[j];
        c.flags[j] = static_cast<std::uint32_t>(m.flags[j]);
        c.pos[j] = m.position[j];
      }
      parts[m.seq] |= 1;
    } else if (raw) {
      exodaq::encoder_raw_t m;
      if (m.decode(ev->data, 0, static_cast<int>(ev->datalen)) < 0) return false;
      Cycle& c = by_seq[m.seq];
      c.present = m.present;
      c.board_seq = static_cast<int>(m.source_seq);  // protocol v1: 0..255
      for (std::size_t j = 0; j < 6; ++j) {          // protocol v1's positions: 16 bits
        c.count16[j] = static_cast<std::int16_t>(static_cast<std::uint16_t>(m.position[j]));
      }
      parts[m.seq] |= 2;
    }
  }
  for (const auto& [seq, c] : by_seq) {
    if (parts[seq] == 3) out.push_back(c);
  }
  return true;
}

// config/vcan.yaml at the loop rate the VM ran (100 Hz under TCG), its
// model and calibration paths made absolute (they are relative to the file).
std::string write_config(const std::string& source, const std::string& work, double rate_hz) {
  std::ifstream in(source + "/config/vcan.yaml");
  std::ostringstream out;
  std::string line;
  char rate[64];
  std::snprintf(rate, sizeof rate, "%.17g", rate_hz);
  while (std::getline(in, line)) {
    if (line.starts_with("  rate_hz: ")) {
      line = std::string("  rate_hz: ") + rate;
    } else if (line.starts_with("model: ")) {
      line = "model: " + source + "/config/" + line.substr(7);
    } else if (line.starts_with("calibration: ")) {
      line = "calibration: " + source + "/config/" + line.substr(13);
    }
    out << line << '\n';
  }
  const std::string path = work + "/vcan-replay.yaml";
  std::ofstream(path) << out.str();
  return path;
}

// --- --protocol canopen ---------------------------------------------------------

struct CoCycle {
  std::int64_t seq = -1, utime = 0, source_seq = -1;
  bool present = false;
  std::uint32_t sample_flags = 0, fresh = 0;
  std::array<std::int64_t, 6> raw{};
  std::array<bool, 6> homed{};
  std::array<std::uint32_t, 6> flags{};
  std::array<double, 6> pos{};
};

bool read_co_live(const std::string& path, std::vector<CoCycle>& out) {
  std::ifstream in(path);
  if (!in) return false;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    CoCycle c;
    int present = 0, valid = 0;
    long long mono_ns = 0;
    std::uint32_t source_flags = 0;
    s >> c.seq >> c.utime >> present >> c.source_seq >> mono_ns >> c.sample_flags >> source_flags >>
        valid >> c.fresh;
    for (auto& v : c.raw) s >> v;
    read_joints(s, c);
    if (!s) {
      std::printf("VCAN-REPLAY: FAIL %s: unreadable line \"%s\"\n", path.c_str(), line.c_str());
      return false;
    }
    c.present = present != 0;
    out.push_back(c);
  }
  return true;
}

bool read_co_replay(const std::string& path, std::vector<CoCycle>& out) {
  lcm::LogFile log(path, "r");
  if (!log.good()) return false;
  std::map<std::int64_t, CoCycle> by_seq;
  std::map<std::int64_t, int> parts;
  while (const lcm::LogEvent* ev = log.readNextEvent()) {
    if (ev->channel.ends_with("EXO_JOINT_STATE")) {
      exodaq::joint_state_t m;
      if (m.decode(ev->data, 0, static_cast<int>(ev->datalen)) < 0) return false;
      CoCycle& c = by_seq[m.seq];
      c.seq = m.seq;
      c.utime = m.utime;
      c.sample_flags = static_cast<std::uint32_t>(m.sample_flags);
      for (std::size_t j = 0; j < 6; ++j) {
        c.homed[j] = m.homed[j];
        c.flags[j] = static_cast<std::uint32_t>(m.flags[j]);
        c.pos[j] = m.position[j];
      }
      parts[m.seq] |= 1;
    } else if (ev->channel.ends_with("EXO_ENCODER_RAW")) {
      exodaq::encoder_raw_t m;
      if (m.decode(ev->data, 0, static_cast<int>(ev->datalen)) < 0) return false;
      CoCycle& c = by_seq[m.seq];
      c.present = m.present;
      c.source_seq = m.source_seq;
      c.fresh = static_cast<std::uint32_t>(m.channel_fresh);
      for (std::size_t j = 0; j < 6; ++j) c.raw[j] = m.position[j];
      parts[m.seq] |= 2;
    }
  }
  for (const auto& [seq, c] : by_seq) {
    if (parts[seq] == 3) out.push_back(c);
  }
  return true;
}

int run_canopen(const std::string& exodaq, const std::string& source, const std::string& work) {
  const std::string candump = work + "/canopen-run.candump";
  const std::string live_path = work + "/canopen-run-live.txt";
  const std::string vm_config = work + "/canopen-run.yaml";
  const int have = (std::filesystem::exists(candump) ? 1 : 0) +
                   (std::filesystem::exists(live_path) ? 1 : 0) +
                   (std::filesystem::exists(vm_config) ? 1 : 0);
  if (have == 0) {
    std::printf("SKIP: no %s: the VM test (vm_vcan) did not run here\n", candump.c_str());
    return 77;
  }
  if (have != 3) {
    std::printf("VCAN-REPLAY: FAIL the VM ran but left only %d of %s, %s, %s\n", have,
                candump.c_str(), live_path.c_str(), vm_config.c_str());
    return 1;
  }
  // The VM's config, its model and calibration paths made absolute.
  std::ifstream in(vm_config);
  std::ostringstream cfg;
  std::string line;
  double rate_hz = 0;
  while (std::getline(in, line)) {
    if (line.starts_with("model: ")) {
      line = "model: " + source + "/config/" + line.substr(7);
    } else if (line.starts_with("calibration: ")) {
      line = "calibration: " + source + "/config/" + line.substr(13);
    } else if (line.starts_with("  rate_hz: ")) {
      rate_hz = std::strtod(line.c_str() + 11, nullptr);
    }
    cfg << line << '\n';
  }
  const std::string config = work + "/canopen-replay.yaml";
  std::ofstream(config) << cfg.str();
  std::vector<CoCycle> live;
  if (rate_hz <= 0 || !read_co_live(live_path, live)) {
    std::printf("VCAN-REPLAY: FAIL cannot read %s (rate %g Hz)\n", live_path.c_str(), rate_hz);
    return 1;
  }
  const std::string out_lcm = work + "/canopen-replay.lcm";
  std::filesystem::remove(out_lcm);
  const auto r = exodaq::test::run({exodaq, "replay", candump, "--config", config, "--format",
                                    "candump", "--speed", "max", "--out", out_lcm, "--quiet"},
                                   std::chrono::seconds(120));
  std::printf("VCAN-REPLAY: canopen: exodaq replay (loop rate %g Hz) rc=%d\n%s%s", rate_hz,
              r.exit_code, r.out.c_str(), r.err.c_str());
  if (r.exit_code != 0) {
    std::printf("VCAN-REPLAY: FAIL exodaq replay exit code %d\n", r.exit_code);
    return 1;
  }
  std::vector<CoCycle> replay;
  if (!read_co_replay(out_lcm, replay)) {
    std::printf("VCAN-REPLAY: FAIL cannot read %s\n", out_lcm.c_str());
    return 1;
  }
  std::map<std::int64_t, const CoCycle*> replay_by_source;
  for (const CoCycle& c : replay) {
    if (c.source_seq >= 0 && !replay_by_source.contains(c.source_seq))
      replay_by_source[c.source_seq] = &c;
  }
  constexpr std::uint32_t kHeld = exodaq::joint_state_t::JOINT_HELD;
  const auto half_period_us = static_cast<std::int64_t>(0.5e6 / rate_hz);
  std::int64_t cycles = 0, paired = 0, unpaired = 0, far = 0, raw_differ = 0, pos_differ = 0,
               homed_differ = 0, homed_moved = 0, fresh_differ = 0, fresh_live_only = 0,
               fresh_replay_only = 0, compared_channels = 0, whole = 0, whole_homed = 0;
  std::int64_t worst_dt_us = 0, last_source_seq = -1;
  double worst = 0;
  int reported = 0;
  std::uint32_t fresh_differed = 0;  // joints with a fresh difference so far
  for (const CoCycle& l : live) {
    // The first live message of each source_seq (a cycle with none closed repeats it).
    if (l.source_seq < 0 || l.source_seq <= last_source_seq) continue;
    last_source_seq = l.source_seq;
    ++cycles;
    const auto it = replay_by_source.find(l.source_seq);
    if (it == replay_by_source.end()) {
      if (unpaired++ < 5)
        std::printf("VCAN-REPLAY: live source_seq %lld not in the replay\n",
                    static_cast<long long>(l.source_seq));
      continue;
    }
    const CoCycle& p = *it->second;
    const std::int64_t dt = std::llabs(p.utime - l.utime);
    worst_dt_us = std::max(worst_dt_us, dt);
    if (dt > half_period_us) {
      ++far;
      continue;
    }
    ++paired;
    fresh_differed |= l.fresh ^ p.fresh;
    if (l.fresh != p.fresh) {
      ++fresh_differ;
      fresh_live_only += std::popcount(l.fresh & ~p.fresh);
      fresh_replay_only += std::popcount(p.fresh & ~l.fresh);
      if (reported++ < 5) {
        std::printf(
            "VCAN-REPLAY: source_seq %lld: fresh live 0x%x replay 0x%x (sample_flags %u / %u)\n",
            static_cast<long long>(l.source_seq), l.fresh, p.fresh, l.sample_flags, p.sample_flags);
      }
    } else if (l.fresh == 0x3FU) {
      ++whole;
      if (std::all_of(l.homed.begin(), l.homed.end(), [](bool h) { return h; })) ++whole_homed;
    }
    bool same_raw = true, same_pos = true, same_homed = true;
    for (std::size_t j = 0; j < 6; ++j) {
      const std::uint32_t bit = 1U << j;
      if ((l.fresh & p.fresh & bit) != 0) {
        ++compared_channels;
        same_raw = same_raw && l.raw[j] == p.raw[j];
      }
      if (l.homed[j] != p.homed[j]) {
        if ((fresh_differed & bit) != 0) {
          ++homed_moved;  // homed a cycle apart after a delivery difference
          continue;
        }
        same_homed = false;
      }
      if ((l.flags[j] & kHeld) != 0 || (p.flags[j] & kHeld) != 0) continue;
      const double d = std::fabs(p.pos[j] - l.pos[j]);
      worst = std::max(worst, d);
      same_pos = same_pos && d <= 1e-9;
    }
    if (!same_raw) ++raw_differ;
    if (!same_pos) ++pos_differ;
    if (!same_homed) ++homed_differ;
    if ((!same_raw || !same_pos || !same_homed) && reported++ < 10) {
      std::printf("VCAN-REPLAY: source_seq %lld: raw %s, angles %s, homed %s\n",
                  static_cast<long long>(l.source_seq), same_raw ? "same" : "DIFFER",
                  same_pos ? "same" : "DIFFER", same_homed ? "same" : "DIFFER");
      for (std::size_t j = 0; j < 6; ++j) {
        std::printf(
            "VCAN-REPLAY:   joint %zu: live %.17g homed %d flags %u raw %lld | replay %.17g "
            "homed %d flags %u raw %lld\n",
            j, l.pos[j], l.homed[j] ? 1 : 0, l.flags[j], static_cast<long long>(l.raw[j]), p.pos[j],
            p.homed[j] ? 1 : 0, p.flags[j], static_cast<long long>(p.raw[j]));
      }
    }
  }
  std::printf(
      "VCAN-REPLAY: canopen: live %zu messages, %lld cycles (source_seq 0..%lld); replay %zu "
      "cycles; paired by source_seq %lld (utime within half a period; worst %lld us), %lld not "
      "in the replay, %lld too far apart\n",
      live.size(), static_cast<long long>(cycles), static_cast<long long>(last_source_seq),
      replay.size(), static_cast<long long>(paired), static_cast<long long>(worst_dt_us),
      static_cast<long long>(unpaired), static_cast<long long>(far));
  std::printf(
      "VCAN-REPLAY: canopen: %lld channel positions compared (fresh on both sides), %lld "
      "cycles with all six fresh on both (%lld every joint homed); %lld cycles whose fresh "
      "channels differ (%lld channels fresh live only, %lld replayed only), after which %lld "
      "joint-cycles were homed on one side only; worst angle difference %.3g rad\n",
      static_cast<long long>(compared_channels), static_cast<long long>(whole),
      static_cast<long long>(whole_homed), static_cast<long long>(fresh_differ),
      static_cast<long long>(fresh_live_only), static_cast<long long>(fresh_replay_only),
      static_cast<long long>(homed_moved), worst);
  check(paired > 0 && unpaired == 0 && far == 0,
        "canopen: every live cycle is the replayed cycle of its source_seq, at its instant (" +
            std::to_string(unpaired) + " missing, " + std::to_string(far) + " too far)");
  check(raw_differ == 0, "canopen: same raw positions on every channel fresh on both sides (" +
                             std::to_string(raw_differ) + " cycles differ)");
  check(pos_differ == 0,
        "canopen: same joint angles (1e-9 rad, joints not HELD) in every "
        "pair (" +
            std::to_string(pos_differ) + " differ)");
  check(homed_differ == 0,
        "canopen: same homed in every pair but after a fresh difference on the joint (" +
            std::to_string(homed_differ) + " differ)");
  check(whole_homed > 0,
        "canopen: cycles with every channel fresh and every joint homed "
        "compared whole (" +
            std::to_string(whole_homed) + ")");
  std::printf("VCAN-REPLAY: %s (%d failed)\n", g_failures == 0 ? "PASS" : "FAIL", g_failures);
  return g_failures == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"exodaq-vcan-replay-check: the vcan VM's candump replays to the live angles"};
  std::string exodaq, source, work;
  app.add_option("--exodaq", exodaq, "the exodaq tool")->required();
  app.add_option("--source", source, "the source tree (config/vcan.yaml)")->required();
  app.add_option("--work", work, "run-vm-tests' work directory")->required();
  std::string protocol = "v1";
  app.add_option("--protocol", protocol, "v1: stage 2's recording; canopen: stage 6's")
      ->check(CLI::IsMember({"v1", "canopen"}));
  CLI11_PARSE(app, argc, argv);
  if (protocol == "canopen") return run_canopen(exodaq, source, work);

  const std::string candump = work + "/vcan-run.candump";
  const std::string live_path = work + "/vcan-run-live.txt";
  const bool have_candump = std::filesystem::exists(candump);
  const bool have_live = std::filesystem::exists(live_path);
  if (!have_candump && !have_live) {
    std::printf("SKIP: no %s nor %s: the VM test (vm_vcan) did not run here\n", candump.c_str(),
                live_path.c_str());
    return 77;
  }
  if (!have_candump || !have_live) {
    std::printf("VCAN-REPLAY: FAIL the VM ran but left only %s\n",
                have_candump ? candump.c_str() : live_path.c_str());
    return 1;
  }
  std::vector<Cycle> live;
  double rate_hz = 0;
  if (!read_live(live_path, live, rate_hz) || rate_hz <= 0) {
    std::printf("VCAN-REPLAY: FAIL cannot read %s\n", live_path.c_str());
    return 1;
  }
  const std::string config = write_config(source, work, rate_hz);
  const std::string out_lcm = work + "/vcan-replay.lcm";
  std::filesystem::remove(out_lcm);
  const auto r = exodaq::test::run({exodaq, "replay", candump, "--config", config, "--format",
                                    "candump", "--speed", "max", "--out", out_lcm, "--quiet"},
                                   std::chrono::seconds(120));
  std::printf("VCAN-REPLAY: exodaq replay (loop rate %g Hz) rc=%d\n%s%s", rate_hz, r.exit_code,
              r.out.c_str(), r.err.c_str());
  if (r.exit_code != 0) {
    std::printf("VCAN-REPLAY: FAIL exodaq replay exit code %d\n", r.exit_code);
    return 1;
  }
  std::vector<Cycle> replay;
  if (!read_replay(out_lcm, replay)) {
    std::printf("VCAN-REPLAY: FAIL cannot read %s\n", out_lcm.c_str());
    return 1;
  }

  // Replayed present cycles by board_seq; a live cycle pairs with the one
  // of its board_seq nearest in utime, within 64 loop periods (board_seq
  // repeats every 256 cycles: unambiguous). Not within a fraction of a
  // period: a live sample the loop closed at its read deadline with one
  // COUNTS frame carries that frame's instant, the replay's the instant of
  // the second frame, which can come several periods later (delay faults).
  const auto pairing_window_us = static_cast<std::int64_t>(64e6 / rate_hz);
  std::multimap<int, std::size_t> by_board_seq;
  for (std::size_t i = 0; i < replay.size(); ++i) {
    if (replay[i].present) by_board_seq.emplace(replay[i].board_seq, i);
  }
  std::vector<bool> replay_paired(replay.size(), false);
  constexpr std::uint32_t kPartial = exodaq::joint_state_t::SAMPLE_PARTIAL;
  constexpr std::uint32_t kHeld = exodaq::joint_state_t::JOINT_HELD;
  constexpr std::uint32_t kBusError = exodaq::joint_state_t::SAMPLE_BUS_ERROR;
  std::int64_t live_present = 0, live_homed = 0, live_homed_present = 0, common = 0, exact = 0,
               exact_homed = 0, partial_live = 0, utime_equal = 0, live_unpaired = 0,
               counts_differ = 0, pos_differ = 0, homed_differ = 0;
  double worst = 0;
  int reported = 0;
  for (const Cycle& l : live) {
    if (l.all_homed()) ++live_homed;
    if (!l.present) continue;
    ++live_present;
    if (l.all_homed()) ++live_homed_present;
    const Cycle* best = nullptr;
    std::size_t best_i = 0;
    const auto [lo, hi] = by_board_seq.equal_range(l.board_seq);
    for (auto it = lo; it != hi; ++it) {
      const Cycle& c = replay[it->second];
      if (std::llabs(c.utime - l.utime) > pairing_window_us) continue;
      if (best == nullptr || std::llabs(c.utime - l.utime) < std::llabs(best->utime - l.utime)) {
        best = &c;
        best_i = it->second;
      }
    }
    if (best == nullptr) {
      if (live_unpaired++ < 10) {
        std::printf("VCAN-REPLAY: live seq %lld (board seq %d, utime %lld) not in the replay\n",
                    static_cast<long long>(l.seq), l.board_seq, static_cast<long long>(l.utime));
      }
      continue;
    }
    replay_paired[best_i] = true;
    ++common;
    if (best->utime == l.utime) ++utime_equal;
    // The live loop closes a cycle at its read deadline (source.socketcan.
    // read_deadline_us after SYNC): when only one of the two COUNTS frames
    // was in by then (SAMPLE_PARTIAL, the other joints JOINT_HELD), the
    // candump replay, which has no deadline, still assembles the whole board
    // cycle. Those are compared on the joints the live sample had fresh.
    // A joint HELD on either side repeats the last fresh value that side's
    // loop saw, which depends on the board cycles it read (the live loop's
    // read deadlines: the machine's speed); neither its angle nor its count
    // is compared.
    const bool live_cut = (l.sample_flags & kPartial) != 0 && (best->sample_flags & kPartial) == 0;
    bool same_counts = true, same_pos = true;
    for (std::size_t j = 0; j < 6; ++j) {
      if ((l.flags[j] & kHeld) != 0 || (best->flags[j] & kHeld) != 0) continue;
      const double d = std::fabs(best->pos[j] - l.pos[j]);
      worst = std::max(worst, d);
      same_pos = same_pos && d <= 1e-9;
    }
    if (live_cut) {
      ++partial_live;
    } else {
      for (std::size_t j = 0; j < 6; ++j) {
        if ((l.flags[j] & kHeld) != 0 || (best->flags[j] & kHeld) != 0) continue;
        same_counts = same_counts && best->count16[j] == l.count16[j];
      }
      ++exact;
      if (l.all_homed()) ++exact_homed;
    }
    const bool same_homed = best->homed == l.homed;
    if (!same_counts) ++counts_differ;
    if (!same_pos) ++pos_differ;
    if (!same_homed) ++homed_differ;
    if ((!same_counts || !same_pos || !same_homed) && reported++ < 10) {
      std::printf(
          "VCAN-REPLAY: board seq %d utime %lld: live seq %lld (sample_flags %u) vs replay seq "
          "%lld (%u): counts %s, positions %s, homed %s\n",
          l.board_seq, static_cast<long long>(l.utime), static_cast<long long>(l.seq),
          l.sample_flags, static_cast<long long>(best->seq), best->sample_flags,
          same_counts ? "same" : "DIFFER", same_pos ? "same" : "DIFFER",
          same_homed ? "same" : "DIFFER");
      for (std::size_t j = 0; j < 6; ++j) {
        std::printf(
            "VCAN-REPLAY:   joint %zu: live %.17g homed %d flags %u count16 %d | replay "
            "%.17g homed %d flags %u count16 %d\n",
            j, l.pos[j], l.homed[j] ? 1 : 0, l.flags[j], l.count16[j], best->pos[j],
            best->homed[j] ? 1 : 0, best->flags[j], best->count16[j]);
      }
    }
  }

  // Replayed cycles no live cycle pairs with, by cause.
  // From live cycle `it` on: every cycle without a sample and without
  // SAMPLE_BUS_ERROR until the first with a sample, which holds a board cycle
  // newer than `board_seq` (the one the live loop never had in time).
  const auto taken_later = [](auto it, auto end, int board_seq) {
    if (it == end || (*it)->present) return false;
    for (; it != end && !(*it)->present; ++it) {
      if (((*it)->sample_flags & kBusError) != 0) return false;
    }
    return it != end &&
           static_cast<std::int8_t>(static_cast<std::uint8_t>((*it)->board_seq - board_seq)) > 0;
  };
  std::int64_t replay_present = 0, before_live = 0, after_live = 0, in_live_gap = 0, superseded = 0,
               late_delivery = 0, lost_down = 0, other = 0;
  const std::int64_t first_live_us = live.empty() ? 0 : live.front().utime;
  const std::int64_t last_live_us = live.empty() ? 0 : live.back().utime;
  // Live cycles by utime, to see what the live loop did at a replayed instant.
  std::vector<const Cycle*> live_by_time;
  for (const Cycle& l : live) live_by_time.push_back(&l);
  std::sort(live_by_time.begin(), live_by_time.end(),
            [](const Cycle* a, const Cycle* b) { return a->utime < b->utime; });
  for (std::size_t i = 0; i < replay.size(); ++i) {
    const Cycle& c = replay[i];
    if (!c.present) continue;
    ++replay_present;
    if (replay_paired[i]) continue;
    if (c.utime < first_live_us) {
      ++before_live;
      continue;
    }
    if (c.utime > last_live_us) {
      ++after_live;
      continue;
    }
    // The first live cycle at or after this instant. A present one of a
    // later board cycle: this board cycle completed after the live loop's
    // read deadline, and the next live cycle found it and the following one
    // and published the newer (the older superseded; the cycle in between
    // is published as missing). A seq jump before it: the live loop skipped
    // deadlines (overrun) while this board cycle went by.
    const auto it = std::lower_bound(live_by_time.begin(), live_by_time.end(), c.utime,
                                     [](const Cycle* a, std::int64_t t) { return a->utime < t; });
    if (it != live_by_time.begin() && it != live_by_time.end() &&
        (*it)->seq > (*(it - 1))->seq + 1) {
      ++in_live_gap;
    } else if (it != live_by_time.end() && (*it)->present &&
               static_cast<std::int8_t>(static_cast<std::uint8_t>((*it)->board_seq - c.board_seq)) >
                   0) {
      ++superseded;
    } else if (taken_later(it, live_by_time.end(), c.board_seq)) {
      // Stamped before the live read's deadline, yet the live read found
      // nothing: the kernel stamps a vcan frame when it is queued and delivers
      // it to the sockets later (under TCG emulation, one read window later
      // or more). The first live cycle with a sample then took a newer board
      // cycle.
      ++late_delivery;
    } else if (it != live_by_time.end() && !(*it)->present &&
               ((*it)->sample_flags & kBusError) != 0) {
      // Completed after the read deadline, and the next live cycle had no
      // sample and SAMPLE_BUS_ERROR: the interface went down with the frame
      // queued on the daemon's socket (the scenario's ip link set down).
      ++lost_down;
    } else if (other++ < 10) {
      std::printf(
          "VCAN-REPLAY: replay seq %lld board seq %d utime %lld: no live sample; next live seq "
          "%lld present %d board seq %d utime %lld\n",
          static_cast<long long>(c.seq), c.board_seq, static_cast<long long>(c.utime),
          it == live_by_time.end() ? -1LL : static_cast<long long>((*it)->seq),
          it == live_by_time.end() ? 0 : ((*it)->present ? 1 : 0),
          it == live_by_time.end() ? -1 : (*it)->board_seq,
          it == live_by_time.end() ? 0LL : static_cast<long long>((*it)->utime));
    }
  }

  std::printf(
      "VCAN-REPLAY: live: %zu cycles received, %lld with a sample, %lld with every joint homed "
      "(%lld of them with a sample)\n",
      live.size(), static_cast<long long>(live_present), static_cast<long long>(live_homed),
      static_cast<long long>(live_homed_present));
  std::printf("VCAN-REPLAY: replay: %zu cycles, %lld with a sample\n", replay.size(),
              static_cast<long long>(replay_present));
  std::printf(
      "VCAN-REPLAY: common board cycles: %lld, utime equal in %lld; "
      "compared whole: %lld (%lld with every joint homed); live cut at its read deadline "
      "(SAMPLE_PARTIAL live, whole in the replay: fresh joints compared): %lld; worst position "
      "difference %.3g rad\n",
      static_cast<long long>(common), static_cast<long long>(utime_equal),
      static_cast<long long>(exact), static_cast<long long>(exact_homed),
      static_cast<long long>(partial_live), worst);
  std::printf(
      "VCAN-REPLAY: live samples without a replayed board cycle: %lld; replayed samples without "
      "a live one: %lld before the first live cycle, %lld after the last, %lld where the live "
      "loop skipped seqs (overrun), %lld superseded live (completed after the read deadline, "
      "the next live cycle took the newer board cycle), %lld delivered to the sockets after the "
      "live read though stamped before it (superseded by the next), %lld queued when the "
      "interface went down, %lld other\n",
      static_cast<long long>(live_unpaired), static_cast<long long>(before_live),
      static_cast<long long>(after_live), static_cast<long long>(in_live_gap),
      static_cast<long long>(superseded), static_cast<long long>(late_delivery),
      static_cast<long long>(lost_down), static_cast<long long>(other));

  check(live_present > 0, "the live run delivered samples");
  check(live_unpaired == 0,
        "every live sample is a replayed board cycle (" + std::to_string(live_unpaired) + " not)");
  check(counts_differ == 0, "same raw counts (joints not HELD) in every cycle compared whole (" +
                                std::to_string(counts_differ) + " differ)");
  check(pos_differ == 0, "same joint positions (1e-9 rad) in every common cycle (" +
                             std::to_string(pos_differ) + " differ)");
  check(homed_differ == 0,
        "same homed in every common cycle (" + std::to_string(homed_differ) + " differ)");
  check(other == 0, "every replayed sample without a live one is explained (" +
                        std::to_string(other) + " not)");
  check(live_homed_present > 0 && exact_homed > 0,
        "all-homed cycles compared whole: " + std::to_string(exact_homed) + " of the " +
            std::to_string(live_homed_present) + " live all-homed cycles with a sample");
  std::printf("VCAN-REPLAY: %s (%d failed)\n", g_failures == 0 ? "PASS" : "FAIL", g_failures);
  return g_failures == 0 ? 0 : 1;
}
