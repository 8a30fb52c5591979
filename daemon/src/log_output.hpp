#pragma once
// The daemon's log output, which never makes the process wait: log lines go
// into a bounded queue (kMaxLines lines, kMaxBytes bytes) that one thread of
// its own writes out. When the output stalls (a pipe nobody reads, a paused
// terminal, a stuck journald) the queue fills and further lines are dropped
// and counted; the sink notes the count in the log as soon as there is room
// again. stop() gives the queue a bounded time to drain, then leaves the
// writer behind: the process exits whatever the output does.
// docs/operations.md, "When the log output stalls".
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <thread>

#include "exodaq/daemon/daemon_runtime.hpp"  // write_stderr()

namespace exodaq::daemon {

// stderr for writes that never block: a pipe, FIFO or terminal is opened
// again (/proc/self/fd/2) as a description of its own with O_NONBLOCK (the
// shell's stays as it was); a socket is written with MSG_DONTWAIT; a file or
// anything else as it is.
class StderrWriter {
 public:
  StderrWriter();
  ~StderrWriter();
  StderrWriter(const StderrWriter&) = delete;
  StderrWriter& operator=(const StderrWriter&) = delete;

  enum class Result { kWritten, kGaveUp, kFailed };
  // All of `text`, waiting for room while `give_up()` says no (it is asked
  // every 50 ms at most). kFailed: the output refused it (closed pipe, error).
  Result write(std::string_view text, const std::function<bool()>& give_up) const noexcept;

 private:
  int fd_ = 2;
  bool own_fd_ = false;
  bool socket_ = false;
};

struct LogRecord {
  int level = 0;     // spdlog::level::level_enum
  std::string text;  // what the destination writes: a line, or a journal payload
};

class LogOutput {
 public:
  static constexpr std::size_t kMaxLines = 1024;
  static constexpr std::size_t kMaxBytes = 256 * 1024;

  // Called on the output's thread for each record; `give_up()` turns true
  // when stop() stops waiting (then kGaveUp). It may outlive the LogOutput:
  // what it uses, it owns.
  using Write =
      std::function<StderrWriter::Result(const LogRecord&, const std::function<bool()>& give_up)>;

  explicit LogOutput(Write write);
  ~LogOutput();  // stop(0) when not stopped yet
  LogOutput(const LogOutput&) = delete;
  LogOutput& operator=(const LogOutput&) = delete;

  // Any thread; never waits for the output. False: dropped (queue full).
  bool push(LogRecord record);
  // Whether `lines` more records fit now.
  bool has_room(std::size_t lines) const;

  struct Counts {
    std::int64_t written = 0;    // delivered to the output
    std::int64_t dropped = 0;    // refused by a full queue (the output stalled)
    std::int64_t failed = 0;     // the output refused them (a closed pipe)
    std::int64_t unwritten = 0;  // still queued when stop() gave up
  };
  Counts counts() const;
  // Dropped lines not yet noted in the log; note_reported() takes them off.
  std::int64_t unreported_drops() const;
  void note_reported(std::int64_t lines);

  // Waits until every queued record is written or `drain` passed; then the
  // thread is told to give up and, if it does not (blocked in the output),
  // is left to the process's exit. Returns the final counts.
  Counts stop(std::chrono::milliseconds drain);

 private:
  struct State;
  static void run(const std::shared_ptr<State>& state);

  std::shared_ptr<State> state_;  // shared with the thread, which may outlive this
  std::thread thread_;
  bool stopped_ = false;
};

}  // namespace exodaq::daemon
