#pragma once
// Per-SYNC-cycle assembly of CANopen encoder nodes (CiA 301/406) into one
// CycleSample: each joint's position value with its modulus, presence,
// latched reference, NMT state, EMCY state and fault bits. Detects a node
// that never booted, a lost heartbeat, a TPDO missing, late, duplicated or of
// the wrong length, a position outside its range, a SYNC counter mismatch
// (SYNC consumer) and a second SYNC producer (SYNC producer).
//
// Driven by the caller's clock: begin_cycle() (producer: the SYNC to send) or
// a received SYNC (consumer) opens a cycle, on_frame() takes every received
// frame, end_cycle() closes the cycle at its deadline, poll() hands closed
// cycles out. No I/O, no threads; allocation-free after construction; one
// owner thread.
#include <array>
#include <cstdint>

#include "exodaq/drivers/canopen/cia301.hpp"
#include "exodaq/drivers/canopen/cia406.hpp"

namespace exodaq::drivers::canopen {

// The most encoder nodes one assembler serves. At 1 Mbit/s and 1 kHz about
// six 4-byte TPDOs and a SYNC fit in 2/3 of the bus; more nodes need a lower
// rate.
inline constexpr int kMaxNodes = 16;

// JointReading::faults bits.
namespace joint_fault {
inline constexpr std::uint32_t kMissing = 1U << 0;  // no valid TPDO this cycle
inline constexpr std::uint32_t kLate = 1U << 1;     // its TPDO stamped after the deadline (dropped)
inline constexpr std::uint32_t kWrongLength = 1U << 2;     // a TPDO of the wrong length arrived
inline constexpr std::uint32_t kDuplicate = 1U << 3;       // a second TPDO in this cycle (dropped)
inline constexpr std::uint32_t kNeverBooted = 1U << 4;     // nothing heard since start
inline constexpr std::uint32_t kHeartbeatLost = 1U << 5;   // consumer heartbeat time exceeded
inline constexpr std::uint32_t kNotOperational = 1U << 6;  // heartbeat state not operational
inline constexpr std::uint32_t kRebooted = 1U << 7;    // boot-up of a node already heard: it reset
inline constexpr std::uint32_t kEmcy = 1U << 8;        // an emergency is active
inline constexpr std::uint32_t kOutOfRange = 1U << 9;  // position >= modulus (dropped)
inline constexpr std::uint32_t kBadFrame = 1U << 10;   // a malformed frame from this node
}  // namespace joint_fault

// CycleSample::flags bits.
namespace cycle_flag {
// Consumer: the SYNC's counter is not its predecessor's successor, or a SYNC
// was malformed (counter 0 or > 240, length > 1).
inline constexpr std::uint32_t kSyncCounterMismatch = 1U << 0;
// Producer: another node sent a SYNC.
inline constexpr std::uint32_t kForeignSync = 1U << 1;
inline constexpr std::uint32_t kOverrun = 1U << 2;  // closed cycles were dropped before this one
}  // namespace cycle_flag

enum class SyncRole : std::uint8_t {
  kProducer,  // the assembler's owner sends SYNC (begin_cycle)
  kConsumer,  // another node does; a received SYNC opens the cycle
};

struct JointConfig {
  NodeId node = 1;
  TpdoSetup tpdo{};  // pdo number, COB-ID, transmission type (1..240), mapping
  ValueObjects values{};
  std::uint32_t total_range = 0;  // 0x6002 when scaling is on; 0: the position's full width
  // Heartbeat consumer time (0x1016): no heartbeat for this long after the
  // last one is a lost heartbeat. 0: not monitored.
  std::int64_t heartbeat_timeout_ns = 0;
};

struct AssemblerConfig {
  std::array<JointConfig, kMaxNodes> joints{};
  int joint_count = 0;
  SyncRole sync_role = SyncRole::kProducer;
  std::uint8_t sync_overflow = 0;  // 0x1019: 0 (no counter) or 2..240
  // A node from which nothing (boot-up, heartbeat, TPDO, EMCY, SDO) was heard
  // this long after reset() never booted.
  std::int64_t boot_timeout_ns = 2'000'000'000;
  // A TPDO stamped more than this after its cycle's SYNC is late (dropped),
  // even when it is read before end_cycle(). 0: only end_cycle() decides.
  std::int64_t tpdo_deadline_ns = 0;
};

struct ConfigError {
  const char* what = nullptr;  // nullptr: valid
  int joint = -1;              // the joint at fault, -1 for the whole config
  MappingError mapping = MappingError::kNone;
};
ConfigError validate(const AssemblerConfig& config) noexcept;

struct JointReading {
  std::uint32_t position = 0;   // as sent, < modulus; the last valid one while not present
  std::uint64_t modulus = 0;    // 2^bits or the total measuring range
  std::uint32_t reference = 0;  // latched reference position (mapped ones), held likewise
  bool has_reference = false;
  bool reference_changed = false;  // differs from the previous present TPDO's
  bool present = false;            // a valid TPDO of this cycle
  bool due = false;                // the node's transmission type sends on this SYNC
  bool state_known = false;
  NmtState state = NmtState::kBootUp;  // from the last heartbeat / boot-up
  std::uint16_t emcy_code = 0;         // the active emergency's code (0: none)
  std::uint8_t error_register = 0;     // from the last EMCY
  std::uint32_t faults = 0;            // joint_fault bits
  std::int64_t rx_mono_ns = 0;         // the TPDO's receive stamp (0: not present)
};

struct CycleSample {
  std::uint64_t cycle = 0;  // cycles opened since reset(), from 0
  std::int64_t sync_mono_ns = 0;
  bool has_sync_counter = false;
  std::uint8_t sync_counter = 0;
  std::uint32_t flags = 0;  // cycle_flag bits
  int joint_count = 0;
  std::array<JointReading, kMaxNodes> joints{};
};

struct AssemblerStats {
  std::int64_t frames = 0;
  std::int64_t error_frames = 0;  // controller error frames (the transport's to act on)
  std::array<std::int64_t, kRejectCount> rejected{};  // by Reject value (index 0 unused)
  std::int64_t foreign = 0;  // valid CANopen, not for this assembler (other nodes, SDO requests)
  std::int64_t cycles = 0;
  std::int64_t tpdos = 0;  // accepted into a cycle
  std::int64_t missing = 0;
  std::int64_t late = 0;
  std::int64_t before_first_cycle = 0;  // TPDOs before the first cycle was opened
  std::int64_t wrong_length = 0;
  std::int64_t duplicates = 0;
  std::int64_t out_of_range = 0;
  std::int64_t emcys = 0;
  std::int64_t heartbeats = 0;
  std::int64_t boot_ups = 0;
  std::int64_t heartbeat_losses = 0;  // transitions into lost
  std::int64_t sync_counter_mismatches = 0;
  std::int64_t foreign_syncs = 0;
  std::int64_t queue_overflows = 0;
  std::int64_t syncs_read_back = 0;  // producer: own SYNCs whose stamp became the cycle's instant
};

// The identifiers the assembler wants from the transport: SYNC, and per node
// EMCY, its TPDO, SDO response, heartbeat.
inline constexpr int kMaxWantedIds = 1 + 4 * kMaxNodes;
struct WantedIds {
  std::array<std::uint32_t, kMaxWantedIds> ids{};
  int count = 0;
};

class Assembler {
 public:
  static constexpr int kQueueCapacity = 8;

  // `config` must pass validate().
  explicit Assembler(const AssemblerConfig& config) noexcept;

  // Forgets every cycle, node and counter; boot timeouts count from `now`.
  void reset(std::int64_t now) noexcept;

  // Producer: closes a cycle still open, opens the next one at `now` and
  // returns the SYNC to send (with the next counter when sync_overflow != 0).
  CanFrame begin_cycle(std::int64_t now) noexcept;

  // Every received frame (mono_ns: its receive stamp, 0 when unknown).
  // Consumer: a SYNC closes a cycle still open and opens the next one.
  // Producer: a SYNC flagged kOwn is one this manager sent, read back with
  // the kernel's stamp of when it went on the bus. The first one stamped no
  // earlier than the open cycle's begin_cycle() (an older SYNC's was sent
  // before it) moves the cycle's instant there, and a TPDO accepted stamped
  // before it becomes late: it answered an earlier SYNC. Every other own
  // frame is ignored.
  void on_frame(const CanFrame& frame) noexcept;
  // The joints whose TPDO of the open cycle is accepted.
  std::uint32_t answered() const noexcept;

  // At the cycle's deadline: closes the open cycle (nothing when none is).
  void end_cycle(std::int64_t now) noexcept;

  // The oldest closed cycle; false when none.
  bool poll(CycleSample& out) noexcept;

  bool cycle_open() const noexcept { return open_; }
  // The SYNC instant of the cycle opened last (open or closed since); 0: none yet.
  std::int64_t last_sync_ns() const noexcept { return current_.sync_mono_ns; }
  // Closed cycles not polled yet.
  int queued() const noexcept { return queue_size_; }
  const AssemblerStats& stats() const noexcept { return stats_; }
  const AssemblerConfig& config() const noexcept { return config_; }
  WantedIds wanted_ids() const noexcept;

 private:
  struct NodeState {
    PdoLayout layout{};
    std::uint64_t modulus = 0;
    std::uint32_t tpdo_id = 0;
    bool heard = false;           // anything since reset
    bool heartbeat_seen = false;  // a boot-up or heartbeat since reset
    bool heartbeat_lost = false;  // currently lost
    std::int64_t last_heartbeat_ns = 0;
    bool state_known = false;
    NmtState state = NmtState::kBootUp;
    std::uint16_t emcy_code = 0;
    std::uint8_t error_register = 0;
    bool got_tpdo = false;  // this cycle
    bool ever_present = false;
    std::uint32_t position = 0;
    std::uint32_t reference = 0;
    bool reference_changed = false;  // this cycle's TPDO
    std::int64_t rx_mono_ns = 0;
    std::uint32_t events = 0;  // joint_fault event bits for the next closed cycle
  };

  void open_cycle(std::int64_t sync_ns, bool has_counter, std::uint8_t counter) noexcept;
  void close_cycle(std::int64_t now) noexcept;
  void flag_cycle(std::uint32_t flags) noexcept;  // the open cycle's, or the next one's
  void on_rejected(int joint, const CanFrame& frame, Reject why) noexcept;
  void on_sync(const CanFrame& frame, const SyncPayload& sync) noexcept;
  void on_own_sync(const CanFrame& frame) noexcept;
  void on_tpdo(int joint, const CanFrame& frame) noexcept;
  void on_emcy(int joint, const EmcyPayload& emcy) noexcept;
  void on_error_control(int joint, const CanFrame& frame, NmtState state) noexcept;
  bool due(int joint) const noexcept;
  JointReading read_joint(int joint, std::int64_t now) noexcept;
  int joint_of_node(NodeId node) const noexcept;
  int joint_of_tpdo(const CanFrame& frame) const noexcept;

  AssemblerConfig config_;
  AssemblerStats stats_{};
  std::array<NodeState, kMaxNodes> nodes_{};
  std::array<std::int8_t, kMaxNodeId + 1> joint_by_node_{};

  std::int64_t start_ns_ = 0;
  std::int64_t last_now_ = 0;  // the latest time known: stamps frames that have none
  bool open_ = false;
  CycleSample current_{};
  std::uint64_t next_cycle_ = 0;
  bool sync_counter_known_ = false;
  std::uint8_t last_sync_counter_ = 0;  // consumer: received; producer: sent
  std::uint32_t pending_flags_ = 0;     // cycle_flag bits for the next cycle opened
  bool read_back_ = false;              // producer: the open cycle's SYNC was read back

  std::array<CycleSample, kQueueCapacity> queue_{};
  int queue_head_ = 0;
  int queue_size_ = 0;
};

}  // namespace exodaq::drivers::canopen
