#include "exodaq/messages/lcm_log.hpp"

#include <stdio_ext.h>
#include <sys/stat.h>

#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>

#include "exodaq/common/files.hpp"

namespace exodaq::msg {

namespace {

constexpr std::size_t kHeaderBytes = 28;
constexpr std::uint32_t kMaxChannelBytes = 1024;
constexpr std::uint32_t kMaxDataBytes = 64U << 20;  // larger than any LCM datagram can carry

std::uint32_t be32(const unsigned char* p) noexcept {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         std::uint32_t{p[3]};
}

std::int64_t be64(const unsigned char* p) noexcept {
  return static_cast<std::int64_t>((std::uint64_t{be32(p)} << 32) | be32(p + 4));
}

void put32(unsigned char* p, std::uint32_t v) noexcept {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<unsigned char>(v >> (24 - 8 * i));
}

void put64(unsigned char* p, std::int64_t v) noexcept {
  const auto u = static_cast<std::uint64_t>(v);
  put32(p, static_cast<std::uint32_t>(u >> 32));
  put32(p + 4, static_cast<std::uint32_t>(u));
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
  int fd = -1;
  try {
    fd = files::open_input(path, -1, &info);  // no size limit: read as a stream
  } catch (const files::FileError& e) {
    throw LogError(path, -1, e.reason());
  }
  f_ = ::fdopen(fd, "rb");
  if (f_ == nullptr) {
    const int e = errno;
    ::close(fd);
    throw LogError(path, -1, errno_text(e));
  }
  __fsetlocking(f_, FSETLOCKING_BYCALLER);
  size_ = info.size;
  if (size_ == 0) {
    std::fclose(f_);
    throw LogError(path, -1, "empty file, not an LCM log");
  }
  std::array<unsigned char, 8> first{};
  const std::size_t n = std::fread(first.data(), 1, first.size(), f_);
  if (n < 4 || be32(first.data()) != kLcmLogMagic) {
    std::fclose(f_);
    throw LogError(path, -1, "not an LCM log (first bytes " + hex_bytes(first.data(), n) + ")");
  }
  std::rewind(f_);
  tell_ = 0;
}

LogReader::~LogReader() {
  if (f_ != nullptr) std::fclose(f_);
}

bool LogReader::read_header(std::int64_t at) {
  std::array<unsigned char, kHeaderBytes> h{};
  if (at != tell_) {
    tell_ = -1;
    if (std::fseek(f_, static_cast<long>(at), SEEK_SET) != 0) return false;
    tell_ = at;
  }
  tell_ = -1;  // unknown until the whole event has been read
  if (std::fread(h.data(), 1, h.size(), f_) != h.size()) return false;
  if (be32(h.data()) != kLcmLogMagic) return false;
  const std::uint32_t channel_len = be32(h.data() + 20);
  const std::uint32_t data_len = be32(h.data() + 24);
  if (channel_len == 0 || channel_len > kMaxChannelBytes || data_len > kMaxDataBytes) return false;
  if (at + static_cast<std::int64_t>(kHeaderBytes + channel_len + data_len) > size_) return false;
  channel_.resize(channel_len);
  data_.resize(data_len);
  if (std::fread(channel_.data(), 1, channel_len, f_) != channel_len) return false;
  if (data_len > 0 && std::fread(data_.data(), 1, data_len, f_) != data_len) return false;
  number_ = be64(h.data() + 4);
  timestamp_ = be64(h.data() + 12);
  pos_ = at + static_cast<std::int64_t>(kHeaderBytes + channel_len + data_len);
  tell_ = pos_;
  return true;
}

// Finds the next offset >= from where a whole event header reads; records the
// skipped stretch as damage. False: nothing readable up to the end.
bool LogReader::resync(std::int64_t from) {
  for (std::int64_t at = from + 1; at + static_cast<std::int64_t>(kHeaderBytes) <= size_; ++at) {
    if (read_header(at)) {
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
  if (!read_header(at)) {
    if (std::ferror(f_)) throw LogError(path_, at, "read error: " + errno_text(errno));
    if (!resync(at)) return false;
  }
  out.number = number_;
  out.timestamp = timestamp_;
  out.offset = pos_ - static_cast<std::int64_t>(kHeaderBytes + channel_.size() + data_.size());
  out.channel = channel_;
  out.data = data_.data();
  out.size = data_.size();
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
}

LogWriter::~LogWriter() = default;  // an OutputFile not committed leaves nothing behind

void LogWriter::write(std::string_view channel, std::int64_t timestamp_us, const void* data,
                      std::size_t size) {
  if (!out_) throw LogError(path_, -1, "write after close");
  if (channel.empty() || channel.size() > kMaxChannelBytes || size > kMaxDataBytes) {
    throw LogError(path_, -1, "event too large or without a channel");
  }
  std::array<unsigned char, kHeaderBytes> h{};
  put32(h.data(), kLcmLogMagic);
  put64(h.data() + 4, number_);
  put64(h.data() + 12, timestamp_us);
  put32(h.data() + 20, static_cast<std::uint32_t>(channel.size()));
  put32(h.data() + 24, static_cast<std::uint32_t>(size));
  try {
    out_->write(h.data(), h.size());
    out_->write(channel);
    if (size > 0) out_->write(data, size);
  } catch (const files::FileError& e) {
    out_.reset();
    throw LogError(path_, -1, e.reason());
  }
  ++number_;
}

void LogWriter::close() {
  if (!out_) return;
  try {
    out_->commit();
  } catch (const files::FileError& e) {
    out_.reset();
    throw LogError(path_, -1, e.reason());
  }
  out_.reset();
}

std::map<std::string, std::int64_t> scan_channels(const std::string& path) {
  std::map<std::string, std::int64_t> channels;
  LogReader reader(path);
  LogEvent ev;
  while (reader.next(ev)) ++channels[std::string(ev.channel)];
  return channels;
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
