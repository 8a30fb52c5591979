// Unit tests of tools/exodaq/subscriber.cpp: the pieces echo and status share.
#include "subscriber.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace sub = exodaq::tools::sub;

namespace {

template <typename T>
std::vector<char> encode(const T& m) {
  std::vector<char> buf(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  return buf;
}

TEST(Subscriber, ChannelNamesCarryThePrefix) {
  EXPECT_EQ(sub::channel_name("", sub::Kind::kJointState), "EXO_JOINT_STATE");
  EXPECT_EQ(sub::channel_name("RIG2_", sub::Kind::kStatus), "RIG2_EXO_STATUS");
  EXPECT_EQ(sub::channel_name("r.", sub::Kind::kPalmPose), "r.EXO_PALM_POSE");
  EXPECT_EQ(sub::channel_name("", sub::Kind::kEncoderRaw), "EXO_ENCODER_RAW");
}

TEST(Subscriber, ParseKindAcceptsShortBaseAndTypeNames) {
  EXPECT_EQ(sub::parse_kind("joint_state"), sub::Kind::kJointState);
  EXPECT_EQ(sub::parse_kind("EXO_JOINT_STATE"), sub::Kind::kJointState);
  EXPECT_EQ(sub::parse_kind("palm_pose_t"), sub::Kind::kPalmPose);
  EXPECT_EQ(sub::parse_kind("raw"), sub::Kind::kEncoderRaw);
  EXPECT_EQ(sub::parse_kind("Status"), sub::Kind::kStatus);
  EXPECT_FALSE(sub::parse_kind("RIG2_EXO_STATUS").has_value());
  EXPECT_FALSE(sub::parse_kind("").has_value());
}

TEST(Subscriber, RegexEscapeMakesALiteral) {
  EXPECT_EQ(sub::regex_escape("EXO_STATUS"), "EXO_STATUS");
  EXPECT_EQ(sub::regex_escape("rig.2(a)*"), "rig\\.2\\(a\\)\\*");
}

TEST(Subscriber, KindOfPayloadUsesTheFingerprint) {
  exodaq::joint_state_t j{};
  exodaq::status_t s{};
  const auto bj = encode(j);
  const auto bs = encode(s);
  EXPECT_EQ(sub::kind_of_payload(bj.data(), bj.size()), sub::Kind::kJointState);
  EXPECT_EQ(sub::kind_of_payload(bs.data(), bs.size()), sub::Kind::kStatus);
  EXPECT_FALSE(sub::kind_of_payload(bj.data(), 7).has_value());
  const char junk[16] = {1, 2, 3, 4, 5, 6, 7, 8};
  EXPECT_FALSE(sub::kind_of_payload(junk, sizeof junk).has_value());
}

TEST(Subscriber, DecodeRejectsWrongTypeAndTruncation) {
  exodaq::palm_pose_t p{};
  p.seq = 77;
  p.position[2] = 0.25;
  const auto b = encode(p);
  auto m = sub::decode(sub::Kind::kPalmPose, b.data(), b.size());
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(sub::kind_of(*m), sub::Kind::kPalmPose);
  EXPECT_EQ(sub::stamp_of(*m).seq, 77);
  EXPECT_EQ(std::get<exodaq::palm_pose_t>(*m).position[2], 0.25);
  EXPECT_FALSE(sub::decode(sub::Kind::kJointState, b.data(), b.size()).has_value());
  EXPECT_FALSE(sub::decode(sub::Kind::kPalmPose, b.data(), b.size() - 1).has_value());
}

TEST(Subscriber, FieldsFlattenArraysInDeclarationOrder) {
  exodaq::joint_state_t j{};
  j.seq = -5;
  j.name[0] = "a,b";
  j.position[5] = 0.1;
  j.homed[1] = 1;
  j.flags[4] = 16;
  const auto f = sub::fields(j);
  const auto names = sub::field_names(sub::Kind::kJointState);
  ASSERT_EQ(f.size(), names.size());
  ASSERT_EQ(f.size(), 41u);
  EXPECT_EQ(f[0].name, "utime");
  EXPECT_EQ(f[2].name, "seq");
  EXPECT_EQ(f[2].value, "-5");
  EXPECT_EQ(f[4].name, "name_0");
  EXPECT_EQ(f[4].value, "a,b");
  EXPECT_EQ(f[15].name, "position_5");
  EXPECT_EQ(f[15].value, "0.1");
  EXPECT_EQ(f[29].name, "homed_1");
  EXPECT_EQ(f[29].value, "1");
  EXPECT_EQ(f[38].name, "flags_4");
  EXPECT_EQ(f[38].value, "16");
  EXPECT_EQ(f[40].name, "sample_flags");
  EXPECT_EQ(sub::field_names(sub::Kind::kPalmPose).size(), 4u + 2 + 3 + 4 + 3 + 3);
  EXPECT_EQ(sub::field_names(sub::Kind::kEncoderRaw).size(), 4u + 2 + 12 + 6);
  EXPECT_EQ(sub::field_names(sub::Kind::kStatus).size(), 4u + 3 + 13 + 11 + 6 + 7 * 6);
}

TEST(Subscriber, DoublesAreExactAndShort) {
  EXPECT_EQ(sub::format_double(0.1), "0.1");
  EXPECT_EQ(sub::format_double(-2.75), "-2.75");
  EXPECT_EQ(sub::format_double(1e-6), "1e-06");
  EXPECT_EQ(std::stod(sub::format_double(std::numbers::pi)), std::numbers::pi);
  EXPECT_EQ(sub::format_double(std::numeric_limits<double>::quiet_NaN()), "nan");
  EXPECT_EQ(sub::format_double(-std::numeric_limits<double>::infinity()), "-inf");
}

TEST(Subscriber, CsvQuotesOnlyWhenNeeded) {
  EXPECT_EQ(sub::csv_escape("plain"), "plain");
  EXPECT_EQ(sub::csv_escape("a,b"), "\"a,b\"");
  EXPECT_EQ(sub::csv_escape("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(sub::csv_line({"1", "x,y", ""}), "1,\"x,y\",");
}

TEST(Subscriber, FlagNames) {
  using J = exodaq::joint_state_t;
  EXPECT_EQ(sub::joint_flag_names(0), "-");
  EXPECT_EQ(sub::joint_flag_names(int32_t{J::JOINT_STALE} | J::JOINT_HELD), "STALE|HELD");
  EXPECT_EQ(sub::joint_flag_names(J::JOINT_UNHOMED | 0x1000), "UNHOMED|0x1000");
  EXPECT_EQ(sub::sample_flag_names(int32_t{J::SAMPLE_SEQ_GAP} | J::SAMPLE_LATE), "SEQ_GAP|LATE");
  EXPECT_EQ(sub::invalid_reason_names(exodaq::palm_pose_t::INVALID_CLOCK), "CLOCK");
  EXPECT_EQ(sub::state_name(exodaq::status_t::STATE_FAULT), "FAULT");
  EXPECT_EQ(sub::bus_state_name(exodaq::status_t::BUS_OFF), "OFF");
  EXPECT_EQ(sub::homing_name(exodaq::status_t::HOMING_REJECTED), "REJECTED");
}

}  // namespace
