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

namespace exodaq::messages {

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
  bool follows_damage = false;  // the first event after a damaged stretch (damage().back())
};

// A stretch of the file that holds no readable event (damage or a cut), or a
// damaged sync word in front of an event that is otherwise intact
// (events_lost 0: the event was read).
struct LogDamage {
  std::int64_t from = 0;  // byte offsets [from, to)
  std::int64_t to = 0;
  std::int64_t after_event = 0;  // events read before it
  // Events the logger wrote there, from the event numbers on either side
  // (lcm-logger numbers them 0, 1, 2, ...); -1: unknown (a cut at the end,
  // or numbers that restart: logs joined with cat).
  std::int64_t events_lost = -1;
  std::string what;  // why the first header there was not taken ("impossible channel length 70000")
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

  // The next complete event; false at the end of the file. An event is taken
  // only when its header is plausible (docs/replay.md, "Damaged logs"): the
  // sync word, a channel of 1 to 1024 bytes without control characters, a
  // data length that ends where the next event's sync word (or its next
  // number) is, or at the end of the file, and a timestamp not out of order
  // with both its neighbours by more than the file's span. After any other
  // header the reader re-synchronises on the next plausible event and records
  // the stretch skipped in damage(): everything after it is kept. Throws
  // LogError on a read error.
  bool next(LogEvent& out);

  const std::vector<LogDamage>& damage() const noexcept { return damage_; }
  // One line per damaged stretch, for summaries ("" when none):
  // "<file>, bytes A..B: <what>; N events lost (after event K)".
  std::string damage_text() const;
  static std::string damage_line(const std::string& path, const LogDamage& d);
  std::int64_t events() const noexcept { return events_; }
  std::int64_t file_size() const noexcept { return size_; }
  const std::string& path() const noexcept { return path_; }

 private:
  bool fill(std::int64_t at, std::size_t bytes);
  bool peek(std::int64_t at, unsigned char* out, std::size_t bytes);
  std::string check_event(std::int64_t at, LogEvent& out, bool resyncing);
  std::int64_t find_sync(std::int64_t from);
  bool known_channel(const unsigned char* name, std::size_t size) const noexcept;
  std::int64_t next_event_start(std::int64_t from, bool bare);
  bool resync(std::int64_t from, const std::string& what, LogEvent& out);
  void find_time_span();
  void take(const LogEvent& ev);

  std::string path_;
  int fd_ = -1;
  std::int64_t size_ = 0;
  std::int64_t pos_ = 0;  // where the next event starts
  std::int64_t events_ = 0;
  std::int64_t last_number_ = -1;    // of the last event taken (-1: none yet)
  std::int64_t last_timestamp_ = 0;  // of the last event taken
  std::int64_t span_us_ = 0;         // the file's time span, first to last event (at least 1 s)
  bool sync_repaired_ = false;       // check_event: taken despite a damaged sync word
  bool cut_event_ = false;           // check_event: the next event, cut by the end of the file
  // A window of the file: bytes [window_at_, window_at_ + window_bytes_) in
  // buffer_, read in chunks of the buffer's size (larger only for an event
  // that does not fit).
  std::vector<std::uint8_t> buffer_;
  std::int64_t window_at_ = 0;
  std::size_t window_bytes_ = 0;
  std::vector<LogDamage> damage_;
  std::vector<std::string> channels_seen_;  // names already found plausible
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

// Writes as it goes, for a recorder (exodaq record): the file is created at
// once, never over an existing one (O_EXCL: a name taken, a planted symlink
// or a directory is refused), and each flush() hands the events to the
// kernel, so a recorder that dies leaves every event flushed before it. The
// same format as LogWriter, events numbered 0, 1, ... in each file.
class LogAppender {
 public:
  // Throws LogError with errno's reason (EEXIST: "exists").
  explicit LogAppender(const std::string& path);
  ~LogAppender();  // closes without fsync; what was written stays
  LogAppender(const LogAppender&) = delete;
  LogAppender& operator=(const LogAppender&) = delete;

  // Appends one event to the buffer (flushed when full). Throws LogError.
  void write(std::string_view channel, std::int64_t timestamp_us, const void* data,
             std::size_t size);
  void flush();  // to the kernel; throws LogError
  void close();  // flush, fsync, close; throws LogError
  std::int64_t events() const noexcept { return number_; }
  std::int64_t bytes() const noexcept { return bytes_; }  // written or buffered
  const std::string& path() const noexcept { return path_; }

 private:
  void write_all(const void* data, std::size_t size);

  std::string path_;
  int fd_ = -1;
  std::int64_t number_ = 0;
  std::int64_t bytes_ = 0;
  std::vector<std::uint8_t> buffer_;
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

}  // namespace exodaq::messages
