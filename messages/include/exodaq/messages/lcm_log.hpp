#pragma once
// LCM event logs, the format lcm-logger writes and lcm-logplayer reads: each
// event is a 28-byte big-endian header (magic 0xEDA1DA01, event number,
// timestamp in us, channel length, data length), the channel and the data.
// One reader and one writer for every part of exodaq; errors name the file
// and the byte offset. Off the loop thread only (they allocate and block).
// Both move the file in chunks of 256 KiB through one buffer of their own
// (docs/replay.md, "Memory and speed").
#include <cstdint>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace exodaq::files {
class OutputFile;
}

namespace exodaq::msg {

inline constexpr std::uint32_t kLcmLogMagic = 0xEDA1DA01U;

// "<file>: <what>" or "<file>, byte <offset>: <what>".
class LogError : public std::runtime_error {
 public:
  LogError(const std::string& file, std::int64_t offset, const std::string& what);
  const std::string& file() const noexcept { return file_; }
  std::int64_t offset() const noexcept { return offset_; }  // -1: not about a position

 private:
  std::string file_;
  std::int64_t offset_;
};

// One event; the views stay valid until the reader's next call.
struct LogEvent {
  std::int64_t number = 0;     // the event number the logger wrote
  std::int64_t timestamp = 0;  // us, when the logger received it
  std::int64_t offset = 0;     // byte offset of the event's header in the file
  std::string_view channel;
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
};

// A stretch of the file that holds no readable event (damage or a cut).
struct LogDamage {
  std::int64_t from = 0;  // byte offsets [from, to)
  std::int64_t to = 0;
  std::int64_t after_event = 0;  // events read before it
};

class LogReader {
 public:
  // Throws LogError: unreadable, not a regular file (checked before reading:
  // a FIFO does not block), or not an LCM log (the message shows the first
  // bytes); an empty file is "empty file, not an LCM log".
  explicit LogReader(const std::string& path);
  ~LogReader();
  LogReader(const LogReader&) = delete;
  LogReader& operator=(const LogReader&) = delete;

  // The next complete event; false at the end of the file. Damaged bytes
  // between events are skipped up to the next event header and recorded in
  // damage(); a cut last event is recorded as damage too. Throws LogError on a
  // read error.
  bool next(LogEvent& out);

  const std::vector<LogDamage>& damage() const noexcept { return damage_; }
  // One line per damaged stretch, for summaries ("" when none).
  std::string damage_text() const;
  std::int64_t events() const noexcept { return events_; }
  std::int64_t file_size() const noexcept { return size_; }
  const std::string& path() const noexcept { return path_; }

 private:
  bool fill(std::int64_t at, std::size_t bytes);
  bool read_event(std::int64_t at, LogEvent& out);
  bool resync(std::int64_t from, LogEvent& out);

  std::string path_;
  int fd_ = -1;
  std::int64_t size_ = 0;
  std::int64_t pos_ = 0;  // where the next event starts
  std::int64_t events_ = 0;
  // A window of the file: bytes [window_at_, window_at_ + window_bytes_) in
  // buffer_, read in chunks of the buffer's size (larger only for an event
  // that does not fit).
  std::vector<std::uint8_t> buffer_;
  std::int64_t window_at_ = 0;
  std::size_t window_bytes_ = 0;
  std::vector<LogDamage> damage_;
};

// Writes through a files::OutputFile: the log appears at `path` only when
// close() succeeds; until then, and after any error, `path` is untouched.
class LogWriter {
 public:
  // Checks `path` as an output (a regular file or none, not one of `inputs`);
  // throws LogError with the reason.
  explicit LogWriter(const std::string& path, const std::vector<std::string>& inputs = {});
  ~LogWriter();  // without close(): nothing is written
  LogWriter(const LogWriter&) = delete;
  LogWriter& operator=(const LogWriter&) = delete;

  // Appends one event (numbered 0, 1, ...). Throws LogError.
  void write(std::string_view channel, std::int64_t timestamp_us, const void* data,
             std::size_t size);
  // Flushes, fsyncs and puts the file in place; throws LogError with errno's
  // reason when anything failed (nothing is left at `path` then).
  void close();
  std::int64_t events() const noexcept { return number_; }

 private:
  void flush();
  void write_all(const void* data, std::size_t size);

  std::string path_;
  std::unique_ptr<files::OutputFile> out_;
  std::int64_t number_ = 0;
  std::vector<std::uint8_t> buffer_;  // events not yet written, written in large chunks
  std::size_t buffered_ = 0;
};

// The channels of a log and their event counts, from the headers only.
std::map<std::string, std::int64_t> scan_channels(const std::string& path);

// A whole log in memory (tests and small tools).
struct OwnedEvent {
  std::string channel;
  std::vector<std::uint8_t> data;
  std::int64_t timestamp = 0;
};
std::vector<OwnedEvent> read_log(const std::string& path);
void write_log(const std::string& path, const std::vector<OwnedEvent>& events);

}  // namespace exodaq::msg
