#pragma once
// The `canopen` encoder backend: the daemon as CANopen manager (NMT master
// and SYNC producer) of one CiA 406 encoder node per joint on a SocketCAN
// interface. The transport is CanLink (re-open after a loss, kernel receive
// stamps, non-blocking send); the protocol is the Startup state machine
// (boot-up, identity 0x1018, configuration by SDO, NMT start, operational
// heartbeat) and the Assembler (one CycleSample per SYNC).
//
// One read() per loop wake (catch-up reads deliver nothing: one SYNC, one
// sample):
// - poll the link (re-open when down: the start-up begins again, the nodes
//   may have reset), receive what is queued, feed every frame to the start-up
//   and the assembler, send the start-up's NMT/SDO frames;
// - until every node is operational or failed: a MISSING sample, never a
//   valid one (kNoSample);
// - then, every cycle: send SYNC (Assembler::begin_cycle), receive until every
//   expected joint's TPDO of this cycle arrived or the poll deadline
//   (deadline + read_deadline_ns, never past the cycle's end minus a tenth of
//   the period; from the SYNC on when the wake was late), close the cycle and
//   convert it (below). The start-up keeps running: a node that resets is
//   configured and started again while its joint is flagged.
// - link down: MISSING with kBusError every cycle (bus state Down).
//
// Conversion of a CycleSample into an EncoderSample (docs/can-protocol.md,
// "The canopen backend"):
// - joint j of the configuration is channel j; position = the TPDO's position
//   as sent, modulus = the reading's (2^bits or the total measuring range);
// - channel_fresh bit j = a valid TPDO of this cycle arrived for joint j and
//   none of kLate, kWrongLength, kDuplicate, kBadFrame, kOutOfRange is set on
//   it; a channel that is not fresh repeats its last fresh position;
// - absolute bit j: the joint is configured `reference: absolute`;
// - a joint with a mapped reference (`reference: index`): index_position =
//   the latched reference, index_count_valid and index_latched bit j when it
//   changed since the previous TPDO;
// - present = any channel fresh; none: kMissing (kNoSample); some: kPartial;
// - board_state bit j: joint j's node reports operational (heartbeat);
// - board_errors bits 0..15: joint j's node has a node fault (EMCY active, not
//   operational, heartbeat lost, never booted, rebooted this cycle); bits
//   16..20: which kinds (kBoardErrorEmcy...); any of them sets kBoardError;
// - kDuplicate on a joint also sets the sample flag kDuplicate;
// - cycle flag kSyncCounterMismatch or kOverrun: kSeqGap; kForeignSync (another
//   SYNC producer), a SYNC that could not be sent, a bus state Off or Down:
//   kBusError;
// - seq = the assembler's cycle number (seq_modulus 0: never wraps);
// - mono_ns = the SYNC's send time (the instant the nodes sample at), wall_ns =
//   mono_ns + the link's wall − mono offset.
// read() allocates, blocks (beyond its poll deadline) and logs nothing.
#include <array>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "exodaq/drivers/can_link.hpp"
#include "exodaq/drivers/can_port.hpp"
#include "exodaq/drivers/canopen/assembler.hpp"
#include "exodaq/drivers/canopen/startup.hpp"
#include "exodaq/drivers/encoder_source.hpp"
#include "exodaq/drivers/frame_assembler.hpp"

namespace exodaq::drivers::canopen {

// EncoderSample::board_errors bits 16..20: which node faults are active on
// some joint (bits 0..15: which joints).
namespace board_error {
inline constexpr std::uint32_t kJointMask = 0xFFFFU;
inline constexpr std::uint32_t kEmcy = 1U << 16;
inline constexpr std::uint32_t kNotOperational = 1U << 17;
inline constexpr std::uint32_t kHeartbeatLost = 1U << 18;
inline constexpr std::uint32_t kNeverBooted = 1U << 19;
inline constexpr std::uint32_t kRebooted = 1U << 20;
}  // namespace board_error

// The joint_fault bits that are the node's own state (kBoardError).
inline constexpr std::uint32_t kNodeFaults = joint_fault::kEmcy | joint_fault::kNotOperational |
                                             joint_fault::kHeartbeatLost |
                                             joint_fault::kNeverBooted | joint_fault::kRebooted;
// The joint_fault bits that make this cycle's reading of the joint untrusted.
inline constexpr std::uint32_t kReadingFaults = joint_fault::kLate | joint_fault::kWrongLength |
                                                joint_fault::kDuplicate | joint_fault::kBadFrame |
                                                joint_fault::kOutOfRange;

enum class ReferenceKind : std::uint8_t {
  kAbsolute,  // an absolute encoder: homed from its first sample
  kIndex,     // homed on the reference latched by an encoder-interface module
};

struct CanopenJoint {
  NodeId node = 1;
  ReferenceKind reference = ReferenceKind::kAbsolute;
  // TPDO number, COB-ID (0: predefined), mapping; transmission type 1.
  TpdoSetup tpdo = position_tpdo(1);
  ValueObjects values{};          // the position and (kIndex) the reference object
  std::uint32_t total_range = 0;  // the position's modulus; 0: 2^bits
  std::uint32_t vendor_id = 0;    // 0x1018 sub 1 expected (0: any)
  std::uint32_t product_code = 0;
  // Write the TPDO's mapping, transmission type and the heartbeat producer
  // time at start-up; false: the node is configured already (read only).
  bool configure = true;
};

struct CanopenSourceConfig {
  std::string interface = "can0";
  int rcvbuf_bytes = 1 << 20;
  int joint_count = kChannelCount;
  std::array<CanopenJoint, kChannelCount> joints{};
  // kProducer: the source sends SYNC every cycle; kConsumer: another device
  // on the bus does, and each SYNC received opens a cycle.
  SyncRole sync = SyncRole::kProducer;
  std::uint8_t sync_overflow = 0;  // 0: SYNC without counter; 2..240
  std::int64_t read_deadline_ns = 400'000;
  std::int64_t reopen_interval_ns = 1'000'000'000;
  // Start-up: no boot-up or heartbeat this long → NMT reset communication
  // (twice), then the node failed; the assembler's never-booted time too.
  std::int64_t boot_timeout_ns = 1'000'000'000;
  // Heartbeat consumer time; the producer time written at start-up is two
  // thirds of it. 0: heartbeats neither written nor monitored (a node is
  // started without waiting for its operational heartbeat).
  std::int64_t heartbeat_timeout_ns = 150'000'000;
  std::int64_t sdo_timeout_ns = 100'000'000;
};

// The heartbeat producer time (0x1017, ms) written at start-up.
std::uint16_t heartbeat_producer_ms(const CanopenSourceConfig& config) noexcept;
AssemblerConfig assembler_config(const CanopenSourceConfig& config) noexcept;
StartupConfig startup_config(const CanopenSourceConfig& config) noexcept;
// The port's identifier filters: SYNC, and per node EMCY, TPDO, SDO response, heartbeat.
CanPortConfig port_config(const CanopenSourceConfig& config);
// nullptr, or what is wrong (a static message; `joint` the joint at fault or -1).
const char* validate(const CanopenSourceConfig& config, int& joint) noexcept;

// Backend-side counters beyond SourceStats (tests, diagnose()).
struct CanopenDetail {
  std::int64_t sync_sent = 0;
  std::int64_t sync_send_failures = 0;  // EAGAIN / ENOBUFS / other errors while up
  std::int64_t late_syncs = 0;          // more than a tenth of a period after the deadline
  std::int64_t startup_frames_sent = 0;
  std::int64_t startup_send_failures = 0;
  std::int64_t startup_restarts = 0;  // after the link came back
  std::int64_t superseded_cycles = 0;
  std::int64_t rx_overflows = 0;
  std::int64_t error_frames = 0;
};

// Samples by what their conversion flagged.
struct SampleCounts {
  std::int64_t missing_samples = 0;
  std::int64_t partial_samples = 0;
  std::int64_t board_error_samples = 0;
  std::int64_t seq_gaps = 0;
};

// One closed cycle as the protocol-neutral sample (the conversion above),
// for the live source and the candump replay alike. `held`: the last sample
// converted (what a stale channel repeats), updated. `extra_flags`: sample
// flags the caller adds (kBusError: the SYNC not sent, the bus off or down).
void to_sample(const CanopenSourceConfig& config, const CycleSample& cycle,
               std::int64_t wall_offset_ns, std::uint32_t extra_flags, EncoderSample& held,
               SampleCounts& counts, EncoderSample& out) noexcept;

// The assembly of a candump log of a CANopen bus (the replay's
// FrameAssembler): the recorded SYNCs open the cycles (the assembler as SYNC
// consumer); a cycle closes where the live source closed it: once every joint
// that ever answered has answered this SYNC, else at the live poll deadline
// (read_deadline_ns after the SYNC, at most nine tenths of `period_ns`); each
// cycle is converted by to_sample(). A frame of the log that reached the live
// source in another cycle than its stamp says (a wake late by more than the
// deadline) can make that cycle differ.
std::unique_ptr<FrameAssembler> make_frame_assembler(const CanopenSourceConfig& config,
                                                     std::int64_t period_ns);

class CanopenSource final : public EncoderSource, private FrameSink {
 public:
  // Throws std::invalid_argument when `config` fails validate().
  CanopenSource(const CanopenSourceConfig& config, std::unique_ptr<CanPort> port);

  std::string_view name() const noexcept override { return "canopen"; }
  // Opens the link (a missing or down interface is not an error: down,
  // retrying) and begins the start-up. Other failures throw.
  void start() override;
  ReadStatus read(const CycleTime& time, EncoderSample& out) noexcept override;
  SourceStats stats() const noexcept override;
  // The link's counters, the assembler's and start-up's; the state: the
  // link's ("can0 open") and the nodes' ("6/6 operational", or the first node
  // that is not with its phase or failure).
  void diagnose(SourceDiagnostics& out) const noexcept override;
  void stop() noexcept override;
  // SYNC consumer: the nodes sample on the producer's clock, and every cycle
  // is delivered once (the loop catches up on those its late wakes left).
  bool free_running() const noexcept override { return config_.sync == SyncRole::kConsumer; }
  int backlog() const noexcept override;

  const CanopenSourceConfig& config() const noexcept { return config_; }
  const Startup& startup() const noexcept { return startup_; }
  const Assembler& assembler() const noexcept { return assembler_; }
  const CanLink& link() const noexcept { return link_; }
  const CanopenDetail& detail() const noexcept { return detail_; }
  // Every node operational or failed at least once since the link came up:
  // cycles run.
  bool cycling() const noexcept { return cycling_; }

 private:
  // FrameSink
  void on_frame(const can::CanFrame& frame) noexcept override;
  void on_rx_overflows(std::int64_t dropped) noexcept override;
  void on_link(bool up) noexcept override;
  bool satisfied() const noexcept override;

  // The link and the start-up, before a cycle: false when read() returns
  // `status` (out filled for kNoSample) without running one.
  bool prepare(const CycleTime& time, EncoderSample& out, ReadStatus& status) noexcept;
  ReadStatus read_producer(const CycleTime& time, std::int64_t period, EncoderSample& out) noexcept;
  ReadStatus read_consumer(const CycleTime& time, std::int64_t period, EncoderSample& out) noexcept;
  void expect_answers() noexcept;
  void send_startup_frames() noexcept;
  std::int64_t poll_deadline(std::int64_t from, std::int64_t period) const noexcept;
  void make_missing(EncoderSample& out, std::int64_t mono_ns, std::uint32_t flags) noexcept;
  void convert(const CycleSample& cycle, bool sync_failed, EncoderSample& out) noexcept;

  CanopenSourceConfig config_;
  Startup startup_;
  Assembler assembler_;
  CanLink link_;
  CanopenDetail detail_{};
  SampleCounts counts_{};
  BusState bus_state_ = BusState::kUnknown;
  bool cycling_ = false;
  bool restart_pending_ = false;  // the link came up: begin the start-up again
  std::uint32_t expected_ = 0;    // joints whose TPDO this cycle waits for
  std::uint32_t arrived_ = 0;     // joints whose TPDO this cycle was accepted
  CycleSample cycle_{};
  EncoderSample held_{};  // the last sample delivered: what a missing one repeats
};

}  // namespace exodaq::drivers::canopen
