// The real CanPort: a CAN_RAW socket. See can_port.hpp for the contract and
// docs/can-protocol.md ("The socketcan backend") for the behaviour.
// <linux/errqueue.h> uses struct timespec without declaring it: these first.
#include <sys/socket.h>
#include <time.h>

#include <linux/can.h>
#include <linux/can/raw.h>
#include <linux/errqueue.h>
#include <linux/net_tstamp.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>

#include "exodaq/common/clock_now.hpp"
#include "exodaq/drivers/can_port.hpp"

namespace exodaq::drivers {
namespace {

std::int64_t to_ns(const timespec& ts) noexcept {
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

class SocketCanPort final : public CanPort {
 public:
  explicit SocketCanPort(const CanPortConfig& config) : config_(config) {
    for (int i = 0; i < kMax; ++i) {
      const auto k = static_cast<std::size_t>(i);
      iov_[k].iov_base = &raw_[k];
      iov_[k].iov_len = sizeof(can_frame);
    }
  }
  ~SocketCanPort() override { close(); }

  int open() noexcept override {
    close();
    // The socket first: a kernel without CAN (EAFNOSUPPORT) is reported as
    // such, not as a missing interface.
    const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
    if (fd < 0) return -errno;
    const unsigned index = if_nametoindex(config_.interface.c_str());
    if (index == 0) {
      ::close(fd);
      return -ENODEV;
    }
    const int r = configure(fd, index);
    if (r != 0) {
      ::close(fd);
      return r;
    }
    fd_ = fd;
    last_ovfl_ = 0;
    return 0;
  }

  void close() noexcept override {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

  bool is_open() const noexcept override { return fd_ >= 0; }

  int receive(can::CanFrame* frames, int max, CanRxInfo& info) noexcept override {
    if (fd_ < 0) return -EBADF;
    const int want = max < kMax ? max : kMax;
    for (int i = 0; i < want; ++i) {
      const auto k = static_cast<std::size_t>(i);
      msgs_[k] = mmsghdr{};
      msgs_[k].msg_hdr.msg_iov = &iov_[k];
      msgs_[k].msg_hdr.msg_iovlen = 1;
      msgs_[k].msg_hdr.msg_control = control_[k].data();
      msgs_[k].msg_hdr.msg_controllen = control_[k].size();
    }
    const int n = ::recvmmsg(fd_, msgs_.data(), static_cast<unsigned>(want), MSG_DONTWAIT, nullptr);
    if (n < 0) return errno == EWOULDBLOCK ? 0 : -errno;
    int out = 0;
    for (int i = 0; i < n; ++i) {
      const auto k = static_cast<std::size_t>(i);
      if (msgs_[k].msg_len != sizeof(can_frame)) continue;  // CAN FD is never enabled
      can::CanFrame& f = frames[out++];
      convert(raw_[k], f);
      f.wall_ns = 0;
      f.mono_ns = 0;
      msghdr& h = msgs_[k].msg_hdr;
      for (cmsghdr* c = CMSG_FIRSTHDR(&h); c != nullptr; c = CMSG_NXTHDR(&h, c)) {
        if (c->cmsg_level != SOL_SOCKET) continue;
        if (c->cmsg_type == SO_TIMESTAMPING) {
          scm_timestamping ts{};
          std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
          f.wall_ns = to_ns(ts.ts[0]);  // software RX stamp, CLOCK_REALTIME
        } else if (c->cmsg_type == SO_TIMESTAMPNS) {
          timespec ts{};
          std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
          f.wall_ns = to_ns(ts);
        } else if (c->cmsg_type == SO_RXQ_OVFL) {
          std::uint32_t dropped = 0;
          std::memcpy(&dropped, CMSG_DATA(c), sizeof dropped);
          info.dropped += static_cast<std::uint32_t>(dropped - last_ovfl_);
          last_ovfl_ = dropped;
        }
      }
      if ((h.msg_flags & MSG_CONFIRM) != 0) f.flags |= can::frame_flag::kOwn;
      if (f.wall_ns == 0) ++info.unstamped;
    }
    return out;
  }

  int send(const can::CanFrame& frame) noexcept override {
    if (fd_ < 0) return -EBADF;
    can_frame cf{};
    if ((frame.flags & can::frame_flag::kError) != 0) {
      cf.can_id = (frame.id & CAN_ERR_MASK) | CAN_ERR_FLAG;
    } else if ((frame.flags & can::frame_flag::kExtended) != 0) {
      cf.can_id = (frame.id & CAN_EFF_MASK) | CAN_EFF_FLAG;
    } else {
      cf.can_id = frame.id & CAN_SFF_MASK;
    }
    if ((frame.flags & can::frame_flag::kRtr) != 0) cf.can_id |= CAN_RTR_FLAG;
    cf.can_dlc = frame.dlc > 8 ? 8 : frame.dlc;
    std::memcpy(cf.data, frame.data.data(), 8);
    const ssize_t n = ::send(fd_, &cf, sizeof cf, MSG_DONTWAIT);
    if (n < 0) return -errno;
    return n == sizeof cf ? 0 : -EIO;
  }

  int wait_readable(std::int64_t deadline_mono_ns) noexcept override {
    if (fd_ < 0) return -EBADF;
    std::int64_t left = deadline_mono_ns - now_mono_ns();
    if (left < 0) left = 0;
    const timespec timeout{static_cast<time_t>(left / 1'000'000'000),
                           static_cast<long>(left % 1'000'000'000)};
    pollfd p{fd_, POLLIN, 0};
    const int r = ::ppoll(&p, 1, &timeout, nullptr);
    if (r < 0) return -errno;
    if (r == 0) return 0;
    if ((p.revents & POLLNVAL) != 0) return -EBADF;
    return 1;  // POLLIN, or POLLERR: receive() reports the pending error
  }

  std::int64_t now_mono_ns() noexcept override { return mono_now_ns(); }
  std::int64_t now_wall_ns() noexcept override { return clock_ns(CLOCK_REALTIME); }

 private:
  static constexpr int kMax = 32;

  static void convert(const can_frame& cf, can::CanFrame& f) noexcept {
    f.flags = 0;
    if ((cf.can_id & CAN_ERR_FLAG) != 0) {
      f.flags |= can::frame_flag::kError;
      f.id = cf.can_id & CAN_ERR_MASK;
    } else if ((cf.can_id & CAN_EFF_FLAG) != 0) {
      f.flags |= can::frame_flag::kExtended;
      f.id = cf.can_id & CAN_EFF_MASK;
    } else {
      f.id = cf.can_id & CAN_SFF_MASK;
    }
    if ((cf.can_id & CAN_RTR_FLAG) != 0 && (cf.can_id & CAN_ERR_FLAG) == 0) {
      f.flags |= can::frame_flag::kRtr;
    }
    f.dlc = cf.can_dlc;
    std::memcpy(f.data.data(), cf.data, 8);
  }

  // The protocol's filters (can_port.hpp); none: nothing but error frames.
  int filters(std::array<can_filter, can::CanIdFilterSet::kCapacity>& out) const noexcept {
    const can::CanIdFilterSet& set = config_.filters;
    for (int i = 0; i < set.count; ++i) {
      const can::CanIdFilter& f = set.filters[static_cast<std::size_t>(i)];
      out[static_cast<std::size_t>(i)].can_id = f.id;
      out[static_cast<std::size_t>(i)].can_mask = f.mask;
    }
    return set.count;
  }

  int configure(int fd, unsigned index) noexcept {
    std::array<can_filter, can::CanIdFilterSet::kCapacity> f{};
    const int nf = filters(f);
    if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_FILTER, f.data(),
                   static_cast<socklen_t>(static_cast<std::size_t>(nf) * sizeof(can_filter))) < 0) {
      return -errno;
    }
    const can_err_mask_t err_mask = can::err_class::kSubscribed;
    if (setsockopt(fd, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) < 0) {
      return -errno;
    }
    const int ts_flags = SOF_TIMESTAMPING_RX_SOFTWARE | SOF_TIMESTAMPING_SOFTWARE;
    if (setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPING, &ts_flags, sizeof ts_flags) < 0) {
      const int one = 1;
      if (setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof one) < 0) return -errno;
    }
    const int one = 1;
    if (setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &one, sizeof one) < 0) return -errno;
    if (config_.receive_own &&
        setsockopt(fd, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &one, sizeof one) < 0) {
      return -errno;
    }
    const int rcvbuf = config_.rcvbuf_bytes;
    if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &rcvbuf, sizeof rcvbuf) < 0) {
      // Without CAP_NET_ADMIN the kernel caps it at net.core.rmem_max.
      (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    }
    ifreq ifr{};
    std::strncpy(ifr.ifr_name, config_.interface.c_str(), IFNAMSIZ - 1);
    if (ioctl(fd, SIOCGIFFLAGS, &ifr) < 0) return -errno;
    if ((ifr.ifr_flags & IFF_UP) == 0) return -ENETDOWN;
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = static_cast<int>(index);
    if (bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) < 0) return -errno;
    return 0;
  }

  CanPortConfig config_;
  int fd_ = -1;
  std::uint32_t last_ovfl_ = 0;
  std::array<can_frame, kMax> raw_{};
  std::array<iovec, kMax> iov_{};
  std::array<mmsghdr, kMax> msgs_{};
  std::array<std::array<char, 256>, kMax> control_{};
};

}  // namespace

std::unique_ptr<CanPort> make_socketcan_port(const CanPortConfig& config) {
  return std::make_unique<SocketCanPort>(config);
}

}  // namespace exodaq::drivers
