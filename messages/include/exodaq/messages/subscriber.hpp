#pragma once
// Receiving exodaq messages live over LCM, decoded by kind: a thin wrapper
// over lcm::LCM for the tools, tests and the daemon's status-channel listener
// (never its loop). Not thread-safe;
// drive it from one thread with handle().
#include <cstdint>
#include <functional>
#include <list>
#include <memory>
#include <optional>
#include <string>

#include "exodaq/messages/message.hpp"
#include "exodaq/messages/run_mix.hpp"

namespace lcm {
class LCM;
struct ReceiveBuffer;
}  // namespace lcm

namespace exodaq::messages {

// The daemon's default: multicast, TTL 0, so nothing leaves the host.
inline constexpr const char* kDefaultUrl = "udpm://239.255.76.67:7667?ttl=0";

// A received and decoded message.
struct Received {
  std::string channel;
  Message msg;
  std::int64_t recv_utime = 0;  // local wall clock at receipt, us
};

// lcm::LCM with raw subscriptions that decode by kind. Not thread-safe; drive
// it from one thread with handle().
class Subscriber {
 public:
  using Handler = std::function<void(const Received&)>;
  // Throws std::runtime_error naming the URL if LCM cannot be set up (for
  // udpm: no multicast route, bad URL).
  explicit Subscriber(const std::string& url);
  ~Subscriber();
  Subscriber(const Subscriber&) = delete;
  Subscriber& operator=(const Subscriber&) = delete;

  // Subscribes to exactly `channel` (escaped). If `kind` is nullopt the type
  // is recognised from the fingerprint. Messages that do not decode are
  // counted in undecodable() and not passed on.
  void subscribe(const std::string& channel, std::optional<Kind> kind, Handler handler);

  // Waits up to timeout_ms for traffic and dispatches it. >0: handled
  // messages, 0: timeout, <0: error.
  int handle(int timeout_ms);
  // The descriptor that becomes readable when handle() has traffic to
  // dispatch, for callers that poll() several sources in one thread.
  int fileno();

  std::int64_t undecodable() const { return undecodable_; }

  // Called once per prefix when two run ids interleave on it (RunMixDetector
  // over every decoded message on an exodaq channel). Messages are still
  // passed on; the caller says so loudly.
  void on_mixed_runs(std::function<void(const RunMix&)> handler) {
    mix_handler_ = std::move(handler);
  }
  bool mixed_runs() const noexcept { return runs_.mixed(); }

 private:
  struct Sub;
  static void on_raw(const lcm::ReceiveBuffer* rbuf, const std::string& channel, Sub* sub);

  std::unique_ptr<lcm::LCM> lcm_;
  std::list<Sub> subs_;
  std::int64_t undecodable_ = 0;
  RunMixDetector runs_;
  std::function<void(const RunMix&)> mix_handler_;
};

}  // namespace exodaq::messages
