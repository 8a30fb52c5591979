#include "exodaq/messages/lcm_log.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "exodaq/common/files.hpp"

namespace exodaq::messages {

namespace {

constexpr std::size_t kHeaderBytes = 28;
constexpr std::uint32_t kMaxChannelBytes = 1024;
constexpr std::uint32_t kMaxDataBytes = 64U << 20;  // larger than any LCM datagram can carry
// What the reader and the writer move per system call: large enough that the
// per-call costs vanish (4 KiB writes, stdio's default here, cost the kernel
// about four times as much per byte on ext4), small enough to stay in cache.
constexpr std::size_t kChunkBytes = 256 * 1024;
// How far a timestamp may be out of order with its neighbours: the file's
// span (first to last event), at least a second; a day when either end does
// not read.
constexpr std::int64_t kMinSpanUs = 1'000'000;
constexpr std::int64_t kUnknownSpanUs = 86'400'000'000;
constexpr std::size_t kTailScanBytes = 1U << 20;  // where the last event is looked for
constexpr std::size_t kChannelsRemembered = 16;   // channel names checked once

// Big-endian fields, the event header's byte order: one load or store each.
template <typename T>
T from_big_endian(const unsigned char* p) noexcept {
  T v;
  std::memcpy(&v, p, sizeof v);
  if constexpr (std::endian::native == std::endian::little) {
    if constexpr (sizeof(T) == 4) v = __builtin_bswap32(v);
    if constexpr (sizeof(T) == 8) v = __builtin_bswap64(v);
  }
  return v;
}

template <typename T>
void to_big_endian(unsigned char* p, T v) noexcept {
  if constexpr (std::endian::native == std::endian::little) {
    if constexpr (sizeof(T) == 4) v = __builtin_bswap32(v);
    if constexpr (sizeof(T) == 8) v = __builtin_bswap64(v);
  }
  std::memcpy(p, &v, sizeof v);
}

std::uint32_t be32(const unsigned char* p) noexcept {
  return from_big_endian<std::uint32_t>(p);
}

std::int64_t be64(const unsigned char* p) noexcept {
  return static_cast<std::int64_t>(from_big_endian<std::uint64_t>(p));
}

void put32(unsigned char* p, std::uint32_t v) noexcept {
  to_big_endian(p, v);
}

void put64(unsigned char* p, std::int64_t v) noexcept {
  to_big_endian(p, static_cast<std::uint64_t>(v));
}

// An event's header and channel at `h` (kHeaderBytes + channel.size() bytes).
void put_header(unsigned char* h, std::int64_t number, std::int64_t timestamp_us,
                std::string_view channel, std::size_t size) noexcept {
  put32(h, kLcmLogMagic);
  put64(h + 4, number);
  put64(h + 12, timestamp_us);
  put32(h + 20, static_cast<std::uint32_t>(channel.size()));
  put32(h + 24, static_cast<std::uint32_t>(size));
  std::memcpy(h + kHeaderBytes, channel.data(), channel.size());
}

std::string hex_bytes(const unsigned char* p, std::size_t n) {
  std::string out;
  char b[4];
  for (std::size_t i = 0; i < n; ++i) {
    std::snprintf(b, sizeof b, "%s%02x", i ? " " : "", p[i]);
    out += b;
  }
  return out;
}

// |a - b| without overflow.
std::uint64_t distance(std::int64_t a, std::int64_t b) noexcept {
  const auto ua = static_cast<std::uint64_t>(a);
  const auto ub = static_cast<std::uint64_t>(b);
  return a >= b ? ua - ub : ub - ua;
}

std::string errno_text(int e) {
  return strerrordesc_np(e) != nullptr ? strerrordesc_np(e) : "unknown error";
}

}  // namespace

LogError::LogError(const std::string& file, std::int64_t offset, const std::string& what)
    : std::runtime_error(offset >= 0 ? file + ", byte " + std::to_string(offset) + ": " + what
                                     : file + ": " + what),
      file_(file),
      offset_(offset) {}

LogReader::LogReader(const std::string& path) : path_(path) {
  files::InputInfo info;
  try {
    // A regular file, checked before reading (a FIFO does not block); no
    // size limit: the log is read as a stream.
    fd_ = files::open_input(path, -1, &info);
  } catch (const files::FileError& e) {
    throw LogError(path, -1, e.reason());
  }
  size_ = info.size;
  try {
    if (size_ == 0) throw LogError(path, -1, "empty file, not an LCM log");
    buffer_.resize(kChunkBytes);
    const auto first = static_cast<std::size_t>(std::min<std::int64_t>(size_, 8));
    const std::size_t n = fill(0, first) ? first : std::min(window_bytes_, first);
    if (n < 4 || be32(buffer_.data()) != kLcmLogMagic) {
      throw LogError(path, -1, "not an LCM log (first bytes " + hex_bytes(buffer_.data(), n) + ")");
    }
    find_time_span();
  } catch (...) {
    ::close(fd_);
    throw;
  }
}

LogReader::~LogReader() {
  if (fd_ >= 0) ::close(fd_);
}

// Makes bytes [at, at + bytes) of the file available in the window, reading
// whole chunks. False when they are not all in the file (past the size it
// had when opened, or it has shrunk since: then the new end is the end).
// Throws LogError on a read error.
bool LogReader::fill(std::int64_t at, std::size_t bytes) {
  const std::int64_t window_end = window_at_ + static_cast<std::int64_t>(window_bytes_);
  if (at >= window_at_ && at + static_cast<std::int64_t>(bytes) <= window_end) return true;
  if (at < 0 || at + static_cast<std::int64_t>(bytes) > size_) return false;
  // Keep what the window already holds from `at` on.
  std::size_t kept = 0;
  if (at >= window_at_ && at < window_end) {
    kept = static_cast<std::size_t>(window_end - at);
    std::memmove(buffer_.data(), buffer_.data() + (at - window_at_), kept);
  }
  if (bytes > buffer_.size()) {
    buffer_.resize(bytes);  // one event larger than a chunk
  } else if (buffer_.size() > kChunkBytes && std::max(bytes, kept) <= kChunkBytes) {
    std::vector<std::uint8_t>(buffer_.data(), buffer_.data() + kChunkBytes).swap(buffer_);
  }
  window_at_ = at;
  window_bytes_ = kept;
  while (window_bytes_ < bytes) {
    const std::int64_t from = at + static_cast<std::int64_t>(window_bytes_);
    const auto want = static_cast<std::size_t>(std::min<std::int64_t>(
        static_cast<std::int64_t>(buffer_.size() - window_bytes_), size_ - from));
    const ssize_t n = ::pread(fd_, buffer_.data() + window_bytes_, want, from);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw LogError(path_, from, "read error: " + errno_text(errno));
    if (n == 0) {
      size_ = from;  // the file has shrunk since it was opened: it ends here now
      return false;
    }
    window_bytes_ += static_cast<std::size_t>(n);
  }
  return true;
}

// `bytes` of the file at `at` copied to `out`, from the window when it holds
// them (without moving it), else read directly. False past the end.
bool LogReader::peek(std::int64_t at, unsigned char* out, std::size_t bytes) {
  const std::int64_t window_end = window_at_ + static_cast<std::int64_t>(window_bytes_);
  if (at >= window_at_ && at + static_cast<std::int64_t>(bytes) <= window_end) {
    std::memcpy(out, buffer_.data() + (at - window_at_), bytes);
    return true;
  }
  std::size_t got = 0;
  while (got < bytes) {
    const ssize_t n = ::pread(fd_, out + got, bytes - got, at + static_cast<std::int64_t>(got));
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw LogError(path_, at, "read error: " + errno_text(errno));
    if (n == 0) return false;
    got += static_cast<std::size_t>(n);
  }
  return true;
}

// The file's time span, from its first event to its last (found from the
// end backwards): how far out of order a timestamp may be. At least a second;
// a day when either end does not read.
void LogReader::find_time_span() {
  span_us_ = kUnknownSpanUs;
  unsigned char head[kHeaderBytes];
  if (size_ < static_cast<std::int64_t>(kHeaderBytes) || !peek(0, head, kHeaderBytes)) return;
  const std::int64_t first = be64(head + 12);
  const auto tail_bytes = static_cast<std::size_t>(std::min<std::int64_t>(size_, kTailScanBytes));
  std::vector<unsigned char> tail(tail_bytes);
  const std::int64_t tail_at = size_ - static_cast<std::int64_t>(tail_bytes);
  if (!peek(tail_at, tail.data(), tail_bytes)) return;
  for (std::size_t i = tail_bytes >= kHeaderBytes ? tail_bytes - kHeaderBytes + 1 : 0; i-- > 0;) {
    const unsigned char* h = tail.data() + i;
    if (be32(h) != kLcmLogMagic) continue;
    const std::uint64_t ch = be32(h + 20);
    const std::uint64_t dl = be32(h + 24);
    if (ch == 0 || ch > kMaxChannelBytes || dl > kMaxDataBytes) continue;
    const std::uint64_t end = i + kHeaderBytes + ch + dl;
    if (end > tail_bytes) continue;
    if (end != tail_bytes && (end + 4 > tail_bytes || be32(tail.data() + end) != kLcmLogMagic)) {
      continue;
    }
    const std::int64_t last = be64(h + 12);
    const std::uint64_t span = std::min<std::uint64_t>(INT64_MAX, distance(first, last));
    span_us_ = std::max<std::int64_t>(kMinSpanUs, static_cast<std::int64_t>(span));
    return;
  }
}

// Whether a whole, plausible event starts at `at`: "" and the event in `out`,
// or why not. `resyncing`: a candidate found by its sync word after damage
// (no repair of a damaged sync word then).
std::string LogReader::check_event(std::int64_t at, LogEvent& out, bool resyncing) {
  sync_repaired_ = false;
  cut_event_ = false;
  if (at + static_cast<std::int64_t>(kHeaderBytes) > size_ || !fill(at, kHeaderBytes)) {
    return "cut at the end (" + std::to_string(size_ - at) + " bytes, less than an event header)";
  }
  const unsigned char* h = buffer_.data() + (at - window_at_);
  const bool sync = be32(h) == kLcmLogMagic;
  const std::int64_t number = be64(h + 4);
  const bool numbered_next = last_number_ >= 0 && number == last_number_ + 1;
  if (!sync && (resyncing || !numbered_next)) {
    return "no event header here (sync word " + hex_bytes(h, 4) + ")";
  }
  const std::uint32_t channel_len = be32(h + 20);
  const std::uint32_t data_len = be32(h + 24);
  const std::int64_t timestamp = be64(h + 12);
  if (channel_len == 0 || channel_len > kMaxChannelBytes) {
    return "impossible channel length " + std::to_string(channel_len);
  }
  if (data_len > kMaxDataBytes) return "impossible data length " + std::to_string(data_len);
  const std::size_t bytes = kHeaderBytes + channel_len + data_len;
  const std::int64_t end = at + static_cast<std::int64_t>(bytes);
  // A length past the next event's header: a damaged length (not when no
  // event follows: a cut event at the end, or garbage after it).
  const std::int64_t data_at = at + static_cast<std::int64_t>(kHeaderBytes + channel_len);
  if (end > size_) {
    if (const std::int64_t later = next_event_start(data_at, resyncing); later >= 0) {
      return "data length " + std::to_string(data_len) + " runs past the next event at byte " +
             std::to_string(later) + " (a damaged length)";
    }
    cut_event_ = sync && (numbered_next || last_number_ < 0);
    return "an event of " + std::to_string(bytes) + " bytes cut by the end of the file";
  }
  // The next header: its sync word, number and timestamp, read with the
  // event when it is small (one window), or first and alone when it is not.
  const auto next_bytes =
      static_cast<std::size_t>(std::min<std::int64_t>(kHeaderBytes, size_ - end));
  unsigned char next[kHeaderBytes];
  if (bytes + next_bytes <= kChunkBytes && !fill(at, bytes + next_bytes)) {
    return "cut at the end";
  }
  if (!peek(end, next, next_bytes)) return "cut at the end";
  const bool next_sync = next_bytes >= 4 && be32(next) == kLcmLogMagic;
  const bool next_numbered = next_bytes >= 12 && be64(next + 4) == number + 1;
  if (next_bytes == kHeaderBytes && !next_sync && !next_numbered) {
    // Damage overwrites bytes, it does not move events: when another event
    // starts after this one's data (before or after its end), this length
    // is damaged. When none does, the event is whole and garbage follows it.
    // Unless it is the next header that is damaged: the event found after
    // this one's end is not the next one by number (one lies damaged between),
    // or the damaged header's lengths lead exactly to it.
    const std::int64_t later = next_event_start(data_at, resyncing);
    const std::int64_t after_next = end + static_cast<std::int64_t>(kHeaderBytes) +
                                    be32(next + 20) + static_cast<std::int64_t>(be32(next + 24));
    unsigned char later_head[12];
    const bool skips_one = later > end && number < INT64_MAX &&
                           peek(later, later_head, sizeof later_head) &&
                           be64(later_head + 4) > number + 1;
    if (later >= 0 && !(later > end && (after_next == later || skips_one))) {
      return "data length " + std::to_string(data_len) +
             (later < end ? " runs past" : " ends before") + " the next event at byte " +
             std::to_string(later) + " (a damaged length)";
    }
  }
  if (!fill(at, bytes)) return "cut at the end";
  h = buffer_.data() + (at - window_at_);  // the window may have moved
  if (!known_channel(h + kHeaderBytes, channel_len)) {
    for (std::uint32_t i = 0; i < channel_len; ++i) {
      const unsigned char c = h[kHeaderBytes + i];
      if (c < 0x20 || c == 0x7f) return "a channel name with control bytes (damaged)";
    }
    if (channels_seen_.size() < kChannelsRemembered) {
      channels_seen_.emplace_back(reinterpret_cast<const char*>(h + kHeaderBytes), channel_len);
    }
  }
  // Out of order with both neighbours (the one before and the one after)
  // by more than the file's span: a damaged timestamp or a false sync word.
  // Logs joined with cat keep their order within each part.
  const bool has_next = next_bytes >= 20 && (next_sync || next_numbered);
  const bool agrees_before = last_number_ >= 0 && distance(timestamp, last_timestamp_) <=
                                                      static_cast<std::uint64_t>(span_us_);
  const bool agrees_after =
      has_next && distance(timestamp, be64(next + 12)) <= static_cast<std::uint64_t>(span_us_);
  if ((last_number_ >= 0 || has_next) && !agrees_before && !agrees_after) {
    return "timestamp " + std::to_string(timestamp) + " us out of order by more than the file's " +
           "span (" + std::to_string(span_us_ / 1'000'000) + " s)";
  }
  sync_repaired_ = !sync;
  out.number = number;
  out.timestamp = timestamp;
  out.offset = at;
  out.channel = std::string_view(reinterpret_cast<const char*>(h + kHeaderBytes), channel_len);
  out.data = h + kHeaderBytes + channel_len;
  out.size = data_len;
  return "";
}

// A channel name already checked (logs hold a few channels: the check is
// then one comparison).
bool LogReader::known_channel(const unsigned char* name, std::size_t size) const noexcept {
  for (const std::string& c : channels_seen_) {
    if (c.size() == size && std::memcmp(c.data(), name, size) == 0) return true;
  }
  return false;
}

// The next offset >= from where the sync word starts; -1: none.
std::int64_t LogReader::find_sync(std::int64_t from) {
  static constexpr unsigned char kSync[4] = {0xED, 0xA1, 0xDA, 0x01};
  while (from + 4 <= size_) {
    const auto want = static_cast<std::size_t>(std::min<std::int64_t>(kChunkBytes, size_ - from));
    if (!fill(from, want)) return -1;
    const unsigned char* p = buffer_.data() + (from - window_at_);
    if (const void* hit = ::memmem(p, want, kSync, sizeof kSync)) {
      return from + (static_cast<const unsigned char*>(hit) - p);
    }
    from += static_cast<std::int64_t>(want) - 3;
  }
  return -1;
}

// The first offset >= from where a plausible event starts (`bare`: where a
// sync word is); -1: none up to the end.
std::int64_t LogReader::next_event_start(std::int64_t from, bool bare) {
  const bool repaired = sync_repaired_;
  const bool cut = cut_event_;
  LogEvent scratch;
  std::int64_t found = -1;
  for (std::int64_t c = find_sync(from); c >= 0; c = find_sync(c + 1)) {
    if (bare || check_event(c, scratch, true).empty()) {
      found = c;
      break;
    }
  }
  sync_repaired_ = repaired;
  cut_event_ = cut;
  return found;
}

// Finds the next plausible event after `from`; records the skipped stretch
// as damage with `what` (why the event at `from` was not taken). False:
// nothing readable up to the end.
bool LogReader::resync(std::int64_t from, const std::string& what, LogEvent& out) {
  const bool cut = cut_event_;
  for (std::int64_t at = find_sync(from + 1); at >= 0; at = find_sync(at + 1)) {
    if (check_event(at, out, true).empty()) {
      std::int64_t lost = -1;
      if (last_number_ >= 0 && out.number > last_number_) lost = out.number - last_number_ - 1;
      if (last_number_ < 0 && out.number >= 0) lost = out.number;  // numbered from 0
      damage_.push_back({from, at, events_, lost, what});
      return true;
    }
  }
  damage_.push_back({from, size_, events_, cut ? 1 : -1, what});
  pos_ = size_;
  return false;
}

void LogReader::take(const LogEvent& ev) {
  pos_ = ev.offset + static_cast<std::int64_t>(kHeaderBytes + ev.channel.size() + ev.size);
  last_number_ = ev.number;
  last_timestamp_ = ev.timestamp;
  ++events_;
}

bool LogReader::next(LogEvent& out) {
  if (pos_ >= size_) return false;
  const std::int64_t at = pos_;
  const std::string why = check_event(at, out, false);
  if (!why.empty()) {
    if (!resync(at, why, out)) return false;
    out.follows_damage = true;
  } else if (sync_repaired_) {
    damage_.push_back({at, at + 4, events_, 0,
                       "sync word damaged (" + hex_bytes(buffer_.data() + (at - window_at_), 4) +
                           "), the event itself intact"});
    out.follows_damage = true;
  } else {
    out.follows_damage = false;
  }
  take(out);
  return true;
}

std::string LogReader::damage_line(const std::string& path, const LogDamage& d) {
  std::string lost;
  if (d.events_lost == 0) {
    lost = "no event lost";
  } else if (d.events_lost > 0) {
    lost = std::to_string(d.events_lost) + (d.events_lost == 1 ? " event" : " events") + " lost";
  } else {
    lost = "events lost there: unknown";
  }
  return path + ", bytes " + std::to_string(d.from) + ".." + std::to_string(d.to) + ": " + d.what +
         "; " + lost + " (after event " + std::to_string(d.after_event) + ")";
}

std::string LogReader::damage_text() const {
  std::string out;
  for (const LogDamage& d : damage_) {
    if (!out.empty()) out += "\n";
    out += damage_line(path_, d);
  }
  return out;
}

LogWriter::LogWriter(const std::string& path, const std::vector<std::string>& inputs)
    : path_(path) {
  files::OutputOptions o;
  o.inputs = inputs;
  try {
    out_ = std::make_unique<files::OutputFile>(path, o);
  } catch (const files::FileError& e) {
    throw LogError(path, -1, e.reason());
  }
  buffer_.resize(kChunkBytes);
}

LogWriter::~LogWriter() = default;  // an OutputFile not committed leaves nothing behind

void LogWriter::write_all(const void* data, std::size_t size) {
  try {
    out_->write(data, size);  // chunks this large go straight to the file
  } catch (const files::FileError& e) {
    out_.reset();
    throw LogError(path_, -1, e.reason());
  }
}

void LogWriter::flush() {
  if (buffered_ == 0) return;
  write_all(buffer_.data(), buffered_);
  buffered_ = 0;
}

void LogWriter::write(std::string_view channel, std::int64_t timestamp_us, const void* data,
                      std::size_t size) {
  if (!out_) throw LogError(path_, -1, "write after close or a failed write");
  if (channel.empty() || channel.size() > kMaxChannelBytes || size > kMaxDataBytes) {
    throw LogError(path_, -1, "event too large or without a channel");
  }
  const std::size_t head = kHeaderBytes + channel.size();
  // An event larger than the buffer: its data is written straight from the caller's.
  const bool direct = head + size > buffer_.size();
  if (buffered_ + (direct ? head : head + size) > buffer_.size()) flush();
  unsigned char* h = buffer_.data() + buffered_;
  put_header(h, number_, timestamp_us, channel, size);
  buffered_ += head;
  if (direct) {
    flush();
    write_all(data, size);
  } else if (size > 0) {
    std::memcpy(h + head, data, size);
    buffered_ += size;
  }
  ++number_;
}

void LogWriter::close() {
  if (!out_) return;
  flush();
  try {
    out_->commit();
  } catch (const files::FileError& e) {
    out_.reset();
    throw LogError(path_, -1, e.reason());
  }
  out_.reset();
}

LogAppender::LogAppender(const std::string& path) : path_(path) {
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC | O_NOCTTY, 0644);
  if (fd_ < 0) {
    const int e = errno;
    throw LogError(path, -1,
                   e == EEXIST ? std::string("exists (a recording is never written over a file)")
                               : "cannot create: " + errno_text(e));
  }
  buffer_.resize(kChunkBytes);
}

LogAppender::~LogAppender() {
  if (fd_ < 0) return;
  try {
    flush();
  } catch (const LogError&) {  // the caller's close() reports; here nothing more can be done
  }
  ::close(fd_);
}

void LogAppender::write_all(const void* data, std::size_t size) {
  const auto* p = static_cast<const unsigned char*>(data);
  while (size > 0) {
    const ssize_t n = ::write(fd_, p, size);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw LogError(path_, -1, "cannot write: " + errno_text(errno));
    p += n;
    size -= static_cast<std::size_t>(n);
  }
}

void LogAppender::flush() {
  if (buffered_ == 0 || fd_ < 0) return;
  const std::size_t n = buffered_;
  buffered_ = 0;  // a failed write is reported once, the buffer not retried
  write_all(buffer_.data(), n);
}

void LogAppender::write(std::string_view channel, std::int64_t timestamp_us, const void* data,
                        std::size_t size) {
  if (fd_ < 0) throw LogError(path_, -1, "write after close");
  if (channel.empty() || channel.size() > kMaxChannelBytes || size > kMaxDataBytes) {
    throw LogError(path_, -1, "event too large or without a channel");
  }
  const std::size_t head = kHeaderBytes + channel.size();
  const bool direct = head + size > buffer_.size();
  if (buffered_ + (direct ? head : head + size) > buffer_.size()) flush();
  put_header(buffer_.data() + buffered_, number_, timestamp_us, channel, size);
  buffered_ += head;
  if (direct) {
    flush();
    write_all(data, size);
  } else if (size > 0) {
    std::memcpy(buffer_.data() + buffered_, data, size);
    buffered_ += size;
  }
  bytes_ += static_cast<std::int64_t>(head + size);
  ++number_;
}

void LogAppender::close() {
  if (fd_ < 0) return;
  flush();
  const int fd = fd_;
  fd_ = -1;
  const bool synced = ::fsync(fd) == 0;
  const int e = errno;
  if (::close(fd) != 0 || !synced) {
    throw LogError(path_, -1, "cannot write: " + errno_text(synced ? errno : e));
  }
}

std::map<std::string, std::int64_t> scan_channels(const std::string& path) {
  std::map<std::string, std::int64_t, std::less<>> channels;
  LogReader reader(path);
  LogEvent ev;
  // Logs hold a few channels, mostly in runs: count against the last one seen.
  std::string_view last;
  std::int64_t* last_count = nullptr;
  while (reader.next(ev)) {
    if (last_count == nullptr || ev.channel != last) {
      auto it = channels.find(ev.channel);
      if (it == channels.end()) it = channels.emplace(std::string(ev.channel), 0).first;
      last = it->first;
      last_count = &it->second;
    }
    ++*last_count;
  }
  return {channels.begin(), channels.end()};
}

std::vector<OwnedEvent> read_log(const std::string& path) {
  std::vector<OwnedEvent> out;
  LogReader reader(path);
  LogEvent ev;
  while (reader.next(ev)) {
    out.push_back({std::string(ev.channel), std::vector<std::uint8_t>(ev.data, ev.data + ev.size),
                   ev.timestamp});
  }
  return out;
}

void write_log(const std::string& path, const std::vector<OwnedEvent>& events) {
  LogWriter writer(path);
  for (const auto& e : events) writer.write(e.channel, e.timestamp, e.data.data(), e.data.size());
  writer.close();
}

}  // namespace exodaq::messages
