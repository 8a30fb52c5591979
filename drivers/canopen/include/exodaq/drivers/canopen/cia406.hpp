#pragma once
// The object dictionary entries a CANopen encoder (CiA 406) and its PDOs are
// configured and read through (CiA 301 communication objects 0x1000..0x1A03,
// CiA 406 objects 0x6000..0x6004), the TPDO mapping description, its
// validation, and unpacking a TPDO into position and latched reference.
//
// Pure functions on plain values: no I/O, no allocation.
#include <array>
#include <cstdint>
#include <string_view>

#include "exodaq/drivers/canopen/cia301.hpp"

namespace exodaq::drivers::canopen {

// ---------------------------------------------------------------------------
// Object indices
// ---------------------------------------------------------------------------

namespace od {
inline constexpr std::uint16_t kDeviceType = 0x1000;                // UNSIGNED32, ro
inline constexpr std::uint16_t kErrorRegister = 0x1001;             // UNSIGNED8, ro
inline constexpr std::uint16_t kCobIdSync = 0x1005;                 // UNSIGNED32, bit 30: producer
inline constexpr std::uint16_t kCommunicationCyclePeriod = 0x1006;  // UNSIGNED32, µs
inline constexpr std::uint16_t kConsumerHeartbeatTime = 0x1016;     // ARRAY of UNSIGNED32
inline constexpr std::uint16_t kProducerHeartbeatTime = 0x1017;     // UNSIGNED16, ms (0: off)
inline constexpr std::uint16_t kIdentity = 0x1018;                  // RECORD, subs 1..4
inline constexpr std::uint16_t kSyncCounterOverflow = 0x1019;       // UNSIGNED8 (cia301.hpp)
inline constexpr std::uint16_t kTpdoCommunication = 0x1800;         // + pdo - 1
inline constexpr std::uint16_t kTpdoMapping = 0x1A00;               // + pdo - 1
// CiA 406 (encoders)
inline constexpr std::uint16_t kOperatingParameters = 0x6000;          // UNSIGNED16
inline constexpr std::uint16_t kMeasuringUnitsPerRevolution = 0x6001;  // UNSIGNED32
inline constexpr std::uint16_t kTotalMeasuringRange = 0x6002;          // UNSIGNED32
inline constexpr std::uint16_t kPresetValue = 0x6003;                  // 32 bit
inline constexpr std::uint16_t kPositionValue = 0x6004;                // 32 bit, ro, mappable

constexpr std::uint16_t tpdo_communication(int pdo) noexcept {
  return static_cast<std::uint16_t>(kTpdoCommunication + pdo - 1);
}
constexpr std::uint16_t tpdo_mapping(int pdo) noexcept {
  return static_cast<std::uint16_t>(kTpdoMapping + pdo - 1);
}
}  // namespace od

// 0x1000: low 16 bits the device profile number, high 16 bits profile-specific.
inline constexpr std::uint16_t kEncoderProfile = 406;
constexpr std::uint16_t device_profile(std::uint32_t device_type) noexcept {
  return static_cast<std::uint16_t>(device_type & 0xFFFF);
}

// 0x1018 identity object.
namespace identity_sub {
inline constexpr std::uint8_t kVendorId = 1;
inline constexpr std::uint8_t kProductCode = 2;
inline constexpr std::uint8_t kRevision = 3;
inline constexpr std::uint8_t kSerialNumber = 4;
}  // namespace identity_sub

struct Identity {
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision = 0;
  std::uint32_t serial_number = 0;
  friend constexpr bool operator==(const Identity&, const Identity&) = default;
};

// 0x1800 + n: TPDO communication parameter sub-indices.
namespace tpdo_comm_sub {
inline constexpr std::uint8_t kHighestSub = 0;
inline constexpr std::uint8_t kCobId = 1;
inline constexpr std::uint8_t kTransmissionType = 2;
inline constexpr std::uint8_t kInhibitTime = 3;  // 100 µs
inline constexpr std::uint8_t kEventTimer = 5;   // ms
inline constexpr std::uint8_t kSyncStart = 6;    // 0: not used, else the SYNC counter to start on
}  // namespace tpdo_comm_sub

// Bits of a PDO's COB-ID entry (sub 1).
namespace pdo_cob_id {
inline constexpr std::uint32_t kInvalid = 1U << 31;   // PDO does not exist / is disabled
inline constexpr std::uint32_t kNoRtr = 1U << 30;     // no RTR allowed on this PDO
inline constexpr std::uint32_t kExtended = 1U << 29;  // 29-bit identifier
}  // namespace pdo_cob_id

// Transmission type (sub 2).
namespace transmission {
inline constexpr std::uint8_t kSynchronousAcyclic = 0;
inline constexpr std::uint8_t kEverySync = 1;
inline constexpr std::uint8_t kSynchronousMax = 240;  // 1..240: every n-th SYNC
inline constexpr std::uint8_t kRtrSynchronous = 252;
inline constexpr std::uint8_t kRtrEvent = 253;
inline constexpr std::uint8_t kEventManufacturer = 254;
inline constexpr std::uint8_t kEventProfile = 255;
constexpr bool is_cyclic(int type) noexcept {
  return type >= 1 && type <= kSynchronousMax;
}
// 241..251 are reserved.
constexpr bool is_valid(int type) noexcept {
  return type >= 0 && type <= 255 && !(type > kSynchronousMax && type < kRtrSynchronous);
}
}  // namespace transmission

// 0x6000 operating parameters (UNSIGNED16).
namespace operating_parameter {
inline constexpr std::uint16_t kCodeSequenceCcw = 1U << 0;  // 0: increasing clockwise
inline constexpr std::uint16_t kCommissioningDiagnostic = 1U << 1;
inline constexpr std::uint16_t kScaling = 1U << 2;  // 0x6001/0x6002 apply
inline constexpr std::uint16_t kMeasuringDirection = 1U << 3;
}  // namespace operating_parameter

// 0x1016 sub n: bits 23..16 the producer's node id, 15..0 its time in ms.
constexpr std::uint32_t consumer_heartbeat_entry(NodeId node, std::uint16_t ms) noexcept {
  return (static_cast<std::uint32_t>(node) << 16) | ms;
}

// ---------------------------------------------------------------------------
// PDO mapping
// ---------------------------------------------------------------------------

// One mapping entry (0x1A00 + n, sub 1..): bits 31..16 index, 15..8 sub-index,
// 7..0 length in bits.
struct MappedObject {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint8_t bits = 0;
  constexpr Multiplexer at() const noexcept { return {index, sub}; }
  friend constexpr bool operator==(const MappedObject&, const MappedObject&) = default;
};

constexpr std::uint32_t encode_mapping_entry(MappedObject m) noexcept {
  return (static_cast<std::uint32_t>(m.index) << 16) | (static_cast<std::uint32_t>(m.sub) << 8) |
         m.bits;
}
constexpr MappedObject decode_mapping_entry(std::uint32_t v) noexcept {
  return {static_cast<std::uint16_t>(v >> 16), static_cast<std::uint8_t>((v >> 8) & 0xFF),
          static_cast<std::uint8_t>(v & 0xFF)};
}

inline constexpr int kMaxPdoBits = 64;
// Byte-aligned entries of at least 8 bits: at most 8 fit in a classic CAN PDO.
inline constexpr int kMaxMappedObjects = 8;

// The objects of one TPDO, in transmission order (first entry in byte 0).
struct TpdoMapping {
  std::array<MappedObject, kMaxMappedObjects> entries{};
  int count = 0;

  constexpr bool add(MappedObject m) noexcept {
    if (count >= kMaxMappedObjects) return false;
    entries[static_cast<std::size_t>(count++)] = m;
    return true;
  }
  friend constexpr bool operator==(const TpdoMapping&, const TpdoMapping&) = default;
};

// 0x6004 sub 0, 32 bits: the standard CiA 406 position.
inline constexpr MappedObject kPositionValue32{od::kPositionValue, 0, 32};

// Which mapped objects the assembler reads: the position (0x6004 by default;
// an encoder-interface module's channel object otherwise) and, optionally,
// the position latched at the reference mark.
struct ValueObjects {
  Multiplexer position{od::kPositionValue, 0};
  bool has_reference = false;
  Multiplexer reference{};
};

enum class MappingError : std::uint8_t {
  kNone = 0,
  kEmpty,                 // no object mapped
  kTooManyObjects,        // count outside 0..8
  kZeroLength,            // an entry of 0 bits
  kUnalignedLength,       // an entry whose length is not a whole number of bytes
  kTooLong,               // over 64 bits in total
  kBadObject,             // index 0x0000
  kPositionNotMapped,     // the position object is not in the mapping
  kPositionMappedTwice,   // the position object appears twice
  kPositionWidth,         // the position is not 16, 24 or 32 bits
  kReferenceNotMapped,    // a reference is configured but not mapped
  kReferenceMappedTwice,  // the reference object appears twice
  kReferenceWidth,        // the reference's width differs from the position's
  kReferenceIsPosition,   // the reference object is the position object
};
std::string_view to_string(MappingError error) noexcept;

// Where the values sit in a TPDO of this mapping (byte offsets).
struct PdoLayout {
  std::uint8_t length = 0;  // bytes the TPDO carries (its DLC)
  std::uint8_t position_offset = 0;
  std::uint8_t position_bytes = 0;
  bool has_reference = false;
  std::uint8_t reference_offset = 0;
  std::uint8_t reference_bytes = 0;
};

struct LayoutResult {
  PdoLayout layout{};
  MappingError error = MappingError::kNone;
  int entry = -1;  // the offending entry (0-based), -1 when none or not entry-specific
};

// Validates `mapping` for reading `values` and locates them.
LayoutResult resolve_layout(const TpdoMapping& mapping, const ValueObjects& values) noexcept;

struct PdoValues {
  std::uint32_t position = 0;
  std::uint32_t reference = 0;  // 0 unless the layout has a reference
};

// false (values untouched) when the frame's DLC is not the layout's length.
bool unpack(const PdoLayout& layout, const CanFrame& frame, PdoValues& out) noexcept;

// The payload of a TPDO with this mapping: each entry's value, little-endian,
// truncated to its length. `value_of(entry)` gives an entry's value.
template <typename ValueOf>
std::array<std::uint8_t, 8> pack(const TpdoMapping& mapping, ValueOf&& value_of,
                                 std::uint8_t& length) noexcept {
  std::array<std::uint8_t, 8> data{};
  std::size_t at = 0;
  for (int i = 0; i < mapping.count; ++i) {
    const MappedObject& m = mapping.entries[static_cast<std::size_t>(i)];
    const std::uint32_t v = value_of(m);
    for (int b = 0; b < m.bits / 8 && at < data.size(); ++b) {
      data[at++] = static_cast<std::uint8_t>(v >> (8 * b));
    }
  }
  length = static_cast<std::uint8_t>(at);
  return data;
}

// ---------------------------------------------------------------------------
// Resolution
// ---------------------------------------------------------------------------

// The count a position value wraps at: the total measuring range (0x6002)
// when set, else 2^(8 × position_bytes).
constexpr std::uint64_t position_modulus(const PdoLayout& layout,
                                         std::uint32_t total_range) noexcept {
  const std::uint64_t full = std::uint64_t{1} << (8 * layout.position_bytes);
  return total_range != 0 ? total_range : full;
}

// nullptr when `total_range` (0: the full width) fits the position's width
// and `units_per_revolution` (0: not configured) divides into it; otherwise a
// static message saying what is wrong.
const char* validate_resolution(const PdoLayout& layout, std::uint32_t units_per_revolution,
                                std::uint32_t total_range) noexcept;

// ---------------------------------------------------------------------------
// Configuration by SDO
// ---------------------------------------------------------------------------

// One expedited SDO download.
struct SdoWrite {
  Multiplexer at{};
  std::uint32_t value = 0;
  std::uint8_t size = 4;  // bytes 1..4
  friend constexpr bool operator==(const SdoWrite&, const SdoWrite&) = default;
};

// A TPDO's configuration as the manager writes it.
struct TpdoSetup {
  int pdo = 1;               // 1..4
  std::uint32_t cob_id = 0;  // 0: the predefined 0x180/0x280/... + node
  std::uint8_t transmission_type = transmission::kEverySync;
  std::uint8_t sync_start = 0;  // 0: not used
  TpdoMapping mapping{};
};

// CiA 301's sequence to (re)map a TPDO: disable it (COB-ID bit 31), clear the
// mapping count, write the entries, set the count, the transmission type and
// the SYNC start value, enable it. Returns the number of writes put into
// `out` (at most kMaxPdoWrites).
inline constexpr int kMaxPdoWrites = kMaxMappedObjects + 6;
int tpdo_setup_writes(NodeId node, const TpdoSetup& setup,
                      std::array<SdoWrite, kMaxPdoWrites>& out) noexcept;

// TPDO `pdo` carrying 0x6004 (32 bits) on every SYNC.
constexpr TpdoSetup position_tpdo(int pdo = 1) noexcept {
  TpdoSetup s;
  s.pdo = pdo;
  s.mapping.add(kPositionValue32);
  return s;
}

// The COB-ID a TPDO uses: setup.cob_id, or the predefined one.
constexpr std::uint32_t tpdo_cob_id(NodeId node, const TpdoSetup& setup) noexcept {
  return setup.cob_id != 0 ? setup.cob_id : cob::tpdo(setup.pdo, node);
}

}  // namespace exodaq::drivers::canopen
