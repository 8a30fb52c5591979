// The publish path: our own udpm sender against stock LCM 1.3.1 (the same
// datagrams, byte for byte, as lcm_publish() sends; received by LCM's own
// subscriber, fragments included), and the Publisher's failure episodes and
// transport re-creation. Sockets use the default LCM group with ttl=0 (this
// host only) on a port of their own per process.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <lcm/lcm.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "alloc_counter.hpp"
#include "exodaq/core/message_encoder.hpp"
#include "exodaq/core/publisher.hpp"
#include "exodaq/core/udpm_receiver.hpp"
#include "exodaq/core/udpm_sender.hpp"

using namespace exodaq;

namespace {

// A port of this test process's own (tests run in parallel).
int own_port(int offset) {
  return 20000 + static_cast<int>(getpid() % 5000) * 8 + offset;
}

std::string url_on(int port) {
  return "udpm://239.255.76.67:" + std::to_string(port) + "?ttl=0";
}

// A plain UDP socket in the group: sees the datagrams exactly as sent.
class Capture {
 public:
  explicit Capture(int port) {
    fd_ = socket(AF_INET, SOCK_DGRAM, 0);
    const int one = 1;
    setsockopt(fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<std::uint16_t>(port));
    a.sin_addr.s_addr = htonl(INADDR_ANY);
    EXPECT_EQ(bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    ip_mreq m{};
    inet_aton("239.255.76.67", &m.imr_multiaddr);
    m.imr_interface.s_addr = htonl(INADDR_ANY);
    EXPECT_EQ(setsockopt(fd_, IPPROTO_IP, IP_ADD_MEMBERSHIP, &m, sizeof m), 0);
    const int big = 4 << 20;  // beyond net.core.rmem_max where allowed (root)
    if (setsockopt(fd_, SOL_SOCKET, SO_RCVBUFFORCE, &big, sizeof big) != 0)
      setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &big, sizeof big);
  }
  ~Capture() { close(fd_); }
  // The next datagram, or empty after 2 s.
  std::vector<std::uint8_t> next() {
    pollfd p{fd_, POLLIN, 0};
    if (poll(&p, 1, 2000) != 1) return {};
    std::vector<std::uint8_t> buf(70000);
    const ssize_t n = recv(fd_, buf.data(), buf.size(), 0);
    buf.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
    return buf;
  }

 private:
  int fd_ = -1;
};

std::vector<std::uint8_t> pattern(std::size_t n) {
  std::vector<std::uint8_t> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<std::uint8_t>((i * 7 + 3) & 0xff);
  return v;
}

struct Received {
  std::vector<std::string> channels;
  std::vector<std::vector<std::uint8_t>> payloads;
};

void on_message(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
  auto* r = static_cast<Received*>(user);
  r->channels.emplace_back(channel);
  const auto* p = static_cast<const std::uint8_t*>(rbuf->data);
  r->payloads.emplace_back(p, p + rbuf->data_size);
}

}  // namespace

TEST(UdpmUrl, TakesWhatLcmTakesAndLeavesTheRestToLcm) {
  const auto a = core::parse_udpm_url("udpm://239.255.76.67:7667?ttl=1");
  ASSERT_TRUE(a.has_value());
  EXPECT_EQ(std::string(inet_ntoa(a->group)), "239.255.76.67");
  EXPECT_EQ(a->port, 7667);
  EXPECT_EQ(a->ttl, 1);
  const auto d = core::parse_udpm_url("udpm://");  // LCM's defaults
  ASSERT_TRUE(d.has_value());
  EXPECT_EQ(d->port, 7667);
  EXPECT_EQ(d->ttl, 0);
  const auto b = core::parse_udpm_url("udpm://239.1.2.3:9000?recv_buf_size=2097152&ttl=0");
  ASSERT_TRUE(b.has_value());
  EXPECT_EQ(b->port, 9000);
  EXPECT_EQ(b->ttl, 0);
  EXPECT_EQ(core::parse_udpm_url("udpm://239.1.2.3:9000")->ttl, 0);
  // Sent through LCM itself: another provider, no port (LCM would use 0), a
  // port or TTL LCM would read differently, an option LCM warns about.
  EXPECT_FALSE(core::parse_udpm_url("file:///tmp/x.lcm").has_value());
  EXPECT_FALSE(core::parse_udpm_url("memq://").has_value());
  EXPECT_FALSE(core::parse_udpm_url("udpm://239.1.2.3").has_value());
  EXPECT_FALSE(core::parse_udpm_url("udpm://239.1.2.3:0x1f").has_value());
  EXPECT_FALSE(core::parse_udpm_url("udpm://239.1.2.3:70000").has_value());
  EXPECT_FALSE(core::parse_udpm_url("udpm://239.1.2.3:7667?ttl=256").has_value());
  EXPECT_FALSE(core::parse_udpm_url("udpm://239.1.2.3:7667?transmit_only=1").has_value());
  EXPECT_FALSE(core::parse_udpm_url("udpm://not-an-address:7667").has_value());
}

// The same message through lcm_publish() and through our sender: the same
// datagrams (both start at message number 0), short and fragmented.
TEST(UdpmSender, SendsTheDatagramsLcmSends) {
  const int port = own_port(0);
  const std::string url = url_on(port);
  Capture capture(port);
  const std::string channel = "UDPM_TEST_CHANNEL";
  const auto small = pattern(142);
  const auto big = pattern(100'000);  // two LC03 fragments

  lcm_t* lcm = lcm_create(url.c_str());
  ASSERT_NE(lcm, nullptr);
  ASSERT_EQ(lcm_publish(lcm, channel.c_str(), small.data(), small.size()), 0);
  ASSERT_EQ(lcm_publish(lcm, channel.c_str(), big.data(), big.size()), 0);
  lcm_destroy(lcm);
  std::vector<std::vector<std::uint8_t>> from_lcm;
  for (int i = 0; i < 3; ++i) from_lcm.push_back(capture.next());

  core::UdpmSender sender(*core::parse_udpm_url(url), url);
  ASSERT_EQ(sender.send(channel, small.data(), small.size()), 0);
  ASSERT_EQ(sender.send(channel, big.data(), big.size()), 0);
  for (int i = 0; i < 3; ++i) {
    const auto ours = capture.next();
    ASSERT_FALSE(ours.empty()) << "datagram " << i;
    EXPECT_EQ(ours, from_lcm[static_cast<std::size_t>(i)]) << "datagram " << i;
  }
  // What they look like: "LC02", message 0, channel, NUL, payload; then "LC03" x 2.
  ASSERT_GE(from_lcm[0].size(), 8U);
  EXPECT_EQ(std::memcmp(from_lcm[0].data(), "LC02\0\0\0\0", 8), 0);
  EXPECT_EQ(from_lcm[0].size(), 8 + channel.size() + 1 + small.size());
  EXPECT_EQ(std::memcmp(from_lcm[1].data(), "LC03\0\0\0\1", 8), 0);
  EXPECT_EQ(std::memcmp(from_lcm[2].data(), "LC03\0\0\0\1", 8), 0);
}

// Stock LCM (C) subscribes and gets every message whole, fragments reassembled.
TEST(UdpmSender, StockLcmReceivesItsMessages) {
  const int port = own_port(1);
  const std::string url = url_on(port);
  lcm_t* lcm = lcm_create(url.c_str());
  ASSERT_NE(lcm, nullptr);
  Received received;
  lcm_subscribe(lcm, "UDPM_.*", on_message, &received);
  core::UdpmSender sender(*core::parse_udpm_url(url), url);
  const auto small = pattern(300);
  const auto big = pattern(100'000);  // two fragments
  // One at a time: a burst of 64 KiB fragments can overflow a receive buffer
  // capped by net.core.rmem_max before LCM's thread drains it.
  const auto send_and_wait = [&](const char* channel, const std::vector<std::uint8_t>& data,
                                 std::size_t n) {
    const std::size_t before = received.channels.size();
    ASSERT_EQ(sender.send(channel, data.data(), n), 0);
    for (int i = 0; i < 50 && received.channels.size() == before; ++i) lcm_handle_timeout(lcm, 100);
  };
  send_and_wait("UDPM_A", small, small.size());
  send_and_wait("UDPM_B", big, big.size());
  send_and_wait("UDPM_A", small, 0);  // an empty payload
  lcm_destroy(lcm);
  ASSERT_EQ(received.channels.size(), 3U);
  EXPECT_EQ(received.channels[0], "UDPM_A");
  EXPECT_EQ(received.payloads[0], small);
  EXPECT_EQ(received.channels[1], "UDPM_B");
  EXPECT_EQ(received.payloads[1], big);
  EXPECT_TRUE(received.payloads[2].empty());
}

TEST(UdpmSender, RefusesWhatLcmRefusesAndKeepsSendingAcrossAReopen) {
  const int port = own_port(2);
  const std::string url = url_on(port);
  Capture capture(port);
  core::UdpmSender sender(*core::parse_udpm_url(url), url);
  const auto small = pattern(10);
  EXPECT_EQ(sender.send(std::string(64, 'C'), small.data(), small.size()), EMSGSIZE);
  ASSERT_EQ(sender.send("BEFORE", small.data(), small.size()), 0);
  ASSERT_EQ(sender.reopen(), 0);
  ASSERT_EQ(sender.send("AFTER", small.data(), small.size()), 0);
  const auto before = capture.next();
  const auto after = capture.next();
  ASSERT_FALSE(before.empty());
  ASSERT_FALSE(after.empty());
  EXPECT_EQ(std::string(reinterpret_cast<const char*>(after.data()) + 8), "AFTER");
  EXPECT_EQ(after[7], 1);  // the message number runs on (the refused one took none)
}

TEST(UdpmSender, SendingAllocatesNothing) {
  const int port = own_port(3);
  const std::string url = url_on(port);
  core::UdpmSender sender(*core::parse_udpm_url(url), url);
  const auto small = pattern(142);
  const auto big = pattern(70'000);
  const std::string channel = "UDPM_ALLOC";
  test::AllocationScope scope;
  for (int i = 0; i < 100; ++i) EXPECT_EQ(sender.send(channel, small.data(), small.size()), 0);
  EXPECT_EQ(sender.send(channel, big.data(), big.size()), 0);
  EXPECT_EQ(scope.count(), 0U);
}

namespace {

// A sink that refuses while `refuse` is set, counting reopen() calls.
class FlakySink final : public core::MessageSink {
 public:
  explicit FlakySink(bool from_loop) : from_loop_(from_loop) {}
  std::atomic<bool> refuse{false};
  std::atomic<int> reopens{0};
  std::atomic<std::int64_t> accepted{0};
  bool publish(const std::string&, const core::OutgoingMessage&) noexcept override {
    if (refuse.load()) return false;
    accepted.fetch_add(1);
    return true;
  }
  bool sends_from_loop() const noexcept override { return from_loop_; }
  int last_error() const noexcept override { return ENETUNREACH; }
  int reopen() noexcept override {
    reopens.fetch_add(1);
    return 0;
  }

 private:
  bool from_loop_;
};

void send_one(core::Publisher& p, std::int64_t seq) {
  core::OutgoingMessage* slot = p.acquire();
  ASSERT_NE(slot, nullptr);
  slot->channel = messages::Kind::kPalmPose;
  slot->size = 4;
  slot->seq = seq;
  slot->utime_us = 1'000'000 + seq;
  p.commit();
  p.notify();
}

}  // namespace

// Refusals form an episode (since which message, how many lost, the errno);
// the first accepted message ends it; meanwhile the transport is re-created
// after 1 s. The same whether the loop or the publisher thread sends.
TEST(Publisher, TracksAFailureEpisodeAndReopensTheTransportWhileItLasts) {
  for (const bool from_loop : {true, false}) {
    SCOPED_TRACE(from_loop ? "sends from the loop" : "publisher thread sends");
    auto owned = std::make_unique<FlakySink>(from_loop);
    FlakySink* sink = owned.get();
    core::Publisher publisher(std::move(owned), "T_");
    EXPECT_EQ(publisher.sends_from_loop(), from_loop);
    publisher.start();
    send_one(publisher, 1);
    publisher.drain();
    EXPECT_EQ(publisher.health().failing_since_ns, 0);

    sink->refuse = true;
    {
      test::AllocationScope scope;  // refusals allocate nothing either
      for (std::int64_t seq = 2; seq <= 11; ++seq) send_one(publisher, seq);
      publisher.drain();
      EXPECT_EQ(scope.count(), 0U);
    }
    auto h = publisher.health();
    EXPECT_NE(h.failing_since_ns, 0);
    EXPECT_EQ(h.failing_since_seq, 2);
    EXPECT_EQ(h.failing_since_utime_us, 1'000'002);
    EXPECT_EQ(h.lost_in_episode, 10);
    EXPECT_EQ(h.failures, 10);
    EXPECT_EQ(h.last_errno, ENETUNREACH);
    EXPECT_EQ(h.recoveries, 0);
    // Persisting: re-created after 1 s (the thread looks every 50 ms), not
    // before; a loaded machine may make it later (60 s only guards a hang),
    // and this thread may see a second one (backoff: 2 s after the first).
    const auto t0 = std::chrono::steady_clock::now();
    while (sink->reopens.load() == 0 &&
           std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60)) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    EXPECT_GE(std::chrono::steady_clock::now() - t0, std::chrono::milliseconds(800));
    EXPECT_GE(sink->reopens.load(), 1);
    EXPECT_EQ(publisher.health().reopens, sink->reopens.load());

    sink->refuse = false;
    send_one(publisher, 12);
    publisher.drain();
    h = publisher.health();
    EXPECT_EQ(h.failing_since_ns, 0);
    EXPECT_EQ(h.recoveries, 1);
    EXPECT_EQ(h.recovered_lost, 10);
    EXPECT_EQ(h.recovered_from_seq, 2);
    EXPECT_EQ(h.recovered_to_seq, 12);
    EXPECT_GE(h.recovered_after_ns, 800'000'000);
    EXPECT_EQ(h.published, 2);
    publisher.stop();
    EXPECT_EQ(sink->accepted.load(), 2);
  }
}

// make_lcm_sink: a udpm URL is sent from the loop, with no ring; the encoder's
// three messages reach a stock LCM subscriber, allocating nothing.
TEST(Publisher, AnUdpmUrlIsSentFromTheLoopToStockLcm) {
  const std::string url = url_on(own_port(4));
  lcm_t* lcm = lcm_create(url.c_str());
  ASSERT_NE(lcm, nullptr);
  Received received;
  lcm_subscribe(lcm, "LOOP_.*", on_message, &received);
  core::Publisher publisher(core::make_lcm_sink(url), "LOOP_");
  ASSERT_TRUE(publisher.sends_from_loop());
  std::array<std::string, core::kJointCount> names{"a", "b", "c", "d", "e", "f"};
  core::MessageEncoder encoder(names, 5, true);
  encoder.warm_up();
  core::CycleResult r;
  r.seq = 41;
  drivers::EncoderSample sample;
  {
    test::AllocationScope scope;
    encoder.publish(r, sample, publisher);
    EXPECT_EQ(scope.count(), 0U);
  }
  for (int i = 0; i < 50 && received.channels.size() < 3; ++i) lcm_handle_timeout(lcm, 100);
  lcm_destroy(lcm);
  ASSERT_EQ(received.channels.size(), 3U);
  EXPECT_EQ(received.channels[0], "LOOP_EXO_PALM_POSE");
  EXPECT_EQ(received.channels[1], "LOOP_EXO_JOINT_STATE");
  EXPECT_EQ(received.channels[2], "LOOP_EXO_ENCODER_RAW");
  exodaq::palm_pose_t palm;
  ASSERT_GT(
      palm.decode(received.payloads[0].data(), 0, static_cast<int>(received.payloads[0].size())),
      0);
  EXPECT_EQ(palm.seq, 41);
  EXPECT_EQ(palm.run_id, 5);
  EXPECT_EQ(publisher.published(), 3);
  EXPECT_EQ(publisher.failures(), 0);
}

// The status listener's socket: the kernel passes exactly the channel's LC02
// datagrams (not another channel, not a longer name sharing its start, not a
// prefixed one), so the daemon's listener is not woken for the cycle messages.
TEST(UdpmChannelReceiver, TheKernelPassesOnlyTheChannel) {
  const int port = own_port(5);
  const auto address = core::parse_udpm_url(url_on(port));
  ASSERT_TRUE(address.has_value());
  core::UdpmChannelReceiver receiver(*address, url_on(port), "PEXO_STATUS");
  core::UdpmSender sender(*address, url_on(port));
  const std::uint8_t other[] = {1, 2, 3, 4};
  for (int k = 0; k < 50; ++k) {
    ASSERT_EQ(sender.send("PEXO_JOINT_STATE", other, sizeof other), 0);
    ASSERT_EQ(sender.send("PEXO_STATUSX", other, sizeof other), 0);
    ASSERT_EQ(sender.send("XPEXO_STATUS", other, sizeof other), 0);
    ASSERT_EQ(sender.send("PEXO_STATU", other, sizeof other), 0);
  }
  const std::uint8_t status[] = {9, 8, 7};
  ASSERT_EQ(sender.send("PEXO_STATUS", status, sizeof status), 0);
  int size = 0;
  for (int tries = 0; tries < 20 && size == 0; ++tries) size = receiver.receive(100);
  ASSERT_EQ(size, 3);
  EXPECT_EQ(std::vector<std::uint8_t>(receiver.payload(), receiver.payload() + 3),
            std::vector<std::uint8_t>({9, 8, 7}));
  EXPECT_EQ(receiver.receive(50), 0);  // nothing else queued
  EXPECT_EQ(receiver.datagrams(), 1);  // 200 others dropped by the filter
}
