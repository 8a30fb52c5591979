// Unit tests of the messages library: the pieces echo, status and export share.
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/common/clock_now.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/csv.hpp"
#include "exodaq/messages/flag_names.hpp"
#include "exodaq_v1/encoder_raw_t.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>
#include <utility>
#include <variant>
#include <vector>

namespace messages = exodaq::messages;
using exodaq::mono_now_ns;

namespace {

template <typename T>
std::vector<char> encode(const T& m) {
  std::vector<char> buf(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(buf.data(), 0, static_cast<int>(buf.size())), static_cast<int>(buf.size()));
  return buf;
}

TEST(Subscriber, ChannelNamesCarryThePrefix) {
  EXPECT_EQ(messages::channel_name("", messages::Kind::kJointState), "EXO_JOINT_STATE");
  EXPECT_EQ(messages::channel_name("RIG2_", messages::Kind::kStatus), "RIG2_EXO_STATUS");
  EXPECT_EQ(messages::channel_name("r.", messages::Kind::kPalmPose), "r.EXO_PALM_POSE");
  EXPECT_EQ(messages::channel_name("", messages::Kind::kEncoderRaw), "EXO_ENCODER_RAW");
}

TEST(Subscriber, ParseKindAcceptsShortBaseAndTypeNames) {
  EXPECT_EQ(messages::parse_kind("joint_state"), messages::Kind::kJointState);
  EXPECT_EQ(messages::parse_kind("EXO_JOINT_STATE"), messages::Kind::kJointState);
  EXPECT_EQ(messages::parse_kind("palm_pose_t"), messages::Kind::kPalmPose);
  EXPECT_EQ(messages::parse_kind("raw"), messages::Kind::kEncoderRaw);
  EXPECT_EQ(messages::parse_kind("Status"), messages::Kind::kStatus);
  EXPECT_FALSE(messages::parse_kind("RIG2_EXO_STATUS").has_value());
  EXPECT_FALSE(messages::parse_kind("").has_value());
}

TEST(Subscriber, RegexEscapeMakesALiteral) {
  EXPECT_EQ(messages::regex_escape("EXO_STATUS"), "EXO_STATUS");
  EXPECT_EQ(messages::regex_escape("rig.2(a)*"), "rig\\.2\\(a\\)\\*");
}

TEST(Subscriber, KindOfPayloadUsesTheFingerprint) {
  exodaq::joint_state_t j{};
  exodaq::status_t s{};
  const auto bj = encode(j);
  const auto bs = encode(s);
  EXPECT_EQ(messages::kind_of_payload(bj.data(), bj.size()), messages::Kind::kJointState);
  EXPECT_EQ(messages::kind_of_payload(bs.data(), bs.size()), messages::Kind::kStatus);
  EXPECT_FALSE(messages::kind_of_payload(bj.data(), 7).has_value());
  const char junk[16] = {1, 2, 3, 4, 5, 6, 7, 8};
  EXPECT_FALSE(messages::kind_of_payload(junk, sizeof junk).has_value());
}

// One all-zero message of every kind of the list, in kind order.
template <std::size_t... I>
std::vector<messages::Message> blank_messages(std::index_sequence<I...>) {
  return {messages::Message(std::in_place_index<I>)...};
}
std::vector<messages::Message> every_kind() {
  return blank_messages(std::make_index_sequence<std::variant_size_v<messages::Message>>{});
}

std::vector<char> encode_any(const messages::Message& m) {
  return std::visit([](const auto& v) { return encode(v); }, m);
}

// Every kind of the list is recognised by its fingerprint, decodes as itself
// and as no other kind, has a channel and names that lead back to it, and CSV
// columns that match its values: what the list derives, checked for each line.
TEST(MessageList, EveryKindIsItselfEverywhere) {
  const auto all = every_kind();
  ASSERT_EQ(all.size(), messages::kAllKinds.size());
  ASSERT_GE(all.size(), 5U);
  for (std::size_t i = 0; i < all.size(); ++i) {
    const messages::Kind k = messages::kAllKinds[i];
    const std::string type(messages::type_name(k));
    EXPECT_EQ(messages::kind_of(all[i]), k) << type;
    const auto bytes = encode_any(all[i]);
    EXPECT_EQ(messages::kind_of_payload(bytes.data(), bytes.size()), k) << type;
    for (const messages::Kind other : messages::kAllKinds) {
      const auto decoded = messages::decode(other, bytes.data(), bytes.size());
      EXPECT_EQ(decoded.has_value(), other == k) << type << " as " << messages::type_name(other);
      if (decoded) {
        EXPECT_EQ(messages::kind_of(*decoded), k);
      }
    }
    EXPECT_EQ(messages::parse_kind(type), k);
    EXPECT_EQ(messages::parse_kind(type.substr(0, type.size() - 2)), k) << type;
    EXPECT_EQ(messages::parse_kind(messages::base_channel(k)), k) << type;
    const auto parts = messages::split_channel(messages::channel_name("RIG2_", k));
    ASSERT_TRUE(parts.has_value()) << type;
    EXPECT_EQ(parts->prefix, "RIG2_");
    EXPECT_EQ(parts->kind, k);
    std::vector<std::string> values;
    messages::csv::append_values(all[i], values);
    EXPECT_EQ(messages::csv::header(k, messages::csv::numbered_joints()).size(), values.size())
        << type;
  }
}

// The wire formats: a change here is a change of every recording and every
// client's generated types (an LCM fingerprint covers the names and types of
// all fields). Types added to the list later are covered by the test above.
// encoder_raw_t is version 2; version 1 keeps its fingerprint (below).
TEST(MessageList, FingerprintsOfTheFirstFiveTypesAreUnchanged) {
  const std::pair<messages::Kind, std::uint64_t> golden[] = {
      {messages::Kind::kJointState, 0x3abbf41b00120c0aULL},
      {messages::Kind::kPalmPose, 0x45316e9d1908ff1dULL},
      {messages::Kind::kEncoderRaw, 0xca36c9169b3356d1ULL},
      {messages::Kind::kStatus, 0xabf6b6946b45ab99ULL},
      {messages::Kind::kHoming, 0x5849a47166a8619eULL}};
  const auto all = every_kind();
  for (const auto& [k, fp] : golden) {
    const auto bytes = encode_any(all[static_cast<std::size_t>(k)]);
    std::uint64_t got = 0;
    for (int i = 0; i < 8; ++i) got = (got << 8) | static_cast<unsigned char>(bytes[i]);
    EXPECT_EQ(got, fp) << messages::type_name(k);
  }
  // Version 1 of encoder_raw_t: what every recording made before version 2
  // holds, still recognised by its fingerprint.
  EXPECT_EQ(static_cast<std::uint64_t>(exodaq_v1::encoder_raw_t::getHash()), 0x2b9ba15490a8aeb1ULL);
  const exodaq_v1::encoder_raw_t v1{};
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(v1.getEncodedSize()));
  v1.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  EXPECT_EQ(messages::kind_of_payload(bytes.data(), bytes.size()), messages::Kind::kEncoderRaw);
}

TEST(MessageList, PerCycleKindsAreTheCycleStreams) {
  EXPECT_TRUE(messages::is_per_cycle(messages::Kind::kJointState));
  EXPECT_TRUE(messages::is_per_cycle(messages::Kind::kPalmPose));
  EXPECT_TRUE(messages::is_per_cycle(messages::Kind::kEncoderRaw));
  EXPECT_FALSE(messages::is_per_cycle(messages::Kind::kStatus));
  EXPECT_FALSE(messages::is_per_cycle(messages::Kind::kHoming));
}

TEST(MessageList, AliasesAreWholeWordsOfOneKind) {
  EXPECT_EQ(messages::parse_kind("joints"), messages::Kind::kJointState);
  EXPECT_EQ(messages::parse_kind("JOINT"), messages::Kind::kJointState);
  EXPECT_EQ(messages::parse_kind("Pose"), messages::Kind::kPalmPose);
  EXPECT_EQ(messages::parse_kind("encoder"), messages::Kind::kEncoderRaw);
  EXPECT_FALSE(messages::parse_kind("joint joints").has_value());
  EXPECT_FALSE(messages::parse_kind("join").has_value());
  EXPECT_FALSE(messages::parse_kind(" ").has_value());
}

TEST(Subscriber, DecodeRejectsWrongTypeAndTruncation) {
  exodaq::palm_pose_t p{};
  p.seq = 77;
  p.position[2] = 0.25;
  const auto b = encode(p);
  auto m = messages::decode(messages::Kind::kPalmPose, b.data(), b.size());
  ASSERT_TRUE(m.has_value());
  EXPECT_EQ(messages::kind_of(*m), messages::Kind::kPalmPose);
  EXPECT_EQ(messages::stamp_of(*m).seq, 77);
  EXPECT_EQ(std::get<exodaq::palm_pose_t>(*m).position[2], 0.25);
  EXPECT_FALSE(messages::decode(messages::Kind::kJointState, b.data(), b.size()).has_value());
  EXPECT_FALSE(messages::decode(messages::Kind::kPalmPose, b.data(), b.size() - 1).has_value());
}

// The one CSV schema (docs/messages.md "CSV"), golden: a change here is a
// change of what every lab script reads, and of docs/messages.md.
const std::string kNames[6] = {"shoulder_azimuth",  "shoulder_abduction", "shoulder_flexion",
                               "shoulder_rotation", "elbow_flexion",      "forearm_pronation"};

std::string joined(const std::vector<std::string>& v) {
  return messages::csv::line(v);
}

TEST(CsvSchema, GoldenCycleHeader) {
  const auto h = messages::csv::cycle_header(messages::csv::joint_columns(kNames));
  EXPECT_EQ(joined(h),
            "utime_us,mono_ns,seq,run_id,"
            "shoulder_azimuth_rad,shoulder_abduction_rad,shoulder_flexion_rad,"
            "shoulder_rotation_rad,elbow_flexion_rad,forearm_pronation_rad,"
            "shoulder_azimuth_vel_rad_s,shoulder_abduction_vel_rad_s,shoulder_flexion_vel_rad_s,"
            "shoulder_rotation_vel_rad_s,elbow_flexion_vel_rad_s,forearm_pronation_vel_rad_s,"
            "shoulder_azimuth_count,shoulder_abduction_count,shoulder_flexion_count,"
            "shoulder_rotation_count,elbow_flexion_count,forearm_pronation_count,"
            "shoulder_azimuth_homed,shoulder_abduction_homed,shoulder_flexion_homed,"
            "shoulder_rotation_homed,elbow_flexion_homed,forearm_pronation_homed,"
            "shoulder_azimuth_flags,shoulder_abduction_flags,shoulder_flexion_flags,"
            "shoulder_rotation_flags,elbow_flexion_flags,forearm_pronation_flags,"
            "sample_flags,"
            "palm_x_m,palm_y_m,palm_z_m,palm_qw,palm_qx,palm_qy,palm_qz,"
            "elbow_x_m,elbow_y_m,elbow_z_m,manipulability,manipulability_raw,near_singular,"
            "palm_valid,palm_invalid_reason");
}

// docs/messages.md "CSV" shows the same header, so the page cannot drift.
TEST(CsvSchema, MessagesMdShowsTheCycleHeader) {
  std::ifstream in(std::string(EXODAQ_SOURCE_DIR) + "/docs/messages.md");
  std::stringstream doc;
  doc << in.rdbuf();
  const std::string header =
      joined(messages::csv::cycle_header(messages::csv::joint_columns(kNames)));
  EXPECT_NE(doc.str().find("\n" + header + "\n"), std::string::npos)
      << "docs/messages.md does not show:\n"
      << header;
}

TEST(CsvSchema, GoldenHeadersOfEachKind) {
  const auto j = messages::csv::joint_columns(kNames);
  const auto joint = messages::csv::header(messages::Kind::kJointState, j);
  const auto cycle = messages::csv::cycle_header(j);
  // echo's joint_state_t columns are export's, up to the palm columns.
  ASSERT_LT(joint.size(), cycle.size());
  EXPECT_TRUE(std::equal(joint.begin(), joint.end(), cycle.begin()));
  EXPECT_EQ(joint.back(), "sample_flags");
  // echo's palm_pose_t columns are export's palm columns, after the header.
  const auto palm = messages::csv::header(messages::Kind::kPalmPose, j);
  EXPECT_EQ(joined(palm),
            "utime_us,mono_ns,seq,run_id,palm_x_m,palm_y_m,palm_z_m,palm_qw,palm_qx,palm_qy,"
            "palm_qz,elbow_x_m,elbow_y_m,elbow_z_m,manipulability,manipulability_raw,"
            "near_singular,palm_valid,palm_invalid_reason");
  EXPECT_TRUE(std::equal(palm.begin() + 4, palm.end(), cycle.begin() + joint.size()));
  EXPECT_EQ(joined(messages::csv::header(messages::Kind::kEncoderRaw, j)),
            "utime_us,mono_ns,seq,run_id,present,source_seq,source_seq_modulus,position_ch0,"
            "position_ch1,position_ch2,position_ch3,position_ch4,position_ch5,modulus_ch0,"
            "modulus_ch1,modulus_ch2,modulus_ch3,modulus_ch4,modulus_ch5,index_position_ch0,"
            "index_position_ch1,index_position_ch2,index_position_ch3,index_position_ch4,"
            "index_position_ch5,index_latched,index_count_valid,absolute,channel_fresh,"
            "board_state,board_errors,source_flags,wall_ns");
  const auto status = messages::csv::header(messages::Kind::kStatus, j);
  EXPECT_EQ(status.size(), 4u + 4 + 9 + 27 + 6 * 6);
  EXPECT_EQ(status[4], "rig");
  EXPECT_EQ(status[36], "clock_steps");
  EXPECT_EQ(joined(std::vector<std::string>(status.begin() + 37, status.begin() + 44)),
            "config_path,config_sha256,calibration_path,calibration_sha256,"
            "calibration_provenance,reloads,foreign_run_id");
  EXPECT_EQ(status[44], "shoulder_azimuth_homing");
  EXPECT_EQ(status.back(), "forearm_pronation_out_of_range_events");
  // Every kind: no name twice in one row.
  for (const auto k : messages::kAllKinds) {
    auto h = messages::csv::header(k, j);
    std::sort(h.begin(), h.end());
    EXPECT_EQ(std::adjacent_find(h.begin(), h.end()), h.end());
  }
}

// is_text_column names exactly the columns whose values are not numbers
// (status --json writes those as strings), for a message of every kind whose
// strings and run ids cannot be read as numbers.
TEST(CsvSchema, TextColumnsAreExactlyTheValuesThatAreNotNumbers) {
  constexpr std::int64_t kRun = 0x0123456789abcdefLL;
  exodaq::status_t st{};
  st.rig = "bench-2";
  st.message = "running: 6/6 homed";
  st.source = "sim";
  st.config_path = "/etc/exodaq/exodaqd.yaml";
  st.config_sha256 = "e3b0c442";
  st.calibration_path = "/etc/exodaq/cal.yaml";
  st.calibration_sha256 = "a1b2c3";
  st.calibration_provenance = "exodaq calibrate";
  st.foreign_run_id = kRun;
  exodaq::joint_state_t js{};
  exodaq::palm_pose_t pp{};
  exodaq::encoder_raw_t raw{};
  exodaq::homing_t hm{};
  const std::vector<messages::Message> all{messages::Message{st}, messages::Message{js},
                                           messages::Message{pp}, messages::Message{raw},
                                           messages::Message{hm}};
  const auto is_number = [](const std::string& v) {
    char* end = nullptr;
    std::strtod(v.c_str(), &end);
    return !v.empty() && *end == '\0';
  };
  std::size_t text = 0;
  for (messages::Message m : all) {
    std::visit([&](auto& v) { v.run_id = kRun; }, m);
    const messages::Kind k = messages::kind_of(m);
    const auto names = messages::csv::header(k, messages::csv::joints_of(m));
    std::vector<std::string> values;
    messages::csv::append_values(m, values);
    ASSERT_EQ(names.size(), values.size());
    for (std::size_t i = 0; i < names.size(); ++i) {
      EXPECT_EQ(messages::csv::is_text_column(k, names[i]), !is_number(values[i]))
          << messages::type_name(k) << " column " << names[i] << " = '" << values[i] << "'";
      text += messages::csv::is_text_column(k, names[i]) ? 1 : 0;
    }
  }
  EXPECT_EQ(text, 9U + 5U);  // status_t's nine, and every kind's run_id
}

TEST(CsvSchema, ValuesFollowTheHeader) {
  exodaq::joint_state_t js{};
  js.utime = 1700000000123456;
  js.mono_ns = 5;
  js.seq = -5;
  js.run_id = 0x0123456789abcdefLL;
  for (int i = 0; i < 6; ++i) js.name[i] = kNames[i];
  js.position[5] = 0.1;
  js.velocity[0] = -0.0;  // no "-0"
  js.homed[1] = 1;
  js.flags[4] = 16;
  exodaq::palm_pose_t p{};
  p.position[2] = -0.297;
  p.valid = 1;
  std::vector<std::string> v;
  messages::csv::append_cycle(js, &p, v);
  const auto h = messages::csv::cycle_header(messages::csv::joints_of(messages::Message{js}));
  ASSERT_EQ(v.size(), h.size());
  const auto at = [&](const std::string& name) {
    return v[static_cast<std::size_t>(std::find(h.begin(), h.end(), name) - h.begin())];
  };
  EXPECT_EQ(at("utime_us"), "1700000000123456");
  EXPECT_EQ(at("seq"), "-5");
  EXPECT_EQ(at("run_id"), "0123456789abcdef");
  EXPECT_EQ(at("forearm_pronation_rad"), "0.1");
  EXPECT_EQ(at("shoulder_azimuth_vel_rad_s"), "0");
  EXPECT_EQ(at("shoulder_abduction_homed"), "1");
  EXPECT_EQ(at("elbow_flexion_flags"), "16");
  EXPECT_EQ(at("palm_z_m"), "-0.297");
  EXPECT_EQ(at("palm_valid"), "1");
  // Without a palm message the palm columns are empty.
  v.clear();
  messages::csv::append_cycle(js, nullptr, v);
  ASSERT_EQ(v.size(), h.size());
  EXPECT_EQ(at("palm_x_m"), "");
  EXPECT_EQ(at("palm_invalid_reason"), "");
  // Joint names that are not column-safe.
  const std::string odd[6] = {"a b", "", "x", "x", "é", "ok"};
  const auto c = messages::csv::joint_columns(odd);
  EXPECT_EQ(c[0], "a_b");
  EXPECT_EQ(c[1], "joint2");
  EXPECT_EQ(c[2], "x");
  EXPECT_EQ(c[3], "joint4");
  EXPECT_EQ(c[4], "__");
  EXPECT_EQ(c[5], "ok");
}

TEST(CsvSchema, RunIdHasOneSpelling) {
  EXPECT_EQ(messages::run_id_text(0x5eed), "0000000000005eed");
  EXPECT_EQ(messages::run_id_text(-0x0123456789abcdefLL), "fedcba9876543211");
  EXPECT_EQ(messages::parse_run_id("fedcba9876543211"), -0x0123456789abcdefLL);
  EXPECT_EQ(messages::parse_run_id("0000000000005EED"), 0x5eed);
  EXPECT_FALSE(messages::parse_run_id("5eed").has_value());
  EXPECT_FALSE(messages::parse_run_id("000000000000xeed").has_value());
}

TEST(CsvSchema, NumbersAreExactShortAndNeverMinusZero) {
  EXPECT_EQ(messages::csv::number(0.1), "0.1");
  EXPECT_EQ(messages::csv::number(-2.75), "-2.75");
  EXPECT_EQ(messages::csv::number(1e-6), "1e-06");
  EXPECT_EQ(messages::csv::number(-0.0), "0");
  EXPECT_EQ(messages::csv::number(-0.297), "-0.297");
  EXPECT_EQ(std::stod(messages::csv::number(std::numbers::pi)), std::numbers::pi);
  EXPECT_EQ(messages::csv::number(std::numeric_limits<double>::quiet_NaN()), "nan");
  EXPECT_EQ(messages::csv::number(-std::numeric_limits<double>::infinity()), "-inf");
}

TEST(CsvSchema, QuotesOnlyWhenNeededAndSplitsBack) {
  EXPECT_EQ(messages::csv::escape("plain"), "plain");
  EXPECT_EQ(messages::csv::escape("a,b"), "\"a,b\"");
  EXPECT_EQ(messages::csv::escape("say \"hi\""), "\"say \"\"hi\"\"\"");
  EXPECT_EQ(messages::csv::line({"1", "x,y", ""}), "1,\"x,y\",");
  std::vector<std::string> back;
  ASSERT_TRUE(messages::csv::split("1,\"x,y\",,\"say \"\"hi\"\"\"", back));
  EXPECT_EQ(back, (std::vector<std::string>{"1", "x,y", "", "say \"hi\""}));
  EXPECT_FALSE(messages::csv::split("\"open", back));
}

// Spaces::kTrim (motion-capture exports, calibration inputs): spaces around an
// unquoted value go, a quoted value keeps its own, a quote inside a value is a
// character; kKeep keeps every space as line() would have written it.
TEST(CsvSchema, TrimModeDropsSpacesAroundUnquotedValuesOnly) {
  std::vector<std::string> v;
  ASSERT_TRUE(messages::csv::split(" 1 ,\t\" a, b \", 2\"in ,", v, messages::csv::Spaces::kTrim));
  EXPECT_EQ(v, (std::vector<std::string>{"1", " a, b ", "2\"in", ""}));
  ASSERT_TRUE(messages::csv::split(" 1 , 2", v));
  EXPECT_EQ(v, (std::vector<std::string>{" 1 ", " 2"}));
  EXPECT_FALSE(messages::csv::split("1, \"open", v, messages::csv::Spaces::kTrim));
}

// Strings from the network in a log line or on a terminal (issue 25.10: a
// foreign status's rig with a line break and ANSI escapes).
TEST(Printable, EscapesControlCharactersAndKeepsUtf8) {
  EXPECT_EQ(messages::printable("rig-b"), "rig-b");
  EXPECT_EQ(messages::printable("evil\nline\x1b[31mred\r\t\x7f"),
            "evil\\nline\\x1b[31mred\\r\\t\\x7f");
  EXPECT_EQ(messages::printable(std::string("a\0b", 3)), "a\\x00b");
  EXPECT_EQ(messages::printable("Zürich µ 日本 🐒"), "Zürich µ 日本 🐒");  // UTF-8 kept
  EXPECT_EQ(messages::printable("\xc3"), "\\xc3");                       // truncated sequence
  EXPECT_EQ(messages::printable("\xc0\xaf"), "\\xc0\\xaf");              // overlong '/'
  EXPECT_EQ(messages::printable("\xed\xa0\x80"), "\\xed\\xa0\\x80");     // a surrogate
  EXPECT_EQ(messages::printable("\xc2\x9b"
                                "31m"),
            "\\xc2\\x9b"
            "31m");  // C1 CSI
  const std::string once = messages::printable("x\ny\x1b");
  EXPECT_EQ(messages::printable(once), once);  // idempotent
}

TEST(Subscriber, FlagNames) {
  using J = exodaq::joint_state_t;
  EXPECT_EQ(messages::joint_flag_names(0), "-");
  EXPECT_EQ(messages::joint_flag_names(int32_t{J::JOINT_STALE} | J::JOINT_HELD), "STALE|HELD");
  EXPECT_EQ(messages::joint_flag_names(J::JOINT_UNHOMED | 0x1000), "UNHOMED|0x1000");
  EXPECT_EQ(messages::sample_flag_names(int32_t{J::SAMPLE_SEQ_GAP} | J::SAMPLE_LATE),
            "SEQ_GAP|LATE");
  EXPECT_EQ(messages::sample_flag_names(J::SAMPLE_NEW_SEGMENT), "NEW_SEGMENT");
  EXPECT_EQ(J::SAMPLE_NEW_SEGMENT, 4096);
  EXPECT_EQ(messages::invalid_reason_names(exodaq::palm_pose_t::INVALID_CLOCK), "CLOCK");
  EXPECT_EQ(messages::state_name(exodaq::status_t::STATE_FAULT), "FAULT");
  EXPECT_EQ(messages::bus_state_name(exodaq::status_t::BUS_OFF), "OFF");
  EXPECT_EQ(messages::homing_name(exodaq::status_t::HOMING_REJECTED), "REJECTED");
  // The same names into a buffer (the loop's status text), cut short to fit.
  char text[11];
  const std::int32_t stale_held = int32_t{J::JOINT_STALE} | J::JOINT_HELD;
  EXPECT_EQ(messages::write_joint_flag_names(stale_held, text, sizeof text), 10u);
  EXPECT_EQ(std::string(text), "STALE|HELD");
  EXPECT_EQ(messages::write_joint_flag_names(stale_held, text, 6), 5u);
  EXPECT_EQ(std::string(text), "STALE");
  EXPECT_EQ(messages::write_sample_flag_names(0, text, sizeof text), 1u);
  EXPECT_EQ(std::string(text), "-");
  // And one per bit, for JSON arrays.
  EXPECT_EQ(messages::joint_flag_list(stale_held), (std::vector<std::string>{"STALE", "HELD"}));
  EXPECT_EQ(messages::joint_flag_list(J::JOINT_GLITCH | 0x1000),
            (std::vector<std::string>{"GLITCH", "0x1000"}));
  EXPECT_TRUE(messages::joint_flag_list(0).empty());
}

}  // namespace
