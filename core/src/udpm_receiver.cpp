#include "exodaq/core/udpm_receiver.hpp"

#include <arpa/inet.h>
#include <linux/filter.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace exodaq::core {

namespace {

// A UDP socket's filter sees the datagram from its UDP header (8 bytes).
constexpr std::uint32_t kUdpHeaderBytes = 8;
constexpr std::uint32_t kLc02HeaderBytes = 8;  // magic, sequence number

// Accepts an LC02 datagram whose channel is `channel` (with its NUL), drops
// anything else.
std::vector<sock_filter> channel_filter(const std::string& channel) {
  std::string name = channel;
  name.push_back('\0');
  std::vector<sock_filter> p;
  std::vector<std::size_t> to_reject;  // jumps to patch
  const auto compare = [&](std::uint16_t size, std::uint32_t at, std::uint32_t value) {
    p.push_back(BPF_STMT(BPF_LD | size | BPF_ABS, at));
    to_reject.push_back(p.size());
    p.push_back(BPF_JUMP(BPF_JMP | BPF_JEQ | BPF_K, value, 0, 0));
  };
  compare(BPF_W, kUdpHeaderBytes, kLcmMagicShort);
  std::uint32_t at = kUdpHeaderBytes + kLc02HeaderBytes;
  std::size_t i = 0;
  for (; i + 4 <= name.size(); i += 4, at += 4) {
    std::uint32_t word = 0;
    for (std::size_t k = 0; k < 4; ++k) word = word << 8 | static_cast<unsigned char>(name[i + k]);
    compare(BPF_W, at, word);
  }
  for (; i < name.size(); ++i, ++at) compare(BPF_B, at, static_cast<unsigned char>(name[i]));
  p.push_back(BPF_STMT(BPF_RET | BPF_K, 0xFFFFFFFF));  // accept, whole
  const std::size_t reject = p.size();
  p.push_back(BPF_STMT(BPF_RET | BPF_K, 0));
  for (const std::size_t j : to_reject) p[j].jf = static_cast<std::uint8_t>(reject - j - 1);
  return p;
}

}  // namespace

void listen_failure(const std::string& url, const char* what) {
  const int e = errno;
  throw std::runtime_error("cannot listen on LCM '" + url + "': " + what + ": " +
                           strerrordesc_np(e));
}

int open_group_socket(const UdpmAddress& address, const std::string& url,
                      const std::function<void(int fd)>& configure) {
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) listen_failure(url, "socket");
  try {
    const int one = 1;
    if (setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0) {
      listen_failure(url, "SO_REUSEADDR");
    }
    configure(fd);
    sockaddr_in local{};
    local.sin_family = AF_INET;
    local.sin_addr.s_addr = htonl(INADDR_ANY);
    local.sin_port = htons(address.port);
    if (bind(fd, reinterpret_cast<const sockaddr*>(&local), sizeof local) != 0) {
      listen_failure(url, "bind");
    }
    ip_mreq group{};
    group.imr_multiaddr = address.group;
    group.imr_interface.s_addr = htonl(INADDR_ANY);
    if (setsockopt(fd, IPPROTO_IP, IP_ADD_MEMBERSHIP, &group, sizeof group) != 0) {
      listen_failure(url, "joining the group");
    }
  } catch (...) {
    close(fd);
    throw;
  }
  return fd;
}

UdpmChannelReceiver::UdpmChannelReceiver(const UdpmAddress& address, const std::string& url,
                                         const std::string& channel)
    : channel_(channel), buffer_(65536) {
  if (channel.size() > kLcmMaxChannelLength) {
    throw std::runtime_error("LCM channel '" + channel + "' is longer than 63 characters");
  }
  payload_offset_ = kLc02HeaderBytes + channel.size() + 1;
  fd_ = open_group_socket(address, url, [&](int fd) {
    std::vector<sock_filter> program = channel_filter(channel);
    sock_fprog fprog{static_cast<unsigned short>(program.size()), program.data()};
    if (setsockopt(fd, SOL_SOCKET, SO_ATTACH_FILTER, &fprog, sizeof fprog) != 0) {
      listen_failure(url, "SO_ATTACH_FILTER");
    }
  });
}

UdpmChannelReceiver::~UdpmChannelReceiver() {
  if (fd_ >= 0) close(fd_);
}

int UdpmChannelReceiver::receive(int timeout_ms) {
  pollfd p{fd_, POLLIN, 0};
  const int ready = poll(&p, 1, timeout_ms);
  if (ready <= 0) return ready < 0 && errno != EINTR ? -1 : 0;
  const ssize_t n = recv(fd_, buffer_.data(), buffer_.size(), MSG_DONTWAIT);
  if (n < 0) return errno == EAGAIN || errno == EINTR ? 0 : -1;
  ++datagrams_;
  // The filter's match, checked again: a datagram queued by another
  // program's filterless socket cannot reach here, but a short one could.
  const auto size = static_cast<std::size_t>(n);
  if (size < payload_offset_ ||
      std::memcmp(buffer_.data() + kLc02HeaderBytes, channel_.c_str(), channel_.size() + 1) != 0) {
    return 0;
  }
  return static_cast<int>(size - payload_offset_);
}

}  // namespace exodaq::core
