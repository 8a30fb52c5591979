#pragma once
// Start-up of CANopen encoder nodes as the NMT manager does it, as a pure
// state machine per node: wait for its boot-up (or heartbeat), read its
// identity (0x1018 subs 1..4) by SDO, check it, write its configuration
// (PDO mapping, transmission type, resolution, heartbeat...) by SDO, start it
// (NMT start) and wait for its heartbeat to say operational.
//
// Driven by the caller's clock: on_frame() takes received frames, advance()
// applies timeouts and retries, next_frame() hands out the frames to send.
// No sleeping, no threads, no allocation after construction; one SDO
// transfer outstanding per node, the nodes in parallel.
#include <array>
#include <cstdint>
#include <string_view>

#include "exodaq/drivers/canopen/assembler.hpp"
#include "exodaq/drivers/canopen/cia301.hpp"
#include "exodaq/drivers/canopen/cia406.hpp"

namespace exodaq::drivers::canopen {

inline constexpr int kMaxSetupWrites = 24;

struct NodeSetup {
  NodeId node = 1;
  // Identity fields that must match (0: any). 0x1018 sub 1 (vendor) is
  // mandatory in CiA 301; subs 2..4 a node may lack (read as 0).
  std::uint32_t expected_vendor_id = 0;
  std::uint32_t expected_product_code = 0;
  std::array<SdoWrite, kMaxSetupWrites> writes{};
  int write_count = 0;
  // The node's heartbeat says operational after NMT start; false for a node
  // without heartbeat (0x1017 = 0): started is then done.
  bool wait_operational = true;

  bool add(const SdoWrite& w) noexcept;
  bool add_tpdo(const TpdoSetup& tpdo) noexcept;  // tpdo_setup_writes()
};

struct StartupConfig {
  std::array<NodeSetup, kMaxNodes> nodes{};
  int node_count = 0;
  // No boot-up or heartbeat this long: send NMT reset communication (the
  // node answers with its boot-up), up to boot_retries times, then fail.
  std::int64_t boot_timeout_ns = 1'000'000'000;
  int boot_retries = 2;
  std::int64_t sdo_timeout_ns = 100'000'000;  // per transfer; repeated up to sdo_retries
  int sdo_retries = 2;
  std::int64_t operational_timeout_ns = 1'000'000'000;  // after NMT start
  int start_retries = 1;
};

enum class StartupPhase : std::uint8_t {
  kWaitBoot,
  kReadIdentity,
  kConfigure,
  kWaitOperational,
  kOperational,  // done
  kFailed,       // done; see failure
};

enum class StartupFailure : std::uint8_t {
  kNone = 0,
  kNeverBooted,       // no boot-up or heartbeat after every reset communication
  kSdoTimeout,        // an SDO transfer unanswered after every retry
  kSdoAbort,          // the node aborted a transfer (abort_code, at)
  kIdentityMismatch,  // vendor id or product code not the expected one
  kNotOperational,    // no operational heartbeat after every NMT start
};
std::string_view to_string(StartupPhase phase) noexcept;
std::string_view to_string(StartupFailure failure) noexcept;

struct NodeProgress {
  StartupPhase phase = StartupPhase::kWaitBoot;
  StartupFailure failure = StartupFailure::kNone;
  std::uint32_t abort_code = 0;  // kSdoAbort
  Multiplexer at{};              // the object of the failed transfer
  Identity identity{};
  int reboots = 0;        // boot-ups after the first: the sequence restarted
  int sdo_retries = 0;    // transfers repeated after a timeout
  int boot_resets = 0;    // NMT reset communication sent
  int start_retries = 0;  // NMT start repeated
};

struct StartupStats {
  std::int64_t frames = 0;
  std::int64_t unexpected_sdo = 0;  // SDO responses matching no outstanding request
  std::int64_t outbox_overflows = 0;
};

class Startup {
 public:
  static constexpr int kOutboxCapacity = 4 * kMaxNodes;

  explicit Startup(const StartupConfig& config) noexcept;

  // Starts every node's sequence at `now` (waiting for its boot-up).
  void begin(std::int64_t now) noexcept;

  void on_frame(const CanFrame& frame, std::int64_t now) noexcept;
  void advance(std::int64_t now) noexcept;
  bool next_frame(CanFrame& out) noexcept;

  bool done() const noexcept;  // every node operational or failed
  bool all_operational() const noexcept;
  int node_count() const noexcept { return config_.node_count; }
  const NodeProgress& progress(int i) const noexcept {
    return nodes_[static_cast<std::size_t>(i)].progress;
  }
  const StartupStats& stats() const noexcept { return stats_; }

 private:
  struct Node {
    NodeProgress progress{};
    std::int64_t deadline = 0;
    int attempts = 0;  // of the current step
    int step = 0;      // identity sub - 1, or write index
    bool sdo_pending = false;
    bool sdo_is_write = false;
    Multiplexer sdo_at{};
  };

  void send(const CanFrame& frame) noexcept;
  void on_booted(int i, std::int64_t now, bool boot_up, NmtState state) noexcept;
  void on_sdo(int i, const SdoPayload& sdo, std::int64_t now) noexcept;
  void on_upload(int i, const SdoPayload& sdo, std::int64_t now) noexcept;
  void next_step(int i, std::int64_t now) noexcept;
  void request(int i, std::int64_t now) noexcept;  // (re)send the current step's SDO
  void start_node(int i, std::int64_t now) noexcept;
  void fail(int i, StartupFailure why) noexcept;
  void timeout(int i, std::int64_t now) noexcept;
  int index_of(NodeId node) const noexcept;

  StartupConfig config_;
  StartupStats stats_{};
  std::array<Node, kMaxNodes> nodes_{};
  std::array<CanFrame, kOutboxCapacity> outbox_{};
  int out_head_ = 0;
  int out_size_ = 0;
};

}  // namespace exodaq::drivers::canopen
