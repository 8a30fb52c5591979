#include "exodaq/drivers/canopen/assembler.hpp"

#include <algorithm>

namespace exodaq::drivers::canopen {
namespace {

ConfigError joint_error(int joint, const char* what) noexcept {
  return {what, joint, {}};
}

std::size_t at(int i) noexcept {
  return static_cast<std::size_t>(i);
}

// The identifiers a node uses besides its TPDO.
bool is_node_service_id(std::uint32_t id, NodeId node) noexcept {
  return id == cob::emcy(node) || id == cob::sdo_tx(node) || id == cob::sdo_rx(node) ||
         id == cob::heartbeat(node);
}

const char* check_transmission(const TpdoSetup& tpdo, std::uint8_t overflow) noexcept {
  if (!transmission::is_cyclic(tpdo.transmission_type)) {
    return "transmission type must be synchronous cyclic (1..240)";
  }
  if (tpdo.sync_start != 0 && (overflow == 0 || tpdo.sync_start > overflow)) {
    return "SYNC start value needs a SYNC counter and must not exceed its overflow value";
  }
  if (tpdo.transmission_type > 1 &&
      (overflow == 0 || overflow % tpdo.transmission_type != 0 || tpdo.sync_start == 0)) {
    return "transmission type n > 1 needs a SYNC counter whose overflow value is a multiple of "
           "n and a SYNC start value";
  }
  return nullptr;
}

ConfigError check_ids(const AssemblerConfig& c, int j) noexcept {
  const JointConfig& joint = c.joints[at(j)];
  const std::uint32_t id = tpdo_cob_id(joint.node, joint.tpdo);
  if (id > cob::kIdMask) return joint_error(j, "TPDO COB-ID must be an 11-bit identifier");
  if (id == cob::kNmt || id == cob::kSync || id == cob::kTime) {
    return joint_error(j, "TPDO COB-ID collides with NMT, SYNC or TIME");
  }
  for (int k = 0; k < c.joint_count; ++k) {
    const JointConfig& other = c.joints[at(k)];
    if (k != j && other.node == joint.node) return joint_error(j, "two joints share a node id");
    if (is_node_service_id(id, other.node)) {
      return joint_error(j, "TPDO COB-ID collides with a node's EMCY, SDO or heartbeat");
    }
    if (k != j && tpdo_cob_id(other.node, other.tpdo) == id) {
      return joint_error(j, "two joints share a TPDO COB-ID");
    }
  }
  return {};
}

ConfigError check_joint(const AssemblerConfig& c, int j) noexcept {
  const JointConfig& joint = c.joints[at(j)];
  if (!is_node_id(joint.node)) return joint_error(j, "node id must be 1..127");
  if (joint.tpdo.pdo < 1 || joint.tpdo.pdo > kTpdoCount) {
    return joint_error(j, "TPDO number must be 1..4");
  }
  if ((joint.tpdo.cob_id & ~cob::kIdMask) != 0) {
    return joint_error(j, "TPDO COB-ID must be an 11-bit identifier without flag bits");
  }
  if (const ConfigError e = check_ids(c, j); e.what != nullptr) return e;
  if (const char* why = check_transmission(joint.tpdo, c.sync_overflow)) {
    return joint_error(j, why);
  }
  const LayoutResult layout = resolve_layout(joint.tpdo.mapping, joint.values);
  if (layout.error != MappingError::kNone) {
    return {"TPDO mapping cannot be read", j, layout.error};
  }
  if (const char* why = validate_resolution(layout.layout, 0, joint.total_range)) {
    return joint_error(j, why);
  }
  if (joint.heartbeat_timeout_ns < 0) return joint_error(j, "heartbeat timeout must be >= 0");
  return {};
}

}  // namespace

ConfigError validate(const AssemblerConfig& c) noexcept {
  if (c.joint_count < 1 || c.joint_count > kMaxNodes) return {"joint count must be 1..16", -1, {}};
  if (!is_sync_overflow(c.sync_overflow)) {
    return {"SYNC counter overflow value must be 0 or 2..240", -1, {}};
  }
  if (c.boot_timeout_ns <= 0) return {"boot timeout must be > 0", -1, {}};
  if (c.tpdo_deadline_ns < 0) return {"TPDO deadline must be >= 0", -1, {}};
  for (int j = 0; j < c.joint_count; ++j) {
    if (const ConfigError e = check_joint(c, j); e.what != nullptr) return e;
  }
  return {};
}

Assembler::Assembler(const AssemblerConfig& config) noexcept : config_(config) {
  // validate() is the caller's; an unvalidated config must still not index
  // out of bounds.
  config_.joint_count = std::clamp(config_.joint_count, 0, kMaxNodes);
  joint_by_node_.fill(-1);
  for (int j = 0; j < config_.joint_count; ++j) {
    const JointConfig& joint = config_.joints[at(j)];
    if (joint.node <= kMaxNodeId) joint_by_node_[joint.node] = static_cast<std::int8_t>(j);
  }
  reset(0);
}

void Assembler::reset(std::int64_t now) noexcept {
  stats_ = {};
  for (int j = 0; j < config_.joint_count; ++j) {
    const JointConfig& joint = config_.joints[at(j)];
    NodeState& n = nodes_[at(j)];
    n = {};
    n.layout = resolve_layout(joint.tpdo.mapping, joint.values).layout;
    n.modulus = position_modulus(n.layout, joint.total_range);
    n.tpdo_id = tpdo_cob_id(joint.node, joint.tpdo);
  }
  start_ns_ = now;
  last_now_ = now;
  open_ = false;
  current_ = {};
  next_cycle_ = 0;
  sync_counter_known_ = false;
  last_sync_counter_ = 0;
  pending_flags_ = 0;
  queue_head_ = 0;
  queue_size_ = 0;
}

CanFrame Assembler::begin_cycle(std::int64_t now) noexcept {
  last_now_ = now;
  if (open_) close_cycle(now);
  const std::uint8_t overflow = config_.sync_overflow;
  if (overflow == 0) {
    open_cycle(now, false, 0);
    return encode_sync();
  }
  const std::uint8_t counter =
      sync_counter_known_ ? next_sync_counter(last_sync_counter_, overflow) : std::uint8_t{1};
  sync_counter_known_ = true;
  last_sync_counter_ = counter;
  open_cycle(now, true, counter);
  return encode_sync(counter);
}

void Assembler::end_cycle(std::int64_t now) noexcept {
  last_now_ = now;
  if (open_) close_cycle(now);
}

bool Assembler::poll(CycleSample& out) noexcept {
  if (queue_size_ == 0) return false;
  out = queue_[at(queue_head_)];
  queue_head_ = (queue_head_ + 1) % kQueueCapacity;
  --queue_size_;
  return true;
}

WantedIds Assembler::wanted_ids() const noexcept {
  WantedIds w;
  auto add = [&w](std::uint32_t id) { w.ids[at(w.count++)] = id; };
  add(cob::kSync);
  for (int j = 0; j < config_.joint_count; ++j) {
    const NodeId node = config_.joints[at(j)].node;
    add(cob::emcy(node));
    add(nodes_[at(j)].tpdo_id);
    add(cob::sdo_tx(node));
    add(cob::heartbeat(node));
  }
  return w;
}

void Assembler::on_frame(const CanFrame& frame) noexcept {
  if ((frame.flags & can::frame_flag::kOwn) != 0) {
    if (frame.id == cob::kSync && config_.sync_role == SyncRole::kProducer) on_own_sync(frame);
    return;
  }
  ++stats_.frames;
  if ((frame.flags & can::frame_flag::kError) != 0) {
    ++stats_.error_frames;
    return;
  }
  if (const int j = joint_of_tpdo(frame); j >= 0) {
    on_tpdo(j, frame);
    return;
  }
  const Decoded d = decode_frame(frame);
  const int j = joint_of_node(d.node);
  switch (d.kind) {
    case FrameKind::kRejected:
      on_rejected(j, frame, d.reject);
      return;
    case FrameKind::kSync:
      on_sync(frame, d.sync);
      return;
    case FrameKind::kEmcy:
      if (j >= 0) return on_emcy(j, d.emcy);
      break;
    case FrameKind::kHeartbeat:
    case FrameKind::kBootUp:
      if (j >= 0) return on_error_control(j, frame, d.heartbeat.state);
      break;
    case FrameKind::kSdo:
      // The start-up machine's business; it tells the node is alive.
      if (j >= 0 && !d.sdo.from_client) {
        nodes_[at(j)].heard = true;
        return;
      }
      break;
    default:
      break;
  }
  ++stats_.foreign;
}

void Assembler::flag_cycle(std::uint32_t flags) noexcept {
  if (open_) {
    current_.flags |= flags;
  } else {
    pending_flags_ |= flags;
  }
}

void Assembler::on_rejected(int joint, const CanFrame& frame, Reject why) noexcept {
  ++stats_.rejected[static_cast<std::size_t>(why)];
  if (frame.id == cob::kSync && (frame.flags & can::frame_flag::kExtended) == 0) {
    // A SYNC with a bad counter or length: another producer's, or a broken one.
    if (config_.sync_role == SyncRole::kProducer) {
      ++stats_.foreign_syncs;
      flag_cycle(cycle_flag::kForeignSync);
    } else {
      ++stats_.sync_counter_mismatches;
      flag_cycle(cycle_flag::kSyncCounterMismatch);
    }
    return;
  }
  if (joint < 0) return;
  // Only what the node itself sends: EMCY, SDO responses, heartbeats.
  const FunctionCode fc = cob::function_of(frame.id);
  if (fc == FunctionCode::kSyncEmcy || fc == FunctionCode::kSdoTx ||
      fc == FunctionCode::kErrorControl) {
    NodeState& n = nodes_[at(joint)];
    n.heard = true;
    n.events |= joint_fault::kBadFrame;
  }
}

void Assembler::on_sync(const CanFrame& frame, const SyncPayload& sync) noexcept {
  const std::int64_t stamp = frame.mono_ns != 0 ? frame.mono_ns : last_now_;
  if (config_.sync_role == SyncRole::kProducer) {
    ++stats_.foreign_syncs;
    flag_cycle(cycle_flag::kForeignSync);
    return;
  }
  const bool want_counter = config_.sync_overflow != 0;
  bool mismatch = sync.has_counter != want_counter;
  if (!mismatch && sync.has_counter && sync_counter_known_) {
    mismatch = sync.counter != next_sync_counter(last_sync_counter_, config_.sync_overflow);
  }
  if (sync.has_counter && sync.counter > config_.sync_overflow) mismatch = true;
  last_now_ = stamp;
  if (open_) close_cycle(stamp);
  sync_counter_known_ = sync.has_counter;
  last_sync_counter_ = sync.counter;
  open_cycle(stamp, sync.has_counter, sync.counter);
  if (mismatch) {
    ++stats_.sync_counter_mismatches;
    current_.flags |= cycle_flag::kSyncCounterMismatch;
  }
}

void Assembler::on_tpdo(int joint, const CanFrame& frame) noexcept {
  NodeState& n = nodes_[at(joint)];
  n.heard = true;
  PdoValues v;
  if (!unpack(n.layout, frame, v)) {
    ++stats_.wrong_length;
    n.events |= joint_fault::kWrongLength;
    return;
  }
  // A node answers a SYNC after it was sent: a frame stamped before this
  // cycle's SYNC, or arriving while no cycle is open, belongs to an earlier
  // cycle that was closed without it (counted; that cycle's channel was
  // already missing); one stamped after the deadline is late for this one
  // (flagged on it). Which cycle a late answer is charged to depends on its
  // stamp only, never on when it was read: a candump replay charges it alike.
  const std::int64_t stamp = frame.mono_ns;
  const std::int64_t deadline = config_.tpdo_deadline_ns;
  const bool this_cycle = open_ && (stamp == 0 || stamp >= current_.sync_mono_ns);
  const bool in_time =
      this_cycle && (stamp == 0 || deadline == 0 || stamp - current_.sync_mono_ns <= deadline);
  if (!open_ && next_cycle_ == 0) {
    ++stats_.before_first_cycle;  // answers a SYNC from before reset(): no cycle to blame
    return;
  }
  if (!in_time) {
    ++stats_.late;
    if (this_cycle) n.events |= joint_fault::kLate;
    return;
  }
  if (n.got_tpdo) {
    ++stats_.duplicates;
    n.events |= joint_fault::kDuplicate;
    return;
  }
  const bool has_reference = n.layout.has_reference;
  if (v.position >= n.modulus || (has_reference && v.reference >= n.modulus)) {
    ++stats_.out_of_range;
    n.events |= joint_fault::kOutOfRange;
    return;
  }
  ++stats_.tpdos;
  n.got_tpdo = true;
  n.reference_changed = has_reference && n.ever_present && v.reference != n.reference;
  n.ever_present = true;
  n.position = v.position;
  n.reference = v.reference;
  n.rx_mono_ns = frame.mono_ns;
}

void Assembler::on_own_sync(const CanFrame& frame) noexcept {
  // The stamps are the kernel's realtime ones moved by the link's estimated
  // offset: a SYNC read back this little before the clock reading that
  // began its cycle is still this cycle's.
  constexpr std::int64_t kStampSlackNs = 20'000;
  if (!open_ || read_back_ || frame.mono_ns == 0) return;
  if (frame.mono_ns < current_.sync_mono_ns - kStampSlackNs) return;  // an older SYNC's
  read_back_ = true;
  current_.sync_mono_ns = frame.mono_ns;
  ++stats_.syncs_read_back;
  for (int j = 0; j < config_.joint_count; ++j) {
    NodeState& n = nodes_[at(j)];
    if (!n.got_tpdo || n.rx_mono_ns == 0 || n.rx_mono_ns >= frame.mono_ns) continue;
    n.got_tpdo = false;  // stamped before this SYNC was on the bus: an earlier one's
    n.reference_changed = false;
    --stats_.tpdos;
    ++stats_.late;
  }
}

std::uint32_t Assembler::answered() const noexcept {
  std::uint32_t mask = 0;
  for (int j = 0; j < config_.joint_count; ++j) {
    if (open_ && nodes_[at(j)].got_tpdo) mask |= 1U << j;
  }
  return mask;
}

void Assembler::on_emcy(int joint, const EmcyPayload& emcy) noexcept {
  NodeState& n = nodes_[at(joint)];
  n.heard = true;
  ++stats_.emcys;
  n.emcy_code = emcy.error_code;  // kNoError: the node's errors were reset
  n.error_register = emcy.error_register;
}

void Assembler::on_error_control(int joint, const CanFrame& frame, NmtState state) noexcept {
  NodeState& n = nodes_[at(joint)];
  if (state == NmtState::kBootUp) {
    ++stats_.boot_ups;
    if (n.heard) n.events |= joint_fault::kRebooted;
    n.emcy_code = 0;
    n.error_register = 0;
    state = NmtState::kPreOperational;  // where a node goes after its boot-up
  } else {
    ++stats_.heartbeats;
  }
  n.heard = true;
  n.heartbeat_seen = true;
  n.state_known = true;
  n.state = state;
  n.last_heartbeat_ns = frame.mono_ns != 0 ? frame.mono_ns : last_now_;
}

void Assembler::open_cycle(std::int64_t sync_ns, bool has_counter, std::uint8_t counter) noexcept {
  current_.cycle = next_cycle_++;
  current_.sync_mono_ns = sync_ns;
  current_.has_sync_counter = has_counter;
  current_.sync_counter = counter;
  current_.flags = pending_flags_;
  pending_flags_ = 0;
  current_.joint_count = config_.joint_count;
  open_ = true;
  read_back_ = false;
}

bool Assembler::due(int joint) const noexcept {
  const TpdoSetup& tpdo = config_.joints[at(joint)].tpdo;
  const int n = tpdo.transmission_type;
  if (n <= 1) return true;
  if (!current_.has_sync_counter) return false;
  // validate(): the overflow value is a multiple of n, so the phase holds
  // across the counter's wrap.
  const int overflow = config_.sync_overflow;
  return (current_.sync_counter - tpdo.sync_start + overflow) % n == 0;
}

JointReading Assembler::read_joint(int joint, std::int64_t now) noexcept {
  const JointConfig& config = config_.joints[at(joint)];
  NodeState& n = nodes_[at(joint)];
  JointReading r;
  r.modulus = n.modulus;
  r.has_reference = n.layout.has_reference;
  r.position = n.position;
  r.reference = n.reference;
  r.reference_changed = n.got_tpdo && n.reference_changed;
  r.present = n.got_tpdo;
  r.due = due(joint);
  r.state_known = n.state_known;
  r.state = n.state;
  r.emcy_code = n.emcy_code;
  r.error_register = n.error_register;
  r.rx_mono_ns = n.got_tpdo ? n.rx_mono_ns : 0;
  std::uint32_t faults = n.events;
  if (!n.heard && now - start_ns_ > config_.boot_timeout_ns) faults |= joint_fault::kNeverBooted;
  if (n.heard && config.heartbeat_timeout_ns > 0) {
    const std::int64_t since = n.heartbeat_seen ? n.last_heartbeat_ns : start_ns_;
    const bool lost = now - since > config.heartbeat_timeout_ns;
    if (lost && !n.heartbeat_lost) ++stats_.heartbeat_losses;
    n.heartbeat_lost = lost;
    if (lost) faults |= joint_fault::kHeartbeatLost;
  }
  if (n.state_known && n.state != NmtState::kOperational) faults |= joint_fault::kNotOperational;
  if (n.emcy_code != emcy_code::kNoError) faults |= joint_fault::kEmcy;
  if (r.due && !r.present) {
    ++stats_.missing;
    faults |= joint_fault::kMissing;
  }
  r.faults = faults;
  n.got_tpdo = false;
  n.reference_changed = false;
  n.events = 0;
  return r;
}

void Assembler::close_cycle(std::int64_t now) noexcept {
  for (int j = 0; j < config_.joint_count; ++j) current_.joints[at(j)] = read_joint(j, now);
  open_ = false;
  ++stats_.cycles;
  if (queue_size_ == kQueueCapacity) {
    queue_head_ = (queue_head_ + 1) % kQueueCapacity;
    --queue_size_;
    ++stats_.queue_overflows;
    queue_[at(queue_head_)].flags |= cycle_flag::kOverrun;
  }
  queue_[at((queue_head_ + queue_size_) % kQueueCapacity)] = current_;
  ++queue_size_;
}

int Assembler::joint_of_node(NodeId node) const noexcept {
  return node <= kMaxNodeId ? joint_by_node_[node] : -1;
}

int Assembler::joint_of_tpdo(const CanFrame& frame) const noexcept {
  if (frame.flags != 0) return -1;  // RTR, extended, FD: the codec rejects them
  for (int j = 0; j < config_.joint_count; ++j) {
    if (nodes_[at(j)].tpdo_id == frame.id) return j;
  }
  return -1;
}

}  // namespace exodaq::drivers::canopen
