// Random byte corruptions in a recording, and what export and replay keep
// (issue 25 item 2, "Done when"): every event outside the damaged ranges
// kept, counted against the original; exit 1; each range named.
//   exodaq_test_damage_check EXODAQ CONFIG LOG WORKDIR CORRUPTIONS SEED
// Writes WORKDIR/damaged.lcm (LOG with CORRUPTIONS bytes changed: the first
// in a random event's data length, the rest anywhere), exports and replays
// LOG and the damaged copy, and checks:
//  - every reported damaged range holds a corrupted byte, and every corrupted
//    sync word or length byte lies in one;
//  - export and replay exit 1 and name every range;
//  - every CSV row of the original whose joint_state_t and palm_pose_t events
//    were not touched is in the damaged export, identical; no row is added;
//  - the replay reads every encoder_raw_t sample but those touched.
// Prints one line of figures (DAMAGE-CHECK: ...); exit 0 when every check
// holds, 1 with the failures.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "process.hpp"

namespace {

using namespace exodaq;
namespace fs = std::filesystem;

struct Index {
  std::vector<std::int64_t> offsets;
  std::vector<std::int64_t> seq;   // joint, palm and raw events: their seq; else -1
  std::vector<std::uint8_t> kind;  // 1 joint, 2 palm, 3 raw, 0 other
  std::int64_t size = 0;
};

Index index_log(const std::string& path) {
  Index ix;
  messages::LogReader log(path);
  messages::LogEvent ev;
  while (log.next(ev)) {
    ix.offsets.push_back(ev.offset);
    std::uint8_t k = 0;
    std::int64_t s = -1;
    if (const auto parts = messages::split_channel(ev.channel)) {
      if (parts->kind == messages::Kind::kJointState) k = 1;
      if (parts->kind == messages::Kind::kPalmPose) k = 2;
      if (parts->kind == messages::Kind::kEncoderRaw) k = 3;
      if (const auto st = messages::peek_stamp(ev.data, ev.size); k != 0 && st) s = st->stamp.seq;
    }
    ix.kind.push_back(k);
    ix.seq.push_back(s);
  }
  ix.size = log.file_size();
  if (!log.damage().empty()) throw std::runtime_error(path + " is damaged already");
  return ix;
}

double seconds_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

// "utime,mono,seq,..." -> seq
std::int64_t seq_of_row(const std::string& line) {
  std::size_t a = line.find(',');
  a = line.find(',', a + 1);
  return std::atoll(line.c_str() + a + 1);
}

std::int64_t samples_of(const std::string& replay_out) {
  std::smatch m;
  static const std::regex r(R"(input: \d+ events, (\d+) samples)");
  return std::regex_search(replay_out, m, r) ? std::stoll(m[1]) : -1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 7) {
    std::fprintf(stderr, "usage: %s EXODAQ CONFIG LOG WORKDIR CORRUPTIONS SEED\n", argv[0]);
    return 2;
  }
  const std::string exodaq = argv[1];
  const std::string config = argv[2];
  const std::string original = argv[3];
  const std::string dir = argv[4];
  const int corruptions = std::atoi(argv[5]);
  const unsigned seed = static_cast<unsigned>(std::atoi(argv[6]));
  const auto timeout = std::chrono::hours(2);
  std::vector<std::string> failures;
  const auto check = [&](bool ok, const std::string& what) {
    if (!ok) failures.push_back(what);
  };

  const Index ix = index_log(original);
  const std::string damaged = dir + "/damaged.lcm";
  fs::remove(damaged);
  fs::copy_file(original, damaged);
  std::mt19937_64 rng(seed);
  std::set<std::int64_t> hit;
  {
    std::fstream f(damaged, std::ios::in | std::ios::out | std::ios::binary);
    const auto first =
        ix.offsets[rng() % ix.offsets.size()] + 24 + static_cast<std::int64_t>(rng() % 4);
    hit.insert(first);
    while (static_cast<int>(hit.size()) < corruptions)
      hit.insert(static_cast<std::int64_t>(rng() % ix.size));
    for (const std::int64_t at : hit) {
      f.seekg(at);
      char c = 0;
      f.read(&c, 1);
      c = static_cast<char>(c ^ static_cast<char>(1 + rng() % 255));
      f.seekp(at);
      f.write(&c, 1);
    }
  }
  // What each corrupted byte touched.
  std::set<std::int64_t> touched_rows;  // seq of a touched joint or palm event
  std::int64_t touched_raw = 0;
  std::set<std::int64_t> header_bytes;  // corrupted sync words and lengths
  std::set<std::size_t> touched_events;
  for (const std::int64_t at : hit) {
    const auto e = static_cast<std::size_t>(
        std::upper_bound(ix.offsets.begin(), ix.offsets.end(), at) - ix.offsets.begin() - 1);
    touched_events.insert(e);
    const std::int64_t in = at - ix.offsets[e];
    if (in < 4 || (in >= 20 && in < 28)) header_bytes.insert(at);
  }
  for (const std::size_t e : touched_events) {
    if (ix.kind[e] == 1 || ix.kind[e] == 2) touched_rows.insert(ix.seq[e]);
    if (ix.kind[e] == 3) ++touched_raw;
  }
  // The damage the reader finds.
  std::vector<messages::LogDamage> ranges;
  std::int64_t events_lost = 0;
  {
    messages::LogReader log(damaged);
    messages::LogEvent ev;
    while (log.next(ev)) {
    }
    ranges = log.damage();
  }
  for (const auto& d : ranges) {
    events_lost += std::max<std::int64_t>(0, d.events_lost);
    bool holds = false;
    for (const std::int64_t at : hit) holds = holds || (at >= d.from && at < d.to);
    check(holds, "range " + std::to_string(d.from) + ".." + std::to_string(d.to) +
                     " holds no corrupted byte");
  }
  for (const std::int64_t at : header_bytes) {
    bool in = false;
    for (const auto& d : ranges) in = in || (at >= d.from && at < d.to);
    check(in, "corrupted header byte " + std::to_string(at) + " in no range");
  }

  // Export: both, compared row by row.
  const std::string csv0 = dir + "/original.csv";
  const std::string csv1 = dir + "/damaged.csv";
  fs::remove(csv1);
  auto t0 = std::chrono::steady_clock::now();
  if (!fs::exists(csv0)) {
    const auto r = test::run({exodaq, "export", original, "-o", csv0, "-q"}, timeout);
    check(r.exit_code == 0,
          "export of the original: exit " + std::to_string(r.exit_code) + " " + r.err);
  }
  t0 = std::chrono::steady_clock::now();
  const auto ex = test::run({exodaq, "export", damaged, "-o", csv1}, timeout);
  const double export_s = seconds_since(t0);
  check(ex.exit_code == 1, "export of the damaged log: exit " + std::to_string(ex.exit_code));
  for (const auto& d : ranges) {
    const std::string named =
        "bytes " + std::to_string(d.from) + ".." + std::to_string(d.to) + ": ";
    check(ex.err.find(named) != std::string::npos, "export does not name " + named);
  }
  std::int64_t rows = 0, kept = 0, missing = 0, differing = 0, bad = 0, extra = 0;
  {
    std::ifstream a(csv0), b(csv1);
    std::string la, lb;
    std::getline(a, la);
    std::getline(b, lb);
    bool have_b = static_cast<bool>(std::getline(b, lb));
    while (std::getline(a, la)) {
      ++rows;
      const std::int64_t s = seq_of_row(la);
      while (have_b && seq_of_row(lb) < s) {
        ++extra;
        have_b = static_cast<bool>(std::getline(b, lb));
      }
      const bool found = have_b && seq_of_row(lb) == s;
      const bool same = found && la == lb;
      if (same) ++kept;
      if (!found) ++missing;
      if (found && !same) ++differing;
      if (!same && touched_rows.count(s) == 0) {
        if (bad++ < 5)
          failures.push_back("untouched row seq " + std::to_string(s) +
                             (found ? " differs" : " missing"));
      }
      if (found) have_b = static_cast<bool>(std::getline(b, lb));
    }
    while (have_b) {
      ++extra;
      have_b = static_cast<bool>(std::getline(b, lb));
    }
  }
  check(bad == 0, std::to_string(bad) + " untouched rows not kept");
  check(extra == 0, std::to_string(extra) + " rows the original does not have");

  // Replay: both.
  const std::string r0 = dir + "/original-replay.lcm";
  const std::string r1 = dir + "/damaged-replay.lcm";
  fs::remove(r0);
  fs::remove(r1);
  const auto rp0 = test::run({exodaq, "replay", original, "-c", config, "-o", r0}, timeout);
  check(rp0.exit_code == 0,
        "replay of the original: exit " + std::to_string(rp0.exit_code) + " " + rp0.err);
  t0 = std::chrono::steady_clock::now();
  const auto rp1 = test::run({exodaq, "replay", damaged, "-c", config, "-o", r1}, timeout);
  const double replay_s = seconds_since(t0);
  check(rp1.exit_code == 1, "replay of the damaged log: exit " + std::to_string(rp1.exit_code));
  for (const auto& d : ranges) {
    const std::string named =
        "bytes " + std::to_string(d.from) + ".." + std::to_string(d.to) + " of";
    check(rp1.err.find(named) != std::string::npos, "replay does not name " + named);
  }
  const std::int64_t s0 = samples_of(rp0.out);
  const std::int64_t s1 = samples_of(rp1.out);
  check(s0 > 0 && s1 >= s0 - touched_raw, "replay samples " + std::to_string(s1) + " of " +
                                              std::to_string(s0) + ", " +
                                              std::to_string(touched_raw) + " raw events touched");
  fs::remove(r0);
  fs::remove(r1);

  std::printf(
      "DAMAGE-CHECK: %lld bytes, %zu events; %d corruptions (seed %u) touching %zu events (%zu "
      "cycles' rows, %lld raw); reader: %zu damaged ranges, %lld events lost there; export: exit "
      "%d, %lld of %lld rows kept identical, %lld missing, %lld differing (all in touched "
      "cycles: %s), %.1f s; replay: exit %d, %lld of %lld samples, %.1f s\n",
      static_cast<long long>(ix.size), ix.offsets.size(), corruptions, seed, touched_events.size(),
      touched_rows.size(), static_cast<long long>(touched_raw), ranges.size(),
      static_cast<long long>(events_lost), ex.exit_code, static_cast<long long>(kept),
      static_cast<long long>(rows), static_cast<long long>(missing),
      static_cast<long long>(differing), bad == 0 ? "yes" : "NO", export_s, rp1.exit_code,
      static_cast<long long>(s1), static_cast<long long>(s0), replay_s);
  for (const auto& f : failures) std::printf("DAMAGE-CHECK FAILED: %s\n", f.c_str());
  return failures.empty() ? 0 : 1;
}
