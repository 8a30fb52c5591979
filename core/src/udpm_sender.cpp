#include "exodaq/core/udpm_sender.hpp"

#include <arpa/inet.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string_view>

namespace exodaq::core {

namespace {

bool parse_decimal(std::string_view text, long max, long& out) {
  if (text.empty() || text.size() > 6) return false;
  long v = 0;
  for (const char c : text) {
    if (c < '0' || c > '9') return false;
    v = v * 10 + (c - '0');
  }
  if (v > max) return false;
  out = v;
  return true;
}

// One `key=value` of the URL's options; false for one LCM would not take as we do.
bool take_option(std::string_view option, UdpmAddress& a) {
  const std::size_t eq = option.find('=');
  const std::string_view key = option.substr(0, eq);
  const std::string_view value = eq == std::string_view::npos ? "" : option.substr(eq + 1);
  if (key == "recv_buf_size") return true;  // the receivers' concern
  if (key == "ttl") {
    long ttl = 0;
    if (!parse_decimal(value, 255, ttl)) return false;
    a.ttl = static_cast<int>(ttl);
    return true;
  }
  return false;
}

// A socket set up as lcm_udpm.c sets up its send socket (TTL, loopback on),
// nonblocking; it does not join the group: it never reads. Not connected
// either, as LCM's: a connected socket keeps its cached route after the route
// is gone and sends into nothing without an error (a lost network path would
// be silent: tests/lab/publish_fault.py); unconnected, each send looks the
// route up and fails with ENETUNREACH.
int open_socket(const UdpmAddress& a) noexcept {
  const int fd = socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd < 0) return -errno;
  const unsigned char ttl = static_cast<unsigned char>(a.ttl);
  const unsigned int loop = 1;
  if (setsockopt(fd, IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof ttl) != 0 ||
      setsockopt(fd, IPPROTO_IP, IP_MULTICAST_LOOP, &loop, sizeof loop) != 0) {
    const int e = errno;
    close(fd);
    return -e;
  }
  return fd;
}

std::string errno_text(int e) {
  const char* name = strerrorname_np(e);
  return std::string(strerrordesc_np(e)) + " (" + (name != nullptr ? name : "?") + ")";
}

}  // namespace

std::optional<UdpmAddress> parse_udpm_url(const std::string& url) {
  constexpr std::string_view kScheme = "udpm://";
  std::string_view rest(url);
  if (rest.substr(0, kScheme.size()) != kScheme) return std::nullopt;
  rest.remove_prefix(kScheme.size());
  const std::size_t q = rest.find('?');
  const std::string_view network = rest.substr(0, q);
  UdpmAddress a;
  const std::size_t colon = network.find(':');
  if (network.empty()) {
    inet_aton("239.255.76.67", &a.group);  // LCM's default group and port
    a.port = 7667;
  } else {
    if (colon == std::string_view::npos) return std::nullopt;  // LCM would send to port 0
    const std::string group(network.substr(0, colon));
    long port = 0;
    if (inet_aton(group.c_str(), &a.group) == 0 ||
        !parse_decimal(network.substr(colon + 1), 65535, port)) {
      return std::nullopt;
    }
    a.port = static_cast<std::uint16_t>(port);
  }
  if (q == std::string_view::npos) return a;
  std::string_view options = rest.substr(q + 1);
  while (!options.empty()) {
    const std::size_t cut = options.find_first_of("&?");
    if (!take_option(options.substr(0, cut), a)) return std::nullopt;
    if (cut == std::string_view::npos) break;
    options.remove_prefix(cut + 1);
  }
  return a;
}

UdpmSender::UdpmSender(const UdpmAddress& address, const std::string& url) : address_(address) {
  destination_.sin_family = AF_INET;
  destination_.sin_addr = address.group;
  destination_.sin_port = htons(address.port);
  // As lcm_create(): a group without a route is refused at start.
  const int test = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (test < 0 ||
      connect(test, reinterpret_cast<const sockaddr*>(&destination_), sizeof destination_) != 0) {
    const int e = errno;
    if (test >= 0) close(test);
    throw std::runtime_error("cannot send to LCM on '" + url + "': " + errno_text(e));
  }
  close(test);
  fd_ = open_socket(address_);
  if (fd_ < 0) {
    throw std::runtime_error("cannot open a socket for LCM on '" + url + "': " + errno_text(-fd_));
  }
}

UdpmSender::~UdpmSender() {
  if (fd_ >= 0) close(fd_);
}

int UdpmSender::reopen() noexcept {
  const int fresh = open_socket(address_);
  if (fresh < 0) return -fresh;
  const int rc = dup2(fresh, fd_) < 0 ? errno : 0;
  close(fresh);
  return rc;
}

int UdpmSender::sendv(const void* header, std::size_t header_size, const std::string* channel,
                      const std::uint8_t* data, std::size_t size) noexcept {
  std::array<iovec, 3> iov{};
  std::size_t n = 0;
  iov[n++] = {const_cast<void*>(header), header_size};
  if (channel != nullptr) {
    iov[n++] = {const_cast<char*>(channel->c_str()), channel->size() + 1};  // with its NUL
  }
  iov[n++] = {const_cast<std::uint8_t*>(data), size};
  msghdr m{};
  m.msg_name = &destination_;
  m.msg_namelen = sizeof destination_;
  m.msg_iov = iov.data();
  m.msg_iovlen = n;
  std::size_t expected = 0;
  for (std::size_t i = 0; i < n; ++i) expected += iov[i].iov_len;
  const ssize_t sent = sendmsg(fd_, &m, MSG_DONTWAIT | MSG_NOSIGNAL);
  if (sent < 0) return errno;
  return static_cast<std::size_t>(sent) == expected ? 0 : EMSGSIZE;
}

int UdpmSender::send(const std::string& channel, const std::uint8_t* data,
                     std::size_t size) noexcept {
  if (channel.size() > kLcmMaxChannelLength) return EMSGSIZE;
  if (channel.size() + 1 + size > kLcmShortMessageMax) return send_fragments(channel, data, size);
  std::array<std::uint32_t, 2> header{htonl(kLcmMagicShort), htonl(seqno_++)};
  return sendv(header.data(), sizeof header, &channel, data, size);
}

// lcm_udpm.c's large-message path: the channel goes in the first fragment only,
// every fragment carries the message size, its offset and its number.
int UdpmSender::send_fragments(const std::string& channel, const std::uint8_t* data,
                               std::size_t size) noexcept {
  const std::size_t payload = channel.size() + 1 + size;
  const std::size_t count =
      payload / kLcmFragmentMaxPayload + (payload % kLcmFragmentMaxPayload != 0 ? 1 : 0);
  if (count > 65535 || size > 0xFFFFFFFFU) return EMSGSIZE;
  struct Header {
    std::uint32_t magic, seqno, size, offset;
    std::uint16_t number, count;
  } h{htonl(kLcmMagicLong),
      htonl(seqno_++),
      htonl(static_cast<std::uint32_t>(size)),
      0,
      0,
      htons(static_cast<std::uint16_t>(count))};
  static_assert(sizeof(Header) == 20);
  std::size_t offset = kLcmFragmentMaxPayload - (channel.size() + 1);
  int rc = sendv(&h, sizeof h, &channel, data, offset);
  for (std::uint16_t k = 1; rc == 0 && k < count; ++k) {
    const std::size_t length = std::min(kLcmFragmentMaxPayload, size - offset);
    h.offset = htonl(static_cast<std::uint32_t>(offset));
    h.number = htons(k);
    rc = sendv(&h, sizeof h, nullptr, data + offset, length);
    offset += length;
  }
  return rc;
}

}  // namespace exodaq::core
