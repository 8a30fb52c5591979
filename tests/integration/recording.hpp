#pragma once
// Reads what lcm_recorder wrote, and lcm-logger files through LCM's log API.
#include <cstdint>
#include <string>
#include <vector>

namespace exodaq::test {

struct RecordedMessage {
  std::string channel;
  std::vector<std::uint8_t> data;
  std::int64_t time = 0;  // recorder: receive mono ns; lcm log: event utime
};

std::vector<RecordedMessage> read_recorder_file(const std::string& path);
std::vector<RecordedMessage> read_lcm_log(const std::string& path);

}  // namespace exodaq::test
