#pragma once
// Six CiA 406 encoder nodes on a CanPort, one per board channel of the shared
// SimRig: each node's position value is the rig's count of its channel at the
// instant asked (a SYNC's arrival for its TPDO), taken modulo the node's total
// measuring range (0x6002; 0x6001 = the rig's counts per revolution). The
// manager (the daemon) sends NMT, SDO and, by default, SYNC; every SYNC is
// one cycle of the truth file, in BoardSim's format; every TPDO sent is a
// line of the answers file ("k channel sent_mono_ns": the SYNC it answers and
// when the frame had left), from which a checker knows which answers went out
// after the next SYNC (a node breaking CiA 301's timing, which the manager
// cannot see). Faults are the node simulator's (canopen::SimFault), scripted
// in time.
// docs/can-protocol.md ("The board simulator", "CANopen nodes").
#include <array>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/drivers/can_link.hpp"
#include "exodaq/drivers/can_port.hpp"
#include "exodaq/drivers/canopen/node_sim.hpp"
#include "exodaq/drivers/sim_rig.hpp"

namespace exodaq::board_sim {

namespace co = drivers::canopen;

inline constexpr int kCanopenNodes = drivers::sim::kJoints;

// One node: node id, range and objects. Node i of CanopenSimOptions::nodes
// carries board channel i.
struct CanopenNodeOptions {
  co::NodeId node = 1;
  std::uint32_t total_range = 1U << 25;  // 0x6002: the position value's modulus
  // An encoder-interface module: its count is the manufacturer object
  // `count_object` as well as 0x6004, and `reference_object` holds the count
  // latched at the last index crossing (0 before the first).
  bool index_module = false;
  co::Multiplexer count_object{0x2000, 1};
  co::Multiplexer reference_object{0x2001, 1};
};

// A scripted node fault: active on node `joint` (0-based index into the
// node list) from start_s for duration_s of simulated time (<= 0: until the end).
struct CanopenFault {
  co::SimFault kind = co::SimFault::kEmcy;
  int joint = 0;
  double start_s = 0.0;
  double duration_s = 0.0;
};

// The fault names (--fault kind), each with the protocol v1 kind of the
// sim vocabulary it stands for (empty: none).
struct CanopenFaultName {
  co::SimFault kind;
  std::string_view name;
  std::string_view v1_name;
};
std::span<const CanopenFaultName> canopen_fault_names() noexcept;
std::string_view canopen_fault_name(co::SimFault kind) noexcept;
// By its name or its v1 name; nullptr: unknown.
const CanopenFaultName* find_canopen_fault(std::string_view name) noexcept;
// {kind, at_s, for_s, joint (1..6)}; throws a ConfigError naming the key.
CanopenFault parse_canopen_fault(MapReader& m);
// A fault of the sim vocabulary (source.sim.faults) whose kind maps; throws
// std::invalid_argument when it does not.
CanopenFault canopen_fault_from(const drivers::sim::SimFault& fault);

struct CanopenSimOptions {
  std::array<CanopenNodeOptions, kCanopenNodes> nodes = default_nodes();
  // Node 0 produces SYNC every sync_period_ns (with a counter when
  // sync_overflow is 2..240) instead of the manager.
  bool sync_producer = false;
  std::int64_t sync_period_ns = 1'000'000;
  std::uint8_t sync_overflow = 0;
  std::int64_t boot_delay_ns = 2'000'000;  // node i boots boot_delay_ns + i ms after power-on
  std::int64_t response_ns = 100'000;      // SYNC to TPDO, SDO request to response
  std::uint16_t heartbeat_ms = 100;        // 0x1017 at power-on (the manager may write it)
  std::vector<CanopenFault> faults;

  static std::array<CanopenNodeOptions, kCanopenNodes> default_nodes() noexcept {
    std::array<CanopenNodeOptions, kCanopenNodes> n{};
    for (int i = 0; i < kCanopenNodes; ++i) {
      n[static_cast<std::size_t>(i)].node = static_cast<co::NodeId>(i + 1);
    }
    return n;
  }
};

// The port's receive filters: NMT, SYNC, each node's SDO request.
drivers::can::CanIdFilterSet canopen_port_filters(const CanopenSimOptions& options) noexcept;

// Truth-file bits: 1 << (kCanopenFaultShift + kind) while a fault of that
// kind is active on some node at the SYNC; kSendFailedBit (board_sim.hpp)
// when a frame could not be sent since the previous SYNC.
inline constexpr unsigned kCanopenFaultShift = 16;
constexpr std::uint32_t canopen_fault_bit(co::SimFault kind) noexcept {
  return 1U << (kCanopenFaultShift + static_cast<unsigned>(kind));
}

struct CanopenCounters {
  std::int64_t syncs = 0;  // cycles: SYNCs seen (received or produced)
  std::int64_t frames_received = 0;
  std::int64_t frames_sent = 0;
  std::int64_t send_failures = 0;
  std::array<std::int64_t, co::kSimFaultCount> fault_cycles{};  // SYNCs with the kind active
};

class CanopenSim {
 public:
  // `truth` and `answers` may be null. Throws std::invalid_argument on
  // inconsistent options (rig options, duplicate or invalid node ids, a fault
  // on no node).
  CanopenSim(const drivers::sim::SimOptions& rig, const CanopenSimOptions& options,
             drivers::CanPort& port, std::FILE* truth, std::FILE* answers = nullptr);

  // Powers every node at `now` (simulated time 0: motion, faults, truth).
  void power_on(std::int64_t now);
  // Receives what is queued, feeds it to every node, runs the nodes' timers to
  // `now` and sends the frames they made (each when due: at `now`, or later
  // at a later poll). A received frame's kernel stamp is its time.
  void poll(std::int64_t now);

  // The count of board channel `channel` at simulated time t_s (what node
  // `channel` reports before its modulus), and the position value itself.
  // reported(): a rig count as node `channel` reports it (absolute: from
  // the joint's index angle; an encoder-interface module: the count itself).
  // The truth file holds reported counts.
  std::int64_t reported(int channel, std::int64_t rig_count) const noexcept;
  std::int64_t count_at(int channel, double t_s) const noexcept;
  std::uint32_t position_value(int channel, double t_s) const noexcept;
  double sim_time_s(std::int64_t mono_ns) const noexcept {
    return static_cast<double>(mono_ns - origin_) * 1e-9;
  }

  co::EncoderNodeSim& node(int i) noexcept { return *nodes_[static_cast<std::size_t>(i)]; }
  const drivers::sim::SimRig& rig() const noexcept { return rig_; }
  const CanopenSimOptions& options() const noexcept { return options_; }
  const CanopenCounters& counters() const noexcept { return counters_; }
  // The SYNC instant of the last cycle (mono ns) and its truth.
  std::int64_t last_sync_ns() const noexcept { return last_sync_ns_; }
  // "BOARD-SIM: protocol=canopen syncs=… tpdos=… frames=… send_failures=…
  // <fault>=…": SYNC cycles each fault kind was active, by canopen_fault_names().
  std::string summary() const;

 private:
  void apply_faults(std::int64_t now) noexcept;
  void on_sync(const drivers::can::CanFrame& frame, std::int64_t at) noexcept;
  void deliver(const drivers::can::CanFrame& frame, int from, std::int64_t at) noexcept;
  void settle(std::int64_t now) noexcept;
  int send(const drivers::can::CanFrame& frame) noexcept;
  void record_answer(const drivers::can::CanFrame& frame, int channel) noexcept;

  drivers::sim::SimRig rig_;
  CanopenSimOptions options_;
  drivers::CanPort& port_;
  std::FILE* truth_;
  std::FILE* answers_;
  std::vector<std::unique_ptr<co::EncoderNodeSim>> nodes_;
  std::array<int, kCanopenNodes> joint_of_channel_{};
  std::array<std::int64_t, kCanopenNodes> reference_{};  // last latched index count, by channel
  CanopenCounters counters_{};
  drivers::sim::SimBoard::Frames frames_{};  // the rig's v1 frames, unused
  std::int64_t origin_ = 0;
  bool powered_ = false;
  std::int64_t k_ = 0;
  std::int64_t last_sync_ns_ = 0;
  // The last SYNCs' instants by k % kSyncHistory: which SYNC a TPDO answers.
  static constexpr int kSyncHistory = 16;
  std::array<std::int64_t, kSyncHistory> sync_ns_{};
  std::int64_t settled_ns_ = 0;  // the nodes' time: frames are never fed earlier
  std::uint32_t pending_bits_ = 0;
  drivers::WallMonoOffset offset_;  // the kernel's receive stamps to CLOCK_MONOTONIC
};

}  // namespace exodaq::board_sim
