#include "exodaq/core/publisher.hpp"

#include <lcm/lcm.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <stdexcept>

#include "exodaq/common/clock_now.hpp"
#include "exodaq/core/udpm_sender.hpp"

namespace exodaq::core {

namespace {

constexpr std::int64_t kFirstReopenAfterNs = 1'000'000'000;  // a persistent failure: 1 s
constexpr std::int64_t kMaxReopenIntervalNs = 30'000'000'000;
constexpr std::int64_t kWatchEveryNs = 50'000'000;  // the publisher thread's longest sleep

// lcm_publish() on the publisher thread; the LCM instance is re-created on reopen().
class LcmSink final : public MessageSink {
 public:
  explicit LcmSink(const std::string& url) : url_(url), lcm_(lcm_create(url.c_str())) {
    if (lcm_ == nullptr) throw std::runtime_error("cannot create LCM on '" + url + "'");
  }
  ~LcmSink() override {
    if (lcm_ != nullptr) lcm_destroy(lcm_);
  }
  LcmSink(const LcmSink&) = delete;
  LcmSink& operator=(const LcmSink&) = delete;
  bool publish(const std::string& channel, const OutgoingMessage& msg) noexcept override {
    if (lcm_ == nullptr) {
      last_errno_ = ENETDOWN;
      return false;
    }
    errno = 0;
    if (lcm_publish(lcm_, channel.c_str(), msg.bytes.data(), msg.size) == 0) return true;
    last_errno_ = errno != 0 ? errno : EIO;
    return false;
  }
  int last_error() const noexcept override { return last_errno_; }
  int reopen() noexcept override {
    if (lcm_ != nullptr) lcm_destroy(lcm_);
    errno = 0;
    lcm_ = lcm_create(url_.c_str());
    return lcm_ != nullptr ? 0 : (errno != 0 ? errno : ENETDOWN);
  }

 private:
  std::string url_;
  lcm_t* lcm_;
  int last_errno_ = 0;
};

// LCM's udpm datagrams from our own nonblocking socket: the loop sends.
class UdpmSink final : public MessageSink {
 public:
  UdpmSink(const UdpmAddress& address, const std::string& url) : sender_(address, url) {}
  bool publish(const std::string& channel, const OutgoingMessage& msg) noexcept override {
    const int rc = sender_.send(channel, msg.bytes.data(), msg.size);
    if (rc == 0) return true;
    last_errno_.store(rc, std::memory_order_relaxed);
    return false;
  }
  bool sends_from_loop() const noexcept override { return true; }
  int last_error() const noexcept override { return last_errno_.load(std::memory_order_relaxed); }
  int reopen() noexcept override { return sender_.reopen(); }

 private:
  UdpmSender sender_;
  std::atomic<int> last_errno_{0};
};

std::size_t round_up_pow2(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

timespec mono_in(std::int64_t ns) {
  const std::int64_t t = mono_now_ns() + ns;
  return {static_cast<time_t>(t / 1'000'000'000), static_cast<long>(t % 1'000'000'000)};
}
}  // namespace

std::unique_ptr<MessageSink> make_lcm_sink(const std::string& url) {
  if (const auto address = parse_udpm_url(url)) return std::make_unique<UdpmSink>(*address, url);
  return std::make_unique<LcmSink>(url);
}

Publisher::Publisher(std::unique_ptr<MessageSink> sink, const std::string& prefix,
                     std::size_t capacity)
    : sink_(std::move(sink)),
      direct_(sink_->sends_from_loop()),
      slots_(direct_ ? 1 : round_up_pow2(capacity)),
      mask_(slots_.size() - 1) {
  for (const messages::Kind k : messages::kAllKinds) {
    channels_[static_cast<std::size_t>(k)] = messages::channel_name(prefix, k);
  }
  sem_init(&ready_, 0, 0);
}

Publisher::~Publisher() {
  stop();
  sem_destroy(&ready_);
}

void Publisher::start() {
  stopping_.store(false);
  thread_ = std::thread([this] { run(); });
}

void Publisher::stop() noexcept {
  if (!thread_.joinable()) return;
  stopping_.store(true, std::memory_order_release);
  sem_post(&ready_);
  thread_.join();
}

OutgoingMessage* Publisher::acquire() noexcept {
  if (direct_) {
    reserved_ = true;
    return &direct_slot_;
  }
  const std::uint64_t head = head_.load(std::memory_order_relaxed);
  if (head - tail_.load(std::memory_order_acquire) >= slots_.size()) {
    drops_.fetch_add(1, std::memory_order_relaxed);
    reserved_ = false;
    return nullptr;
  }
  reserved_ = true;
  return &slots_[head & mask_];
}

void Publisher::commit() noexcept {
  if (!reserved_) return;
  reserved_ = false;
  if (direct_) {
    deliver(direct_slot_);
    return;
  }
  head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
}

void Publisher::notify() noexcept {
  if (!direct_) sem_post(&ready_);  // never blocks
}

// The sending thread's only writer of the counters and episodes.
void Publisher::deliver(const OutgoingMessage& msg) noexcept {
  if (sink_->publish(channels_[static_cast<std::size_t>(msg.channel)], msg)) {
    published_.fetch_add(1, std::memory_order_relaxed);
    const std::int64_t since = failing_since_ns_.load(std::memory_order_relaxed);
    if (since != 0) {
      recovered_lost_.store(lost_in_episode_.load(std::memory_order_relaxed),
                            std::memory_order_relaxed);
      recovered_from_seq_.store(failing_since_seq_.load(std::memory_order_relaxed),
                                std::memory_order_relaxed);
      recovered_to_seq_.store(msg.seq, std::memory_order_relaxed);
      const std::int64_t now = mono_now_ns();
      recovered_after_ns_.store(now - since, std::memory_order_relaxed);
      recovered_at_ns_.store(now, std::memory_order_relaxed);
      failing_since_ns_.store(0, std::memory_order_relaxed);
      recoveries_.fetch_add(1, std::memory_order_release);
    }
    return;
  }
  failures_.fetch_add(1, std::memory_order_relaxed);
  last_errno_.store(sink_->last_error(), std::memory_order_relaxed);
  if (failing_since_ns_.load(std::memory_order_relaxed) == 0) {
    failing_since_seq_.store(msg.seq, std::memory_order_relaxed);
    failing_since_utime_us_.store(msg.utime_us, std::memory_order_relaxed);
    lost_in_episode_.store(0, std::memory_order_relaxed);
    failing_since_ns_.store(mono_now_ns(), std::memory_order_release);
  }
  lost_in_episode_.fetch_add(1, std::memory_order_relaxed);
}

bool Publisher::publish_one() noexcept {
  const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
  if (tail == head_.load(std::memory_order_acquire)) return false;
  deliver(slots_[tail & mask_]);
  tail_.store(tail + 1, std::memory_order_release);
  return true;
}

// While an episode lasts: re-create the transport 1 s after its start, then
// with doubling intervals up to 30 s.
void Publisher::supervise(std::int64_t now) noexcept {
  const std::int64_t since = failing_since_ns_.load(std::memory_order_acquire);
  if (since == 0) {
    reopen_delay_ns_ = kFirstReopenAfterNs;
    next_reopen_ns_ = 0;
    return;
  }
  if (next_reopen_ns_ == 0) next_reopen_ns_ = since + reopen_delay_ns_;
  if (now < next_reopen_ns_) return;
  last_reopen_errno_.store(sink_->reopen(), std::memory_order_relaxed);
  reopens_.fetch_add(1, std::memory_order_release);
  reopen_delay_ns_ = std::min(reopen_delay_ns_ * 2, kMaxReopenIntervalNs);
  next_reopen_ns_ = now + reopen_delay_ns_;
}

void Publisher::run() noexcept {
  reopen_delay_ns_ = kFirstReopenAfterNs;
  for (;;) {
    const timespec until = mono_in(kWatchEveryNs);
    while (sem_clockwait(&ready_, CLOCK_MONOTONIC, &until) != 0 && errno == EINTR) {
    }
    while (publish_one()) {
    }
    if (stopping_.load(std::memory_order_acquire)) {
      while (publish_one()) {
      }
      sink_->flush();
      return;
    }
    supervise(mono_now_ns());
  }
}

void Publisher::drain() noexcept {
  if (!thread_.joinable()) {
    while (publish_one()) {
    }
    sink_->flush();
    return;
  }
  while (tail_.load(std::memory_order_acquire) != head_.load(std::memory_order_acquire)) {
    sem_post(&ready_);
    std::this_thread::yield();
  }
}

PublishHealth Publisher::health() const noexcept {
  PublishHealth h;
  constexpr auto r = std::memory_order_relaxed;
  h.recoveries = recoveries_.load(std::memory_order_acquire);
  h.reopens = reopens_.load(std::memory_order_acquire);
  h.failing_since_ns = failing_since_ns_.load(std::memory_order_acquire);
  h.published = published_.load(r);
  h.failures = failures_.load(r);
  h.ring_drops = drops_.load(r);
  h.last_errno = last_errno_.load(r);
  h.failing_since_seq = failing_since_seq_.load(r);
  h.failing_since_utime_us = failing_since_utime_us_.load(r);
  h.lost_in_episode = lost_in_episode_.load(r);
  h.recovered_lost = recovered_lost_.load(r);
  h.recovered_from_seq = recovered_from_seq_.load(r);
  h.recovered_to_seq = recovered_to_seq_.load(r);
  h.recovered_after_ns = recovered_after_ns_.load(r);
  h.recovered_at_ns = recovered_at_ns_.load(r);
  h.last_reopen_errno = last_reopen_errno_.load(r);
  return h;
}

}  // namespace exodaq::core
