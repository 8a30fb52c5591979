#include "log_output.hpp"

#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>

namespace exodaq::daemon {

StderrWriter::StderrWriter() {
  struct stat st {};
  if (fstat(STDERR_FILENO, &st) != 0) return;
  if (S_ISSOCK(st.st_mode)) {
    socket_ = true;
  } else if (S_ISFIFO(st.st_mode) || (S_ISCHR(st.st_mode) && isatty(STDERR_FILENO) != 0)) {
    // A description of our own: O_NONBLOCK on fd 2's would be the shell's too.
    const int fd = open("/proc/self/fd/2", O_WRONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
    if (fd >= 0) {
      fd_ = fd;
      own_fd_ = true;
    }
  }
}

StderrWriter::~StderrWriter() {
  if (own_fd_) close(fd_);
}

StderrWriter::Result StderrWriter::write(std::string_view text,
                                         const std::function<bool()>& give_up) const noexcept {
  while (!text.empty()) {
    const ssize_t n = socket_ ? send(fd_, text.data(), text.size(), MSG_DONTWAIT | MSG_NOSIGNAL)
                              : ::write(fd_, text.data(), text.size());
    if (n > 0) {
      text.remove_prefix(static_cast<std::size_t>(n));
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      if (give_up()) return Result::kGaveUp;
      pollfd p{fd_, POLLOUT, 0};
      poll(&p, 1, 50);
      continue;
    }
    return Result::kFailed;  // EPIPE (nobody reads any more), EIO, ENOSPC...
  }
  return Result::kWritten;
}

bool write_stderr(std::string_view text, std::chrono::milliseconds limit) {
  const auto deadline = std::chrono::steady_clock::now() + limit;
  const StderrWriter out;
  return out.write(text, [deadline] { return std::chrono::steady_clock::now() >= deadline; }) ==
         StderrWriter::Result::kWritten;
}

struct LogOutput::State {
  explicit State(Write w) : write(std::move(w)) {}
  const Write write;
  mutable std::mutex mutex;
  std::condition_variable wake;  // the writer: records or closing
  std::condition_variable idle;  // stop(): the writer is done
  std::deque<LogRecord> queue;
  std::size_t bytes = 0;
  bool closing = false;
  bool done = false;
  std::atomic<bool> abandon{false};
  Counts counts;
  std::int64_t reported = 0;  // dropped lines noted in the log
};

LogOutput::LogOutput(Write write) : state_(std::make_shared<State>(std::move(write))) {
  thread_ = std::thread(&LogOutput::run, state_);
}

LogOutput::~LogOutput() {
  if (!stopped_) stop(std::chrono::milliseconds(0));
}

void LogOutput::run(const std::shared_ptr<State>& state) {
  pthread_setname_np(pthread_self(), "exodaq-log");
  State& s = *state;
  const std::function<bool()> give_up = [&s] { return s.abandon.load(); };
  std::unique_lock lock(s.mutex);
  for (;;) {
    s.wake.wait(lock, [&s] { return !s.queue.empty() || s.closing || s.abandon.load(); });
    if (s.queue.empty() || s.abandon.load()) break;
    LogRecord record = std::move(s.queue.front());
    s.queue.pop_front();
    s.bytes -= record.text.size();
    lock.unlock();
    StderrWriter::Result result = StderrWriter::Result::kFailed;
    try {
      result = s.write(record, give_up);
    } catch (...) {
      // bad_alloc in a destination: the line is lost, the output goes on
    }
    lock.lock();
    if (result == StderrWriter::Result::kWritten) {
      ++s.counts.written;
    } else if (result == StderrWriter::Result::kFailed) {
      ++s.counts.failed;
    } else {
      ++s.counts.unwritten;
      break;
    }
  }
  s.counts.unwritten += static_cast<std::int64_t>(s.queue.size());
  s.queue.clear();
  s.done = true;
  s.idle.notify_all();
}

bool LogOutput::push(LogRecord record) {
  State& s = *state_;
  std::lock_guard lock(s.mutex);
  if (s.closing || s.queue.size() >= kMaxLines || s.bytes + record.text.size() > kMaxBytes) {
    ++s.counts.dropped;
    return false;
  }
  s.bytes += record.text.size();
  s.queue.push_back(std::move(record));
  s.wake.notify_one();
  return true;
}

bool LogOutput::has_room(std::size_t lines) const {
  std::lock_guard lock(state_->mutex);
  return state_->queue.size() + lines <= kMaxLines;
}

LogOutput::Counts LogOutput::counts() const {
  std::lock_guard lock(state_->mutex);
  return state_->counts;
}

std::int64_t LogOutput::unreported_drops() const {
  std::lock_guard lock(state_->mutex);
  return state_->counts.dropped - state_->reported;
}

void LogOutput::note_reported(std::int64_t lines) {
  std::lock_guard lock(state_->mutex);
  state_->reported += lines;
}

LogOutput::Counts LogOutput::stop(std::chrono::milliseconds drain) {
  State& s = *state_;
  std::unique_lock lock(s.mutex);
  if (stopped_) return s.counts;
  stopped_ = true;
  s.closing = true;
  s.wake.notify_all();
  if (!s.idle.wait_for(lock, drain, [&s] { return s.done; })) {
    // The output stalls: the writer gives up at its next look (50 ms)...
    s.abandon.store(true);
    s.wake.notify_all();
    s.idle.wait_for(lock, std::chrono::milliseconds(200), [&s] { return s.done; });
  }
  Counts c = s.counts;
  const bool done = s.done;
  if (!done) c.unwritten += static_cast<std::int64_t>(s.queue.size()) + 1;  // + the one it holds
  lock.unlock();
  // ... or, blocked in an output that cannot be asked (a journald that does
  // not read), is left to the process's exit, holding its own state.
  if (done) {
    thread_.join();
  } else {
    thread_.detach();
  }
  return c;
}

}  // namespace exodaq::daemon
