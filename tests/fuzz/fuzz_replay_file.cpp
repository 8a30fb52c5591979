// Fuzz target replay_file: ReplaySource::start() on any file: an LCM log
// (lcm-logger's event format, the encoder_raw_t -> EncoderSample conversion
// and the joint_state_t loop bits) or a candump -l text log (every line
// through parse_candump_line(), the codec and the BoardDecoder, missing
// cycles for sequence gaps). Documented behaviour (replay_source.hpp): the
// samples, or std::runtime_error naming the file; malformed content is kept
// in issues(). The input lives in a memfd: no disk I/O per run.
#include <sys/mman.h>
#include <unistd.h>

#include <stdexcept>
#include <string>

#include "exodaq/drivers/replay_source.hpp"
#include "fuzz_input.hpp"

namespace drv = exodaq::drivers;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 65536) return 0;
  static const int fd = memfd_create("exodaq-fuzz-replay", 0);
  FUZZ_CHECK(fd >= 0);
  FUZZ_CHECK(ftruncate(fd, 0) == 0);
  FUZZ_CHECK(pwrite(fd, data, size, 0) == static_cast<ssize_t>(size));
  static const std::string path = "/proc/self/fd/" + std::to_string(fd);

  drv::ReplaySettings settings;
  settings.path = path;
  drv::SourceContext context;
  for (int j = 0; j < 6; ++j) context.joints[static_cast<std::size_t>(j)].channel = j;
  drv::ReplaySource source(settings, context);
  try {
    source.start();
  } catch (const std::runtime_error& e) {
    FUZZ_CHECK(std::string(e.what()).find(path) != std::string::npos);
    return 0;
  }
  FUZZ_CHECK(source.sample_count() > 0);
  std::int64_t present = 0;
  drv::EncoderSample s;
  drv::CycleTime t{};
  for (std::int64_t i = 0; i < source.sample_count(); ++i) {
    const drv::ReadStatus r = source.read(t, s);
    FUZZ_CHECK(r != drv::ReadStatus::kEndOfStream);
    FUZZ_CHECK((s.flags & drv::sample_flag::kReplay) != 0);
    FUZZ_CHECK((s.channel_fresh & ~0x3FU) == 0);
    if (s.present) ++present;
  }
  FUZZ_CHECK(source.read(t, s) == drv::ReadStatus::kEndOfStream);
  FUZZ_CHECK(source.summary().missing == source.sample_count() - present);
  return 0;
}
