// exodaq_lcm_fixture: one known message of each exodaq type, with distinctive
// values (negative, > 32 bit, every flag family, non-trivial strings), for the
// client binding tests.
//
//   exodaq_lcm_fixture dump                 canonical text of the four messages
//   exodaq_lcm_fixture write DIR            DIR/<type>.bin, the encoded bytes
//   exodaq_lcm_fixture publish URL PREFIX [--count N] [--interval-ms M] [--vary-seq]
//                                           [--big BYTES] [--clock-unknown]
//       publishes the four messages on PREFIX + EXO_* every M ms, N times;
//       --vary-seq adds the iteration number to seq, mono_ns and utime;
//       --big also publishes BYTES bytes (i*7+3 mod 256) on PREFIX + BIG, which
//       LCM sends as fragmented LC03 datagrams when large enough;
//       --clock-unknown gives the status the kernel's "no estimate" clock
//       errors (16 s) and no foreign run (what JSON writes as null).
//       With EXODAQ_FIXTURE_SENDER=exodaq in the environment the messages go
//       out through exodaqd's own sender (core/udpm_sender.hpp) instead of
//       LCM's, so the stock subscribers are tested against its datagrams.
//
// The canonical text is one line per scalar, "<type>.<field>[<i>]=<value>":
// integers in decimal, booleans 0/1, strings as they are, doubles as the hex of
// their IEEE-754 bits (exact, and the same in C, C++, Java and Python). The
// client programs print the same text from what they decoded; the tests
// compare the sorted lines.
#include <lcm/lcm-cpp.hpp>

#include <chrono>
#include <cinttypes>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "exodaq/core/udpm_sender.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"

namespace {

using exodaq::encoder_raw_t;
using exodaq::joint_state_t;
using exodaq::palm_pose_t;
using exodaq::status_t;

constexpr int64_t kUtime = 1700000000123456;       // 2023-11-14T22:13:20.123456Z
constexpr int64_t kMonoNs = 987654321012345;       // > 2^32
constexpr int64_t kSeq = 4242424242;               // > 2^31
constexpr int64_t kRunId = -0x0123456789abcdefLL;  // negative, all 64 bits used

const char* const kNames[6] = {"shoulder_abduction", "shoulder_flexion", "shoulder_rotation",
                               "elbow_flexion",      "wrist_pronation",  "wrist_flexion"};

joint_state_t make_joint_state() {
  joint_state_t m{};
  m.utime = kUtime;
  m.mono_ns = kMonoNs;
  m.seq = kSeq;
  m.run_id = kRunId;
  const double pos[6] = {-0.375, 0.25, 1.5, -2.75, 0.1, 3.125};
  const double vel[6] = {0.5, -1.25, 2.0, -0.125, 4.5, -8.0};
  const int64_t raw[6] = {0, -1, 123456789012, -40000, 65536, 9999};
  const int8_t homed[6] = {1, 0, 1, 1, 0, 1};
  const int32_t flags[6] = {
      0,
      joint_state_t::JOINT_UNHOMED,
      int32_t{joint_state_t::JOINT_STALE} | joint_state_t::JOINT_HELD,
      int32_t{joint_state_t::JOINT_GLITCH} | joint_state_t::JOINT_OUT_OF_RANGE,
      int32_t{joint_state_t::JOINT_UNHOMED} | joint_state_t::JOINT_LOST_COUNTS,
      int32_t{joint_state_t::JOINT_HOMING_REJECTED} | joint_state_t::JOINT_BOARD_ERROR};
  for (int i = 0; i < 6; ++i) {
    m.name[i] = kNames[i];
    m.position[i] = pos[i];
    m.velocity[i] = vel[i];
    m.raw_count[i] = raw[i];
    m.homed[i] = homed[i];
    m.flags[i] = flags[i];
  }
  m.sample_flags = int32_t{joint_state_t::SAMPLE_SEQ_GAP} | joint_state_t::SAMPLE_LATE;
  return m;
}

palm_pose_t make_palm_pose() {
  palm_pose_t m{};
  m.utime = kUtime;
  m.mono_ns = kMonoNs;
  m.seq = kSeq;
  m.run_id = kRunId;
  m.valid = 0;
  m.invalid_reason = int32_t{palm_pose_t::INVALID_UNHOMED} | palm_pose_t::INVALID_JOINT_FAULT;
  const double p[3] = {0.1234, -0.05, 0.3};
  const double q[4] = {0.5, 0.5, -0.5, 0.5};
  const double e[3] = {0.01, -0.2, 0.15};
  for (int i = 0; i < 3; ++i) m.position[i] = p[i];
  for (int i = 0; i < 4; ++i) m.orientation[i] = q[i];
  for (int i = 0; i < 3; ++i) m.elbow[i] = e[i];
  m.shoulder_manipulability = 0.75;
  m.shoulder_manipulability_raw = 0.0123;
  m.near_singular = 1;
  return m;
}

encoder_raw_t make_encoder_raw() {
  encoder_raw_t m{};
  m.utime = kUtime;
  m.mono_ns = kMonoNs;
  m.seq = kSeq;
  m.run_id = kRunId;
  m.present = 1;
  m.source_seq = 255;
  m.source_seq_modulus = 256;
  const int64_t c[6] = {0, -1, 4294967295, -9007199254740992, 12345, 9007199254740992};
  const int64_t mod[6] = {65536, 0, 4294967296, 0, 65536, 0};
  const int64_t ic[6] = {1, 2, 3, -4, 5, -6};
  for (int i = 0; i < 6; ++i) {
    m.position[i] = c[i];
    m.modulus[i] = mod[i];
    m.index_position[i] = ic[i];
  }
  m.index_latched = 0x29;
  m.index_count_valid = 0x01;
  m.absolute = 0x0A;
  m.channel_fresh = 0x07;
  m.board_state = 2;
  m.board_errors = 0x40;
  m.source_flags = joint_state_t::SAMPLE_PARTIAL;
  m.wall_ns = 1700000000123456789;
  return m;
}

status_t make_status() {
  status_t m{};
  m.utime = kUtime + 5;
  m.mono_ns = kMonoNs + 5000;
  m.seq = kSeq;
  m.run_id = kRunId;
  m.rig = "sim-rig, bench 2";
  m.state = status_t::STATE_DEGRADED;
  m.message = "joint 3 \"elbow_flexion\" stale";
  m.window_cycles = 100;
  m.period_p50_us = 1000.0;
  m.period_p99_us = 1003.5;
  m.period_max_us = 1250.25;
  m.lateness_p50_us = 12.5;
  m.lateness_p99_us = 48.0;
  m.lateness_max_us = 250.0;
  m.work_p50_us = 7.75;
  m.work_p99_us = 15.5;
  m.work_max_us = 31.0;
  m.overruns = 3;
  m.cycles = 4242424243;
  m.publish_failures = 1;
  m.source = "sim";
  m.frames = 8484848486;
  m.bad_frames = 2;
  m.missing_samples = 4;
  m.seq_gaps = 5;
  m.duplicates = 6;
  m.out_of_order = 7;
  m.bus_errors = 8;
  m.rx_overflows = 9;
  m.bus_state = status_t::BUS_WARNING;
  m.board_errors = 0x40;
  m.clock_synchronised = 1;
  m.clock_est_error_us = 16.0;
  m.clock_max_error_us = 500.0;
  m.clock_offset_us = -3.25;
  m.utime_correction_us = 0.5;
  m.clock_steps = 1;
  m.config_path = "/etc/exodaq/exodaqd.yaml";
  m.config_sha256 = "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad";
  m.calibration_path = "/etc/exodaq/calibration/rig-2.yaml";
  m.calibration_sha256 = "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855";
  m.calibration_provenance = "exodaq calibrate 0.1.0, 2026-11-22, rms 4.1 -> 0.8 mm, 1200 samples";
  m.reloads = 3;
  m.foreign_run_id = 0x0123456789abcdefLL;
  const int8_t homing[6] = {status_t::HOMING_HOMED,    status_t::HOMING_UNHOMED,
                            status_t::HOMING_HOMED,    status_t::HOMING_HOMED,
                            status_t::HOMING_REJECTED, status_t::HOMING_HOMED};
  for (int i = 0; i < 6; ++i) {
    m.joint_name[i] = kNames[i];
    m.homing[i] = homing[i];
    m.joint_flags[i] = (i == 3) ? joint_state_t::JOINT_STALE : 0;
    m.glitches[i] = 10 + i;
    m.lost_count_events[i] = 20 + i;
    m.stale_events[i] = 30 + i;
    m.out_of_range_events[i] = 40 + i;
  }
  return m;
}

// Canonical text. (lcm-gen C++ makes each constant its own unnamed enum, so OR
// them as int32_t: enum | enum of different types is deprecated in C++20.)
class Dump {
 public:
  explicit Dump(std::string type) : type_(std::move(type)) {}
  void operator()(const char* f, int64_t v) { line(f, -1, std::to_string(v)); }
  void operator()(const char* f, int32_t v) { line(f, -1, std::to_string(v)); }
  void operator()(const char* f, int16_t v) { line(f, -1, std::to_string(v)); }
  void operator()(const char* f, int8_t v) { line(f, -1, std::to_string(int{v})); }
  void operator()(const char* f, double v) { line(f, -1, bits(v)); }
  void operator()(const char* f, const std::string& v) { line(f, -1, v); }
  template <typename T, int N>
  void operator()(const char* f, const T (&a)[N]) {
    for (int i = 0; i < N; ++i) {
      Dump d(type_);
      d.index_ = i;
      d(f, a[i]);
    }
  }

 private:
  static std::string bits(double v) {
    uint64_t u;
    std::memcpy(&u, &v, sizeof u);
    char buf[32];
    std::snprintf(buf, sizeof buf, "0x%016" PRIx64, u);
    return buf;
  }
  void line(const char* f, int, const std::string& v) {
    if (index_ >= 0) {
      std::printf("%s.%s[%d]=%s\n", type_.c_str(), f, index_, v.c_str());
    } else {
      std::printf("%s.%s=%s\n", type_.c_str(), f, v.c_str());
    }
  }
  std::string type_;
  int index_ = -1;
};

#define D(field) d(#field, m.field)

void dump(const joint_state_t& m) {
  Dump d("joint_state_t");
  D(utime), D(mono_ns), D(seq), D(run_id), D(name), D(position), D(velocity), D(raw_count),
      D(homed), D(flags), D(sample_flags);
}
void dump(const palm_pose_t& m) {
  Dump d("palm_pose_t");
  D(utime), D(mono_ns), D(seq), D(run_id), D(valid), D(invalid_reason), D(position), D(orientation),
      D(elbow), D(shoulder_manipulability), D(shoulder_manipulability_raw), D(near_singular);
}
void dump(const encoder_raw_t& m) {
  Dump d("encoder_raw_t");
  D(utime), D(mono_ns), D(seq), D(run_id), D(present), D(source_seq), D(source_seq_modulus),
      D(position), D(modulus), D(index_position), D(index_latched), D(index_count_valid),
      D(absolute), D(channel_fresh), D(board_state), D(board_errors), D(source_flags), D(wall_ns);
}
void dump(const status_t& m) {
  Dump d("status_t");
  D(utime), D(mono_ns), D(seq), D(run_id), D(rig), D(state), D(message), D(window_cycles),
      D(period_p50_us), D(period_p99_us), D(period_max_us), D(lateness_p50_us), D(lateness_p99_us),
      D(lateness_max_us), D(work_p50_us), D(work_p99_us), D(work_max_us), D(overruns), D(cycles),
      D(publish_failures), D(source), D(frames), D(bad_frames), D(missing_samples), D(seq_gaps),
      D(duplicates), D(out_of_order), D(bus_errors), D(rx_overflows), D(bus_state), D(board_errors),
      D(clock_synchronised), D(clock_est_error_us), D(clock_max_error_us), D(clock_offset_us),
      D(utime_correction_us), D(clock_steps), D(config_path), D(config_sha256), D(calibration_path),
      D(calibration_sha256), D(calibration_provenance), D(reloads), D(foreign_run_id),
      D(joint_name), D(homing), D(joint_flags), D(glitches), D(lost_count_events), D(stale_events),
      D(out_of_range_events);
}
#undef D

template <typename T>
std::vector<char> encode(const T& m) {
  std::vector<char> buf(static_cast<std::size_t>(m.getEncodedSize()));
  if (m.encode(buf.data(), 0, static_cast<int>(buf.size())) != static_cast<int>(buf.size())) {
    std::fprintf(stderr, "encode failed\n");
    std::exit(1);
  }
  return buf;
}

template <typename T>
bool write_file(const std::string& dir, const char* type, const T& m) {
  const auto buf = encode(m);
  std::ofstream out(dir + "/" + type + ".bin", std::ios::binary);
  out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
  return static_cast<bool>(out);
}

int usage() {
  std::fprintf(stderr,
               "usage: exodaq_lcm_fixture dump | write DIR | publish URL PREFIX [--count N] "
               "[--interval-ms M] [--vary-seq] [--big BYTES]\n");
  return 2;
}

template <typename T>
void shift(T& m, int64_t k) {
  m.seq += k;
  m.mono_ns += k * 1'000'000;
  m.utime += k * 1'000;
}

int publish(int argc, char** argv) {
  if (argc < 4) return usage();
  const std::string url = argv[2];
  const std::string prefix = argv[3];
  long count = 100;
  long interval_ms = 20;
  bool vary = false;
  long big = 0;
  bool clock_unknown = false;
  for (int i = 4; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--count" && i + 1 < argc) {
      count = std::atol(argv[++i]);
    } else if (a == "--interval-ms" && i + 1 < argc) {
      interval_ms = std::atol(argv[++i]);
    } else if (a == "--vary-seq") {
      vary = true;
    } else if (a == "--big" && i + 1 < argc) {
      big = std::atol(argv[++i]);
    } else if (a == "--clock-unknown") {
      clock_unknown = true;
    } else {
      return usage();
    }
  }
  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::fprintf(stderr, "exodaq_lcm_fixture: cannot open LCM at %s\n", url.c_str());
    return 3;
  }
  std::unique_ptr<exodaq::core::UdpmSender> own;
  if (const char* s = std::getenv("EXODAQ_FIXTURE_SENDER"); s && std::strcmp(s, "exodaq") == 0) {
    const auto address = exodaq::core::parse_udpm_url(url);
    if (!address) {
      std::fprintf(stderr, "exodaq_lcm_fixture: exodaq's sender does not take %s\n", url.c_str());
      return 3;
    }
    own = std::make_unique<exodaq::core::UdpmSender>(*address, url);
  }
  auto send = [&](const std::string& channel, const void* data, std::size_t size) {
    if (own) return own->send(channel, static_cast<const std::uint8_t*>(data), size) == 0;
    return lcm.publish(channel, data, static_cast<unsigned>(size)) == 0;
  };
  std::vector<char> blob(static_cast<std::size_t>(big));
  for (std::size_t i = 0; i < blob.size(); ++i) blob[i] = static_cast<char>((i * 7 + 3) & 0xff);
  int failures = 0;
  for (long k = 0; k < count; ++k) {
    auto j = make_joint_state();
    auto p = make_palm_pose();
    auto e = make_encoder_raw();
    auto s = make_status();
    if (clock_unknown) {
      s.clock_est_error_us = 16'000'000.0;
      s.clock_max_error_us = 16'000'000.0;
      s.foreign_run_id = 0;
    }
    if (vary) shift(j, k), shift(p, k), shift(e, k), shift(s, k);
    // Encode into our own buffers and publish raw bytes, as the daemon does.
    const auto bj = encode(j), bp = encode(p), be = encode(e), bs = encode(s);
    failures += !send(prefix + "EXO_JOINT_STATE", bj.data(), bj.size());
    failures += !send(prefix + "EXO_PALM_POSE", bp.data(), bp.size());
    failures += !send(prefix + "EXO_ENCODER_RAW", be.data(), be.size());
    failures += !send(prefix + "EXO_STATUS", bs.data(), bs.size());
    if (big > 0) failures += !send(prefix + "BIG", blob.data(), blob.size());
    std::fflush(stdout);
    if (interval_ms > 0) std::this_thread::sleep_for(std::chrono::milliseconds(interval_ms));
  }
  if (failures) std::fprintf(stderr, "exodaq_lcm_fixture: %d publish failures\n", failures);
  return failures ? 1 : 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) return usage();
  const std::string mode = argv[1];
  if (mode == "dump") {
    dump(make_joint_state());
    dump(make_palm_pose());
    dump(make_encoder_raw());
    dump(make_status());
    return 0;
  }
  if (mode == "write" && argc == 3) {
    const std::string dir = argv[2];
    const bool ok = write_file(dir, "joint_state_t", make_joint_state()) &&
                    write_file(dir, "palm_pose_t", make_palm_pose()) &&
                    write_file(dir, "encoder_raw_t", make_encoder_raw()) &&
                    write_file(dir, "status_t", make_status());
    if (!ok) std::fprintf(stderr, "exodaq_lcm_fixture: cannot write to %s\n", dir.c_str());
    return ok ? 0 : 1;
  }
  if (mode == "publish") return publish(argc, argv);
  return usage();
}
