// Replay of candump -l / -L logs: every line through parse_candump_line(), the
// frames through the BoardDecoder exactly as the SocketCAN backend does live.
#include <cerrno>
#include <cstring>
#include <fstream>
#include <stdexcept>

#include "recording.hpp"

namespace exodaq::drivers::replay {

namespace {

// span * k / d without overflowing (0 < k < d <= 127; a file's stamps may be
// decades apart): the same value as the plain expression would give.
std::int64_t fraction_of(std::int64_t span, int k, int d) noexcept {
  return span / d * k + span % d * k / d;
}

std::uint64_t fnv1a(std::uint64_t h, const void* data, std::size_t n) noexcept {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < n; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ULL;
  }
  return h;
}

}  // namespace

void load_candump(const std::string& path, Recording& out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("replay: cannot open '" + path + "': " + std::strerror(errno));
  BoardDecoder decoder{BoardDecoderConfig{}};
  std::uint64_t hash = 0xcbf29ce484222325ULL;

  EncoderSample previous{};
  bool have_previous = false;
  const auto push = [&](EncoderSample s) {
    s.flags |= sample_flag::kReplay;
    if (have_previous && s.present && previous.board_seq >= 0 && s.board_seq >= 0 &&
        (s.flags & sample_flag::kSeqGap) != 0) {
      // The board's cycles in between never reached the bus: replay them as
      // the live loop saw them, missing samples evenly spaced in the gap.
      const int d = can::seq_delta(static_cast<std::uint8_t>(previous.board_seq),
                                   static_cast<std::uint8_t>(s.board_seq));
      for (int k = 1; k < d; ++k) {
        Entry m;
        m.sample = previous;
        m.sample.present = false;
        m.sample.channel_fresh = 0;
        m.sample.index_latched = 0;
        m.sample.index_count_valid = 0;
        m.sample.flags = sample_flag::kMissing | sample_flag::kReplay;
        m.sample.mono_ns = previous.mono_ns + fraction_of(s.mono_ns - previous.mono_ns, k, d);
        m.sample.wall_ns = previous.wall_ns + fraction_of(s.wall_ns - previous.wall_ns, k, d);
        out.entries.push_back(m);
        ++out.stats.missing_samples;
      }
    }
    Entry e;
    e.sample = s;
    out.entries.push_back(e);
    previous = s;
    have_previous = true;
  };

  std::string line;
  std::int64_t line_no = 0;
  EncoderSample sample;
  while (std::getline(in, line)) {
    ++line_no;
    hash = fnv1a(hash, line.data(), line.size());
    can::CanFrame frame;
    const CandumpError err = parse_candump_line(line, frame);
    if (err == CandumpError::kBlank) continue;
    if (err != CandumpError::kNone) {
      ++out.summary.bad_lines;
      const std::string shown = line.size() > 80 ? line.substr(0, 77) + "..." : line;
      out.note(line_no, std::string(to_string(err)) + ": \"" + shown + "\"");
      continue;
    }
    ++out.summary.frames;
    decoder.on_frame(frame);
    while (decoder.poll_sample(sample)) push(sample);
  }
  if (in.bad()) throw std::runtime_error("replay: error reading '" + path + "'");
  if (decoder.flush(sample)) push(sample);
  out.summary.events = line_no;

  const SourceStats d = decoder.stats();
  const std::int64_t inserted_missing = out.stats.missing_samples;
  out.stats = d;
  out.stats.missing_samples += inserted_missing;
  out.stats.bad_frames += out.summary.bad_lines;
  out.summary.missing = out.stats.missing_samples;
  out.summary.run_id = static_cast<std::int64_t>(hash & 0x7FFF'FFFF'FFFF'FFFFULL);
  if (out.summary.run_id == 0) out.summary.run_id = 1;
}

}  // namespace exodaq::drivers::replay
