#pragma once
// One LCM channel from a `udpm://` group, with the kernel dropping every other
// datagram (a socket filter matching the LC02 header and the channel name):
// a listener for the daemon's own 10 Hz status channel is woken 10 times a
// second, not for each of the group's 3 000 cycle messages a second as an LCM
// subscription would be. Fragmented (LC03) messages are not received: the
// channels it is for fit one datagram. The counterpart of udpm_sender.hpp.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "exodaq/core/udpm_sender.hpp"

namespace exodaq::core {

// The error of every group receiver: "cannot listen on LCM 'URL': what: the
// errno's text".
[[noreturn]] void listen_failure(const std::string& url, const char* what);

// A UDP socket on the group of `address`, as every receiver of the project
// opens it (this class, `exodaq record`): SO_REUSEADDR (the port is shared
// with other receivers, as LCM's sockets are), then `configure(fd)` for the
// receiver's own options and filters (before the bind: nothing unfiltered is
// ever queued), then bound to the group's port and joined to the group on the
// default interface. Throws listen_failure()'s error; the socket is closed.
int open_group_socket(const UdpmAddress& address, const std::string& url,
                      const std::function<void(int fd)>& configure);

class UdpmChannelReceiver {
 public:
  // Joins the group on its port (shared with other receivers, as LCM's
  // sockets are) and installs the filter. Throws std::runtime_error naming the
  // URL and the errno.
  UdpmChannelReceiver(const UdpmAddress& address, const std::string& url,
                      const std::string& channel);
  ~UdpmChannelReceiver();
  UdpmChannelReceiver(const UdpmChannelReceiver&) = delete;
  UdpmChannelReceiver& operator=(const UdpmChannelReceiver&) = delete;

  // Waits up to timeout_ms for one message of the channel. Returns its
  // payload size (the payload in payload()), 0 on timeout, -1 on an error of
  // the socket (errno set).
  int receive(int timeout_ms);
  const std::uint8_t* payload() const noexcept { return buffer_.data() + payload_offset_; }
  // Datagrams that reached this socket: only the channel's, if the filter holds.
  std::int64_t datagrams() const noexcept { return datagrams_; }

 private:
  std::string channel_;
  int fd_ = -1;
  std::vector<std::uint8_t> buffer_;
  std::size_t payload_offset_ = 0;
  std::int64_t datagrams_ = 0;
};

}  // namespace exodaq::core
