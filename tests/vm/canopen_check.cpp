// exodaq-canopen-check: the subscriber of the VM test's CANopen stage
// (tests/vm/scenario.sh, stage 6). While exodaqd's canopen backend manages six
// nodes simulated by `exodaq-board-sim --protocol canopen` over a kernel vcan
// interface, it records every joint_state_t / encoder_raw_t / palm_pose_t /
// status_t; at SIGTERM it reads the simulator's truth file and judges.
//
// Matching: the canopen source numbers its cycles from 0 at its first SYNC
// (encoder_raw_t.source_seq, never wrapping) and the simulator writes one
// truth line per SYNC it received, k from 0: a sample of source_seq s is the
// SYNC of truth line k = s. A cycle's sample repeats the last one's
// source_seq only when no cycle was closed (MISSING): the first message of
// each source_seq (increasing) is matched, the others are not. The match is
// verified by the instants, all on the VM's CLOCK_MONOTONIC: the sample's
// mono_ns (its SYNC's kernel stamp read back, or the clock reading before
// sending it) is no later than the truth line's instant (the same SYNC's
// stamp at the simulator), which precedes the next cycle's mono_ns, both
// within the 1 ms the stamps' conversions may differ by; a SYNC the
// simulator did not see would make a truth line the next SYNC's and fail
// that check. Neither depends on how late either process ran.
//
// It checks, on the matched cycles:
//   - every valid sample (palm_pose_t.valid) has no invalidating flag, every
//     joint homed, and every angle within one count of the truth (counts per
//     revolution and gear ratio from the config);
//   - every fresh channel's raw position (encoder_raw_t.channel_fresh) equals
//     the truth count modulo encoder_raw_t.modulus, a channel not fresh
//     holds its joint flagged (HELD/STALE) or the sample invalidated;
//   - each injected fault (--fault kind:joint) was active in the truth and
//     every one of its cycles is flagged as drivers/canopen's canopen_source.hpp
//     says: emcy, heartbeat_stops: SAMPLE_BOARD_ERROR and board_errors bit of
//     the joint; tpdo_missing, tpdo_late (when read_deadline < the simulator's
//     700 us lateness), wrong_pdo_length: the joint's channel not fresh and the
//     sample PARTIAL (or MISSING). The first and the last cycle of a window
//     are not judged: the fault's begin or end races the SYNC and the cycle's
//     wait (an EMCY error reset or a heartbeat received before the cycle
//     closed clears it); heartbeat loss is due only heartbeat_timeout_ms after the last
//     heartbeat (the producer sends every two thirds of it), so its first
//     heartbeat_timeout_ms + one period are not judged;
//   - no flagged sample valid;
//   - a channel whose node answered an earlier SYNC after this cycle's SYNC
//     instant (the simulator's --answers file: when each TPDO had left) is
//     not judged in this cycle, nor is the cycle's validity: such an answer
//     breaks CiA 301's timing, the manager cannot tell it from this cycle's
//     own (docs/can-protocol.md), and a simulator descheduled on a loaded
//     machine sends it; how many there were is printed;
//   - after the first all-homed sample and outside every fault window, a
//     cycle with all six channels fresh and nothing flagged (sample or
//     joint) is valid, and at least one such cycle was judged; how many
//     there are the machine's speed decides (a TPDO late under load makes
//     its channel stale, which is flagged and judged above), so no share
//     of them is required.
// --live-out FILE also writes every received cycle as text for the host-side
// candump replay comparison (vcan_replay_check.cpp --protocol canopen).
// Prints a table and "CANOPEN-CHECK: PASS"/"FAIL"; exit 0 only on PASS.
#include <poll.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "exodaq/drivers/canopen/canopen_backend.hpp"
#include "exodaq/drivers/canopen/node_sim.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/settings/service_config.hpp"
#include "exodaq/status_t.hpp"
#include "process.hpp"
#include "vm_check.hpp"

namespace {

namespace co = exodaq::drivers::canopen;

using exodaq::vm::g_stop;
using exodaq::vm::on_signal;
using exodaq::vm::parse_board_log;
using exodaq::vm::Truth;

using JS = exodaq::joint_state_t;
constexpr std::uint32_t kMissing = JS::SAMPLE_MISSING, kBoardError = JS::SAMPLE_BOARD_ERROR,
                        kBusError = JS::SAMPLE_BUS_ERROR, kPartial = JS::SAMPLE_PARTIAL;
constexpr std::uint32_t kInvalidating = kMissing | kPartial | kBoardError | kBusError;
constexpr std::uint32_t kJointBoardError = JS::JOINT_BOARD_ERROR;
// Instants this close may be in either order: both sides move the kernel's
// realtime receive stamps to the monotonic clock by an estimated offset.
constexpr std::int64_t kStampMarginNs = 1'000'000;
constexpr std::int64_t kSimLateNs = 700'000;  // the simulator's tpdo_late (docs/can-protocol.md)

struct Rec {
  bool js = false, raw = false, palm = false;
  std::int64_t utime = 0;
  std::uint32_t sample_flags = 0;
  std::array<std::uint32_t, 6> jflags{};
  std::array<bool, 6> homed{};
  std::array<double, 6> pos{};
  bool present = false;
  std::int64_t source_seq = -1;
  std::int64_t mono_ns = 0;
  std::array<std::int64_t, 6> raw_pos{};
  std::array<std::int64_t, 6> modulus{};
  std::uint32_t fresh = 0, board_errors = 0, source_flags = 0;
  bool valid = false;
  std::int64_t k = -1;  // truth line matched (-1: none)
  // Channels an earlier SYNC's answer may have filled (not judged).
  std::uint32_t overtaken = 0;
  bool all_homed() const {
    return std::all_of(homed.begin(), homed.end(), [](bool h) { return h; });
  }
};

class Recorder {
 public:
  std::vector<Rec> recs;
  std::vector<exodaq::status_t> statuses;
  Rec& at(std::int64_t seq) {
    if (seq < 0) seq = 0;
    if (static_cast<std::size_t>(seq) >= recs.size())
      recs.resize(static_cast<std::size_t>(seq) + 1);
    return recs[static_cast<std::size_t>(seq)];
  }
  void js(const lcm::ReceiveBuffer*, const std::string&, const exodaq::joint_state_t* m) {
    Rec& r = at(m->seq);
    r.js = true;
    r.utime = m->utime;
    r.sample_flags = static_cast<std::uint32_t>(m->sample_flags);
    for (std::size_t i = 0; i < 6; ++i) {
      r.jflags[i] = static_cast<std::uint32_t>(m->flags[i]);
      r.homed[i] = m->homed[i];
      r.pos[i] = m->position[i];
    }
  }
  void raw(const lcm::ReceiveBuffer*, const std::string&, const exodaq::encoder_raw_t* m) {
    Rec& r = at(m->seq);
    r.raw = true;
    r.present = m->present;
    r.source_seq = m->source_seq;
    r.mono_ns = m->mono_ns;
    for (std::size_t i = 0; i < 6; ++i) {
      r.raw_pos[i] = m->position[i];
      r.modulus[i] = m->modulus[i];
    }
    r.fresh = static_cast<std::uint32_t>(m->channel_fresh);
    r.board_errors = static_cast<std::uint32_t>(m->board_errors);
    r.source_flags = static_cast<std::uint32_t>(m->source_flags);
  }
  void palm(const lcm::ReceiveBuffer*, const std::string&, const exodaq::palm_pose_t* m) {
    Rec& r = at(m->seq);
    r.palm = true;
    r.valid = m->valid;
  }
  void status(const lcm::ReceiveBuffer*, const std::string&, const exodaq::status_t* m) {
    statuses.push_back(*m);
  }
};

exodaq::vm::Verdicts g_verdicts{"CANOPEN-CHECK"};
void check(bool ok, const std::string& what) {
  g_verdicts.check(ok, what);
}

// One line per cycle with joint_state_t and encoder_raw_t (doubles in %.17g:
// exact), for exodaq-vcan-replay-check --protocol canopen.
bool write_live(const std::string& path, const Recorder& rec, double rate_hz) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return false;
  std::fprintf(f,
               "# exodaq-canopen-check live cycles, rate_hz %.17g\n"
               "# seq utime present source_seq mono_ns sample_flags source_flags valid "
               "channel_fresh position[6] homed[6] flags[6] angle[6]\n",
               rate_hz);
  for (std::size_t s = 0; s < rec.recs.size(); ++s) {
    const Rec& r = rec.recs[s];
    if (!(r.js && r.raw)) continue;
    std::fprintf(f, "%zu %lld %d %lld %lld %u %u %d %u", s, static_cast<long long>(r.utime),
                 r.present ? 1 : 0, static_cast<long long>(r.source_seq),
                 static_cast<long long>(r.mono_ns), r.sample_flags, r.source_flags, r.valid ? 1 : 0,
                 r.fresh);
    for (auto p : r.raw_pos) std::fprintf(f, " %lld", static_cast<long long>(p));
    for (bool h : r.homed) std::fprintf(f, " %d", h ? 1 : 0);
    for (auto jf : r.jflags) std::fprintf(f, " %u", jf);
    for (double q : r.pos) std::fprintf(f, " %.17g", q);
    std::fprintf(f, "\n");
  }
  return std::fclose(f) == 0;
}

struct Fault {
  co::SimFault kind = co::SimFault::kEmcy;
  int joint = 0;  // 0-based
  std::string name;
};

bool parse_fault(const std::string& text, Fault& out) {
  const auto colon = text.find(':');
  if (colon == std::string::npos) return false;
  out.name = text.substr(0, colon);
  out.joint = std::atoi(text.c_str() + colon + 1) - 1;
  if (out.joint < 0 || out.joint >= 6) return false;
  // exodaq-board-sim's --fault kinds: co::SimFault's names with '_' for ' '.
  std::string spaced = out.name;
  std::replace(spaced.begin(), spaced.end(), '_', ' ');
  for (int k = 0; k < co::kSimFaultCount; ++k) {
    if (co::to_string(static_cast<co::SimFault>(k)) == spaced) {
      out.kind = static_cast<co::SimFault>(k);
      return true;
    }
  }
  return false;
}

// The simulator's start on CLOCK_MONOTONIC ("# origin_mono_ns N" in its
// truth file); 0: not given.
std::int64_t read_origin(const std::string& truth_path) {
  std::ifstream in(truth_path);
  std::string line;
  const std::string key = "# origin_mono_ns ";
  while (std::getline(in, line)) {
    if (line.rfind(key, 0) == 0) return std::atoll(line.c_str() + key.size());
  }
  return 0;
}

// One line of the simulator's answers file: a TPDO, the SYNC it answered
// and when it had left.
struct Answer {
  std::int64_t k = 0;
  int channel = 0;
  std::int64_t sent_ns = 0;
};

std::vector<Answer> read_answers(const std::string& path) {
  std::vector<Answer> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    Answer a;
    s >> a.k >> a.channel >> a.sent_ns;
    if (s && a.channel >= 0 && a.channel < 6) out.push_back(a);
  }
  std::stable_sort(out.begin(), out.end(),
                   [](const Answer& a, const Answer& b) { return a.k < b.k; });
  return out;
}

// Marks, in each matched cycle, the channels an answer to an earlier SYNC
// reached after (or within the stamps' margin before) the cycle's SYNC
// instant; returns how many channel-cycles that is. `by_k`: matched records
// by truth line.
std::int64_t mark_overtaken(const std::vector<Answer>& answers, std::vector<Rec*>& by_k) {
  std::array<std::int64_t, 6> last_sent{};  // per channel, over the SYNCs before k
  std::size_t next = 0;
  std::int64_t marked = 0;
  for (std::size_t k = 0; k < by_k.size(); ++k) {
    for (; next < answers.size() && answers[next].k < static_cast<std::int64_t>(k); ++next) {
      auto& t = last_sent[static_cast<std::size_t>(answers[next].channel)];
      t = std::max(t, answers[next].sent_ns);
    }
    Rec* r = by_k[k];
    if (r == nullptr) continue;
    for (std::size_t c = 0; c < 6; ++c) {
      if (last_sent[c] != 0 && last_sent[c] + kStampMarginNs >= r->mono_ns) {
        r->overtaken |= 1U << c;
        ++marked;
      }
    }
  }
  return marked;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"exodaq-canopen-check: subscriber/checker of the VM test's CANopen stage"};
  std::string config_path, truth_path, answers_path, board_log, url, live_out;
  std::vector<std::string> fault_texts;
  app.add_option("--config", config_path)->required();
  app.add_option("--truth", truth_path)->required();
  app.add_option("--answers", answers_path,
                 "exodaq-board-sim's --answers file: when each TPDO had left")
      ->required();
  app.add_option("--board-log", board_log, "exodaq-board-sim's stderr (BOARD-SIM: counters)");
  app.add_option("--url", url, "LCM URL (default: the config's)");
  app.add_option("--fault", fault_texts,
                 "an injected fault, kind:joint (joint 1..6; kind as exodaq-board-sim's --fault)");
  app.add_option("--live-out", live_out,
                 "also write every received cycle to this file (not checked here)");
  CLI11_PARSE(app, argc, argv);

  const auto cfg = exodaq::settings::load_service_config(config_path);
  const auto* settings = cfg.source.section_as<co::CanopenSettings>("canopen");
  if (settings == nullptr) {
    std::printf("CANOPEN-CHECK: FAIL %s has no source.canopen\n", config_path.c_str());
    return 1;
  }
  const co::CanopenSourceConfig& cc = settings->config;
  std::vector<Fault> faults;
  for (const std::string& t : fault_texts) {
    Fault f;
    if (!parse_fault(t, f)) {
      std::printf("CANOPEN-CHECK: FAIL --fault %s: want kind:joint\n", t.c_str());
      return 1;
    }
    faults.push_back(f);
  }
  if (url.empty()) url = cfg.lcm.url;
  const std::string prefix = cfg.lcm.prefix;
  lcm::LCM lc(url);
  if (!lc.good()) {
    std::printf("CANOPEN-CHECK: FAIL LCM %s not usable\n", url.c_str());
    return 1;
  }
  Recorder rec;
  rec.recs.reserve(1 << 16);
  // Unbounded queues: LCM's default of 30 messages would drop silently.
  lc.subscribe(prefix + "EXO_JOINT_STATE", &Recorder::js, &rec)->setQueueCapacity(0);
  lc.subscribe(prefix + "EXO_ENCODER_RAW", &Recorder::raw, &rec)->setQueueCapacity(0);
  lc.subscribe(prefix + "EXO_PALM_POSE", &Recorder::palm, &rec)->setQueueCapacity(0);
  lc.subscribe(prefix + "EXO_STATUS", &Recorder::status, &rec)->setQueueCapacity(0);
  std::signal(SIGTERM, on_signal);
  std::signal(SIGINT, on_signal);
  std::printf("CANOPEN-CHECK: recording (%s)\n", url.c_str());
  std::fflush(stdout);
  while (!g_stop.load()) {
    pollfd p{lc.getFileno(), POLLIN, 0};
    if (poll(&p, 1, 50) > 0 && (p.revents & POLLIN)) lc.handle();
  }
  for (int i = 0; i < 20; ++i) lc.handleTimeout(10);  // the last messages in flight

  if (!live_out.empty()) {
    const bool ok = write_live(live_out, rec, cfg.loop.rate_hz);
    std::printf("CANOPEN-CHECK: live cycles %s %s\n", ok ? "written to" : "NOT written to",
                live_out.c_str());
  }

  // --- truth -------------------------------------------------------------
  const std::vector<Truth> truth = exodaq::vm::read_truth(truth_path, true);
  const std::vector<Answer> answers = read_answers(answers_path);
  const auto board = parse_board_log(board_log);
  const auto rate = cfg.loop.rate_hz;
  const auto period_ns = static_cast<std::int64_t>(1e9 / rate);
  std::printf(
      "CANOPEN-CHECK: %zu cycles published, %zu status, %zu truth lines (SYNCs), rate %g Hz, "
      "read_deadline %lld us, heartbeat timeout %lld ms; board-sim syncs=%lld tpdos=%lld\n",
      rec.recs.size(), rec.statuses.size(), truth.size(), rate,
      static_cast<long long>(cc.read_deadline_ns / 1000),
      static_cast<long long>(cc.heartbeat_timeout_ns / 1'000'000),
      board.contains("syncs") ? board.at("syncs") : -1LL,
      board.contains("tpdos") ? board.at("tpdos") : -1LL);
  check(!truth.empty() && !rec.statuses.empty() && static_cast<double>(truth.size()) > 3 * rate,
        "ran >= 3 s of SYNCs with data on every side");
  if (truth.empty() || rec.statuses.empty()) {
    std::printf("CANOPEN-CHECK: FAIL\n");
    return 1;
  }
  const exodaq::status_t& last = rec.statuses.back();

  // --- matching: source_seq == truth k, verified by the instants ----------
  std::int64_t matched = 0, unmatched_repeat = 0, beyond_truth = 0, received = 0;
  std::int64_t last_source_seq = -1;
  std::vector<Rec*> by_k(truth.size(), nullptr);
  for (Rec& r : rec.recs) {
    if (!(r.js && r.raw && r.palm)) continue;
    ++received;
    if (r.source_seq < 0 || r.source_seq <= last_source_seq) {
      if (r.source_seq >= 0) ++unmatched_repeat;
      continue;
    }
    last_source_seq = r.source_seq;
    if (r.source_seq >= static_cast<std::int64_t>(truth.size())) {
      ++beyond_truth;  // cycles after the simulator stopped
      continue;
    }
    r.k = r.source_seq;
    by_k[static_cast<std::size_t>(r.k)] = &r;
    ++matched;
  }
  // Causally, on the one CLOCK_MONOTONIC of the VM: cycle k's instant is
  // SYNC k's stamp (read back) or the clock reading before sending it; the
  // nodes receive it (truth line k's instant) before cycle k + 1 begins. A
  // SYNC the nodes missed would make truth line k the daemon's SYNC k + 1.
  const std::int64_t origin = read_origin(truth_path);
  std::int64_t acausal = 0, worst_lead = INT64_MIN, worst_after_next = INT64_MIN;
  for (std::size_t k = 0; origin != 0 && k < by_k.size(); ++k) {
    if (by_k[k] == nullptr) continue;
    const std::int64_t at = origin + std::llround(truth[k].t * 1e9);
    const std::int64_t lead = by_k[k]->mono_ns - at;  // <= 0: clock read before the SYNC arrived
    worst_lead = std::max(worst_lead, lead);
    bool ok = lead <= kStampMarginNs;
    if (k + 1 < by_k.size() && by_k[k + 1] != nullptr) {
      const std::int64_t after_next = at - by_k[k + 1]->mono_ns;  // < 0: arrived before cycle k+1
      worst_after_next = std::max(worst_after_next, after_next);
      ok = ok && after_next < kStampMarginNs;
    }
    if (!ok) ++acausal;
  }
  std::printf(
      "CANOPEN-CHECK: %lld cycles received, %lld matched to a truth line by source_seq (%lld "
      "repeating the last source_seq: no cycle closed; %lld after the simulator's last SYNC); "
      "sample instant minus the SYNC's stamp at the nodes at most %.3f ms, the SYNC at the nodes "
      "before the next cycle's instant by at least %.3f ms\n",
      static_cast<long long>(received), static_cast<long long>(matched),
      static_cast<long long>(unmatched_repeat), static_cast<long long>(beyond_truth),
      static_cast<double>(worst_lead) / 1e6, static_cast<double>(-worst_after_next) / 1e6);
  check(origin != 0, "the truth gives the simulator's start (# origin_mono_ns)");
  check(matched > 0 && acausal == 0,
        "every matched cycle's SYNC reached the nodes after the daemon's cycle began and before "
        "its next one (" +
            std::to_string(acausal) + " did not)");
  // Every cycle the daemon ran from the first one heard here to its last
  // status reached this checker, but for counted losses.
  std::int64_t first_seq = -1, holes = 0;
  const auto covered = static_cast<std::size_t>(
      std::min<std::int64_t>(last.seq + 1, static_cast<std::int64_t>(rec.recs.size())));
  for (std::size_t s = 0; s < covered; ++s) {
    const Rec& r = rec.recs[s];
    if (r.js || r.raw || r.palm) {
      if (first_seq < 0) first_seq = static_cast<std::int64_t>(s);
    } else if (first_seq >= 0) {
      ++holes;
    }
  }
  const std::int64_t drops = exodaq::test::udp_drops(getpid());
  check(holes <= last.overruns + last.publish_failures + drops,
        "cycles received: every seq hole a skipped deadline, a publish failure or this "
        "checker's socket drop (" +
            std::to_string(holes) + " <= " + std::to_string(last.overruns) + " + " +
            std::to_string(last.publish_failures) + " + " + std::to_string(drops) + ")");
  auto truth_of = [&](const Rec& r) -> const Truth* {
    return r.k < 0 ? nullptr : &truth[static_cast<std::size_t>(r.k)];
  };
  const std::int64_t overtaken = mark_overtaken(answers, by_k);
  std::printf(
      "CANOPEN-CHECK: %zu TPDOs in the simulator's answers; %lld channel-cycles not judged: an "
      "answer to an earlier SYNC left after (or less than %lld us before) the cycle's SYNC\n",
      answers.size(), static_cast<long long>(overtaken),
      static_cast<long long>(kStampMarginNs / 1000));
  check(!answers.empty(), "the simulator's answers file lists its TPDOs");

  // --- angles, raw positions, flags --------------------------------------
  const double two_pi = 2.0 * std::numbers::pi;
  std::array<double, 6> one_count{};
  for (std::size_t j = 0; j < 6; ++j) {
    one_count[j] = two_pi / (static_cast<double>(cfg.encoders.counts_per_rev()) *
                             cfg.encoders.joints[j].gear_ratio);
  }
  std::int64_t valid = 0, valid_flagged = 0, valid_wrong = 0, valid_compared = 0,
               valid_overtaken = 0, fresh_channels = 0, fresh_wrong = 0, stale_unflagged = 0,
               board_unflagged = 0;
  double worst_counts = 0;
  int reported = 0;
  std::int64_t first_homed_k = -1;
  for (const Rec& r : rec.recs) {
    if (!(r.js && r.raw && r.palm)) continue;
    bool flagged = (r.sample_flags & kInvalidating) != 0;
    for (std::size_t j = 0; j < 6; ++j) flagged = flagged || r.jflags[j] != 0 || !r.homed[j];
    if (r.valid) {
      ++valid;
      if (flagged) ++valid_flagged;
    }
    const Truth* t = truth_of(r);
    if (t == nullptr) continue;
    if (first_homed_k < 0 && r.all_homed()) first_homed_k = r.k;
    for (std::size_t c = 0; c < 6; ++c) {
      const std::uint32_t bit = 1U << c;
      if ((r.overtaken & bit) != 0) continue;
      if ((r.fresh & bit) != 0) {
        ++fresh_channels;
        const std::int64_t m = r.modulus[c];
        std::int64_t want = m > 0 ? t->count[c] % m : t->count[c];
        if (want < 0) want += m;
        if (r.raw_pos[c] != want) {
          ++fresh_wrong;
          if (reported++ < 10) {
            std::printf(
                "CANOPEN-CHECK: seq k=%lld channel %zu: position %lld, truth %lld mod %lld = "
                "%lld\n",
                static_cast<long long>(r.k), c, static_cast<long long>(r.raw_pos[c]),
                static_cast<long long>(t->count[c]), static_cast<long long>(m),
                static_cast<long long>(want));
          }
        }
      } else if (r.jflags[c] == 0 && (r.sample_flags & kInvalidating) == 0) {
        ++stale_unflagged;
      }
      if ((r.board_errors & bit) != 0 && (r.sample_flags & kBoardError) == 0 &&
          (r.jflags[c] & kJointBoardError) == 0) {
        ++board_unflagged;
      }
    }
    if (!r.valid) continue;
    if ((r.overtaken & r.fresh) != 0) {
      ++valid_overtaken;
      continue;
    }
    ++valid_compared;
    double worst = 0;
    for (std::size_t j = 0; j < 6; ++j)
      worst = std::max(worst, std::fabs(r.pos[j] - t->q[j]) / one_count[j]);
    worst_counts = std::max(worst_counts, worst);
    if (worst > 1.0 + 1e-6) {
      ++valid_wrong;
      if (reported++ < 10) {
        std::printf("CANOPEN-CHECK: valid k=%lld off by %.3f counts:", static_cast<long long>(r.k),
                    worst);
        for (std::size_t j = 0; j < 6; ++j) std::printf(" %.6f/%.6f", r.pos[j], t->q[j]);
        std::printf("\n");
      }
    }
  }
  std::printf(
      "CANOPEN-CHECK: %lld valid samples (%lld compared with truth, %lld holding an overtaking "
      "answer), worst error %.3f counts; %lld fresh channel positions compared with truth mod "
      "modulus (%lld differ)\n",
      static_cast<long long>(valid), static_cast<long long>(valid_compared),
      static_cast<long long>(valid_overtaken), worst_counts, static_cast<long long>(fresh_channels),
      static_cast<long long>(fresh_wrong));
  check(valid_compared > 0 && valid_compared + valid_overtaken == valid,
        "valid samples exist and every one is matched to a truth line");
  check(valid_wrong == 0,
        "every valid sample within one count of truth (" + std::to_string(valid_wrong) + " off)");
  check(valid_flagged == 0,
        "no flagged (or unhomed) sample published valid (" + std::to_string(valid_flagged) + ")");
  check(fresh_channels > 0 && fresh_wrong == 0,
        "every fresh channel's position == truth count mod modulus (" +
            std::to_string(fresh_wrong) + " differ)");
  check(stale_unflagged == 0,
        "every channel not fresh has its joint flagged or the sample "
        "invalidated (" +
            std::to_string(stale_unflagged) + " not)");
  check(board_unflagged == 0,
        "every board_errors joint bit has BOARD_ERROR on the sample or "
        "joint (" +
            std::to_string(board_unflagged) + " not)");

  // --- faults ---------------------------------------------------------------
  std::printf("CANOPEN-CHECK: fault table\n");
  std::printf(
      "CANOPEN-CHECK: | fault | joint | truth cycles (board-sim) | judged | flagged as due | "
      "not flagged | judged valid |\n");
  for (const Fault& f : faults) {
    const std::uint32_t bit = 1U << (16U + static_cast<unsigned>(f.kind));
    const std::uint32_t jbit = 1U << f.joint;
    const bool node_fault =
        f.kind == co::SimFault::kEmcy || f.kind == co::SimFault::kHeartbeatStops;
    const bool late_judged = f.kind != co::SimFault::kTpdoLate || cc.read_deadline_ns < kSimLateNs;
    // Not judged: the first and last cycle, and the heartbeat consumer's
    // timeout + a period from the window's begin.
    const double grace_s = f.kind == co::SimFault::kHeartbeatStops
                               ? static_cast<double>(cc.heartbeat_timeout_ns + period_ns) / 1e9
                               : 0.0;
    std::int64_t applied = 0, judged = 0, ok = 0, bad = 0, flagged_valid = 0;
    double start_t = -1;
    for (const Truth& t : truth) {
      if ((t.faults & bit) == 0) continue;
      ++applied;
      if (start_t < 0 || (t.k > 0 && (truth[static_cast<std::size_t>(t.k - 1)].faults & bit) == 0))
        start_t = t.t;  // a window begins
      const Rec* r = by_k[static_cast<std::size_t>(t.k)];
      if (r == nullptr) continue;
      const bool first_cycle =
          t.k == 0 || (truth[static_cast<std::size_t>(t.k - 1)].faults & bit) == 0;
      const bool last_cycle = static_cast<std::size_t>(t.k) + 1 == truth.size() ||
                              (truth[static_cast<std::size_t>(t.k + 1)].faults & bit) == 0;
      if (first_cycle || last_cycle || t.t - start_t < grace_s || !late_judged) continue;
      if (!node_fault && (r->overtaken & jbit) != 0) continue;  // an earlier answer may fill it
      ++judged;
      if (r->valid) ++flagged_valid;
      bool due = false;
      if (node_fault) {
        due = (r->sample_flags & kBoardError) != 0 && (r->board_errors & jbit) != 0;
      } else {
        due = (r->fresh & jbit) == 0 && (r->sample_flags & (kPartial | kMissing)) != 0;
      }
      if (due) {
        ++ok;
      } else {
        ++bad;
        if (bad <= 5) {
          std::printf(
              "CANOPEN-CHECK: %s joint %d truth k=%lld t=%.3f s: sample_flags 0x%x fresh 0x%x "
              "board_errors 0x%x\n",
              f.name.c_str(), f.joint + 1, static_cast<long long>(t.k), t.t, r->sample_flags,
              r->fresh, r->board_errors);
        }
      }
    }
    const long long sim = board.contains(f.name) ? board.at(f.name) : -1;
    std::printf("CANOPEN-CHECK: | %s | %d | %lld (%lld) | %lld | %lld | %lld | %lld |\n",
                f.name.c_str(), f.joint + 1, static_cast<long long>(applied), sim,
                static_cast<long long>(judged), static_cast<long long>(ok),
                static_cast<long long>(bad), static_cast<long long>(flagged_valid));
    check(applied > 0, f.name + ": active on some SYNC (truth)");
    if (!late_judged) {
      std::printf(
          "CANOPEN-CHECK: %s: not judged: read_deadline %lld us >= the simulator's 700 us\n",
          f.name.c_str(), static_cast<long long>(cc.read_deadline_ns / 1000));
      continue;
    }
    check(judged > 0 && bad == 0, f.name + " on joint " + std::to_string(f.joint + 1) +
                                      ": every cycle of it flagged as due (" + std::to_string(ok) +
                                      "/" + std::to_string(judged) + ")");
    check(flagged_valid == 0, f.name + ": none of its judged cycles valid");
  }

  // --- the floor of valid samples after homing ------------------------------
  // Outside the fault windows (and a second after each, the faults' tails:
  // a heartbeat's return, velocity windows), after the first all-homed sample.
  std::int64_t clean = 0, clean_complete = 0, clean_valid = 0, clean_unexplained = 0;
  const auto tail = static_cast<std::int64_t>(rate);
  std::int64_t last_fault_k = -tail - 1;
  for (const Truth& t : truth) {
    if (t.faults != 0) last_fault_k = t.k;
    if (first_homed_k < 0 || t.k < first_homed_k || t.k - last_fault_k <= tail) continue;
    const Rec* r = by_k[static_cast<std::size_t>(t.k)];
    if (r == nullptr) continue;
    ++clean;
    if (r->fresh == 0x3FU) ++clean_complete;
    if (r->valid) ++clean_valid;
    const bool flagged =
        r->sample_flags != 0 ||
        std::any_of(r->jflags.begin(), r->jflags.end(), [](std::uint32_t f) { return f != 0; });
    if (r->fresh == 0x3FU && r->all_homed() && !flagged && !r->valid) ++clean_unexplained;
  }
  std::printf(
      "CANOPEN-CHECK: after homing (truth k >= %lld), outside the fault windows: %lld cycles, "
      "%lld with all six channels fresh, %lld valid\n",
      static_cast<long long>(first_homed_k), static_cast<long long>(clean),
      static_cast<long long>(clean_complete), static_cast<long long>(clean_valid));
  check(first_homed_k >= 0, "every joint homed");
  check(clean_valid > 0, "some clean cycle after homing judged valid (" +
                             std::to_string(clean_valid) + " of " + std::to_string(clean) + ")");
  check(clean_unexplained == 0, "every complete, homed, unflagged clean cycle valid (" +
                                    std::to_string(clean_unexplained) + " invalid without a flag)");

  std::printf(
      "CANOPEN-CHECK: status: cycles %lld frames %lld bad_frames %lld missing %lld seq_gaps %lld "
      "bus_errors %lld rx_overflows %lld overruns %lld bus_state %d state %d \"%s\"\n",
      static_cast<long long>(last.cycles), static_cast<long long>(last.frames),
      static_cast<long long>(last.bad_frames), static_cast<long long>(last.missing_samples),
      static_cast<long long>(last.seq_gaps), static_cast<long long>(last.bus_errors),
      static_cast<long long>(last.rx_overflows), static_cast<long long>(last.overruns),
      last.bus_state, last.state, last.message.c_str());
  std::printf("CANOPEN-CHECK: %s (%d failed)\n", g_verdicts.failures() == 0 ? "PASS" : "FAIL",
              g_verdicts.failures());
  return g_verdicts.failures() == 0 ? 0 : 1;
}
