// parse_candump_line(): every frame type candump -l / -L writes, every
// rejection, and a fuzz pass (random and mutated lines never crash, never
// allocate, and whatever parses prints back to a line that parses the same).
#include <gtest/gtest.h>

#include <random>
#include <string>

#include "alloc_counter.hpp"
#include "exodaq/drivers/candump.hpp"
#include "replay_support.hpp"

namespace exodaq::drivers {
namespace {

namespace ff = can::frame_flag;

can::CanFrame parse_ok(const std::string& line) {
  can::CanFrame f;
  const CandumpError e = parse_candump_line(line, f);
  EXPECT_EQ(e, CandumpError::kNone) << line << ": " << to_string(e);
  return f;
}

CandumpError parse_err(const std::string& line) {
  can::CanFrame f;
  return parse_candump_line(line, f);
}

TEST(CandumpParser, StandardDataFrame) {
  const auto f = parse_ok("(1700000000.123456) can0 181#34120000FFFF0005");
  EXPECT_EQ(f.id, 0x181U);
  EXPECT_EQ(f.dlc, 8);
  EXPECT_EQ(f.flags, 0);
  EXPECT_EQ(f.data[0], 0x34);
  EXPECT_EQ(f.data[1], 0x12);
  EXPECT_EQ(f.data[7], 0x05);
  EXPECT_EQ(f.wall_ns, 1'700'000'000'123'456'000LL);
  EXPECT_EQ(f.mono_ns, f.wall_ns);
}

TEST(CandumpParser, EmptyAndShortFramesAndSeparators) {
  auto f = parse_ok("(0.000001) vcan0 080#");
  EXPECT_EQ(f.id, 0x080U);
  EXPECT_EQ(f.dlc, 0);
  EXPECT_EQ(f.wall_ns, 1000);
  f = parse_ok("(12.5) can1 190#11.22.33");
  EXPECT_EQ(f.dlc, 3);
  EXPECT_EQ(f.data[2], 0x33);
  EXPECT_EQ(f.wall_ns, 12'500'000'000LL);
  f = parse_ok("(1.000000) can0 701#0100\r\n");  // CRLF
  EXPECT_EQ(f.dlc, 2);
  f = parse_ok("(1.000000) can0 701#0100 R");  // direction annotation
  EXPECT_EQ(f.id, 0x701U);
  f = parse_ok("  (1.000000)\tcan0\t701#0100  ");
  EXPECT_EQ(f.dlc, 2);
  f = parse_ok("(1.000000) can0 123#1122334455667788_C");  // len8_dlc
  EXPECT_EQ(f.dlc, 8);
}

TEST(CandumpParser, ExtendedRtrErrorAndFd) {
  auto f = parse_ok("(1.0) can0 12345678#AA");
  EXPECT_EQ(f.id, 0x12345678U);
  EXPECT_EQ(f.flags, ff::kExtended);
  f = parse_ok("(1.0) can0 123#R");
  EXPECT_EQ(f.flags, ff::kRtr);
  EXPECT_EQ(f.dlc, 0);
  f = parse_ok("(1.0) can0 123#R5");
  EXPECT_EQ(f.dlc, 5);
  f = parse_ok("(1.0) can0 1234ABCD#R");
  EXPECT_EQ(f.flags, ff::kRtr | ff::kExtended);
  // Error frame: CAN_ERR_FLAG in the 8-digit ID, classes in the rest.
  f = parse_ok("(1.0) can0 20000044#0004000000000000");
  EXPECT_EQ(f.flags, ff::kError);
  EXPECT_EQ(f.id, 0x44U);
  EXPECT_EQ(f.dlc, 8);
  EXPECT_EQ(f.data[1], 0x04);
  const can::Decoded d = can::decode(f);
  EXPECT_EQ(d.kind, can::FrameKind::kError);
  EXPECT_EQ(d.error.classes, 0x44U);
  // CAN FD, flags nibble, up to 64 bytes (only 8 kept).
  f = parse_ok("(1.0) can0 181##1" + std::string(24, 'A'));
  EXPECT_EQ(f.flags, ff::kFd);
  EXPECT_EQ(f.dlc, 12);
  EXPECT_EQ(f.data[7], 0xAA);
  f = parse_ok("(1.0) can0 181##0" + std::string(128, '0'));
  EXPECT_EQ(f.dlc, 64);
  EXPECT_EQ(can::decode(f).reject, can::Reject::kFd);  // v1 is classic CAN: the codec rejects it
}

TEST(CandumpParser, Rejections) {
  EXPECT_EQ(parse_err(""), CandumpError::kBlank);
  EXPECT_EQ(parse_err("   \t"), CandumpError::kBlank);
  EXPECT_EQ(parse_err("1.0 can0 181#00"), CandumpError::kTimestamp);
  EXPECT_EQ(parse_err("(1.0 can0 181#00"), CandumpError::kTimestamp);
  EXPECT_EQ(parse_err("(.5) can0 181#00"), CandumpError::kTimestamp);
  EXPECT_EQ(parse_err("(1.) can0 181#00"), CandumpError::kTimestamp);
  EXPECT_EQ(parse_err("(1.0000000001) can0 181#00"), CandumpError::kTimestamp);
  EXPECT_EQ(parse_err("(99999999999.0) can0 181#00"), CandumpError::kTimestamp);
  EXPECT_EQ(parse_err("(1.0)"), CandumpError::kInterface);
  EXPECT_EQ(parse_err("(1.0) can0"), CandumpError::kInterface);
  EXPECT_EQ(parse_err("(1.0)can0 181#00"), CandumpError::kInterface);
  EXPECT_EQ(parse_err("(1.0) can0 18#00"), CandumpError::kId);
  EXPECT_EQ(parse_err("(1.0) can0 1811#00"), CandumpError::kId);
  EXPECT_EQ(parse_err("(1.0) can0 800#00"), CandumpError::kId);  // > 11 bits
  EXPECT_EQ(parse_err("(1.0) can0 18G#00"), CandumpError::kId);
  EXPECT_EQ(parse_err("(1.0) can0 #00"), CandumpError::kId);
  EXPECT_EQ(parse_err("(1.0) can0 80000181#00"), CandumpError::kId);  // EFF bit as digits
  EXPECT_EQ(parse_err("(1.0) can0 123456789#00"), CandumpError::kId);
  EXPECT_EQ(parse_err("(1.0) can0 181"), CandumpError::kSeparator);
  EXPECT_EQ(parse_err("(1.0) can0 181#0"), CandumpError::kData);
  EXPECT_EQ(parse_err("(1.0) can0 181#0G"), CandumpError::kData);
  EXPECT_EQ(parse_err("(1.0) can0 181#.00"), CandumpError::kData);
  EXPECT_EQ(parse_err("(1.0) can0 181#00..11"), CandumpError::kData);
  EXPECT_EQ(parse_err("(1.0) can0 181#00."), CandumpError::kData);
  EXPECT_EQ(parse_err("(1.0) can0 181#001122334455667788"), CandumpError::kLength);
  EXPECT_EQ(parse_err("(1.0) can0 181#0011_C"), CandumpError::kLength);
  EXPECT_EQ(parse_err("(1.0) can0 181#1122334455667788_5"), CandumpError::kLength);
  EXPECT_EQ(parse_err("(1.0) can0 181#R9"), CandumpError::kLength);
  EXPECT_EQ(parse_err("(1.0) can0 181#RX"), CandumpError::kLength);
  EXPECT_EQ(parse_err("(1.0) can0 181##"), CandumpError::kFdFlags);
  EXPECT_EQ(parse_err("(1.0) can0 181##Z00"), CandumpError::kFdFlags);
  EXPECT_EQ(parse_err("(1.0) can0 181##0" + std::string(130, '0')), CandumpError::kLength);
  EXPECT_EQ(parse_err("(1.0) can0 181#00 extra"), CandumpError::kTrailing);
  EXPECT_EQ(parse_err("(1.0) can0 181#00 R T"), CandumpError::kTrailing);
  for (int e = 0; e <= static_cast<int>(CandumpError::kTrailing); ++e) {
    EXPECT_FALSE(to_string(static_cast<CandumpError>(e)).empty());
  }
}

TEST(CandumpParser, RoundTripsTheCodecFrames) {
  const std::vector<can::CanFrame> frames = {
      can::encode_sync(),
      can::encode_counts(0, {0x1234, 0xFFFF, 0}, 0x05, 200),
      can::encode_counts(1, {1, 2, 3}, 0, 201),
      can::encode_index(4, 0xBEEF, 7),
      can::encode_heartbeat({1, 0x81, 0x04, 1}),
      can::encode_error({can::err_class::kCrtl | can::err_class::kBusOff, 0, 0x10, 0, 0, 0, 3, 9}),
  };
  for (const auto& in : frames) {
    const std::string line = test::candump_line(in, 1'700'000'000'000'001'000LL);
    const can::CanFrame out = parse_ok(line);
    EXPECT_EQ(out.id, in.id) << line;
    EXPECT_EQ(out.dlc, in.dlc) << line;
    EXPECT_EQ(out.flags, in.flags) << line;
    EXPECT_EQ(out.data, in.data) << line;
    EXPECT_EQ(out.wall_ns, 1'700'000'000'000'001'000LL);
    const can::Decoded a = can::decode(in);
    const can::Decoded b = can::decode(out);
    EXPECT_EQ(a.kind, b.kind) << line;
  }
}

TEST(CandumpParser, FuzzNeverCrashesNorAllocates) {
  std::mt19937_64 rng(12345);
  const std::string alphabet = "()0123456789.#_RrTabcdefABCDEFxyz \t-\r\n";
  const std::vector<std::string> seeds = {
      "(1700000000.123456) can0 181#34120000FFFF0005",
      "(1.0) can0 20000044#0004000000000000",
      "(1.0) can0 181##1AABBCCDDEEFF00112233",
      "(1.0) can0 123#R5",
      "(1.0) can0 12345678#11.22.33 T",
  };
  std::vector<std::string> lines;
  for (int i = 0; i < 20000; ++i) {
    std::string s;
    if (i % 2 == 0) {
      const int n = static_cast<int>(rng() % 90);
      for (int k = 0; k < n; ++k) s += alphabet[rng() % alphabet.size()];
    } else {
      s = seeds[rng() % seeds.size()];
      const int edits = 1 + static_cast<int>(rng() % 4);
      for (int k = 0; k < edits && !s.empty(); ++k) {
        const std::size_t pos = rng() % s.size();
        switch (rng() % 3) {
          case 0:
            s[pos] = alphabet[rng() % alphabet.size()];
            break;
          case 1:
            s.erase(pos, 1);
            break;
          default:
            s.insert(pos, 1, alphabet[rng() % alphabet.size()]);
            break;
        }
      }
    }
    lines.push_back(std::move(s));
  }
  int ok = 0;
  std::uint64_t allocations = 0;
  {
    const test::AllocationScope scope;
    for (const auto& s : lines) {
      can::CanFrame f;
      if (parse_candump_line(s, f) == CandumpError::kNone) ++ok;
    }
    allocations = scope.count();
  }
  EXPECT_EQ(allocations, 0U);
  EXPECT_GT(ok, 100);  // the mutations keep a fair share valid
  // Whatever parses, printed again, parses to the same frame.
  for (const auto& s : lines) {
    can::CanFrame f;
    if (parse_candump_line(s, f) != CandumpError::kNone || (f.flags & ff::kFd) != 0) continue;
    if (f.dlc > 8) continue;
    can::CanFrame g;
    const std::string again = test::candump_line(f, f.wall_ns);
    ASSERT_EQ(parse_candump_line(again, g), CandumpError::kNone) << s << " -> " << again;
    EXPECT_EQ(g.id, f.id);
    EXPECT_EQ(g.flags, f.flags);
    EXPECT_EQ(g.dlc, f.dlc);
    EXPECT_EQ(g.data, f.data);
    EXPECT_EQ(g.wall_ns / 1000, f.wall_ns / 1000);
  }
}

}  // namespace
}  // namespace exodaq::drivers
