// Fuzz target candump_line: parse_candump_line() on any line, then the frame
// through the codec. An accepted classic frame written back in candump's own
// format parses to the same frame and time stamp.
#include <cinttypes>
#include <string>
#include <string_view>

#include "exodaq/drivers/can_codec.hpp"
#include "exodaq/drivers/candump.hpp"
#include "fuzz_input.hpp"

namespace can = exodaq::drivers::can;
namespace drv = exodaq::drivers;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string line = exodaq::fuzz::as_text(data, size);
  can::CanFrame f;
  const drv::CandumpError e = drv::parse_candump_line(line, f);
  FUZZ_CHECK(!drv::to_string(e).empty());
  if (e != drv::CandumpError::kNone) return 0;

  const bool fd = (f.flags & can::frame_flag::kFd) != 0;
  const bool ext = (f.flags & can::frame_flag::kExtended) != 0;
  const bool err = (f.flags & can::frame_flag::kError) != 0;
  const bool rtr = (f.flags & can::frame_flag::kRtr) != 0;
  FUZZ_CHECK(f.dlc <= (fd ? 64 : can::kMaxClassicDlc));
  FUZZ_CHECK(f.id <= (ext || err ? 0x1FFFFFFFU : 0x7FFU));
  FUZZ_CHECK(f.mono_ns >= 0 && f.mono_ns == f.wall_ns);
  (void)can::decode(f);

  if (fd || rtr || line.find('_') != std::string::npos) return 0;
  char head[64];
  std::snprintf(head, sizeof head, "(%" PRId64 ".%09" PRId64 ") can0 ", f.mono_ns / 1'000'000'000,
                f.mono_ns % 1'000'000'000);
  std::string again = head;
  char id[16];
  if (ext || err) {
    std::snprintf(id, sizeof id, "%08X#", f.id | (err ? 0x20000000U : 0U));
  } else {
    std::snprintf(id, sizeof id, "%03X#", f.id);
  }
  again += id;
  for (int i = 0; i < f.dlc; ++i) {
    char b[4];
    std::snprintf(b, sizeof b, "%02X", f.data[static_cast<std::size_t>(i)]);
    again += b;
  }
  can::CanFrame g;
  FUZZ_CHECK(drv::parse_candump_line(again, g) == drv::CandumpError::kNone);
  FUZZ_CHECK(g.id == f.id && g.dlc == f.dlc && g.flags == f.flags && g.data == f.data);
  FUZZ_CHECK(g.mono_ns == f.mono_ns);
  return 0;
}
