#pragma once
// What the VM checkers (exodaq-vcan-check, exodaq-canopen-check) share: the
// board simulator's truth file and summary line, a stop on SIGTERM/SIGINT,
// and the "<PREFIX>: ok / FAIL <what>" verdict lines with their count.
#include <array>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace exodaq::vm {

// One line of the truth file: "k seq t_s q0..q5 c0..c5 fault_bits".
struct Truth {
  std::int64_t k = 0;
  int seq = 0;
  double t = 0;
  std::array<double, 6> q{};
  std::array<std::int64_t, 6> count{};
  std::uint32_t faults = 0;
};

// Every complete line; with `consecutive`, only while k counts 0, 1, 2, ...
inline std::vector<Truth> read_truth(const std::string& path, bool consecutive) {
  std::vector<Truth> truth;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    Truth t;
    s >> t.k >> t.seq >> t.t;
    for (double& q : t.q) s >> q;
    for (auto& c : t.count) s >> c;
    s >> t.faults;
    if (!s) continue;
    if (consecutive && t.k != static_cast<std::int64_t>(truth.size())) continue;
    truth.push_back(t);
  }
  return truth;
}

// The board simulator's "BOARD-SIM: key=value ..." summary, numbers only.
inline std::map<std::string, long long> parse_board_log(const std::string& path) {
  std::map<std::string, long long> out;
  std::ifstream in(path);
  std::string line;
  while (std::getline(in, line)) {
    const auto p = line.find("BOARD-SIM:");
    if (p == std::string::npos) continue;
    std::istringstream s(line.substr(p + 10));
    std::string kv;
    while (s >> kv) {
      const auto eq = kv.find('=');
      if (eq == std::string::npos) continue;
      char* end = nullptr;
      const std::string v = kv.substr(eq + 1);
      const long long n = std::strtoll(v.c_str(), &end, 10);
      if (end != v.c_str() && *end == '\0') out[kv.substr(0, eq)] = n;
    }
  }
  return out;
}

inline std::atomic<bool> g_stop{false};
inline void on_signal(int) {
  g_stop.store(true);
}

// Verdict lines "<prefix>: ok   <what>" / "<prefix>: FAIL <what>".
class Verdicts {
 public:
  explicit Verdicts(const char* prefix) : prefix_(prefix) {}
  void check(bool ok, const std::string& what) {
    std::printf("%s: %s %s\n", prefix_, ok ? "ok  " : "FAIL", what.c_str());
    if (!ok) ++failures_;
  }
  int failures() const { return failures_; }

 private:
  const char* prefix_;
  int failures_ = 0;
};

}  // namespace exodaq::vm
