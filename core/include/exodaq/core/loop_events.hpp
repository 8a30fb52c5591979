#pragma once
// What the loop wants logged, and the single-producer/single-consumer ring
// that carries it to the thread that logs. push() never blocks or allocates;
// a full ring drops the event and counts it.
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>

#include "exodaq/core/health.hpp"
#include "exodaq/core/joint_tracker.hpp"

namespace exodaq::core {

struct LogEvent {
  enum class Kind : std::uint8_t {
    kJoint,
    kOverrun,
    kClockStep,
    kStateChange,
    kReloadApplied,
    kNewSegment,  // joint: the one that moved most, value: by how much (rad)
    kEndOfStream,
  };
  Kind kind = Kind::kJoint;
  std::int64_t seq = 0;
  int joint = -1;
  JointEvent joint_event = JointEvent::kNone;
  double value = 0.0;      // angle, drift... by kind; kOverrun: the wake's lateness (us)
  double work_us = 0.0;    // kOverrun: the cycle's work, wake to end (us)
  std::int64_t count = 0;  // counter value after the event; kOverrun: deadlines skipped
  ServiceState state = ServiceState::kStarting;
  StateCause cause;  // kStateChange: why
};

class EventRing {
 public:
  static constexpr std::size_t kCapacity = 1024;

  void push(const LogEvent& e) noexcept;  // the producer (loop thread)
  bool pop(LogEvent& out) noexcept;       // the consumer
  std::int64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }

 private:
  std::array<LogEvent, kCapacity> events_{};
  alignas(64) std::atomic<std::uint64_t> head_{0};
  alignas(64) std::atomic<std::uint64_t> tail_{0};
  std::atomic<std::int64_t> dropped_{0};
};

}  // namespace exodaq::core
