#pragma once
// The receive path of `exodaq record`: one UDP socket joined to the LCM group,
// drained by a thread of its own (optionally SCHED_FIFO) into 1 MiB blocks of
// memory, which the writer takes in order. The thread does nothing else:
// recvmmsg, copy, hand over; it never waits for the disk. The socket's buffer
// is sized for the daemon's catch-up burst (docs/replay.md, "Recording"),
// raised past net.core.rmem_max with SO_RCVBUFFORCE where the process may;
// datagrams the kernel still drops are counted (SO_RXQ_OVFL), and so are any
// the recorder drops when its memory cap is reached.
#include <netinet/in.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <cstring>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "exodaq/core/udpm_sender.hpp"

namespace exodaq::tools::record {

// One received datagram, as the writer sees it.
struct Datagram {
  std::int64_t recv_ns = 0;       // the kernel's receive stamp, CLOCK_REALTIME
  std::uint32_t source_ip = 0;    // network order
  std::uint16_t source_port = 0;  // network order
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
};

// Datagrams packed one after another: a 24-byte record header, the bytes,
// padding to 8.
class Block {
 public:
  static constexpr std::size_t kBytes = 1U << 20;
  Block();
  bool add(const Datagram& d);  // false: no room
  bool empty() const noexcept { return used_ == 0; }
  void clear() noexcept { used_ = 0; }
  template <typename F>
  void for_each(F&& f) const;

 private:
  std::unique_ptr<std::uint8_t[]> bytes_;
  std::size_t used_ = 0;
};

struct ReceiverOptions {
  core::UdpmAddress address;
  std::string url;
  std::int64_t rcvbuf_bytes = 0;  // wanted, in the kernel's accounting (SO_RCVBUF reads it back)
  int priority = 0;               // SCHED_FIFO priority of the receive thread; 0: SCHED_OTHER
  std::size_t initial_bytes = 0;  // memory allocated (and touched) before the first datagram
  std::size_t memory_bytes = 0;   // the most held in memory for the writer
};

struct ReceiverStats {
  std::int64_t datagrams = 0;
  std::int64_t bytes = 0;
  std::int64_t kernel_drops = 0;  // dropped by the kernel at this socket: its queue was full
  std::int64_t memory_drops = 0;  // dropped here: the memory cap reached (the writer behind)
  std::int64_t truncated = 0;     // longer than 64 KiB (not LCM)
  std::int64_t peak_queued = 0;   // most bytes seen queued in the socket (SO_MEMINFO)
  std::int64_t peak_memory = 0;   // most bytes held in blocks
};

class Receiver {
 public:
  // Opens and joins the socket, sizes its buffer; throws std::runtime_error
  // naming the URL and errno.
  explicit Receiver(const ReceiverOptions& options);
  ~Receiver();
  Receiver(const Receiver&) = delete;
  Receiver& operator=(const Receiver&) = delete;

  void start();  // the receive thread; its priority report in priority_report()
  void stop();   // joins it; what it received waits in take()
  // The next block of datagrams in arrival order (a partial one after 20 ms
  // of quiet); nullptr when none came within timeout_ms.
  std::unique_ptr<Block> take(int timeout_ms);
  void give_back(std::unique_ptr<Block> block);
  ReceiverStats stats() const;

  std::int64_t rcvbuf_granted() const noexcept { return granted_; }
  bool rcvbuf_forced() const noexcept { return forced_; }
  const std::string& priority_report() const noexcept { return priority_report_; }

 private:
  void run() noexcept;
  void receive_batch(int n) noexcept;
  void hand_over() noexcept;
  void note_queued() noexcept;

  int fd_ = -1;
  std::int64_t granted_ = 0;
  bool forced_ = false;
  ReceiverOptions options_;
  std::string priority_report_;
  std::thread thread_;
  std::atomic<bool> stop_{false};

  // Receive thread only.
  struct Slots;
  std::unique_ptr<Slots> slots_;
  std::unique_ptr<Block> current_;

  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<std::unique_ptr<Block>> full_;
  std::vector<std::unique_ptr<Block>> free_;
  std::size_t blocks_ = 0;  // allocated
  std::size_t max_blocks_ = 0;
  bool started_ = false;

  std::atomic<std::int64_t> datagrams_{0};
  std::atomic<std::int64_t> bytes_{0};
  std::atomic<std::int64_t> kernel_drops_{0};
  std::atomic<std::int64_t> memory_drops_{0};
  std::atomic<std::int64_t> truncated_{0};
  std::atomic<std::int64_t> peak_queued_{0};
  std::atomic<std::int64_t> peak_memory_{0};
};

template <typename F>
void Block::for_each(F&& f) const {
  std::size_t at = 0;
  while (at < used_) {
    const std::uint8_t* h = bytes_.get() + at;
    Datagram d;
    std::uint32_t size = 0;
    std::memcpy(&size, h, 4);
    std::memcpy(&d.source_port, h + 4, 2);
    std::memcpy(&d.source_ip, h + 8, 4);
    std::memcpy(&d.recv_ns, h + 16, 8);
    d.data = h + 24;
    d.size = size;
    f(d);
    at += (24 + size + 7) & ~std::size_t{7};
  }
}

}  // namespace exodaq::tools::record
