#pragma once
// A CANopen encoder node (CiA 301 + CiA 406) as a pure, clock-driven model:
// an object dictionary with the communication and encoder objects, NMT
// states, boot-up, heartbeat producer, synchronous TPDOs on every n-th SYNC
// (position from a caller-supplied source), an expedited SDO server with
// CiA 301 abort codes, EMCY, optionally the bus's SYNC producer, and fault
// injection for every failure the assembler must detect.
//
// on_frame() takes frames from the bus at the caller's time, advance() runs
// the node's own timers, next_frame() hands out the frames it sent, stamped
// (mono_ns) with the time they left it. No I/O, no threads.
#include <array>
#include <cstdint>
#include <functional>
#include <string_view>

#include "exodaq/drivers/canopen/cia301.hpp"
#include "exodaq/drivers/canopen/cia406.hpp"

namespace exodaq::drivers::canopen {

enum class SimFault : std::uint8_t {
  kNeverBoots,           // mute: no boot-up, heartbeat, SDO answer or PDO; clearing boots it
  kHeartbeatStops,       // no heartbeat (everything else works)
  kEmcy,                 // EMCY with the configured code on set, error reset on clear
  kTpdoMissing,          // synchronous TPDOs not sent
  kTpdoLate,             // synchronous TPDOs sent late_ns after their SYNC
  kWrongPdoLength,       // synchronous TPDOs one byte short
  kSyncCounterMismatch,  // as SYNC producer: each SYNC's counter skips one value
};
inline constexpr int kSimFaultCount = static_cast<int>(SimFault::kSyncCounterMismatch) + 1;
std::string_view to_string(SimFault fault) noexcept;

// What the encoder measures at an instant, before its scaling and preset: the
// raw count and, for an encoder-interface module, the count latched at the
// last reference mark.
struct SimPosition {
  std::uint32_t position = 0;
  std::uint32_t reference = 0;
};
using PositionSource = std::function<SimPosition(std::int64_t now_ns)>;

struct NodeSimConfig {
  NodeId node = 1;
  Identity identity{0x00000A5E, 0x00000406, 0x00010000, 1};
  std::uint32_t device_type = kEncoderProfile;
  std::int64_t boot_delay_ns = 2'000'000;  // power-on or NMT reset to boot-up
  std::int64_t response_ns = 100'000;      // SYNC to TPDO, request to response
  std::uint16_t heartbeat_ms = 100;        // 0x1017 at power-on
  std::uint16_t operating_parameters = operating_parameter::kScaling;
  std::uint32_t units_per_revolution = 1U << 13;
  std::uint32_t total_range = 1U << 25;  // 4096 revolutions of 8192 counts
  TpdoSetup tpdo1 = position_tpdo(1);    // TPDO1 at power-on (TPDO2..4 disabled)
  // An encoder-interface module's latched position (manufacturer-specific
  // object, mappable); none when has_reference_object is false.
  bool has_reference_object = false;
  Multiplexer reference_object{0x2100, 1};
  // Such a module's channel count as a manufacturer-specific object too
  // (mappable, the same value as 0x6004); none when has_count_object is false.
  bool has_count_object = false;
  Multiplexer count_object{0x2000, 1};
  // SYNC producer (0x1005 bit 30): a SYNC every sync_period_ns from boot-up,
  // with a counter when sync_overflow (0x1019) is 2..240.
  bool sync_producer = false;
  std::int64_t sync_period_ns = 1'000'000;
  std::uint8_t sync_overflow = 0;
  EmcyPayload fault_emcy{emcy_code::kDeviceHardware, error_register::kGeneric, {}};
  // kTpdoLate: the TPDO this long after its SYNC: past a 0.5 ms deadline,
  // before the next SYNC at 1 kHz. (Later than a period it would pass for the
  // next SYNC's answer: a PDO carries no sequence.)
  std::int64_t late_ns = 700'000;
};

class EncoderNodeSim {
 public:
  static constexpr int kMaxEntries = 96;
  static constexpr int kMaxScheduled = 32;

  EncoderNodeSim(const NodeSimConfig& config, PositionSource source);

  // Power applied at `now`: boot-up after boot_delay_ns.
  void power_on(std::int64_t now) noexcept;
  void on_frame(const CanFrame& frame, std::int64_t now) noexcept;
  void advance(std::int64_t now) noexcept;
  // The next frame sent up to the last advance()/on_frame() time, oldest first.
  bool next_frame(CanFrame& out) noexcept;

  void set_fault(SimFault fault, bool active, std::int64_t now) noexcept;
  bool fault(SimFault f) const noexcept { return faults_[static_cast<std::size_t>(f)]; }

  bool booted() const noexcept { return booted_; }
  NmtState state() const noexcept { return state_; }
  NodeId node() const noexcept { return config_.node; }
  // An entry's stored value (no access check; 0x6004 reads the source).
  bool read(Multiplexer at, std::uint32_t& value) const noexcept;
  std::int64_t tpdos_sent() const noexcept { return tpdos_sent_; }
  std::int64_t frames_dropped() const noexcept { return dropped_; }  // outbox full
  std::int64_t syncs_seen() const noexcept { return syncs_seen_; }

 private:
  enum class Access : std::uint8_t { kRo, kRw };
  struct Entry {
    Multiplexer at{};
    std::uint8_t size = 4;
    Access access = Access::kRo;
    bool mappable = false;
    std::uint32_t value = 0;
    std::uint32_t initial = 0;
  };
  struct Scheduled {
    CanFrame frame{};
    bool used = false;
    std::uint64_t order = 0;  // ties in time leave in the order they were sent
  };
  struct PdoRun {
    bool started = false;
    int count = 0;  // SYNCs since started
  };

  void build_dictionary() noexcept;
  void add_entry(Multiplexer at, std::uint8_t size, Access access, std::uint32_t value,
                 bool mappable = false) noexcept;
  Entry* find(Multiplexer at) noexcept;
  const Entry* find(Multiplexer at) const noexcept;
  bool has_index(std::uint16_t index) const noexcept;
  std::uint32_t stored(Multiplexer at) const noexcept;  // 0 when absent
  std::uint32_t value_of(const Entry& e, const SimPosition& p) const noexcept;
  std::int64_t range() const noexcept;
  bool counts_ccw() const noexcept;
  std::uint32_t scaled(std::uint32_t raw) const noexcept;
  bool sync_producer() const noexcept;
  std::int64_t sync_period_ns() const noexcept;
  std::int64_t heartbeat_period_ns() const noexcept;
  void reset_entries(bool communication_only) noexcept;

  void schedule(CanFrame frame, std::int64_t at) noexcept;
  void reboot(std::int64_t now) noexcept;
  void on_nmt(const NmtPayload& nmt, std::int64_t now) noexcept;
  void on_sync(bool has_counter, std::uint8_t counter, std::int64_t now) noexcept;
  void send_tpdo(int pdo, std::int64_t now) noexcept;
  void on_sdo(const SdoPayload& sdo, std::int64_t now) noexcept;
  std::uint32_t check_write(const Entry& e, const SdoPayload& sdo) const noexcept;
  std::uint32_t check_pdo_write(const Entry& e, std::uint32_t value) const noexcept;
  void apply_write(Entry& e, std::uint32_t value, std::int64_t now) noexcept;
  void produce_sync(std::int64_t at) noexcept;

  NodeSimConfig config_;
  PositionSource source_;
  std::array<Entry, kMaxEntries> od_{};
  int od_count_ = 0;
  std::array<Scheduled, kMaxScheduled> scheduled_{};
  std::array<bool, kSimFaultCount> faults_{};
  std::array<PdoRun, kTpdoCount> pdo_runs_{};

  std::int64_t now_ = 0;
  bool powered_ = false;
  bool booted_ = false;
  std::int64_t boot_at_ = 0;
  NmtState state_ = NmtState::kBootUp;
  std::int64_t next_heartbeat_ = 0;
  std::int64_t next_sync_ = 0;
  std::uint8_t sync_counter_ = 0;
  std::int64_t position_offset_ = 0;  // preset (0x6003)
  std::int64_t tpdos_sent_ = 0;
  std::int64_t syncs_seen_ = 0;
  std::int64_t dropped_ = 0;
  std::uint64_t next_order_ = 0;
};

}  // namespace exodaq::drivers::canopen
