// Unit tests of the messages library: the pieces echo, status and export share.
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/common/clock_now.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/fields.hpp"
#include "exodaq/messages/flag_names.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

namespace msg = exodaq::msg;
using exodaq::mono_now_ns;
using exodaq::wall_now_us;

namespace {

template <typename T>
std::vector<char> encode(const T& m) {
  std::vector<char> buf(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  return buf;
}

TEST(Subscriber, ChannelNamesCarryThePrefix) {
  EXPECT_EQ(msg::channel_name("", msg::Kind::kJointState), "EXO_JOINT_STATE");
  EXPECT_EQ(msg::channel_name("RIG2_", msg::Kind::kStatus), "RIG2_EXO_STATUS");
  EXPECT_EQ(msg::channel_name("r.", msg::Kind::kPalmPose), "r.EXO_PALM_POSE");
  EXPECT_EQ(msg::channel_name("", msg::Kind::kEncoderRaw), "EXO_ENCODER_RAW");
}

TEST(Subscriber, ParseKindAcceptsShortBaseAndTypeNames) {
  EXPECT_EQ(msg::parse_kind("joint_state"), msg::Kind::kJointState);
  EXPECT_EQ(msg::parse_kind("EXO_JOINT_STATE"), msg::Kind::kJointState);
  EXPECT_EQ(msg::parse_kind("palm_pose_t"), msg::Kind::kPalmPose);
  EXPECT_EQ(msg::parse_kind("raw"), msg::Kind::kEncoderRaw);
  EXPECT_EQ(msg::parse_kind("Status"), msg::Kind::kStatus);
  EXPECT_FALSE(msg::parse_kind("RIG2_EXO_STATUS").has_value());
  EXPECT_FALSE(msg::parse_kind("").has_value());
}

TEST(Subscriber, RegexEscapeMakesALiteral) {
  EXPECT_EQ(msg::regex_escape("EXO_STATUS"), "EXO_STATUS");
  EXPECT_EQ(msg::regex_escape("rig.2(a)*"), "rig\\.2\\(a\\)\\*");
}

TEST(Subscriber, KindOfPayloadUsesTheFingerprint) {
  exodaq::joint_state_t j{};
  exodaq::status_t s{};
  const auto bj = encode(j);
  const auto bs = encode(s);
  EXPECT_EQ(msg::kind_of_payload(bj.data(), bj.size()), msg::Kind::kJointState);
  EXPECT_EQ(msg::kind_of_payload(bs.data(), bs.size()), msg::Kind::kStatus);
  EXPECT_FALSE(msg::kind_of_payload(bj.data(), 7).has_value());
  const char junk[16] = {1, 2, 3, 4, 5, 6, 7, 8};
  EXPECT_FALSE(msg::kind_of_payload(junk, sizeof junk).has_value());
}

TEST(Subscriber, DecodeRejectsWrongTypeAndTruncation) {
  exodaq::palm_pose_t p{};
  p.seq = 77;
  p.position[2] = 0.25;
  const auto b = encode(p);
  auto m = msg::decode(msg::Kind::kPalmPose, b.data(), b.size());
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(msg::kind_of(*m), msg::Kind::kPalmPose);
  EXPECT_EQ(msg::stamp_of(*m).seq, 77);
  EXPECT_EQ(std::get<exodaq::palm_pose_t>(*m).position[2], 0.25);
  EXPECT_FALSE(msg::decode(msg::Kind::kJointState, b.data(), b.size()).has_value());
  EXPECT_FALSE(msg::decode(msg::Kind::kPalmPose, b.data(), b.size() - 1).has_value());
}

TEST(Subscriber, FieldsFlattenArraysInDeclarationOrder) {
  exodaq::joint_state_t j{};
  j.seq = -5;
  j.name[0] = "a,b";
  j.position[5] = 0.1;
  j.homed[1] = 1;
  j.flags[4] = 16;
  const auto f = msg::fields(j);
  const auto names = msg::field_names(msg::Kind::kJointState);
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
  EXPECT_EQ(msg::field_names(msg::Kind::kPalmPose).size(), 4u + 2 + 3 + 4 + 3 + 3);
  EXPECT_EQ(msg::field_names(msg::Kind::kEncoderRaw).size(), 4u + 2 + 12 + 6);
  EXPECT_EQ(msg::field_names(msg::Kind::kStatus).size(), 4u + 3 + 13 + 11 + 6 + 7 * 6);
}

TEST(Subscriber, DoublesAreExactAndShort) {
  EXPECT_EQ(msg::format_double(0.1), "0.1");
  EXPECT_EQ(msg::format_double(-2.75), "-2.75");
  EXPECT_EQ(msg::format_double(1e-6), "1e-06");
  EXPECT_EQ(std::stod(msg::format_double(std::numbers::pi)), std::numbers::pi);
  EXPECT_EQ(msg::format_double(std::numeric_limits<double>::quiet_NaN()), "nan");
  EXPECT_EQ(msg::format_double(-std::numeric_limits<double>::infinity()), "-inf");
}

TEST(Subscriber, CsvQuotesOnlyWhenNeeded) {
  EXPECT_EQ(msg::csv_escape("plain"), "plain");
  EXPECT_EQ(msg::csv_escape("a,b"), "\"a,b\"");
  EXPECT_EQ(msg::csv_escape("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(msg::csv_line({"1", "x,y", ""}), "1,\"x,y\",");
}

TEST(Subscriber, FlagNames) {
  using J = exodaq::joint_state_t;
  EXPECT_EQ(msg::joint_flag_names(0), "-");
  EXPECT_EQ(msg::joint_flag_names(int32_t{J::JOINT_STALE} | J::JOINT_HELD), "STALE|HELD");
  EXPECT_EQ(msg::joint_flag_names(J::JOINT_UNHOMED | 0x1000), "UNHOMED|0x1000");
  EXPECT_EQ(msg::sample_flag_names(int32_t{J::SAMPLE_SEQ_GAP} | J::SAMPLE_LATE), "SEQ_GAP|LATE");
  EXPECT_EQ(msg::invalid_reason_names(exodaq::palm_pose_t::INVALID_CLOCK), "CLOCK");
  EXPECT_EQ(msg::state_name(exodaq::status_t::STATE_FAULT), "FAULT");
  EXPECT_EQ(msg::bus_state_name(exodaq::status_t::BUS_OFF), "OFF");
  EXPECT_EQ(msg::homing_name(exodaq::status_t::HOMING_REJECTED), "REJECTED");
}

}  // namespace
