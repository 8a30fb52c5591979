#include "exodaq/drivers/canopen/node_sim.hpp"

#include <utility>

#include "le_bytes.hpp"

namespace exodaq::drivers::canopen {
namespace {

constexpr std::int64_t kNsPerMs = 1'000'000;
constexpr std::int64_t kNsPerUs = 1'000;
constexpr std::uint32_t kSyncProducerBit = 1U << 30;
constexpr std::uint8_t kTpdoCommHighestSub = 6;

constexpr std::uint32_t abort_code(SdoAbort a) noexcept {
  return static_cast<std::uint32_t>(a);
}

// 0..3 when `index` is one of the four TPDO communication or mapping objects.
int pdo_slot(std::uint16_t index, std::uint16_t base) noexcept {
  return index >= base && index < base + kTpdoCount ? index - base : -1;
}

}  // namespace

std::string_view to_string(SimFault fault) noexcept {
  switch (fault) {
    case SimFault::kNeverBoots:
      return "never boots";
    case SimFault::kHeartbeatStops:
      return "heartbeat stops";
    case SimFault::kEmcy:
      return "emcy";
    case SimFault::kTpdoMissing:
      return "tpdo missing";
    case SimFault::kTpdoLate:
      return "tpdo late";
    case SimFault::kWrongPdoLength:
      return "wrong pdo length";
    case SimFault::kSyncCounterMismatch:
      return "sync counter mismatch";
  }
  return "?";
}

EncoderNodeSim::EncoderNodeSim(const NodeSimConfig& config, PositionSource source)
    : config_(config), source_(std::move(source)) {
  build_dictionary();
}

// ---------------------------------------------------------------------------
// Object dictionary
// ---------------------------------------------------------------------------

void EncoderNodeSim::add_entry(Multiplexer at, std::uint8_t size, Access access,
                               std::uint32_t value, bool mappable) noexcept {
  if (od_count_ >= kMaxEntries) return;
  od_[static_cast<std::size_t>(od_count_++)] = {at, size, access, mappable, value, value};
}

void EncoderNodeSim::build_dictionary() noexcept {
  const NodeSimConfig& c = config_;
  const NodeId node = c.node;
  add_entry({od::kDeviceType, 0}, 4, Access::kRo, c.device_type);
  add_entry({od::kErrorRegister, 0}, 1, Access::kRo, 0);
  add_entry({od::kCobIdSync, 0}, 4, Access::kRw,
            cob::kSync | (c.sync_producer ? kSyncProducerBit : 0));
  add_entry({od::kCommunicationCyclePeriod, 0}, 4, Access::kRw,
            c.sync_producer ? static_cast<std::uint32_t>(c.sync_period_ns / kNsPerUs) : 0);
  add_entry({od::kConsumerHeartbeatTime, 0}, 1, Access::kRo, 1);
  add_entry({od::kConsumerHeartbeatTime, 1}, 4, Access::kRw, 0);
  add_entry({od::kProducerHeartbeatTime, 0}, 2, Access::kRw, c.heartbeat_ms);
  add_entry({od::kIdentity, 0}, 1, Access::kRo, 4);
  add_entry({od::kIdentity, identity_sub::kVendorId}, 4, Access::kRo, c.identity.vendor_id);
  add_entry({od::kIdentity, identity_sub::kProductCode}, 4, Access::kRo, c.identity.product_code);
  add_entry({od::kIdentity, identity_sub::kRevision}, 4, Access::kRo, c.identity.revision);
  add_entry({od::kIdentity, identity_sub::kSerialNumber}, 4, Access::kRo, c.identity.serial_number);
  add_entry({od::kSyncCounterOverflow, 0}, 1, Access::kRw, c.sync_overflow);
  for (int pdo = 1; pdo <= kTpdoCount; ++pdo) {
    const bool first = pdo == 1;
    const TpdoSetup& t = c.tpdo1;
    const std::uint16_t comm = od::tpdo_communication(pdo);
    const std::uint16_t map = od::tpdo_mapping(pdo);
    add_entry({comm, tpdo_comm_sub::kHighestSub}, 1, Access::kRo, kTpdoCommHighestSub);
    add_entry({comm, tpdo_comm_sub::kCobId}, 4, Access::kRw,
              first ? tpdo_cob_id(node, t) : cob::tpdo(pdo, node) | pdo_cob_id::kInvalid);
    add_entry({comm, tpdo_comm_sub::kTransmissionType}, 1, Access::kRw,
              first ? t.transmission_type : transmission::kEverySync);
    add_entry({comm, tpdo_comm_sub::kInhibitTime}, 2, Access::kRw, 0);
    add_entry({comm, tpdo_comm_sub::kEventTimer}, 2, Access::kRw, 0);
    add_entry({comm, tpdo_comm_sub::kSyncStart}, 1, Access::kRw, first ? t.sync_start : 0);
    add_entry({map, 0}, 1, Access::kRw, first ? static_cast<std::uint32_t>(t.mapping.count) : 0);
    for (int k = 0; k < kMaxMappedObjects; ++k) {
      const bool mapped = first && k < t.mapping.count;
      add_entry({map, static_cast<std::uint8_t>(k + 1)}, 4, Access::kRw,
                mapped ? encode_mapping_entry(t.mapping.entries[static_cast<std::size_t>(k)]) : 0);
    }
  }
  add_entry({od::kOperatingParameters, 0}, 2, Access::kRw, c.operating_parameters);
  add_entry({od::kMeasuringUnitsPerRevolution, 0}, 4, Access::kRw, c.units_per_revolution);
  add_entry({od::kTotalMeasuringRange, 0}, 4, Access::kRw, c.total_range);
  add_entry({od::kPresetValue, 0}, 4, Access::kRw, 0);
  add_entry({od::kPositionValue, 0}, 4, Access::kRo, 0, true);
  if (c.has_reference_object) {
    if (c.reference_object.sub != 0) {
      add_entry({c.reference_object.index, 0}, 1, Access::kRo, c.reference_object.sub);
    }
    add_entry(c.reference_object, 4, Access::kRo, 0, true);
  }
  if (c.has_count_object) {
    if (c.count_object.sub != 0 && !has_index(c.count_object.index)) {
      add_entry({c.count_object.index, 0}, 1, Access::kRo, c.count_object.sub);
    }
    add_entry(c.count_object, 4, Access::kRo, 0, true);
  }
}

const EncoderNodeSim::Entry* EncoderNodeSim::find(Multiplexer at) const noexcept {
  for (int i = 0; i < od_count_; ++i) {
    if (od_[static_cast<std::size_t>(i)].at == at) return &od_[static_cast<std::size_t>(i)];
  }
  return nullptr;
}

EncoderNodeSim::Entry* EncoderNodeSim::find(Multiplexer at) noexcept {
  return const_cast<Entry*>(std::as_const(*this).find(at));
}

bool EncoderNodeSim::has_index(std::uint16_t index) const noexcept {
  for (int i = 0; i < od_count_; ++i) {
    if (od_[static_cast<std::size_t>(i)].at.index == index) return true;
  }
  return false;
}

std::uint32_t EncoderNodeSim::stored(Multiplexer at) const noexcept {
  const Entry* e = find(at);
  return e != nullptr ? e->value : 0;
}

std::int64_t EncoderNodeSim::range() const noexcept {
  const std::uint32_t r = stored({od::kTotalMeasuringRange, 0});
  return r != 0 ? static_cast<std::int64_t>(r) : std::int64_t{1} << 32;
}

bool EncoderNodeSim::counts_ccw() const noexcept {
  return (stored({od::kOperatingParameters, 0}) & operating_parameter::kCodeSequenceCcw) != 0;
}

// The 0x6004 value of a raw count: preset offset, total measuring range
// (0x6002, always applied here), code sequence (0x6000 bit 0).
std::uint32_t EncoderNodeSim::scaled(std::uint32_t raw) const noexcept {
  const std::int64_t r = range();
  std::int64_t v = (static_cast<std::int64_t>(raw) + position_offset_) % r;
  if (v < 0) v += r;
  if (counts_ccw()) v = (r - v) % r;
  return static_cast<std::uint32_t>(v);
}

std::uint32_t EncoderNodeSim::value_of(const Entry& e, const SimPosition& p) const noexcept {
  if (e.at == Multiplexer{od::kPositionValue, 0}) return scaled(p.position);
  if (config_.has_count_object && e.at == config_.count_object) return scaled(p.position);
  if (config_.has_reference_object && e.at == config_.reference_object) {
    return scaled(p.reference);
  }
  return e.value;
}

bool EncoderNodeSim::read(Multiplexer at, std::uint32_t& value) const noexcept {
  const Entry* e = find(at);
  if (e == nullptr) return false;
  value = value_of(*e, source_(now_));
  return true;
}

void EncoderNodeSim::reset_entries(bool communication_only) noexcept {
  for (int i = 0; i < od_count_; ++i) {
    Entry& e = od_[static_cast<std::size_t>(i)];
    if (!communication_only || e.at.index < 0x2000) e.value = e.initial;
  }
  if (!communication_only) position_offset_ = 0;
}

// ---------------------------------------------------------------------------
// Time, boot, heartbeat, SYNC production
// ---------------------------------------------------------------------------

void EncoderNodeSim::schedule(CanFrame frame, std::int64_t at) noexcept {
  frame.mono_ns = at;
  for (Scheduled& s : scheduled_) {
    if (!s.used) {
      s = {frame, true, next_order_++};
      return;
    }
  }
  ++dropped_;  // more in flight than a node ever has: a test configuration error
}

bool EncoderNodeSim::next_frame(CanFrame& out) noexcept {
  Scheduled* best = nullptr;
  for (Scheduled& s : scheduled_) {
    if (!s.used || s.frame.mono_ns > now_) continue;
    if (best == nullptr || s.frame.mono_ns < best->frame.mono_ns ||
        (s.frame.mono_ns == best->frame.mono_ns && s.order < best->order)) {
      best = &s;
    }
  }
  if (best == nullptr) return false;
  out = best->frame;
  best->used = false;
  return true;
}

void EncoderNodeSim::power_on(std::int64_t now) noexcept {
  now_ = now;
  powered_ = true;
  reset_entries(false);
  reboot(now);
}

void EncoderNodeSim::reboot(std::int64_t now) noexcept {
  booted_ = false;
  state_ = NmtState::kBootUp;
  boot_at_ = now + config_.boot_delay_ns;
  for (Scheduled& s : scheduled_) s.used = false;
  pdo_runs_ = {};
}

bool EncoderNodeSim::sync_producer() const noexcept {
  return (stored({od::kCobIdSync, 0}) & kSyncProducerBit) != 0 &&
         stored({od::kCommunicationCyclePeriod, 0}) != 0;
}

std::int64_t EncoderNodeSim::sync_period_ns() const noexcept {
  return static_cast<std::int64_t>(stored({od::kCommunicationCyclePeriod, 0})) * kNsPerUs;
}

std::int64_t EncoderNodeSim::heartbeat_period_ns() const noexcept {
  return static_cast<std::int64_t>(stored({od::kProducerHeartbeatTime, 0})) * kNsPerMs;
}

void EncoderNodeSim::advance(std::int64_t now) noexcept {
  now_ = now;
  if (!powered_ || fault(SimFault::kNeverBoots)) return;
  if (!booted_ && now >= boot_at_) {
    booted_ = true;
    state_ = NmtState::kPreOperational;
    schedule(encode_boot_up(config_.node), boot_at_);
    next_heartbeat_ = boot_at_ + heartbeat_period_ns();
    next_sync_ = boot_at_ + sync_period_ns();
    sync_counter_ = 0;
  }
  if (!booted_) return;
  const std::int64_t hb = heartbeat_period_ns();
  while (hb > 0 && next_heartbeat_ <= now) {
    if (!fault(SimFault::kHeartbeatStops)) {
      schedule(encode_heartbeat(config_.node, state_), next_heartbeat_);
    }
    next_heartbeat_ += hb;
  }
  const std::int64_t period = sync_period_ns();
  while (sync_producer() && state_ != NmtState::kStopped && next_sync_ <= now) {
    produce_sync(next_sync_);
    next_sync_ += period;
  }
}

void EncoderNodeSim::produce_sync(std::int64_t at) noexcept {
  const auto overflow = static_cast<std::uint8_t>(stored({od::kSyncCounterOverflow, 0}));
  if (overflow == 0) {
    schedule(encode_sync(), at);
    on_sync(false, 0, at);
    return;
  }
  sync_counter_ = sync_counter_ == 0 ? std::uint8_t{1} : next_sync_counter(sync_counter_, overflow);
  if (fault(SimFault::kSyncCounterMismatch)) {
    sync_counter_ = next_sync_counter(sync_counter_, overflow);
  }
  schedule(encode_sync(sync_counter_), at);
  on_sync(true, sync_counter_, at);  // the producer's own synchronous PDOs
}

void EncoderNodeSim::set_fault(SimFault f, bool active, std::int64_t now) noexcept {
  const bool was = fault(f);
  faults_[static_cast<std::size_t>(f)] = active;
  now_ = now;
  if (was == active) return;
  if (f == SimFault::kNeverBoots) {
    for (Scheduled& s : scheduled_) s.used = false;
    if (!active && powered_) reboot(now);
    return;
  }
  if (f == SimFault::kEmcy && booted_) {
    EmcyPayload emcy = active ? config_.fault_emcy : EmcyPayload{};
    if (active) emcy.error_register |= error_register::kGeneric;
    if (Entry* reg = find({od::kErrorRegister, 0})) reg->value = emcy.error_register;
    schedule(encode_emcy(config_.node, emcy), now + config_.response_ns);
  }
}

// ---------------------------------------------------------------------------
// Received frames
// ---------------------------------------------------------------------------

void EncoderNodeSim::on_frame(const CanFrame& frame, std::int64_t now) noexcept {
  now_ = now;
  if (!booted_ || fault(SimFault::kNeverBoots)) return;
  const Decoded d = decode_frame(frame);
  switch (d.kind) {
    case FrameKind::kNmt:
      if (d.nmt.node == kAllNodes || d.nmt.node == config_.node) on_nmt(d.nmt, now);
      return;
    case FrameKind::kSync:
      if (!sync_producer()) on_sync(d.sync.has_counter, d.sync.counter, now);
      return;
    case FrameKind::kSdo:
      if (d.sdo.from_client && d.sdo.node == config_.node) on_sdo(d.sdo, now);
      return;
    case FrameKind::kRejected:
      // A request this server cannot parse: CiA 301 answers with an abort.
      if (frame.id == cob::sdo_rx(config_.node) && frame.dlc == kSdoDlc &&
          state_ != NmtState::kStopped) {
        const Multiplexer at{get_u16(frame.data, 1), frame.data[3]};
        schedule(encode_sdo_abort(config_.node, at, abort_code(SdoAbort::kUnknownCommand), false),
                 now + config_.response_ns);
      }
      return;
    default:
      return;
  }
}

void EncoderNodeSim::on_nmt(const NmtPayload& nmt, std::int64_t now) noexcept {
  switch (nmt.command) {
    case NmtCommand::kStart:
      if (state_ != NmtState::kOperational) pdo_runs_ = {};
      state_ = NmtState::kOperational;
      return;
    case NmtCommand::kStop:
      state_ = NmtState::kStopped;
      return;
    case NmtCommand::kEnterPreOperational:
      state_ = NmtState::kPreOperational;
      return;
    case NmtCommand::kResetNode:
      reset_entries(false);
      reboot(now);
      return;
    case NmtCommand::kResetCommunication:
      reset_entries(true);
      reboot(now);
      return;
  }
}

void EncoderNodeSim::on_sync(bool has_counter, std::uint8_t counter, std::int64_t now) noexcept {
  ++syncs_seen_;
  if (state_ != NmtState::kOperational) return;
  for (int pdo = 1; pdo <= kTpdoCount; ++pdo) {
    const std::uint16_t comm = od::tpdo_communication(pdo);
    if ((stored({comm, tpdo_comm_sub::kCobId}) & pdo_cob_id::kInvalid) != 0) continue;
    const auto n = static_cast<int>(stored({comm, tpdo_comm_sub::kTransmissionType}));
    if (!transmission::is_cyclic(n)) continue;
    PdoRun& run = pdo_runs_[static_cast<std::size_t>(pdo - 1)];
    if (!run.started) {
      const std::uint32_t start = stored({comm, tpdo_comm_sub::kSyncStart});
      if (start != 0 && has_counter && counter != start) continue;
      run.started = true;
      run.count = 0;
    }
    if (run.count % n == 0) send_tpdo(pdo, now);
    run.count = (run.count + 1) % n;
  }
}

void EncoderNodeSim::send_tpdo(int pdo, std::int64_t sync_ns) noexcept {
  if (fault(SimFault::kTpdoMissing)) return;
  const std::uint16_t map = od::tpdo_mapping(pdo);
  TpdoMapping mapping;
  const auto count = static_cast<int>(stored({map, 0}));
  for (int k = 1; k <= count; ++k) {
    mapping.add(decode_mapping_entry(stored({map, static_cast<std::uint8_t>(k)})));
  }
  const SimPosition sample = source_(sync_ns);
  std::uint8_t length = 0;
  const std::array<std::uint8_t, 8> data = pack(
      mapping,
      [&](const MappedObject& m) {
        const Entry* e = find(m.at());
        return e != nullptr ? value_of(*e, sample) : 0U;
      },
      length);
  if (fault(SimFault::kWrongPdoLength))
    length = static_cast<std::uint8_t>(length > 1 ? length - 1 : 2);
  CanFrame frame = encode_tpdo(pdo, config_.node, data, length);
  frame.id = stored({od::tpdo_communication(pdo), tpdo_comm_sub::kCobId}) & cob::kIdMask;
  const bool late = fault(SimFault::kTpdoLate);
  schedule(frame, sync_ns + (late ? config_.late_ns : config_.response_ns));
  ++tpdos_sent_;
}

// ---------------------------------------------------------------------------
// SDO server
// ---------------------------------------------------------------------------

void EncoderNodeSim::on_sdo(const SdoPayload& sdo, std::int64_t now) noexcept {
  if (state_ == NmtState::kStopped) return;  // no SDO in stopped
  const NodeId node = config_.node;
  const std::int64_t at = now + config_.response_ns;
  if (sdo.kind == SdoKind::kAbort) return;
  if (sdo.kind != SdoKind::kUploadRequest && sdo.kind != SdoKind::kDownloadRequest) {
    schedule(encode_sdo_abort(node, sdo.at, abort_code(SdoAbort::kUnknownCommand), false), at);
    return;
  }
  Entry* e = find(sdo.at);
  if (e == nullptr) {
    const SdoAbort why = has_index(sdo.at.index) ? SdoAbort::kNoSubIndex : SdoAbort::kNoObject;
    schedule(encode_sdo_abort(node, sdo.at, abort_code(why), false), at);
    return;
  }
  if (sdo.kind == SdoKind::kUploadRequest) {
    schedule(encode_sdo_upload_response(node, sdo.at, value_of(*e, source_(now)), e->size), at);
    return;
  }
  if (const std::uint32_t code = check_write(*e, sdo); code != 0) {
    schedule(encode_sdo_abort(node, sdo.at, code, false), at);
    return;
  }
  apply_write(*e, sdo.value & size_mask(e->size), now);
  schedule(encode_sdo_download_response(node, sdo.at), at);
}

std::uint32_t EncoderNodeSim::check_write(const Entry& e, const SdoPayload& sdo) const noexcept {
  if (e.access == Access::kRo) return abort_code(SdoAbort::kReadOnly);
  if (sdo.size_indicated && sdo.size != e.size) {
    return abort_code(sdo.size > e.size ? SdoAbort::kLengthTooHigh : SdoAbort::kLengthTooLow);
  }
  const std::uint32_t value = sdo.value & size_mask(e.size);
  const std::uint16_t index = e.at.index;
  if (pdo_slot(index, od::kTpdoCommunication) >= 0 || pdo_slot(index, od::kTpdoMapping) >= 0) {
    return check_pdo_write(e, value);
  }
  switch (index) {
    case od::kSyncCounterOverflow:
      return is_sync_overflow(static_cast<int>(value)) ? 0 : abort_code(SdoAbort::kInvalidValue);
    case od::kCobIdSync:
      return (value & pdo_cob_id::kExtended) != 0 ? abort_code(SdoAbort::kInvalidValue) : 0;
    case od::kOperatingParameters:
      return (value & ~std::uint32_t{0xF}) != 0 ? abort_code(SdoAbort::kInvalidValue) : 0;
    case od::kMeasuringUnitsPerRevolution:
    case od::kTotalMeasuringRange:
      return value == 0 ? abort_code(SdoAbort::kValueTooLow) : 0;
    case od::kPresetValue: {
      const std::uint32_t range = stored({od::kTotalMeasuringRange, 0});
      return range != 0 && value >= range ? abort_code(SdoAbort::kValueTooHigh) : 0;
    }
    default:
      return 0;
  }
}

// CiA 301's rules for PDO parameters: the COB-ID and the mapping change only
// while the PDO is disabled (COB-ID bit 31), the entries only while the
// mapping count is 0; a mapped object must exist, be mappable and have the
// entry's length; the count must not map more than 64 bits.
std::uint32_t EncoderNodeSim::check_pdo_write(const Entry& e, std::uint32_t value) const noexcept {
  const bool comm = pdo_slot(e.at.index, od::kTpdoCommunication) >= 0;
  const int slot =
      comm ? pdo_slot(e.at.index, od::kTpdoCommunication) : pdo_slot(e.at.index, od::kTpdoMapping);
  const std::uint32_t cob_id = stored({od::tpdo_communication(slot + 1), tpdo_comm_sub::kCobId});
  const bool valid = (cob_id & pdo_cob_id::kInvalid) == 0;
  const std::uint32_t invalid_value = abort_code(SdoAbort::kInvalidValue);
  if (comm) {
    switch (e.at.sub) {
      case tpdo_comm_sub::kCobId:
        if ((value & pdo_cob_id::kExtended) != 0) return invalid_value;
        if (valid && (value & pdo_cob_id::kInvalid) == 0 &&
            (value & cob::kIdMask) != (cob_id & cob::kIdMask)) {
          return invalid_value;
        }
        return 0;
      case tpdo_comm_sub::kTransmissionType:
        return transmission::is_valid(static_cast<int>(value)) ? 0 : invalid_value;
      case tpdo_comm_sub::kSyncStart:
        return value > kSyncCounterMax ? invalid_value : 0;
      default:
        return 0;
    }
  }
  if (valid) return abort_code(SdoAbort::kUnsupportedAccess);
  const std::uint16_t map = e.at.index;
  if (e.at.sub == 0) {
    if (value > kMaxMappedObjects) return abort_code(SdoAbort::kValueTooHigh);
    int bits = 0;
    for (std::uint32_t k = 1; k <= value; ++k) {
      bits += decode_mapping_entry(stored({map, static_cast<std::uint8_t>(k)})).bits;
    }
    return bits > kMaxPdoBits ? abort_code(SdoAbort::kPdoLengthExceeded) : 0;
  }
  if (stored({map, 0}) != 0) return abort_code(SdoAbort::kUnsupportedAccess);
  const MappedObject m = decode_mapping_entry(value);
  const Entry* target = find(m.at());
  if (target == nullptr || !target->mappable || m.bits != target->size * 8) {
    return abort_code(SdoAbort::kNotMappable);
  }
  return 0;
}

void EncoderNodeSim::apply_write(Entry& e, std::uint32_t value, std::int64_t now) noexcept {
  e.value = value;
  switch (e.at.index) {
    case od::kPresetValue: {
      // From now on the current position reads `value`.
      const std::int64_t r = range();
      const std::int64_t target = counts_ccw() ? (r - value) % r : value;
      position_offset_ = target - static_cast<std::int64_t>(source_(now).position);
      return;
    }
    case od::kProducerHeartbeatTime:
      next_heartbeat_ = now + heartbeat_period_ns();
      return;
    case od::kCobIdSync:
    case od::kCommunicationCyclePeriod:
      next_sync_ = now + sync_period_ns();
      return;
    default:
      if (const int slot = pdo_slot(e.at.index, od::kTpdoCommunication); slot >= 0) {
        pdo_runs_[static_cast<std::size_t>(slot)] = {};
      }
      return;
  }
}

}  // namespace exodaq::drivers::canopen
