#include "exodaq/drivers/canopen/startup.hpp"

#include <algorithm>

namespace exodaq::drivers::canopen {
namespace {

constexpr int kIdentitySubs = 4;

std::size_t at(int i) noexcept {
  return static_cast<std::size_t>(i);
}

bool is_done(StartupPhase p) noexcept {
  return p == StartupPhase::kOperational || p == StartupPhase::kFailed;
}

void store_identity(Identity& id, std::uint8_t sub, std::uint32_t value) noexcept {
  switch (sub) {
    case identity_sub::kVendorId:
      id.vendor_id = value;
      break;
    case identity_sub::kProductCode:
      id.product_code = value;
      break;
    case identity_sub::kRevision:
      id.revision = value;
      break;
    default:
      id.serial_number = value;
      break;
  }
}

}  // namespace

bool NodeSetup::add(const SdoWrite& w) noexcept {
  if (write_count >= kMaxSetupWrites) return false;
  writes[at(write_count++)] = w;
  return true;
}

bool NodeSetup::add_tpdo(const TpdoSetup& tpdo) noexcept {
  std::array<SdoWrite, kMaxPdoWrites> pdo_writes{};
  const int n = tpdo_setup_writes(node, tpdo, pdo_writes);
  if (write_count + n > kMaxSetupWrites) return false;
  for (int i = 0; i < n; ++i) add(pdo_writes[at(i)]);
  return true;
}

std::string_view to_string(StartupPhase phase) noexcept {
  switch (phase) {
    case StartupPhase::kWaitBoot:
      return "waiting for boot-up";
    case StartupPhase::kReadIdentity:
      return "reading identity";
    case StartupPhase::kConfigure:
      return "configuring";
    case StartupPhase::kWaitOperational:
      return "waiting for operational";
    case StartupPhase::kOperational:
      return "operational";
    case StartupPhase::kFailed:
      return "failed";
  }
  return "?";
}

std::string_view to_string(StartupFailure failure) noexcept {
  switch (failure) {
    case StartupFailure::kNone:
      return "none";
    case StartupFailure::kNeverBooted:
      return "never booted";
    case StartupFailure::kSdoTimeout:
      return "SDO timeout";
    case StartupFailure::kSdoAbort:
      return "SDO abort";
    case StartupFailure::kIdentityMismatch:
      return "identity mismatch";
    case StartupFailure::kNotOperational:
      return "not operational";
  }
  return "?";
}

Startup::Startup(const StartupConfig& config) noexcept : config_(config) {
  config_.node_count = std::clamp(config_.node_count, 0, kMaxNodes);
  for (NodeSetup& n : config_.nodes) n.write_count = std::clamp(n.write_count, 0, kMaxSetupWrites);
}

void Startup::begin(std::int64_t now) noexcept {
  stats_ = {};
  out_head_ = 0;
  out_size_ = 0;
  for (int i = 0; i < config_.node_count; ++i) {
    nodes_[at(i)] = {};
    nodes_[at(i)].deadline = now + config_.boot_timeout_ns;
  }
}

bool Startup::done() const noexcept {
  for (int i = 0; i < config_.node_count; ++i) {
    if (!is_done(nodes_[at(i)].progress.phase)) return false;
  }
  return true;
}

bool Startup::all_operational() const noexcept {
  for (int i = 0; i < config_.node_count; ++i) {
    if (nodes_[at(i)].progress.phase != StartupPhase::kOperational) return false;
  }
  return true;
}

bool Startup::next_frame(CanFrame& out) noexcept {
  if (out_size_ == 0) return false;
  out = outbox_[at(out_head_)];
  out_head_ = (out_head_ + 1) % kOutboxCapacity;
  --out_size_;
  return true;
}

void Startup::send(const CanFrame& frame) noexcept {
  if (out_size_ == kOutboxCapacity) {
    ++stats_.outbox_overflows;
    return;
  }
  outbox_[at((out_head_ + out_size_) % kOutboxCapacity)] = frame;
  ++out_size_;
}

void Startup::on_frame(const CanFrame& frame, std::int64_t now) noexcept {
  ++stats_.frames;
  const Decoded d = decode_frame(frame);
  const int i = index_of(d.node);
  if (i < 0) return;
  if (d.kind == FrameKind::kBootUp || d.kind == FrameKind::kHeartbeat) {
    on_booted(i, now, d.kind == FrameKind::kBootUp, d.heartbeat.state);
  } else if (d.kind == FrameKind::kSdo && !d.sdo.from_client) {
    on_sdo(i, d.sdo, now);
  }
}

void Startup::on_booted(int i, std::int64_t now, bool boot_up, NmtState state) noexcept {
  Node& n = nodes_[at(i)];
  const NodeId node = config_.nodes[at(i)].node;
  switch (n.progress.phase) {
    case StartupPhase::kFailed:
      return;
    case StartupPhase::kWaitBoot:
      // A node already running: back to pre-operational, where SDO works and
      // the PDO mapping may change.
      if (!boot_up && state != NmtState::kPreOperational) {
        send(encode_nmt(NmtCommand::kEnterPreOperational, node));
      }
      break;
    case StartupPhase::kWaitOperational:
      if (!boot_up) {
        if (state == NmtState::kOperational) n.progress.phase = StartupPhase::kOperational;
        return;
      }
      ++n.progress.reboots;
      break;
    default:
      if (!boot_up) return;
      ++n.progress.reboots;  // the node reset itself: its configuration is gone
      break;
  }
  n.progress.phase = StartupPhase::kReadIdentity;
  n.step = 0;
  n.attempts = 0;
  n.sdo_pending = false;
  request(i, now);
}

void Startup::on_sdo(int i, const SdoPayload& sdo, std::int64_t now) noexcept {
  Node& n = nodes_[at(i)];
  if (!n.sdo_pending || sdo.at != n.sdo_at) {
    ++stats_.unexpected_sdo;
    return;
  }
  if (sdo.kind == SdoKind::kAbort) {
    const bool optional_identity =
        !n.sdo_is_write && n.sdo_at.sub != identity_sub::kVendorId &&
        (sdo.abort_code == static_cast<std::uint32_t>(SdoAbort::kNoSubIndex));
    if (!optional_identity) {
      n.progress.abort_code = sdo.abort_code;
      n.progress.at = sdo.at;
      fail(i, StartupFailure::kSdoAbort);
      return;
    }
  } else if (sdo.kind == SdoKind::kUploadResponse && !n.sdo_is_write) {
    store_identity(n.progress.identity, sdo.at.sub, sdo.value);
  } else if (sdo.kind != SdoKind::kDownloadResponse || !n.sdo_is_write) {
    ++stats_.unexpected_sdo;
    return;
  }
  n.sdo_pending = false;
  ++n.step;
  n.attempts = 0;
  next_step(i, now);
}

void Startup::next_step(int i, std::int64_t now) noexcept {
  Node& n = nodes_[at(i)];
  const NodeSetup& setup = config_.nodes[at(i)];
  if (n.progress.phase == StartupPhase::kReadIdentity) {
    if (n.step < kIdentitySubs) return request(i, now);
    const Identity& id = n.progress.identity;
    if ((setup.expected_vendor_id != 0 && id.vendor_id != setup.expected_vendor_id) ||
        (setup.expected_product_code != 0 && id.product_code != setup.expected_product_code)) {
      n.progress.at = {od::kIdentity, 0};
      return fail(i, StartupFailure::kIdentityMismatch);
    }
    n.progress.phase = StartupPhase::kConfigure;
    n.step = 0;
  }
  if (n.step < setup.write_count) return request(i, now);
  start_node(i, now);
}

void Startup::request(int i, std::int64_t now) noexcept {
  Node& n = nodes_[at(i)];
  const NodeSetup& setup = config_.nodes[at(i)];
  n.sdo_pending = true;
  n.deadline = now + config_.sdo_timeout_ns;
  if (n.progress.phase == StartupPhase::kReadIdentity) {
    n.sdo_is_write = false;
    n.sdo_at = {od::kIdentity, static_cast<std::uint8_t>(n.step + 1)};
    send(encode_sdo_upload_request(setup.node, n.sdo_at));
    return;
  }
  const SdoWrite& w = setup.writes[at(n.step)];
  n.sdo_is_write = true;
  n.sdo_at = w.at;
  send(encode_sdo_download_request(setup.node, w.at, w.value, w.size));
}

void Startup::start_node(int i, std::int64_t now) noexcept {
  Node& n = nodes_[at(i)];
  const NodeSetup& setup = config_.nodes[at(i)];
  send(encode_nmt(NmtCommand::kStart, setup.node));
  if (!setup.wait_operational) {
    n.progress.phase = StartupPhase::kOperational;
    return;
  }
  n.progress.phase = StartupPhase::kWaitOperational;
  n.attempts = 0;
  n.deadline = now + config_.operational_timeout_ns;
}

void Startup::fail(int i, StartupFailure why) noexcept {
  Node& n = nodes_[at(i)];
  n.progress.phase = StartupPhase::kFailed;
  n.progress.failure = why;
  n.sdo_pending = false;
}

void Startup::advance(std::int64_t now) noexcept {
  for (int i = 0; i < config_.node_count; ++i) {
    const Node& n = nodes_[at(i)];
    if (!is_done(n.progress.phase) && now >= n.deadline) timeout(i, now);
  }
}

void Startup::timeout(int i, std::int64_t now) noexcept {
  Node& n = nodes_[at(i)];
  const NodeId node = config_.nodes[at(i)].node;
  switch (n.progress.phase) {
    case StartupPhase::kWaitBoot:
      if (n.attempts >= config_.boot_retries) return fail(i, StartupFailure::kNeverBooted);
      ++n.attempts;
      ++n.progress.boot_resets;
      send(encode_nmt(NmtCommand::kResetCommunication, node));
      n.deadline = now + config_.boot_timeout_ns;
      return;
    case StartupPhase::kReadIdentity:
    case StartupPhase::kConfigure:
      if (n.attempts >= config_.sdo_retries) {
        n.progress.at = n.sdo_at;
        return fail(i, StartupFailure::kSdoTimeout);
      }
      ++n.attempts;
      ++n.progress.sdo_retries;
      // CiA 301: the client aborts the transfer it gives up before a new one.
      send(encode_sdo_abort(node, n.sdo_at, static_cast<std::uint32_t>(SdoAbort::kTimeout), true));
      return request(i, now);
    case StartupPhase::kWaitOperational:
      if (n.attempts >= config_.start_retries) return fail(i, StartupFailure::kNotOperational);
      ++n.attempts;
      ++n.progress.start_retries;
      send(encode_nmt(NmtCommand::kStart, node));
      n.deadline = now + config_.operational_timeout_ns;
      return;
    default:
      return;
  }
}

int Startup::index_of(NodeId node) const noexcept {
  if (node == 0) return -1;
  for (int i = 0; i < config_.node_count; ++i) {
    if (config_.nodes[at(i)].node == node) return i;
  }
  return -1;
}

}  // namespace exodaq::drivers::canopen
