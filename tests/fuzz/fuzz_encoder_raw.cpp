// Fuzz target encoder_raw: messages::decode_encoder_raw() (what replay runs on
// every recorded raw message: version 2, else version 1 upgraded) on any
// bytes. A version 2 message re-encodes to the same bytes; a version 1
// message becomes protocol v1's moduli and positions, always in range. The
// conversion of a decoded message to an EncoderSample runs in the replay_file
// target.
#include <cstring>
#include <vector>

#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/messages/raw_sample.hpp"
#include "fuzz_input.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > 4096) return 0;
  using exodaq::messages::RawVersion;
  exodaq::encoder_raw_t raw;
  const RawVersion version = exodaq::messages::decode_encoder_raw(raw, data, size);
  if (version == RawVersion::kNone) return 0;
  const int used = raw.getEncodedSize();
  if (version == RawVersion::kV2) {
    FUZZ_CHECK(static_cast<std::size_t>(used) == size);
    std::vector<std::uint8_t> out(static_cast<std::size_t>(used));
    FUZZ_CHECK(raw.encode(out.data(), 0, used) == used);
    FUZZ_CHECK(std::memcmp(out.data(), data, static_cast<std::size_t>(used)) == 0);
    return 0;
  }
  FUZZ_CHECK(raw.source_seq_modulus == 256 && raw.absolute == 0);
  FUZZ_CHECK(raw.source_seq >= -32768 && raw.source_seq <= 32767);
  for (int c = 0; c < 6; ++c) {
    FUZZ_CHECK(raw.modulus[c] == 65536);
    FUZZ_CHECK(raw.position[c] >= 0 && raw.position[c] < 65536);
    FUZZ_CHECK(raw.index_position[c] >= 0 && raw.index_position[c] < 65536);
  }
  FUZZ_CHECK(raw.channel_fresh == (raw.present ? 0x3F : 0));
  return 0;
}
