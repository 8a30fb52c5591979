#include "recording.hpp"

#include <lcm/lcm.h>

#include <cstdio>
#include <stdexcept>

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
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "r");
  if (log == nullptr) throw std::runtime_error("cannot open LCM log " + path);
  while (lcm_eventlog_event_t* e = lcm_eventlog_read_next_event(log)) {
    RecordedMessage m;
    m.channel.assign(e->channel, e->channellen);
    const auto* d = static_cast<const std::uint8_t*>(e->data);
    m.data.assign(d, d + e->datalen);
    m.time = e->timestamp;
    out.push_back(std::move(m));
    lcm_eventlog_free_event(e);
  }
  lcm_eventlog_destroy(log);
  return out;
}

}  // namespace exodaq::test
