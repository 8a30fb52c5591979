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

namespace exodaq::msg {

namespace {

constexpr std::size_t kHeaderBytes = 28;
constexpr std::uint32_t kMaxChannelBytes = 1024;
constexpr std::uint32_t kMaxDataBytes = 64U << 20;  // larger than any LCM datagram can carry
// What the reader and the writer move per system call: large enough that the
// per-call costs vanish (4 KiB writes, stdio's default here, cost the kernel
// about four times as much per byte on ext4), small enough to stay in cache.
constexpr std::size_t kChunkBytes = 256 * 1024;

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

std::string hex_bytes(const unsigned char* p, std::size_t n) {
  std::string out;
  char b[4];
  for (std::size_t i = 0; i < n; ++i) {
    std::snprintf(b, sizeof b, "%s%02x", i ? " " : "", p[i]);
    out += b;
  }
  return out;
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

// The event whose header starts at `at`, if one whole event reads there.
bool LogReader::read_event(std::int64_t at, LogEvent& out) {
  if (!fill(at, kHeaderBytes)) return false;
  const unsigned char* h = buffer_.data() + (at - window_at_);
  if (be32(h) != kLcmLogMagic) return false;
  const std::uint32_t channel_len = be32(h + 20);
  const std::uint32_t data_len = be32(h + 24);
  if (channel_len == 0 || channel_len > kMaxChannelBytes || data_len > kMaxDataBytes) return false;
  const std::size_t bytes = kHeaderBytes + channel_len + data_len;
  if (at + static_cast<std::int64_t>(bytes) > size_ || !fill(at, bytes)) return false;
  h = buffer_.data() + (at - window_at_);  // the window may have moved
  out.number = be64(h + 4);
  out.timestamp = be64(h + 12);
  out.offset = at;
  out.channel = std::string_view(reinterpret_cast<const char*>(h + kHeaderBytes), channel_len);
  out.data = h + kHeaderBytes + channel_len;
  out.size = data_len;
  pos_ = at + static_cast<std::int64_t>(bytes);
  return true;
}

// Finds the next offset > from where a whole event reads; records the
// skipped stretch as damage. False: nothing readable up to the end.
bool LogReader::resync(std::int64_t from, LogEvent& out) {
  for (std::int64_t at = from + 1; at + static_cast<std::int64_t>(kHeaderBytes) <= size_; ++at) {
    if (read_event(at, out)) {
      damage_.push_back({from, at, events_});
      return true;
    }
  }
  damage_.push_back({from, size_, events_});
  pos_ = size_;
  return false;
}

bool LogReader::next(LogEvent& out) {
  if (pos_ >= size_) return false;
  const std::int64_t at = pos_;
  if (!read_event(at, out) && !resync(at, out)) return false;
  ++events_;
  return true;
}

std::string LogReader::damage_text() const {
  std::string out;
  for (const LogDamage& d : damage_) {
    if (!out.empty()) out += "\n";
    out += path_ + ", bytes " + std::to_string(d.from) + ".." + std::to_string(d.to) +
           (d.to == size_ ? ": damaged or cut at the end" : ": damaged") + " after event " +
           std::to_string(d.after_event) + "; those bytes were not read";
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
  put32(h, kLcmLogMagic);
  put64(h + 4, number_);
  put64(h + 12, timestamp_us);
  put32(h + 20, static_cast<std::uint32_t>(channel.size()));
  put32(h + 24, static_cast<std::uint32_t>(size));
  std::memcpy(h + kHeaderBytes, channel.data(), channel.size());
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

}  // namespace exodaq::msg
