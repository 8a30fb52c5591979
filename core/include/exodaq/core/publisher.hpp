#pragma once
// Publishing without touching the loop: the loop thread encodes each message
// into a pre-allocated slot of a single-producer/single-consumer ring and
// posts a semaphore once per cycle; the publisher thread hands the bytes to the sink (LCM,
// a log file, or a test's memory). The loop never blocks on the network.
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
  msg::Kind channel = msg::Kind::kJointState;
  std::uint32_t size = 0;
  std::int64_t utime_us = 0;  // the message's sample time (log files use it as the event time)
  std::array<std::uint8_t, kMaxMessageBytes> bytes{};
};

// Where encoded messages go. Called on the publisher thread only.
class MessageSink {
 public:
  virtual ~MessageSink() = default;
  // Returns false when the transport refused the message (counted).
  virtual bool publish(const std::string& channel, const OutgoingMessage& msg) noexcept = 0;
  virtual void flush() noexcept {}
};

// LCM over UDP multicast (lcm_publish of pre-encoded bytes).
std::unique_ptr<MessageSink> make_lcm_sink(const std::string& url);

class Publisher {
 public:
  // 2048 slots hold ~680 ms of messages at 1 kHz: the publisher thread is
  // SCHED_OTHER and may be held off that long on a loaded machine before the
  // ring fills and messages are dropped (counted in publish_failures).
  Publisher(std::unique_ptr<MessageSink> sink, const std::string& prefix,
            std::size_t capacity = 2048);
  ~Publisher();
  Publisher(const Publisher&) = delete;
  Publisher& operator=(const Publisher&) = delete;

  void start();
  void stop() noexcept;  // drains what is queued, then joins

  // Loop thread: a slot to encode into, or nullptr when the ring is full (the
  // message is dropped and counted). commit() hands it over; notify() wakes
  // the publisher thread once for everything committed since the last call
  // (one wake-up per cycle, not per message).
  OutgoingMessage* acquire() noexcept;
  void commit() noexcept;
  void notify() noexcept;

  // Blocks until everything committed so far has been handed to the sink (tests, replay).
  void drain() noexcept;

  std::int64_t published() const noexcept { return published_.load(std::memory_order_relaxed); }
  std::int64_t failures() const noexcept { return failures_.load(std::memory_order_relaxed); }
  std::int64_t ring_drops() const noexcept { return drops_.load(std::memory_order_relaxed); }
  const std::string& channel_name(msg::Kind id) const noexcept {
    return channels_[static_cast<std::size_t>(id)];
  }

 private:
  void run() noexcept;
  bool publish_one() noexcept;

  std::unique_ptr<MessageSink> sink_;
  std::array<std::string, msg::kKindCount> channels_;
  std::vector<OutgoingMessage> slots_;
  std::size_t mask_;
  alignas(64) std::atomic<std::uint64_t> head_{0};  // written by the loop
  alignas(64) std::atomic<std::uint64_t> tail_{0};  // written by the publisher thread
  std::atomic<std::int64_t> published_{0};
  std::atomic<std::int64_t> failures_{0};
  std::atomic<std::int64_t> drops_{0};
  std::atomic<bool> stopping_{false};
  sem_t ready_{};
  std::thread thread_;
  bool reserved_ = false;
};

}  // namespace exodaq::core
