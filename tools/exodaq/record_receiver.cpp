#include "record_receiver.hpp"

#include <arpa/inet.h>
#include <linux/sock_diag.h>
#include <poll.h>
#include <pthread.h>
#include <sched.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <future>
#include <stdexcept>

#include "exodaq/common/clock_now.hpp"
#include "exodaq/core/udpm_receiver.hpp"

namespace exodaq::tools::record {

namespace {

constexpr int kBatch = 64;                 // datagrams per recvmmsg
constexpr std::size_t kSlotBytes = 65536;  // the largest UDP payload, and then some
constexpr std::size_t kRecordHeader = 24;
constexpr int kPollMs = 20;  // a partial block goes to the writer after this much quiet

void raise_to(std::atomic<std::int64_t>& v, std::int64_t x) {
  std::int64_t cur = v.load(std::memory_order_relaxed);
  while (x > cur && !v.compare_exchange_weak(cur, x, std::memory_order_relaxed)) {
  }
}

}  // namespace

Block::Block() : bytes_(new std::uint8_t[kBytes]) {
  std::fill_n(bytes_.get(), kBytes, std::uint8_t{0});  // touched now, not on the first burst
}

bool Block::add(const Datagram& d) {
  const std::size_t need = (kRecordHeader + d.size + 7) & ~std::size_t{7};
  if (used_ + need > kBytes) return false;
  std::uint8_t* h = bytes_.get() + used_;
  const auto size = static_cast<std::uint32_t>(d.size);
  std::memcpy(h, &size, 4);
  std::memcpy(h + 4, &d.source_port, 2);
  std::memcpy(h + 8, &d.source_ip, 4);
  std::memcpy(h + 16, &d.recv_ns, 8);
  std::memcpy(h + kRecordHeader, d.data, d.size);
  used_ += need;
  return true;
}

struct Receiver::Slots {
  std::vector<std::uint8_t> buffers = std::vector<std::uint8_t>(kBatch * kSlotBytes);
  mmsghdr msgs[kBatch]{};
  iovec iov[kBatch]{};
  sockaddr_in from[kBatch]{};
  alignas(cmsghdr) char control[kBatch]
                               [CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(std::uint32_t))]{};
};

Receiver::Receiver(const ReceiverOptions& options) : options_(options) {
  const std::string& url = options.url;
  fd_ = core::open_group_socket(options.address, url, [&](int fd) {
    const int one = 1;
    const int zero = 0;
    if (setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof one) != 0) {
      core::listen_failure(url, "SO_RXQ_OVFL");
    }
    if (setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof one) != 0) {
      core::listen_failure(url, "SO_TIMESTAMPNS");
    }
    // Only this group's datagrams, not every group joined on the port.
    setsockopt(fd, IPPROTO_IP, IP_MULTICAST_ALL, &zero, sizeof zero);
    // The kernel doubles what it is given (its bookkeeping); SO_RCVBUFFORCE
    // passes net.core.rmem_max where the process may (CAP_NET_ADMIN).
    const int half =
        static_cast<int>(std::min<std::int64_t>(options.rcvbuf_bytes / 2, INT32_MAX / 2));
    forced_ = setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &half, sizeof half) == 0;
    if (!forced_ && setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &half, sizeof half) != 0) {
      core::listen_failure(url, "SO_RCVBUF");
    }
    int granted = 0;
    socklen_t len = sizeof granted;
    if (getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &granted, &len) == 0) granted_ = granted;
  });
  slots_ = std::make_unique<Slots>();
  for (int i = 0; i < kBatch; ++i) {
    slots_->iov[i] = {slots_->buffers.data() + static_cast<std::size_t>(i) * kSlotBytes,
                      kSlotBytes};
  }
  max_blocks_ = std::max<std::size_t>(2, options.memory_bytes / Block::kBytes);
  const std::size_t initial =
      std::min(max_blocks_, std::max<std::size_t>(2, options.initial_bytes / Block::kBytes));
  for (std::size_t i = 0; i < initial; ++i) free_.push_back(std::make_unique<Block>());
  blocks_ = initial;
  current_ = std::move(free_.back());
  free_.pop_back();
}

Receiver::~Receiver() {
  stop();
  if (fd_ >= 0) close(fd_);
}

void Receiver::start() {
  std::promise<std::string> report;
  auto ready = report.get_future();
  thread_ = std::thread([this, &report] {
    pthread_setname_np(pthread_self(), "exodaq-record");
    sigset_t stops;  // the main thread takes the signals that end a recording
    sigemptyset(&stops);
    for (const int sig : {SIGINT, SIGTERM, SIGHUP}) sigaddset(&stops, sig);
    pthread_sigmask(SIG_BLOCK, &stops, nullptr);
    std::string r = "SCHED_OTHER";
    if (options_.priority > 0) {
      sched_param p{};
      p.sched_priority = options_.priority;
      const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &p);
      r = rc == 0 ? "SCHED_FIFO priority " + std::to_string(options_.priority)
                  : "SCHED_FIFO " + std::to_string(options_.priority) + " refused (" +
                        strerrordesc_np(rc) + "), running SCHED_OTHER";
    }
    report.set_value(r);
    run();
  });
  priority_report_ = ready.get();
  started_ = true;
}

void Receiver::stop() {
  if (!started_) return;
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
  started_ = false;
  // The kernel's own count of this socket's drops, also those after the
  // last datagram received (SO_RXQ_OVFL comes only with one).
  std::uint32_t info[SK_MEMINFO_VARS]{};
  socklen_t len = sizeof info;
  if (getsockopt(fd_, SOL_SOCKET, SO_MEMINFO, info, &len) == 0 &&
      len > SK_MEMINFO_DROPS * sizeof(std::uint32_t)) {
    raise_to(kernel_drops_, info[SK_MEMINFO_DROPS]);
  }
}

void Receiver::run() noexcept {
  int last_batch = 0;
  while (!stop_.load(std::memory_order_relaxed)) {
    if (last_batch < kBatch) {
      pollfd p{fd_, POLLIN, 0};
      const int ready = poll(&p, 1, kPollMs);
      if (ready <= 0) {
        if (current_ && !current_->empty()) hand_over();  // quiet: the writer gets what there is
        last_batch = 0;
        continue;
      }
    } else {
      note_queued();  // a full batch: a backlog in the socket
    }
    for (int i = 0; i < kBatch; ++i) {
      mmsghdr& m = slots_->msgs[i];
      m.msg_hdr.msg_name = &slots_->from[i];
      m.msg_hdr.msg_namelen = sizeof(sockaddr_in);
      m.msg_hdr.msg_iov = &slots_->iov[i];
      m.msg_hdr.msg_iovlen = 1;
      m.msg_hdr.msg_control = slots_->control[i];
      m.msg_hdr.msg_controllen = sizeof slots_->control[i];
      m.msg_hdr.msg_flags = 0;
    }
    const int n = recvmmsg(fd_, slots_->msgs, kBatch, MSG_DONTWAIT, nullptr);
    last_batch = n > 0 ? n : 0;
    if (n > 0) receive_batch(n);
  }
  if (current_ && !current_->empty()) hand_over();
}

void Receiver::receive_batch(int n) noexcept {
  for (int i = 0; i < n; ++i) {
    const msghdr& h = slots_->msgs[i].msg_hdr;
    Datagram d;
    d.recv_ns = 0;
    for (cmsghdr* c = CMSG_FIRSTHDR(const_cast<msghdr*>(&h)); c != nullptr;
         c = CMSG_NXTHDR(const_cast<msghdr*>(&h), c)) {
      if (c->cmsg_level != SOL_SOCKET) continue;
      if (c->cmsg_type == SCM_TIMESTAMPNS) {
        timespec ts{};
        std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
        d.recv_ns = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
      } else if (c->cmsg_type == SO_RXQ_OVFL) {
        std::uint32_t drops = 0;
        std::memcpy(&drops, CMSG_DATA(c), sizeof drops);
        raise_to(kernel_drops_, drops);
      }
    }
    if (d.recv_ns == 0) d.recv_ns = clock_ns(CLOCK_REALTIME);
    if ((h.msg_flags & MSG_TRUNC) != 0) {
      truncated_.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    d.source_ip = slots_->from[i].sin_addr.s_addr;
    d.source_port = slots_->from[i].sin_port;
    d.data = static_cast<const std::uint8_t*>(h.msg_iov->iov_base);
    d.size = slots_->msgs[i].msg_len;
    datagrams_.fetch_add(1, std::memory_order_relaxed);
    bytes_.fetch_add(static_cast<std::int64_t>(d.size), std::memory_order_relaxed);
    if (!current_) hand_over();  // a block freed since the memory cap was reached?
    if (current_ && !current_->add(d)) {
      hand_over();
      if (current_) current_->add(d);
    }
    if (!current_) memory_drops_.fetch_add(1, std::memory_order_relaxed);
  }
}

// The current block to the writer (if any), and a fresh one: a free one, a
// new one under the cap, or none (datagrams are then dropped and counted
// until the writer gives one back).
void Receiver::hand_over() noexcept {
  {
    std::lock_guard lock(mutex_);
    if (current_ && !current_->empty()) full_.push_back(std::move(current_));
    if (!current_) {
      if (!free_.empty()) {
        current_ = std::move(free_.back());
        free_.pop_back();
      } else if (blocks_ < max_blocks_) {
        try {
          current_ = std::make_unique<Block>();
          ++blocks_;
        } catch (...) {
        }
      }
    }
    raise_to(peak_memory_, static_cast<std::int64_t>((full_.size() + 1) * Block::kBytes));
  }
  ready_.notify_one();
}

void Receiver::note_queued() noexcept {
  std::uint32_t info[SK_MEMINFO_VARS]{};
  socklen_t len = sizeof info;
  if (getsockopt(fd_, SOL_SOCKET, SO_MEMINFO, info, &len) == 0) {
    raise_to(peak_queued_, info[SK_MEMINFO_RMEM_ALLOC]);
  }
}

std::unique_ptr<Block> Receiver::take(int timeout_ms) {
  std::unique_lock lock(mutex_);
  ready_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [this] { return !full_.empty(); });
  if (full_.empty()) return nullptr;
  auto b = std::move(full_.front());
  full_.pop_front();
  return b;
}

void Receiver::give_back(std::unique_ptr<Block> block) {
  block->clear();
  std::lock_guard lock(mutex_);
  free_.push_back(std::move(block));
}

ReceiverStats Receiver::stats() const {
  ReceiverStats s;
  s.datagrams = datagrams_.load();
  s.bytes = bytes_.load();
  s.kernel_drops = kernel_drops_.load();
  s.memory_drops = memory_drops_.load();
  s.truncated = truncated_.load();
  s.peak_queued = peak_queued_.load();
  s.peak_memory = peak_memory_.load();
  return s;
}

}  // namespace exodaq::tools::record
