#include "replay_support.hpp"

#include <sys/stat.h>

#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace exodaq::test {

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path);
}

std::int64_t file_size(const std::string& path) {
  struct stat st {};
  if (stat(path.c_str(), &st) != 0) return -1;
  return static_cast<std::int64_t>(st.st_size);
}

std::string candump_line(const drivers::can::CanFrame& f, std::int64_t stamp_ns,
                         const std::string& iface) {
  namespace ff = drivers::can::frame_flag;
  char buf[128];
  int n = std::snprintf(buf, sizeof buf, "(%lld.%06lld) %s ",
                        static_cast<long long>(stamp_ns / 1'000'000'000),
                        static_cast<long long>((stamp_ns % 1'000'000'000) / 1000), iface.c_str());
  if ((f.flags & ff::kError) != 0) {
    n += std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n), "%08X#",
                       f.id | 0x20000000U);
  } else if ((f.flags & ff::kExtended) != 0) {
    n += std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n), "%08X#", f.id);
  } else {
    n += std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n), "%03X#", f.id);
  }
  if ((f.flags & ff::kRtr) != 0) {
    if (f.dlc > 0) {
      std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n), "R%d", f.dlc);
    } else {
      std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n), "R");
    }
  } else {
    for (int i = 0; i < f.dlc && i < 8; ++i) {
      n += std::snprintf(buf + n, sizeof buf - static_cast<std::size_t>(n), "%02X",
                         f.data[static_cast<std::size_t>(i)]);
    }
  }
  return std::string(buf) + "\n";
}

SimCandump sim_candump(const drivers::sim::SimOptions& options, std::int64_t cycles,
                       std::int64_t wall_start_ns) {
  drivers::sim::SimRig rig(options);
  SimCandump out;
  drivers::sim::SimBoard::Frames frames{};
  for (std::int64_t k = 0; k < cycles; ++k) {
    const int n = rig.step(k, frames, wall_start_ns, 0);
    std::array<std::int64_t, 6> counts{};
    for (int j = 0; j < 6; ++j) {
      counts[static_cast<std::size_t>(rig.encoders().params(j).channel)] = rig.encoders().count(j);
    }
    out.counts.push_back(counts);
    out.stamp_ns.push_back(wall_start_ns + rig.sample_offset_ns(k));
    for (int i = 0; i < n; ++i) {
      const auto& f = frames[static_cast<std::size_t>(i)];
      out.text += candump_line(f, f.wall_ns);
    }
  }
  return out;
}

}  // namespace exodaq::test
