// Fuzz target encoder_raw: exodaq::encoder_raw_t::decode() (the raw-log
// channel's generated decoder, what replay runs on every recorded message) on
// any bytes. What decodes re-encodes to the same bytes. The conversion of a
// decoded message to an EncoderSample runs in the replay_file target.
#include <vector>

#include "exodaq/encoder_raw_t.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 4096) return 0;
  const int len = static_cast<int>(size);
  exodaq::encoder_raw_t raw;
  const int used = raw.decode(data, 0, len);
  if (used < 0) return 0;
  FUZZ_CHECK(used <= len);
  FUZZ_CHECK(used == raw.getEncodedSize());
  std::vector<std::uint8_t> out(static_cast<std::size_t>(used));
  FUZZ_CHECK(raw.encode(out.data(), 0, used) == used);
  FUZZ_CHECK(std::memcmp(out.data(), data, static_cast<std::size_t>(used)) == 0);
  return 0;
}
