// Replay of candump -l / -L logs: every line through parse_candump_line(), the
// frames through the BoardDecoder exactly as the SocketCAN backend does live.
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string_view>

#include "exodaq/common/wrapping.hpp"
#include "recording.hpp"

namespace exodaq::drivers::replay {

namespace {

// span * k / d without overflowing (0 < k < d <= 127; a file's stamps may be
// decades apart): the same value as the plain expression would give.
std::int64_t fraction_of(std::int64_t span, std::int64_t k, std::int64_t d) noexcept {
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

// The lines of a text file as std::getline gives them (without the '\n'; a
// last line without one counts), read in chunks through one fixed buffer. A
// line longer than kMaxLine is not kept: next() says so and gives its start.
// Every byte of every line, '\n' excepted, goes into an FNV-1a hash.
class LineReader {
 public:
  static constexpr std::size_t kMaxLine = 4096;  // candump lines are < 100 characters
  static constexpr std::size_t kShown = 77;      // of a line too long, for the message

  explicit LineReader(const std::string& path) : path_(path), buffer_(kChunk) {
    fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) {
      throw std::runtime_error("replay: cannot open '" + path + "': " + std::strerror(errno));
    }
  }
  ~LineReader() { ::close(fd_); }
  LineReader(const LineReader&) = delete;
  LineReader& operator=(const LineReader&) = delete;

  bool next(std::string_view& line, bool& too_long);
  std::uint64_t hash() const noexcept { return hash_; }

 private:
  static constexpr std::size_t kChunk = 256 * 1024;
  bool refill();
  bool skip_long_line(std::string_view& line);

  std::string path_;
  int fd_ = -1;
  std::vector<char> buffer_;
  std::size_t begin_ = 0;  // the current line starts here
  std::size_t end_ = 0;    // bytes read
  std::string head_;       // the start of a line too long
  std::uint64_t hash_ = 0xcbf29ce484222325ULL;
};

// Moves the current line to the front and reads more after it; false at the
// end of the file.
bool LineReader::refill() {
  std::memmove(buffer_.data(), buffer_.data() + begin_, end_ - begin_);
  end_ -= begin_;
  begin_ = 0;
  for (;;) {
    const ssize_t n = ::read(fd_, buffer_.data() + end_, buffer_.size() - end_);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw std::runtime_error("replay: error reading '" + path_ + "'");
    end_ += static_cast<std::size_t>(n);
    return n > 0;
  }
}

bool LineReader::next(std::string_view& line, bool& too_long) {
  too_long = false;
  std::size_t searched = begin_;
  for (;;) {
    const void* nl = std::memchr(buffer_.data() + searched, '\n', end_ - searched);
    const std::size_t stop =
        nl != nullptr ? static_cast<std::size_t>(static_cast<const char*>(nl) - buffer_.data())
                      : end_;
    if (stop - begin_ > kMaxLine) {
      too_long = true;
      return skip_long_line(line);
    }
    if (nl != nullptr) {
      line = std::string_view(buffer_.data() + begin_, stop - begin_);
      begin_ = stop + 1;
      hash_ = fnv1a(hash_, line.data(), line.size());
      return true;
    }
    searched = end_ - begin_;
    if (!refill()) {
      if (end_ == 0) return false;
      line = std::string_view(buffer_.data(), end_);  // the last line, without '\n'
      begin_ = end_;
      hash_ = fnv1a(hash_, line.data(), line.size());
      return true;
    }
  }
}

// Hashes the current line up to its '\n' (or the end of the file) and drops
// it; `line` is its first kShown characters.
bool LineReader::skip_long_line(std::string_view& line) {
  head_.assign(buffer_.data() + begin_, kShown);
  for (;;) {
    const void* nl = std::memchr(buffer_.data() + begin_, '\n', end_ - begin_);
    const std::size_t stop =
        nl != nullptr ? static_cast<std::size_t>(static_cast<const char*>(nl) - buffer_.data())
                      : end_;
    hash_ = fnv1a(hash_, buffer_.data() + begin_, stop - begin_);
    begin_ = stop;
    if (nl != nullptr) {
      ++begin_;
      break;
    }
    if (!refill()) break;
  }
  line = head_;
  return true;
}

// Feeds the decoder's samples to the sink, with the board cycles that never
// reached the log in between as missing samples.
class CandumpPass {
 public:
  CandumpPass(Pass& out, EntrySink& sink) : out_(out), sink_(sink) {}

  // False: the sink wants no more.
  bool push(EncoderSample s);

 private:
  Pass& out_;
  EntrySink& sink_;
  EncoderSample previous_{};
  bool have_previous_ = false;
};

bool CandumpPass::push(EncoderSample s) {
  s.flags |= sample_flag::kReplay;
  if (have_previous_ && s.present && previous_.seq >= 0 && s.seq >= 0 &&
      (s.flags & sample_flag::kSeqGap) != 0) {
    // The board's cycles in between never reached the bus: replay them as
    // the live loop saw them, missing samples evenly spaced in the gap.
    const std::int64_t d = wrapped_delta(previous_.seq, s.seq, s.seq_modulus);
    for (std::int64_t k = 1; k < d; ++k) {
      Entry m;
      m.sample = previous_;
      m.sample.present = false;
      m.sample.channel_fresh = 0;
      m.sample.index_latched = 0;
      m.sample.index_count_valid = 0;
      m.sample.flags = sample_flag::kMissing | sample_flag::kReplay;
      m.sample.mono_ns = previous_.mono_ns + fraction_of(s.mono_ns - previous_.mono_ns, k, d);
      m.sample.wall_ns = previous_.wall_ns + fraction_of(s.wall_ns - previous_.wall_ns, k, d);
      ++out_.stats.missing_samples;
      if (!sink_.put(m)) return false;
    }
  }
  Entry e;
  e.sample = s;
  previous_ = s;
  have_previous_ = true;
  return sink_.put(e);
}

}  // namespace

void read_candump(const std::string& path, FrameAssembler& decoder, Pass& out, EntrySink& sink) {
  LineReader in(path);
  CandumpPass pass(out, sink);
  std::string_view line;
  bool too_long = false;
  bool more = true;
  std::int64_t line_no = 0;
  EncoderSample sample;
  while (more && in.next(line, too_long)) {
    ++line_no;
    if (too_long) {
      ++out.summary.bad_lines;
      out.note(line_no, "line longer than " + std::to_string(LineReader::kMaxLine) +
                            " characters: \"" + std::string(line) + "...\"");
      continue;
    }
    can::CanFrame frame;
    const CandumpError err = parse_candump_line(line, frame);
    if (err == CandumpError::kBlank) continue;
    if (err != CandumpError::kNone) {
      ++out.summary.bad_lines;
      const std::string shown =
          line.size() > 80 ? std::string(line.substr(0, 77)) + "..." : std::string(line);
      out.note(line_no, std::string(to_string(err)) + ": \"" + shown + "\"");
      continue;
    }
    ++out.summary.frames;
    decoder.on_frame(frame);
    while (more && decoder.poll(sample)) more = pass.push(sample);
  }
  if (more && decoder.finish(sample)) pass.push(sample);
  out.summary.events = line_no;

  const SourceStats d = decoder.stats();
  const std::int64_t inserted_missing = out.stats.missing_samples;
  out.stats = d;
  out.stats.missing_samples += inserted_missing;
  out.stats.bad_frames += out.summary.bad_lines;
  out.summary.missing = out.stats.missing_samples;
  out.summary.run_id = static_cast<std::int64_t>(in.hash() & 0x7FFF'FFFF'FFFF'FFFFULL);
  if (out.summary.run_id == 0) out.summary.run_id = 1;
}

}  // namespace exodaq::drivers::replay
