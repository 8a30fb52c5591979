// CiA 406 objects and TPDO mappings: entry encoding, layout resolution and
// its rejections, unpacking, the remapping sequence.
#include <gtest/gtest.h>

#include <array>
#include <cstdint>

#include "exodaq/drivers/canopen/cia406.hpp"

namespace exodaq::drivers::canopen {
namespace {

constexpr Multiplexer kReference{0x2100, 1};
constexpr MappedObject kReference32{0x2100, 1, 32};
constexpr MappedObject kStatus8{0x2101, 0, 8};

TpdoMapping mapping_of(std::initializer_list<MappedObject> entries) {
  TpdoMapping m;
  for (const MappedObject& e : entries) EXPECT_TRUE(m.add(e));
  return m;
}

ValueObjects with_reference() {
  ValueObjects v;
  v.has_reference = true;
  v.reference = kReference;
  return v;
}

TEST(Cia406, ObjectNumbers) {
  EXPECT_EQ(od::kOperatingParameters, 0x6000);
  EXPECT_EQ(od::kMeasuringUnitsPerRevolution, 0x6001);
  EXPECT_EQ(od::kTotalMeasuringRange, 0x6002);
  EXPECT_EQ(od::kPositionValue, 0x6004);
  EXPECT_EQ(od::kIdentity, 0x1018);
  EXPECT_EQ(od::kProducerHeartbeatTime, 0x1017);
  EXPECT_EQ(od::kConsumerHeartbeatTime, 0x1016);
  EXPECT_EQ(od::tpdo_communication(1), 0x1800);
  EXPECT_EQ(od::tpdo_communication(4), 0x1803);
  EXPECT_EQ(od::tpdo_mapping(1), 0x1A00);
  EXPECT_EQ(od::tpdo_mapping(4), 0x1A03);
  EXPECT_EQ(device_profile(0x00020196), kEncoderProfile);
  EXPECT_EQ(consumer_heartbeat_entry(5, 150), 0x00050096U);
}

TEST(Cia406, TransmissionTypes) {
  EXPECT_TRUE(transmission::is_cyclic(1));
  EXPECT_TRUE(transmission::is_cyclic(240));
  EXPECT_FALSE(transmission::is_cyclic(0));
  EXPECT_FALSE(transmission::is_cyclic(254));
  EXPECT_TRUE(transmission::is_valid(0));
  EXPECT_FALSE(transmission::is_valid(241));
  EXPECT_FALSE(transmission::is_valid(251));
  EXPECT_TRUE(transmission::is_valid(252));
  EXPECT_TRUE(transmission::is_valid(255));
}

TEST(Cia406, MappingEntryLayout) {
  // 0x6004 sub 0, 32 bits: index in bits 31..16, sub-index 15..8, length 7..0.
  EXPECT_EQ(encode_mapping_entry(kPositionValue32), 0x60040020U);
  EXPECT_EQ(encode_mapping_entry({0x2100, 1, 16}), 0x21000110U);
  EXPECT_EQ(decode_mapping_entry(0x21000110U), (MappedObject{0x2100, 1, 16}));
}

TEST(Cia406, PositionOnlyLayout) {
  const LayoutResult r = resolve_layout(position_tpdo().mapping, {});
  ASSERT_EQ(r.error, MappingError::kNone);
  EXPECT_EQ(r.layout.length, 4);
  EXPECT_EQ(r.layout.position_offset, 0);
  EXPECT_EQ(r.layout.position_bytes, 4);
  EXPECT_FALSE(r.layout.has_reference);
}

TEST(Cia406, ReferenceBeforePositionIsLocatedByOffset) {
  const LayoutResult r =
      resolve_layout(mapping_of({kReference32, kPositionValue32}), with_reference());
  ASSERT_EQ(r.error, MappingError::kNone);
  EXPECT_EQ(r.layout.length, 8);
  EXPECT_EQ(r.layout.reference_offset, 0);
  EXPECT_EQ(r.layout.position_offset, 4);
  EXPECT_TRUE(r.layout.has_reference);
}

TEST(Cia406, UnpacksLittleEndianValuesAtTheirOffsets) {
  const TpdoMapping m = mapping_of({kStatus8, {od::kPositionValue, 0, 16}, {0x2100, 1, 16}});
  const LayoutResult layout = resolve_layout(m, with_reference());
  ASSERT_EQ(layout.error, MappingError::kNone);
  EXPECT_EQ(layout.layout.length, 5);
  EXPECT_EQ(layout.layout.position_offset, 1);
  EXPECT_EQ(layout.layout.reference_offset, 3);
  CanFrame f;
  f.dlc = 5;
  f.data = {0xEE, 0x34, 0x12, 0x78, 0x56, 0, 0, 0};
  PdoValues values;
  ASSERT_TRUE(unpack(layout.layout, f, values));
  EXPECT_EQ(values.position, 0x1234U);
  EXPECT_EQ(values.reference, 0x5678U);
  f.dlc = 4;
  values = {};
  EXPECT_FALSE(unpack(layout.layout, f, values));
  EXPECT_EQ(values.position, 0U);
}

TEST(Cia406, PackIsTheInverseOfUnpack) {
  const TpdoMapping m = mapping_of({kPositionValue32, kReference32});
  std::uint8_t length = 0;
  const auto data = pack(
      m,
      [](const MappedObject& o) {
        return o.index == od::kPositionValue ? 0x01020304U : 0xA0B0C0D0U;
      },
      length);
  EXPECT_EQ(length, 8);
  EXPECT_EQ(data, (std::array<std::uint8_t, 8>{0x04, 0x03, 0x02, 0x01, 0xD0, 0xC0, 0xB0, 0xA0}));
  const LayoutResult r = resolve_layout(m, with_reference());
  ASSERT_EQ(r.error, MappingError::kNone);
  CanFrame f;
  f.dlc = length;
  f.data = data;
  PdoValues v;
  ASSERT_TRUE(unpack(r.layout, f, v));
  EXPECT_EQ(v.position, 0x01020304U);
  EXPECT_EQ(v.reference, 0xA0B0C0D0U);
}

struct BadMapping {
  const char* name;
  TpdoMapping mapping;
  ValueObjects values;
  MappingError error;
  int entry;
};

TEST(Cia406, RejectsImpossibleMappings) {
  TpdoMapping too_many;
  too_many.count = 9;
  const BadMapping cases[] = {
      {"empty", {}, {}, MappingError::kEmpty, -1},
      {"count 9", too_many, {}, MappingError::kTooManyObjects, -1},
      {"zero length",
       mapping_of({kPositionValue32, {0x2101, 0, 0}}),
       {},
       MappingError::kZeroLength,
       1},
      {"12 bits",
       mapping_of({{0x2101, 0, 12}, kPositionValue32}),
       {},
       MappingError::kUnalignedLength,
       0},
      {"position 31 bits",
       mapping_of({{od::kPositionValue, 0, 31}}),
       {},
       MappingError::kUnalignedLength,
       0},
      {"72 bits", mapping_of({kPositionValue32, kReference32, kStatus8}), with_reference(),
       MappingError::kTooLong, 2},
      {"index 0", mapping_of({kPositionValue32, {0, 0, 8}}), {}, MappingError::kBadObject, 1},
      {"no position", mapping_of({kReference32}), {}, MappingError::kPositionNotMapped, -1},
      {"position twice",
       mapping_of({kPositionValue32, kPositionValue32}),
       {},
       MappingError::kPositionMappedTwice,
       1},
      {"position 8 bits",
       mapping_of({{od::kPositionValue, 0, 8}}),
       {},
       MappingError::kPositionWidth,
       0},
      {"reference missing", position_tpdo().mapping, with_reference(),
       MappingError::kReferenceNotMapped, -1},
      {"reference twice", mapping_of({kPositionValue32, {0x2100, 1, 16}, {0x2100, 1, 16}}),
       with_reference(), MappingError::kReferenceMappedTwice, 2},
      {"reference 16 of 32", mapping_of({kPositionValue32, {0x2100, 1, 16}}), with_reference(),
       MappingError::kReferenceWidth, 1},
      {"reference is position", position_tpdo().mapping,
       ValueObjects{{od::kPositionValue, 0}, true, {od::kPositionValue, 0}},
       MappingError::kReferenceIsPosition, -1},
  };
  for (const BadMapping& c : cases) {
    const LayoutResult r = resolve_layout(c.mapping, c.values);
    EXPECT_EQ(r.error, c.error) << c.name << ": " << to_string(r.error);
    EXPECT_EQ(r.entry, c.entry) << c.name;
    EXPECT_NE(to_string(r.error), "?") << c.name;
  }
}

TEST(Cia406, FullSixtyFourBitsIsAccepted) {
  const LayoutResult r =
      resolve_layout(mapping_of({kPositionValue32, kReference32}), with_reference());
  ASSERT_EQ(r.error, MappingError::kNone);
  EXPECT_EQ(r.layout.length, 8);
}

TEST(Cia406, ModulusAndResolution) {
  const PdoLayout layout = resolve_layout(position_tpdo().mapping, {}).layout;
  EXPECT_EQ(position_modulus(layout, 0), std::uint64_t{1} << 32);
  EXPECT_EQ(position_modulus(layout, 1U << 25), 1U << 25);
  EXPECT_EQ(validate_resolution(layout, 1U << 13, 1U << 25), nullptr);
  EXPECT_EQ(validate_resolution(layout, 0, 0), nullptr);
  EXPECT_NE(validate_resolution(layout, 3000, 1U << 25), nullptr);  // not whole revolutions
  const PdoLayout narrow = resolve_layout(mapping_of({{od::kPositionValue, 0, 16}}), {}).layout;
  EXPECT_EQ(position_modulus(narrow, 0), 65536U);
  EXPECT_NE(validate_resolution(narrow, 0, 70000), nullptr);
  EXPECT_EQ(validate_resolution(narrow, 4096, 65536), nullptr);
}

TEST(Cia406, RemappingSequenceFollowsCia301) {
  TpdoSetup setup = position_tpdo(1);
  setup.mapping.add(kReference32);
  std::array<SdoWrite, kMaxPdoWrites> w{};
  const int n = tpdo_setup_writes(5, setup, w);
  ASSERT_EQ(n, 7);
  EXPECT_EQ(w[0], (SdoWrite{{0x1800, 1}, 0x80000185U, 4}));  // disable
  EXPECT_EQ(w[1], (SdoWrite{{0x1A00, 0}, 0, 1}));            // clear the count
  EXPECT_EQ(w[2], (SdoWrite{{0x1A00, 1}, 0x60040020U, 4}));
  EXPECT_EQ(w[3], (SdoWrite{{0x1A00, 2}, 0x21000120U, 4}));
  EXPECT_EQ(w[4], (SdoWrite{{0x1A00, 0}, 2, 1}));
  EXPECT_EQ(w[5], (SdoWrite{{0x1800, 2}, 1, 1}));            // every SYNC
  EXPECT_EQ(w[6], (SdoWrite{{0x1800, 1}, 0x00000185U, 4}));  // enable

  TpdoSetup other;
  other.pdo = 3;
  other.cob_id = 0x1F0;
  other.transmission_type = 4;
  other.sync_start = 2;
  other.mapping.add(kPositionValue32);
  const int m = tpdo_setup_writes(5, other, w);
  ASSERT_EQ(m, 7);
  EXPECT_EQ(w[0], (SdoWrite{{0x1802, 1}, 0x800001F0U, 4}));
  EXPECT_EQ(w[4], (SdoWrite{{0x1802, 2}, 4, 1}));
  EXPECT_EQ(w[5], (SdoWrite{{0x1802, 6}, 2, 1}));
  EXPECT_EQ(w[6], (SdoWrite{{0x1802, 1}, 0x1F0U, 4}));
}

}  // namespace
}  // namespace exodaq::drivers::canopen
