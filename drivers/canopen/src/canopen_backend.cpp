#include "exodaq/drivers/canopen/canopen_backend.hpp"

#include <cstdint>
#include <ios>
#include <set>
#include <sstream>
#include <string>

#include "exodaq/common/yaml_reader.hpp"

namespace exodaq::drivers::canopen {

namespace {

const std::string kSection = "source.canopen";

std::int64_t ranged(exodaq::MapReader& m, const std::string& key, const std::string& name,
                    std::int64_t fallback, std::int64_t lo, std::int64_t hi) {
  const std::int64_t v = m.integer_or(key, fallback);
  if (v < lo || v > hi) {
    m.fail_key(key, name + " must be " + std::to_string(lo) + ".." + std::to_string(hi));
  }
  return v;
}

std::string hex(std::uint32_t v) {
  std::ostringstream s;
  s << "0x" << std::hex << std::uppercase << v;
  return s.str();
}

CanopenJoint parse_joint(exodaq::MapReader& j, const std::string& name) {
  CanopenJoint out;
  if (!j.has("node")) j.fail(j.node(), name + ".node is required (1..127)");
  out.node = static_cast<NodeId>(ranged(j, "node", name + ".node", 1, kMinNodeId, kMaxNodeId));
  const std::string reference = j.choice_or("reference", {"absolute", "index"}, "absolute");
  out.reference = reference == "index" ? ReferenceKind::kIndex : ReferenceKind::kAbsolute;
  const int pdo = static_cast<int>(ranged(j, "pdo", name + ".pdo", 1, 1, kTpdoCount));
  const auto cob_id = static_cast<std::uint32_t>(
      ranged(j, "cob_id", name + ".cob_id", cob::tpdo(pdo, out.node), 1, cob::kIdMask));
  const auto object =
      static_cast<std::uint16_t>(ranged(j, "object", name + ".object", 0x6004, 1, 0xFFFF));
  const auto sub =
      static_cast<std::uint8_t>(ranged(j, "sub_index", name + ".sub_index", 0, 0, 0xFF));
  const auto bits = static_cast<std::uint8_t>(ranged(j, "bits", name + ".bits", 32, 16, 32));
  if (bits % 8 != 0) j.fail_key("bits", name + ".bits must be 16, 24 or 32");
  out.total_range = static_cast<std::uint32_t>(
      ranged(j, "total_range", name + ".total_range", 0, 0, std::int64_t{1} << bits));
  if (out.total_range == (std::uint64_t{1} << bits)) out.total_range = 0;  // the full width
  out.tpdo = TpdoSetup{};
  out.tpdo.pdo = pdo;
  out.tpdo.cob_id = cob_id;
  out.tpdo.transmission_type = transmission::kEverySync;
  out.tpdo.mapping.add({object, sub, bits});
  out.values.position = {object, sub};
  if (j.has("reference_object")) {
    const auto ref_object = static_cast<std::uint16_t>(
        ranged(j, "reference_object", name + ".reference_object", 0, 1, 0xFFFF));
    const auto ref_sub = static_cast<std::uint8_t>(
        ranged(j, "reference_sub_index", name + ".reference_sub_index", 0, 0, 0xFF));
    if (ref_object == object && ref_sub == sub) {
      j.fail_key("reference_object", name + ".reference_object must differ from its object");
    }
    out.tpdo.mapping.add({ref_object, ref_sub, bits});
    out.values.has_reference = true;
    out.values.reference = {ref_object, ref_sub};
  } else if (j.has("reference_sub_index")) {
    j.fail_key("reference_sub_index", name + ".reference_sub_index needs reference_object");
  }
  if (out.reference == ReferenceKind::kIndex && !out.values.has_reference) {
    j.fail_key("reference", name +
                                ".reference: index needs reference_object (the module's latched "
                                "reference position, mapped into the TPDO)");
  }
  if (out.reference == ReferenceKind::kAbsolute && out.values.has_reference) {
    j.fail_key("reference_object", name + ".reference_object needs reference: index");
  }
  out.vendor_id =
      static_cast<std::uint32_t>(ranged(j, "vendor_id", name + ".vendor_id", 0, 0, 0xFFFFFFFF));
  out.product_code = static_cast<std::uint32_t>(
      ranged(j, "product_code", name + ".product_code", 0, 0, 0xFFFFFFFF));
  out.configure = j.boolean_or("configure", true);
  j.finish();
  return out;
}

void parse_joints(exodaq::MapReader& s, CanopenSourceConfig& out) {
  const YAML::Node joints = s.child("joints");
  const std::string count = std::to_string(kChannelCount);
  if (!joints.IsSequence() || joints.size() != static_cast<std::size_t>(kChannelCount)) {
    s.fail(joints, kSection + ".joints must be a list of " + count +
                       " joints (one per channel, in channel order)" +
                       (joints.IsSequence() ? ", has " + std::to_string(joints.size()) : ""));
  }
  out.joint_count = kChannelCount;
  std::set<int> nodes;
  for (int i = 0; i < kChannelCount; ++i) {
    const std::string name = kSection + ".joints[" + std::to_string(i) + "]";
    exodaq::MapReader j(s.file(), joints[static_cast<std::size_t>(i)], name);
    const CanopenJoint joint = parse_joint(j, name);
    if (!nodes.insert(joint.node).second) {
      j.fail_key("node", name + ".node " + std::to_string(joint.node) +
                             " is another joint's: node ids must be unique");
    }
    out.joints[static_cast<std::size_t>(i)] = joint;
  }
  int joint = -1;
  if (const char* why = validate(out, joint)) {
    if (joint >= 0) {
      s.fail(joints[static_cast<std::size_t>(joint)],
             kSection + ".joints[" + std::to_string(joint) + "]: " + why);
    }
    s.fail(joints, kSection + ": " + why);
  }
}

void parse_limits(exodaq::MapReader& s, CanopenSourceConfig& out) {
  out.rcvbuf_bytes = static_cast<int>(s.integer_or("rcvbuf_bytes", out.rcvbuf_bytes));
  if (out.rcvbuf_bytes < 4096)
    s.fail_key("rcvbuf_bytes", kSection + ".rcvbuf_bytes must be >= 4096");
  // The wait ends at nine tenths of the period whatever this says
  // (CanopenSource::poll_deadline, the replay's window): up to 90 ms, nine
  // tenths of the longest period (loop.rate_hz >= 10), so that a slower loop
  // (the VM test under emulation: docs/can-protocol.md) may wait longer.
  const double deadline_us = s.number_or("read_deadline_us", 400.0);
  if (deadline_us <= 0.0 || deadline_us > 90'000.0) {
    s.fail_key("read_deadline_us", kSection + ".read_deadline_us must be in (0, 90000]");
  }
  out.read_deadline_ns = static_cast<std::int64_t>(deadline_us * 1000.0);
  const double reopen_ms = s.number_or("reopen_interval_ms", 1000.0);
  if (reopen_ms < 10.0 || reopen_ms > 60'000.0) {
    s.fail_key("reopen_interval_ms", kSection + ".reopen_interval_ms must be between 10 and 60000");
  }
  out.reopen_interval_ns = static_cast<std::int64_t>(reopen_ms * 1e6);
  out.boot_timeout_ns =
      ranged(s, "boot_timeout_ms", kSection + ".boot_timeout_ms", 1000, 10, 60'000) * 1'000'000;
  const std::int64_t heartbeat_ms = s.integer_or("heartbeat_timeout_ms", 150);
  if (heartbeat_ms != 0 && (heartbeat_ms < 10 || heartbeat_ms > 60'000)) {
    s.fail_key("heartbeat_timeout_ms",
               kSection + ".heartbeat_timeout_ms must be 0 (not monitored) or 10..60000");
  }
  out.heartbeat_timeout_ns = heartbeat_ms * 1'000'000;
}

std::shared_ptr<const BackendSettings> parse_canopen(exodaq::MapReader* s, exodaq::MapReader& src,
                                                     bool selected) {
  auto out = std::make_shared<CanopenSettings>();
  if (s == nullptr) {
    if (selected) {
      src.fail_key("backend", "source.backend canopen needs " + kSection +
                                  " with its joints (one CANopen node per channel)");
    }
    return out;
  }
  CanopenSourceConfig& c = out->config;
  c.interface = s->string_or("interface", c.interface);
  if (c.interface.empty() || c.interface.size() > 15) {
    s->fail_key("interface",
                kSection + ".interface must be a network interface name (1-15 characters)");
  }
  const std::string sync = s->choice_or("sync", {"producer", "consumer"}, "producer");
  c.sync = sync == "consumer" ? SyncRole::kConsumer : SyncRole::kProducer;
  const std::int64_t overflow = s->integer_or("sync_overflow", 0);
  if (!is_sync_overflow(static_cast<int>(overflow)) || overflow < 0 || overflow > 240) {
    s->fail_key("sync_overflow", kSection + ".sync_overflow must be 0 or 2..240");
  }
  c.sync_overflow = static_cast<std::uint8_t>(overflow);
  parse_limits(*s, c);
  parse_joints(*s, c);
  s->finish();
  return out;
}

std::unique_ptr<EncoderSource> make_canopen(const BackendSettings& settings,
                                            const SourceContext& /*context*/) {
  const CanopenSourceConfig& config = dynamic_cast<const CanopenSettings&>(settings).config;
  return std::make_unique<CanopenSource>(config, make_socketcan_port(port_config(config)));
}

// A candump log of the bus: needs the section (the nodes and their objects).
std::unique_ptr<FrameAssembler> canopen_assembler(const BackendSettings* settings,
                                                  const SourceContext& context) {
  const auto* s = dynamic_cast<const CanopenSettings*>(settings);
  return s != nullptr ? make_frame_assembler(s->config, context.period_ns) : nullptr;
}

}  // namespace

std::string CanopenSettings::describe() const {
  const CanopenSourceConfig& c = config;
  std::ostringstream s;
  s << "{interface: " << c.interface << ", sync: "
    << (c.sync == SyncRole::kConsumer ? "consumer" : "producer")
    << ", sync_overflow: " << static_cast<int>(c.sync_overflow)
    << ", read_deadline_us: " << c.read_deadline_ns / 1000.0
    << ", reopen_interval_ms: " << c.reopen_interval_ns / 1e6
    << ", rcvbuf_bytes: " << c.rcvbuf_bytes
    << ", boot_timeout_ms: " << c.boot_timeout_ns / 1'000'000
    << ", heartbeat_timeout_ms: " << c.heartbeat_timeout_ns / 1'000'000 << ", joints: [";
  for (int i = 0; i < c.joint_count; ++i) {
    const CanopenJoint& j = c.joints[static_cast<std::size_t>(i)];
    const MappedObject& position = j.tpdo.mapping.entries[0];
    s << (i > 0 ? ", " : "") << "{node: " << static_cast<int>(j.node)
      << ", reference: " << (j.reference == ReferenceKind::kIndex ? "index" : "absolute")
      << ", pdo: " << j.tpdo.pdo << ", cob_id: " << hex(tpdo_cob_id(j.node, j.tpdo))
      << ", object: " << hex(position.index) << ", sub_index: " << static_cast<int>(position.sub)
      << ", bits: " << static_cast<int>(position.bits) << ", total_range: " << j.total_range;
    if (j.values.has_reference) {
      s << ", reference_object: " << hex(j.values.reference.index)
        << ", reference_sub_index: " << static_cast<int>(j.values.reference.sub);
    }
    s << ", vendor_id: " << hex(j.vendor_id) << ", product_code: " << hex(j.product_code)
      << ", configure: " << (j.configure ? "true" : "false") << "}";
  }
  s << "]}";
  return s.str();
}

const Backend& canopen_backend() {
  static const Backend b{"canopen", parse_canopen, make_canopen, canopen_assembler};
  return b;
}

}  // namespace exodaq::drivers::canopen
