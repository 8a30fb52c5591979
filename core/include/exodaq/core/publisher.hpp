#pragma once
// Publishing without blocking the loop. The loop thread encodes each message
// into a pre-allocated slot and commits it. With a sink that can send from the
// loop (LCM udpm:// through our own nonblocking socket, udpm_sender.hpp) the
// commit sends it at once: no hand-off. Otherwise (another LCM URL, a log
// file, a test's memory) the slot goes into a single-producer/single-consumer
// ring and the publisher thread, woken once per cycle, hands it to the sink.
// Either way refusals are counted and tracked as episodes (since when, how
// many lost), and the publisher thread re-creates the transport with backoff
// while they persist. docs/architecture.md, "Publishing".
#include <semaphore.h>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "exodaq/messages/channels.hpp"

namespace exodaq::core {

// The largest message (status_t with a full 255-character message and 31-character
// joint names) is about 1 KiB; start-up checks every message fits.
inline constexpr std::size_t kMaxMessageBytes = 1536;

struct OutgoingMessage {
  messages::Kind channel = messages::Kind::kJointState;
  std::uint32_t size = 0;
  std::int64_t utime_us = 0;  // the message's sample time (log files use it as the event time)
  std::int64_t seq = 0;       // its cycle's seq (failure reports name it)
  std::array<std::uint8_t, kMaxMessageBytes> bytes{};
};

// Where encoded messages go.
class MessageSink {
 public:
  virtual ~MessageSink() = default;
  // Returns false when the transport refused the message (counted). Called on
  // the publisher thread, or on the loop thread when sends_from_loop().
  virtual bool publish(const std::string& channel, const OutgoingMessage& msg) noexcept = 0;
  virtual void flush() noexcept {}
  // True when publish() never blocks or allocates, so the loop thread may call it.
  virtual bool sends_from_loop() const noexcept { return false; }
  // The errno of the last refusal (0: not known).
  virtual int last_error() const noexcept { return 0; }
  // Publisher thread, while refusals persist: re-creates the transport (socket,
  // LCM instance, multicast membership). May run concurrently with publish()
  // when sends_from_loop(). Returns 0 or an errno.
  virtual int reopen() noexcept { return 0; }
};

// LCM on `url`: udpm:// URLs that udpm_sender.hpp reproduces exactly are sent
// from the loop through our own socket; any other URL through lcm_publish()
// on the publisher thread. Throws when the transport cannot be opened.
std::unique_ptr<MessageSink> make_lcm_sink(const std::string& url);

// The publish path's health, read by the main thread (log, STATUS=) and the
// status window. An episode runs from a refusal to the next accepted message.
struct PublishHealth {
  std::int64_t published = 0;
  std::int64_t failures = 0;  // refused by the transport, since start
  std::int64_t ring_drops = 0;
  int last_errno = 0;  // of the last refusal
  // The episode under way (failing_since_ns == 0: none).
  std::int64_t failing_since_ns = 0;  // CLOCK_MONOTONIC of its first refusal
  std::int64_t failing_since_seq = 0;
  std::int64_t failing_since_utime_us = 0;
  std::int64_t lost_in_episode = 0;
  // The last episode that ended, and how many have.
  std::int64_t recoveries = 0;
  std::int64_t recovered_lost = 0;
  std::int64_t recovered_from_seq = 0;
  std::int64_t recovered_to_seq = 0;  // the first message through again
  std::int64_t recovered_after_ns = 0;
  std::int64_t recovered_at_ns = 0;  // CLOCK_MONOTONIC
  // Transport re-creations while an episode lasts (1 s, 2 s, 4 s ... 30 s apart).
  std::int64_t reopens = 0;
  int last_reopen_errno = 0;
};

class Publisher {
 public:
  // 2048 slots hold ~680 ms of messages at 1 kHz: when the publisher thread
  // sends (not from the loop) it may be held off that long on a loaded
  // machine before the ring fills and messages are dropped (counted).
  Publisher(std::unique_ptr<MessageSink> sink, const std::string& prefix,
            std::size_t capacity = 2048);
  ~Publisher();
  Publisher(const Publisher&) = delete;
  Publisher& operator=(const Publisher&) = delete;

  // Starts the publisher thread (sending from the ring, or only watching the
  // episodes when the loop sends).
  void start();
  void stop() noexcept;  // drains what is queued, then joins

  // Loop thread: a slot to encode into, or nullptr when the ring is full (the
  // message is dropped and counted). commit() hands it over (sends it, when
  // the loop sends); notify() wakes the publisher thread once for everything
  // committed since the last call (one wake-up per cycle, none when the loop sends).
  OutgoingMessage* acquire() noexcept;
  void commit() noexcept;
  void notify() noexcept;

  // Blocks until everything committed so far has been handed to the sink (tests, replay).
  void drain() noexcept;

  bool sends_from_loop() const noexcept { return direct_; }
  std::int64_t published() const noexcept { return published_.load(std::memory_order_relaxed); }
  std::int64_t failures() const noexcept { return failures_.load(std::memory_order_relaxed); }
  std::int64_t ring_drops() const noexcept { return drops_.load(std::memory_order_relaxed); }
  PublishHealth health() const noexcept;
  const std::string& channel_name(messages::Kind id) const noexcept {
    return channels_[static_cast<std::size_t>(id)];
  }

 private:
  void run() noexcept;
  bool publish_one() noexcept;
  void deliver(const OutgoingMessage& msg) noexcept;
  void supervise(std::int64_t now_ns) noexcept;

  std::unique_ptr<MessageSink> sink_;
  bool direct_ = false;
  std::array<std::string, messages::kKindCount> channels_;
  std::vector<OutgoingMessage> slots_;
  std::size_t mask_;
  OutgoingMessage direct_slot_;                     // the loop's one slot when it sends itself
  alignas(64) std::atomic<std::uint64_t> head_{0};  // written by the loop
  alignas(64) std::atomic<std::uint64_t> tail_{0};  // written by the publisher thread
  std::atomic<std::int64_t> published_{0};
  std::atomic<std::int64_t> failures_{0};
  std::atomic<std::int64_t> drops_{0};
  std::atomic<int> last_errno_{0};
  // Episodes: written by the sending thread only.
  std::atomic<std::int64_t> failing_since_ns_{0};
  std::atomic<std::int64_t> failing_since_seq_{0};
  std::atomic<std::int64_t> failing_since_utime_us_{0};
  std::atomic<std::int64_t> lost_in_episode_{0};
  std::atomic<std::int64_t> recoveries_{0};
  std::atomic<std::int64_t> recovered_lost_{0};
  std::atomic<std::int64_t> recovered_from_seq_{0};
  std::atomic<std::int64_t> recovered_to_seq_{0};
  std::atomic<std::int64_t> recovered_after_ns_{0};
  std::atomic<std::int64_t> recovered_at_ns_{0};
  // Re-creation: the publisher thread's.
  std::atomic<std::int64_t> reopens_{0};
  std::atomic<int> last_reopen_errno_{0};
  std::int64_t reopen_delay_ns_ = 0;
  std::int64_t next_reopen_ns_ = 0;
  std::atomic<bool> stopping_{false};
  sem_t ready_{};
  std::thread thread_;
  bool reserved_ = false;
};

}  // namespace exodaq::core
