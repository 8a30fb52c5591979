#include "exodaq/core/publisher.hpp"

#include <lcm/lcm.h>

#include <cerrno>
#include <stdexcept>

namespace exodaq::core {

namespace {
class LcmSink final : public MessageSink {
 public:
  explicit LcmSink(const std::string& url) : lcm_(lcm_create(url.c_str())) {
    if (lcm_ == nullptr) throw std::runtime_error("cannot create LCM on '" + url + "'");
  }
  ~LcmSink() override { lcm_destroy(lcm_); }
  LcmSink(const LcmSink&) = delete;
  LcmSink& operator=(const LcmSink&) = delete;
  bool publish(const std::string& channel, const OutgoingMessage& msg) noexcept override {
    return lcm_publish(lcm_, channel.c_str(), msg.bytes.data(), msg.size) == 0;
  }

 private:
  lcm_t* lcm_;
};

std::size_t round_up_pow2(std::size_t n) {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}
}  // namespace

std::unique_ptr<MessageSink> make_lcm_sink(const std::string& url) {
  return std::make_unique<LcmSink>(url);
}

Publisher::Publisher(std::unique_ptr<MessageSink> sink, const std::string& prefix,
                     std::size_t capacity)
    : sink_(std::move(sink)), slots_(round_up_pow2(capacity)), mask_(slots_.size() - 1) {
  for (const msg::Kind k : msg::kAllKinds) {
    channels_[static_cast<std::size_t>(k)] = msg::channel_name(prefix, k);
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
  head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
}

void Publisher::notify() noexcept {
  sem_post(&ready_);  // never blocks
}

bool Publisher::publish_one() noexcept {
  const std::uint64_t tail = tail_.load(std::memory_order_relaxed);
  if (tail == head_.load(std::memory_order_acquire)) return false;
  const OutgoingMessage& msg = slots_[tail & mask_];
  if (sink_->publish(channels_[static_cast<std::size_t>(msg.channel)], msg)) {
    published_.fetch_add(1, std::memory_order_relaxed);
  } else {
    failures_.fetch_add(1, std::memory_order_relaxed);
  }
  tail_.store(tail + 1, std::memory_order_release);
  return true;
}

void Publisher::run() noexcept {
  for (;;) {
    while (sem_wait(&ready_) != 0 && errno == EINTR) {
    }
    while (publish_one()) {
    }
    if (stopping_.load(std::memory_order_acquire)) {
      while (publish_one()) {
      }
      sink_->flush();
      return;
    }
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

}  // namespace exodaq::core
