#include "exodaq/drivers/canopen/cia406.hpp"

namespace exodaq::drivers::canopen {
namespace {

LayoutResult failed(MappingError error, int entry = -1) noexcept {
  LayoutResult r;
  r.error = error;
  r.entry = entry;
  return r;
}

bool supported_value_width(int bytes) noexcept {
  return bytes >= 2 && bytes <= 4;
}

std::uint32_t read_le(const CanFrame& f, std::uint8_t offset, std::uint8_t bytes) noexcept {
  std::uint32_t v = 0;
  for (std::uint8_t i = 0; i < bytes; ++i) {
    v |= static_cast<std::uint32_t>(f.data[static_cast<std::size_t>(offset + i)]) << (8 * i);
  }
  return v;
}

}  // namespace

std::string_view to_string(MappingError error) noexcept {
  switch (error) {
    case MappingError::kNone:
      return "none";
    case MappingError::kEmpty:
      return "no object mapped";
    case MappingError::kTooManyObjects:
      return "more than 8 mapped objects";
    case MappingError::kZeroLength:
      return "mapped object of length 0";
    case MappingError::kUnalignedLength:
      return "mapped object length not a whole number of bytes";
    case MappingError::kTooLong:
      return "mapped objects exceed 64 bits";
    case MappingError::kBadObject:
      return "mapped object index 0x0000";
    case MappingError::kPositionNotMapped:
      return "position object not mapped";
    case MappingError::kPositionMappedTwice:
      return "position object mapped twice";
    case MappingError::kPositionWidth:
      return "position object not 16, 24 or 32 bits";
    case MappingError::kReferenceNotMapped:
      return "reference object not mapped";
    case MappingError::kReferenceMappedTwice:
      return "reference object mapped twice";
    case MappingError::kReferenceWidth:
      return "reference object width differs from the position's";
    case MappingError::kReferenceIsPosition:
      return "reference object is the position object";
  }
  return "?";
}

LayoutResult resolve_layout(const TpdoMapping& mapping, const ValueObjects& values) noexcept {
  if (mapping.count < 0 || mapping.count > kMaxMappedObjects) {
    return failed(MappingError::kTooManyObjects);
  }
  if (mapping.count == 0) return failed(MappingError::kEmpty);
  if (values.has_reference && values.reference == values.position) {
    return failed(MappingError::kReferenceIsPosition);
  }
  LayoutResult r;
  int bits = 0;
  bool position_seen = false;
  for (int i = 0; i < mapping.count; ++i) {
    const MappedObject& m = mapping.entries[static_cast<std::size_t>(i)];
    if (m.index == 0) return failed(MappingError::kBadObject, i);
    if (m.bits == 0) return failed(MappingError::kZeroLength, i);
    if (m.bits % 8 != 0) return failed(MappingError::kUnalignedLength, i);
    if (bits + m.bits > kMaxPdoBits) return failed(MappingError::kTooLong, i);
    const auto offset = static_cast<std::uint8_t>(bits / 8);
    const auto bytes = static_cast<std::uint8_t>(m.bits / 8);
    bits += m.bits;
    if (m.at() == values.position) {
      if (position_seen) return failed(MappingError::kPositionMappedTwice, i);
      if (!supported_value_width(bytes)) return failed(MappingError::kPositionWidth, i);
      position_seen = true;
      r.layout.position_offset = offset;
      r.layout.position_bytes = bytes;
    } else if (values.has_reference && m.at() == values.reference) {
      if (r.layout.has_reference) return failed(MappingError::kReferenceMappedTwice, i);
      r.layout.has_reference = true;
      r.layout.reference_offset = offset;
      r.layout.reference_bytes = bytes;
      r.entry = i;  // checked against the position's width below
    }
  }
  if (!position_seen) return failed(MappingError::kPositionNotMapped);
  if (values.has_reference && !r.layout.has_reference) {
    return failed(MappingError::kReferenceNotMapped);
  }
  if (r.layout.has_reference && r.layout.reference_bytes != r.layout.position_bytes) {
    return failed(MappingError::kReferenceWidth, r.entry);
  }
  r.layout.length = static_cast<std::uint8_t>(bits / 8);
  r.entry = -1;
  return r;
}

bool unpack(const PdoLayout& layout, const CanFrame& frame, PdoValues& out) noexcept {
  if (frame.dlc != layout.length) return false;
  out.position = read_le(frame, layout.position_offset, layout.position_bytes);
  out.reference =
      layout.has_reference ? read_le(frame, layout.reference_offset, layout.reference_bytes) : 0;
  return true;
}

const char* validate_resolution(const PdoLayout& layout, std::uint32_t units_per_revolution,
                                std::uint32_t total_range) noexcept {
  const std::uint64_t full = std::uint64_t{1} << (8 * layout.position_bytes);
  if (total_range > full) return "total measuring range does not fit the position's width";
  if (units_per_revolution > full) {
    return "measuring units per revolution do not fit the position's width";
  }
  const std::uint64_t range = total_range != 0 ? total_range : full;
  if (units_per_revolution != 0 && range % units_per_revolution != 0) {
    return "total measuring range is not a whole number of revolutions";
  }
  return nullptr;
}

int tpdo_setup_writes(NodeId node, const TpdoSetup& setup,
                      std::array<SdoWrite, kMaxPdoWrites>& out) noexcept {
  const std::uint16_t comm = od::tpdo_communication(setup.pdo);
  const std::uint16_t map = od::tpdo_mapping(setup.pdo);
  const std::uint32_t cob_id = tpdo_cob_id(node, setup);
  int n = 0;
  auto put = [&](SdoWrite w) { out[static_cast<std::size_t>(n++)] = w; };
  put({{comm, tpdo_comm_sub::kCobId}, cob_id | pdo_cob_id::kInvalid, 4});
  put({{map, 0}, 0, 1});
  for (int i = 0; i < setup.mapping.count; ++i) {
    const MappedObject& m = setup.mapping.entries[static_cast<std::size_t>(i)];
    put({{map, static_cast<std::uint8_t>(i + 1)}, encode_mapping_entry(m), 4});
  }
  put({{map, 0}, static_cast<std::uint32_t>(setup.mapping.count), 1});
  put({{comm, tpdo_comm_sub::kTransmissionType}, setup.transmission_type, 1});
  if (setup.sync_start != 0) put({{comm, tpdo_comm_sub::kSyncStart}, setup.sync_start, 1});
  put({{comm, tpdo_comm_sub::kCobId}, cob_id, 4});
  return n;
}

}  // namespace exodaq::drivers::canopen
