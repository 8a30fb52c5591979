#pragma once
// LCM's UDP multicast transport (`udpm://`) from a socket of our own, so the
// loop thread can send without a hand-off: the datagrams are byte for byte
// those of LCM 1.3.1's lcm_udpm.c (a "LC02" header with the message number,
// then the channel, a NUL and the payload; "LC03" fragments above 65 499
// bytes), sent to the group like lcm_publish() does. The socket is
// nonblocking: a full send buffer is a refused message (EAGAIN), never a wait.
// Sending allocates nothing. docs/architecture.md, "Publishing".
#include <netinet/in.h>

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace exodaq::core {

// LCM 1.3.1's wire constants (lcm/udpm_util.h, Linux).
inline constexpr std::uint32_t kLcmMagicShort = 0x4c433032;  // "LC02"
inline constexpr std::uint32_t kLcmMagicLong = 0x4c433033;   // "LC03"
inline constexpr std::size_t kLcmShortMessageMax = 65499;    // channel + NUL + payload
inline constexpr std::size_t kLcmFragmentMaxPayload = 65487;
inline constexpr std::size_t kLcmMaxChannelLength = 63;

// What the sender takes from an LCM URL: udpm://GROUP:PORT?ttl=N
// (recv_buf_size, the receivers' option, is accepted and ignored). nullopt for
// a URL this sender would not reproduce exactly: another provider, a missing
// port, an option LCM would warn about; those go through LCM itself.
struct UdpmAddress {
  in_addr group{};
  std::uint16_t port = 0;  // host order
  int ttl = 0;
};
std::optional<UdpmAddress> parse_udpm_url(const std::string& url);

class UdpmSender {
 public:
  // Opens the send socket. Throws std::runtime_error naming the URL and the
  // errno when the group has no route (lcm_create() fails the same way).
  UdpmSender(const UdpmAddress& address, const std::string& url);
  ~UdpmSender();
  UdpmSender(const UdpmSender&) = delete;
  UdpmSender& operator=(const UdpmSender&) = delete;

  // One message as LCM sends it. Returns 0, or the errno of the refusal
  // (EMSGSIZE for a channel longer than 63 characters). One thread at a time.
  int send(const std::string& channel, const std::uint8_t* data, std::size_t size) noexcept;

  // Any thread, concurrently with send(): a new socket takes the old one's
  // descriptor atomically (dup2), so a send in flight finishes on the old one.
  // Returns 0 or the errno.
  int reopen() noexcept;

 private:
  int send_fragments(const std::string& channel, const std::uint8_t* data,
                     std::size_t size) noexcept;
  int sendv(const void* header, std::size_t header_size, const std::string* channel,
            const std::uint8_t* data, std::size_t size) noexcept;

  UdpmAddress address_;
  sockaddr_in destination_{};
  int fd_ = -1;
  std::uint32_t seqno_ = 0;  // LCM's msg_seqno: one per message, fragments share it
};

}  // namespace exodaq::core
