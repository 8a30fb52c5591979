// The real CanPort against a kernel vcan interface: filters, kernel
// timestamps, SO_RXQ_OVFL and ENETDOWN. Needs PF_CAN and the interface named
// by $EXODAQ_VCAN (default vcan0), and root for taking it down: skipped on
// machines whose kernel has no CAN (the usual build host), run for real inside
// the VM (tests/vm).
#include <gtest/gtest.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <net/if.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <string>
#include <vector>

#include "exodaq/common/clock_now.hpp"
#include "exodaq/drivers/can_codec.hpp"
#include "exodaq/drivers/can_port.hpp"

namespace exodaq::drivers {
namespace {

std::string iface() {
  const char* e = std::getenv("EXODAQ_VCAN");
  return e != nullptr ? e : "vcan0";
}

bool have_vcan() {
  const int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (fd < 0) return false;
  close(fd);
  return if_nametoindex(iface().c_str()) != 0;
}

#define REQUIRE_VCAN() \
  if (!have_vcan()) GTEST_SKIP() << "no PF_CAN or no " << iface() << " (runs in the VM)"

std::int64_t wall_now() {
  return clock_ns(CLOCK_REALTIME);
}

// A second node on the bus.
struct Peer {
  Peer() {
    fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
    sockaddr_can a{};
    a.can_family = AF_CAN;
    a.can_ifindex = static_cast<int>(if_nametoindex(iface().c_str()));
    bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  }
  ~Peer() { close(fd); }
  void send(canid_t id, int dlc) {
    can_frame f{};
    f.can_id = id;
    f.can_dlc = static_cast<__u8>(dlc);
    ASSERT_EQ(write(fd, &f, sizeof f), static_cast<ssize_t>(sizeof f)) << std::strerror(errno);
  }
  int fd = -1;
};

// Board 0's frames, as the socketcan backend asks for them (sync master).
CanPortConfig config() {
  CanPortConfig c;
  c.interface = iface();
  c.filters = can::port_filters(can::ProtocolIds{}, false);
  return c;
}

int receive_all(CanPort& port, std::vector<can::CanFrame>& out, CanRxInfo& info) {
  can::CanFrame buf[64];
  for (int tries = 0; tries < 50; ++tries) {
    const int n = port.receive(buf, 64, info);
    if (n < 0) return n;
    for (int i = 0; i < n; ++i) out.push_back(buf[i]);
    if (n == 0 && port.wait_readable(port.now_mono_ns() + 20'000'000) == 0) break;
  }
  return 0;
}

// The kernel turns receive timestamping on lazily: the first socket asking
// for it flips a static key from a work item, so frames received before that
// work ran come without a stamp (docs/can-protocol.md, "Time stamp"). A frame
// is then stamped 0 and counted in CanRxInfo::unstamped, never given a wrong
// stamp; once the kernel stamps, every frame is stamped.
TEST(SocketCanPort, FiltersErrorFramesAndKernelTimestamps) {
  REQUIRE_VCAN();
  auto port = make_socketcan_port(config());
  ASSERT_EQ(port->open(), 0);
  Peer peer;
  const auto send_block = [&peer] {
    peer.send(0x181, 8);                          // COUNTS_A: in the board's block
    peer.send(0x185, 8);                          // unused ID of the block: admitted (bad frame)
    peer.send(0x123, 1);                          // another node's ID: filtered by the kernel
    peer.send(0x1A1, 8);                          // board 1's COUNTS_A: filtered
    peer.send(0x701, 4);                          // HEARTBEAT
    peer.send(CAN_ERR_FLAG | CAN_ERR_BUSOFF, 8);  // error frame (subscribed)
    peer.send(0x080, 0);                          // SYNC: not admitted when we are the master
  };
  const std::set<std::uint32_t> admitted{0x181, 0x185, 0x701, 0xE0000000U | CAN_ERR_BUSOFF};
  // One block of frames: the IDs admitted, each frame's stamp within the
  // block's window or 0, and the unstamped ones counted. Returns how many
  // were unstamped.
  const auto receive_block = [&](const char* what) {
    const std::int64_t before = wall_now();
    send_block();
    std::vector<can::CanFrame> got;
    CanRxInfo info;
    EXPECT_EQ(receive_all(*port, got, info), 0) << what;
    const std::int64_t after = wall_now();
    std::set<std::uint32_t> ids;
    int zero = 0;
    for (const auto& f : got) {
      ids.insert((f.flags & can::frame_flag::kError) != 0 ? 0xE0000000U | f.id : f.id);
      if (f.wall_ns == 0) {
        ++zero;
        continue;
      }
      EXPECT_GE(f.wall_ns, before) << what;  // kernel receive stamp, CLOCK_REALTIME
      EXPECT_LE(f.wall_ns, after) << what;
    }
    EXPECT_EQ(ids, admitted) << what;
    EXPECT_EQ(info.unstamped, zero) << what;
    return zero;
  };
  const int unstamped_first = receive_block("first block");
  // Until the kernel stamps (its work item has run): one frame at a time.
  bool stamped = unstamped_first < static_cast<int>(admitted.size());
  for (int i = 0; i < 500 && !stamped; ++i) {
    peer.send(0x181, 8);
    std::vector<can::CanFrame> got;
    CanRxInfo info;
    ASSERT_EQ(receive_all(*port, got, info), 0);
    for (const auto& f : got) stamped = stamped || f.wall_ns != 0;
  }
  ASSERT_TRUE(stamped) << "no frame ever came with a kernel timestamp";
  // From then on every frame is stamped, within its window.
  EXPECT_EQ(receive_block("after the kernel stamps"), 0);
  std::printf("SocketCanPort: %d of the first %zu frames unstamped\n", unstamped_first,
              admitted.size());
}

// Two boards on one bus (docs/can-protocol.md, "Several boards on one bus"):
// the ports of rig A (board 0, sync master) and rig B (board 1, following
// the SYNC) each receive their own board's frames only; B also the SYNC.
TEST(SocketCanPort, TwoBoardsOneBusEachPortHearsItsOwnBoard) {
  REQUIRE_VCAN();
  CanPortConfig ca = config();
  CanPortConfig cb = config();
  can::ProtocolIds board1;
  board1.board = 1;
  cb.filters = can::port_filters(board1, true);
  auto a = make_socketcan_port(ca);
  auto b = make_socketcan_port(cb);
  ASSERT_EQ(a->open(), 0);
  ASSERT_EQ(b->open(), 0);
  Peer peer;
  peer.send(0x080, 0);  // SYNC
  for (canid_t base : {0x181U, 0x182U, 0x190U, 0x195U, 0x701U}) {
    peer.send(base, base == 0x701U ? 4 : (base >= 0x190U ? 3 : 8));         // board 0
    peer.send(base + 0x20, base == 0x701U ? 4 : (base >= 0x190U ? 3 : 8));  // board 1
  }
  const auto ids_of = [](CanPort& port) {
    std::vector<can::CanFrame> got;
    CanRxInfo info;
    EXPECT_EQ(receive_all(port, got, info), 0);
    std::set<std::uint32_t> ids;
    for (const auto& f : got) ids.insert(f.id);
    return ids;
  };
  EXPECT_EQ(ids_of(*a), (std::set<std::uint32_t>{0x181, 0x182, 0x190, 0x195, 0x701}));
  EXPECT_EQ(ids_of(*b), (std::set<std::uint32_t>{0x080, 0x1A1, 0x1A2, 0x1B0, 0x1B5, 0x721}));
}

TEST(SocketCanPort, SendsSync) {
  REQUIRE_VCAN();
  auto port = make_socketcan_port(config());
  ASSERT_EQ(port->open(), 0);
  Peer peer;
  timeval tv{1, 0};
  setsockopt(peer.fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
  ASSERT_EQ(port->send(can::encode_sync()), 0);
  can_frame f{};
  ASSERT_EQ(read(peer.fd, &f, sizeof f), static_cast<ssize_t>(sizeof f));
  EXPECT_EQ(f.can_id, 0x080U);
  EXPECT_EQ(f.can_dlc, 0);
}

TEST(SocketCanPort, KernelDropsReportedAsRxOverflows) {
  REQUIRE_VCAN();
  CanPortConfig c = config();
  c.rcvbuf_bytes = 4096;  // the kernel's minimum: a few frames
  auto port = make_socketcan_port(c);
  ASSERT_EQ(port->open(), 0);
  Peer peer;
  constexpr int kSent = 300;
  for (int i = 0; i < kSent; ++i) peer.send(0x181, 8);
  std::vector<can::CanFrame> got;
  CanRxInfo info;
  ASSERT_EQ(receive_all(*port, got, info), 0);
  // The kernel reports the drop counter with the next frame it queues, so
  // the drops behind the last queued frame show up with the frame after them.
  peer.send(0x181, 8);
  ASSERT_EQ(receive_all(*port, got, info), 0);
  EXPECT_GT(info.dropped, 0);
  EXPECT_EQ(static_cast<std::int64_t>(got.size()) + info.dropped, kSent + 1);
}

TEST(SocketCanPort, InterfaceDownIsEnetdownAndReopenWorksWhenUp) {
  REQUIRE_VCAN();
  if (geteuid() != 0) GTEST_SKIP() << "needs root to take the interface down";
  auto port = make_socketcan_port(config());
  ASSERT_EQ(port->open(), 0);
  const std::string down = "ip link set " + iface() + " down";
  const std::string up = "ip link set " + iface() + " up";
  ASSERT_EQ(std::system(down.c_str()), 0);
  ASSERT_EQ(port->wait_readable(port->now_mono_ns() + 500'000'000), 1);  // POLLERR
  can::CanFrame f[4];
  CanRxInfo info;
  EXPECT_EQ(port->receive(f, 4, info), -ENETDOWN);
  EXPECT_EQ(port->send(can::encode_sync()), -ENETDOWN);
  EXPECT_EQ(port->open(), -ENETDOWN);  // still down: left closed
  EXPECT_FALSE(port->is_open());
  ASSERT_EQ(std::system(up.c_str()), 0);
  EXPECT_EQ(port->open(), 0);
  EXPECT_EQ(port->send(can::encode_sync()), 0);
}

TEST(SocketCanPort, MissingInterfaceIsEnodev) {
  const int fd = socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (fd < 0) GTEST_SKIP() << "no PF_CAN";
  close(fd);
  CanPortConfig c;
  c.interface = "nocan7";
  auto port = make_socketcan_port(c);
  EXPECT_EQ(port->open(), -ENODEV);
}

}  // namespace
}  // namespace exodaq::drivers
