// A decoder host of the network lab (tests/lab/run_lab.py): subscribes to the
// four exodaq channels like a BMI decoder would (no LCM queue limit, a 2 MB
// socket buffer asked for in the URL), and counts, per channel, messages,
// sequence gaps, out-of-order or repeated seqs, decode failures and run ids,
// and the one-way latency of each per-cycle message: receive time (taken
// first thing in the handler) - the message's mono_ns (the sample instant),
// and the same on the wall clock (receive CLOCK_REALTIME - utime). Meaningful
// because the lab's namespaces share the kernel's clocks.
//
//   exodaq_lab_decoder --url URL --out SUMMARY.json [--prefix P]
//                      [--latency-dir DIR] [--duration S]
//
// Prints "subscribed" when ready. Runs until SIGTERM/SIGINT or --duration,
// then writes SUMMARY.json (per channel: counts, gaps as [first, last] seq
// ranges, latency percentiles; the last status_t's counters) and, with
// --latency-dir, DIR/<channel>.ns: every latency in ns as native int64 (the
// driver pools them across hosts). Memory is reserved up front.
#include <lcm/lcm.h>
#include <signal.h>
#include <time.h>

#include <algorithm>
#include <array>
#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"

namespace {

volatile sig_atomic_t g_stop = 0;
void on_signal(int) {
  g_stop = 1;
}

std::int64_t now_ns(clockid_t clock) noexcept {
  timespec ts{};
  clock_gettime(clock, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// The header every exodaq message starts with.
struct Stamp {
  std::int64_t utime, mono_ns, seq, run_id;
};

template <typename Msg>
bool decode_stamp(const lcm_recv_buf_t* rbuf, Msg& msg, Stamp& s) {
  if (msg.decode(rbuf->data, 0, static_cast<int>(rbuf->data_size)) < 0) return false;
  s = {msg.utime, msg.mono_ns, msg.seq, msg.run_id};
  return true;
}

struct Channel {
  std::string name;
  std::int64_t count = 0, decode_errors = 0, out_of_order = 0, run_ids = 0;
  std::int64_t run_id = 0, first_seq = -1, last_seq = -1, missing = 0;
  std::vector<std::array<std::int64_t, 2>> gaps;  // [first, last] missing seq
  std::vector<std::int64_t> latency_ns, wall_latency_ns;
};

struct State {
  std::array<Channel, 4> channels;  // joint state, palm pose, encoder raw, status
  exodaq::joint_state_t joint;
  exodaq::palm_pose_t palm;
  exodaq::encoder_raw_t raw;
  exodaq::status_t status;
  bool have_status = false;
};

// `final_status`: the daemon's last status, which may repeat the previous
// status's seq when no cycle ran after that window (docs/messages.md).
void account(Channel& c, const Stamp& s, std::int64_t mono, std::int64_t wall, bool per_cycle,
             bool final_status) {
  if (c.count == 0 || s.run_id != c.run_id) {
    ++c.run_ids;
    c.run_id = s.run_id;
    c.first_seq = s.seq;
  } else if (s.seq < c.last_seq || (s.seq == c.last_seq && !final_status)) {
    ++c.out_of_order;
    return;
  } else if (s.seq > c.last_seq + 1 && per_cycle) {
    c.missing += s.seq - c.last_seq - 1;
    if (c.gaps.size() < c.gaps.capacity()) c.gaps.push_back({c.last_seq + 1, s.seq - 1});
  }
  ++c.count;
  c.last_seq = s.seq;
  if (per_cycle && c.latency_ns.size() < c.latency_ns.capacity()) {
    c.latency_ns.push_back(mono - s.mono_ns);
    c.wall_latency_ns.push_back(wall - s.utime * 1000);
  }
}

struct Subscription {
  State* state;
  int index;
};

void handle(const lcm_recv_buf_t* rbuf, const char*, void* user) {
  const std::int64_t mono = now_ns(CLOCK_MONOTONIC);
  const std::int64_t wall = now_ns(CLOCK_REALTIME);
  const auto* sub = static_cast<const Subscription*>(user);
  State& st = *sub->state;
  Channel& c = st.channels[static_cast<std::size_t>(sub->index)];
  Stamp s{};
  bool ok = false;
  switch (sub->index) {
    case 0:
      ok = decode_stamp(rbuf, st.joint, s);
      break;
    case 1:
      ok = decode_stamp(rbuf, st.palm, s);
      break;
    case 2:
      ok = decode_stamp(rbuf, st.raw, s);
      break;
    default:
      ok = decode_stamp(rbuf, st.status, s);
      st.have_status = st.have_status || ok;
      break;
  }
  if (!ok) {
    ++c.decode_errors;
    return;
  }
  const bool status = sub->index == 3;
  account(c, s, mono, wall, !status, status && st.status.state == exodaq::status_t::STATE_STOPPING);
}

double percentile(std::vector<std::int64_t> v, double q) {
  if (v.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return static_cast<double>(v[k]) / 1000.0;
}

void write_latency(std::FILE* f, const char* key, const std::vector<std::int64_t>& v) {
  const double max =
      v.empty() ? 0.0 : static_cast<double>(*std::max_element(v.begin(), v.end())) / 1000.0;
  std::fprintf(f,
               "\"%s\": {\"n\": %zu, \"p50\": %.3f, \"p99\": %.3f, \"p999\": %.3f, \"max\": %.3f}",
               key, v.size(), percentile(v, 0.5), percentile(v, 0.99), percentile(v, 0.999), max);
}

void write_channel(std::FILE* f, const Channel& c) {
  std::fprintf(f,
               "    \"%s\": {\"count\": %" PRId64 ", \"decode_errors\": %" PRId64
               ", \"out_of_order\": %" PRId64 ", \"run_ids\": %" PRId64 ", \"run_id\": %" PRId64
               ", \"first_seq\": %" PRId64 ", \"last_seq\": %" PRId64 ", \"missing\": %" PRId64
               ",\n      \"gaps\": [",
               c.name.c_str(), c.count, c.decode_errors, c.out_of_order, c.run_ids, c.run_id,
               c.first_seq, c.last_seq, c.missing);
  for (std::size_t i = 0; i < c.gaps.size(); ++i) {
    std::fprintf(f, "%s[%" PRId64 ", %" PRId64 "]", i ? ", " : "", c.gaps[i][0], c.gaps[i][1]);
  }
  std::fprintf(f, "],\n      ");
  write_latency(f, "latency_us", c.latency_ns);
  std::fprintf(f, ",\n      ");
  write_latency(f, "wall_latency_us", c.wall_latency_ns);
  std::fprintf(f, "}");
}

std::string json_escape(const std::string& text) {
  std::string out;
  for (const char ch : text) {
    if (ch == '"' || ch == '\\') out += '\\';
    if (static_cast<unsigned char>(ch) >= 0x20) out += ch;
  }
  return out;
}

bool write_summary(const std::string& path, const State& st) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return false;
  std::fprintf(f, "{\n  \"channels\": {\n");
  for (std::size_t i = 0; i < st.channels.size(); ++i) {
    write_channel(f, st.channels[i]);
    std::fprintf(f, i + 1 < st.channels.size() ? ",\n" : "\n");
  }
  const exodaq::status_t& s = st.status;
  std::fprintf(f, "  },\n  \"status\": ");
  if (st.have_status) {
    std::fprintf(f,
                 "{\"seq\": %" PRId64 ", \"state\": %d, \"cycles\": %" PRId64
                 ", \"overruns\": %" PRId64 ", \"publish_failures\": %" PRId64
                 ", \"run_id\": %" PRId64 ", \"message\": \"%s\"}\n}\n",
                 s.seq, static_cast<int>(s.state), s.cycles, s.overruns, s.publish_failures,
                 s.run_id, json_escape(s.message).c_str());
  } else {
    std::fprintf(f, "null\n}\n");
  }
  return std::fclose(f) == 0;
}

bool write_latencies(const std::string& dir, const State& st) {
  for (const Channel& c : st.channels) {
    if (c.latency_ns.empty()) continue;
    std::FILE* f = std::fopen((dir + "/" + c.name + ".ns").c_str(), "wb");
    if (f == nullptr) return false;
    std::fwrite(c.latency_ns.data(), sizeof(std::int64_t), c.latency_ns.size(), f);
    if (std::fclose(f) != 0) return false;
  }
  return true;
}

struct Args {
  std::string url, out, prefix, latency_dir;
  double duration_s = 0;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "exodaq_lab_decoder: %s needs a value\n", k.c_str());
      std::exit(2);
    }
    const std::string v = argv[++i];
    if (k == "--url") {
      a.url = v;
    } else if (k == "--out") {
      a.out = v;
    } else if (k == "--prefix") {
      a.prefix = v;
    } else if (k == "--latency-dir") {
      a.latency_dir = v;
    } else if (k == "--duration") {
      a.duration_s = std::atof(v.c_str());
    } else {
      std::fprintf(stderr, "exodaq_lab_decoder: unknown argument %s\n", k.c_str());
      std::exit(2);
    }
  }
  if (a.url.empty() || a.out.empty()) {
    std::fprintf(stderr,
                 "usage: exodaq_lab_decoder --url URL --out SUMMARY.json [--prefix P] "
                 "[--latency-dir DIR] [--duration S]\n");
    std::exit(2);
  }
  return a;
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  static State st;
  const char* names[] = {"EXO_JOINT_STATE", "EXO_PALM_POSE", "EXO_ENCODER_RAW", "EXO_STATUS"};
  const auto expected =
      static_cast<std::size_t>((args.duration_s > 0 ? args.duration_s : 600) * 1000 + 10'000);
  for (std::size_t i = 0; i < st.channels.size(); ++i) {
    st.channels[i].name = args.prefix + names[i];
    st.channels[i].gaps.reserve(100'000);
    if (i < 3) {
      st.channels[i].latency_ns.reserve(expected);
      st.channels[i].wall_latency_ns.reserve(expected);
    }
  }
  struct sigaction sa {};
  sa.sa_handler = on_signal;
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);

  lcm_t* lcm = lcm_create(args.url.c_str());
  if (lcm == nullptr) {
    std::fprintf(stderr, "exodaq_lab_decoder: cannot create LCM on %s\n", args.url.c_str());
    return 1;
  }
  static Subscription subs[4];
  for (int i = 0; i < 4; ++i) {
    subs[i] = {&st, i};
    // The channel names are literal; a prefix with regex characters is not supported here.
    lcm_subscription_t* s =
        lcm_subscribe(lcm, st.channels[static_cast<std::size_t>(i)].name.c_str(), handle, &subs[i]);
    lcm_subscription_set_queue_capacity(s, 0);
  }
  std::printf("subscribed\n");
  std::fflush(stdout);
  const std::int64_t end =
      args.duration_s > 0
          ? now_ns(CLOCK_MONOTONIC) + static_cast<std::int64_t>(args.duration_s * 1e9)
          : INT64_MAX;
  while (g_stop == 0 && now_ns(CLOCK_MONOTONIC) < end) lcm_handle_timeout(lcm, 50);
  lcm_destroy(lcm);

  if (!write_summary(args.out, st)) {
    std::perror(args.out.c_str());
    return 1;
  }
  if (!args.latency_dir.empty() && !write_latencies(args.latency_dir, st)) {
    std::perror(args.latency_dir.c_str());
    return 1;
  }
  return 0;
}
