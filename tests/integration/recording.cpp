#include "recording.hpp"

#include <cstdio>
#include <stdexcept>

#include "exodaq/messages/lcm_log.hpp"

namespace exodaq::test {

std::vector<RecordedMessage> read_recorder_file(const std::string& path) {
  std::vector<RecordedMessage> out;
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) throw std::runtime_error("cannot open " + path);
  for (;;) {
    std::uint32_t clen = 0;
    if (std::fread(&clen, 4, 1, f) != 1) break;
    RecordedMessage m;
    m.channel.resize(clen);
    std::uint32_t dlen = 0;
    if (std::fread(m.channel.data(), 1, clen, f) != clen || std::fread(&dlen, 4, 1, f) != 1) break;
    m.data.resize(dlen);
    if (std::fread(m.data.data(), 1, dlen, f) != dlen || std::fread(&m.time, 8, 1, f) != 1) break;
    out.push_back(std::move(m));
  }
  std::fclose(f);
  return out;
}

std::vector<RecordedMessage> read_lcm_log(const std::string& path) {
  std::vector<RecordedMessage> out;
  for (auto& e : messages::read_log(path)) {
    RecordedMessage m;
    m.channel = std::move(e.channel);
    m.data = std::move(e.data);
    m.time = e.timestamp;
    out.push_back(std::move(m));
  }
  return out;
}

}  // namespace exodaq::test
