// The replay backend on generated inputs: candump text from the simulated
// rig (counts bit-exact, malformed lines line-numbered and skipped, lost
// cycles replayed as missing), and LCM logs (encoder_raw_t decoded field for
// field, recorded seq and utime kept, start-up and other runs skipped).
#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "alloc_counter.hpp"
#include "exodaq/drivers/replay_source.hpp"
#include "exodaq/drivers/sim_rig.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq_v1/encoder_raw_t.hpp"
#include "process.hpp"
#include "replay_support.hpp"

namespace exodaq::drivers {
namespace {

using test::event;

constexpr std::int64_t kWallStart = 1'700'000'000'000'000'000LL;

std::string temp_dir() {
  return test::make_temp_dir("replay-src");
}

ReplaySource make(const std::string& path, const std::string& format = "auto",
                  const std::string& channel = "EXO_ENCODER_RAW") {
  ReplaySettings s;
  s.path = path;
  s.format = format;
  s.channel = channel;
  return ReplaySource(s, SourceContext{});
}

TEST(ReplayCandump, SimRigFramesReplayBitExact) {
  const std::string dir = temp_dir();
  sim::SimOptions opt;
  constexpr std::int64_t kCycles = 3000;
  const test::SimCandump cd = test::sim_candump(opt, kCycles, kWallStart);
  test::write_text(dir + "/sim.candump", cd.text);

  ReplaySource src = make(dir + "/sim.candump");
  src.start();
  EXPECT_EQ(src.summary().format, ReplayFormat::kCandump);
  EXPECT_EQ(src.summary().bad_lines, 0);
  EXPECT_TRUE(src.issues().empty());
  ASSERT_EQ(src.sample_count(), kCycles);

  EncoderSample s;
  CycleTime t;
  std::int64_t k = 0;
  std::uint64_t allocations = 0;
  std::vector<EncoderSample> got;
  got.reserve(kCycles);
  {
    const test::AllocationScope scope;
    while (true) {
      const std::int64_t due = src.next_sample_mono_ns();
      const ReadStatus st = src.read(t, s);
      if (st == ReadStatus::kEndOfStream) {
        EXPECT_EQ(due, -1);
        break;
      }
      EXPECT_EQ(st, ReadStatus::kSample);
      EXPECT_EQ(s.mono_ns, due);
      EXPECT_EQ(src.recorded_seq(), -1);  // candump: the loop counts
      got.push_back(s);
      ++k;
    }
    allocations = scope.count();
  }
  EXPECT_EQ(allocations, 0U);
  ASSERT_EQ(k, kCycles);
  for (std::int64_t i = 0; i < kCycles; ++i) {
    const EncoderSample& g = got[static_cast<std::size_t>(i)];
    ASSERT_TRUE(g.present);
    EXPECT_EQ(g.seq, static_cast<std::int16_t>(i & 0xFF));
    EXPECT_EQ(g.wall_ns, cd.stamp_ns[static_cast<std::size_t>(i)]);
    EXPECT_NE(g.flags & sample_flag::kReplay, 0U);
    for (std::size_t c = 0; c < 6; ++c) {
      ASSERT_EQ(g.position[c],
                static_cast<std::uint16_t>(cd.counts[static_cast<std::size_t>(i)][c]))
          << "cycle " << i << " channel " << c;
    }
  }
  // Deterministic run_id from the content; start() again rewinds.
  const std::int64_t id = src.run_id();
  EXPECT_NE(id, 0);
  src.start();
  EXPECT_EQ(src.position(), 0);
  ReplaySource again = make(dir + "/sim.candump", "candump");
  again.start();
  EXPECT_EQ(again.run_id(), id);
}

TEST(ReplayCandump, MalformedLinesAreNumberedCountedAndSkipped) {
  const std::string dir = temp_dir();
  sim::SimOptions opt;
  const test::SimCandump cd = test::sim_candump(opt, 400, kWallStart);
  // Insert bad lines at known places; drop every frame of cycles 200..202
  // (a gap the decoder sees by sequence); add an error frame.
  std::vector<std::string> lines;
  std::size_t start = 0;
  while (start < cd.text.size()) {
    const std::size_t end = cd.text.find('\n', start);
    lines.push_back(cd.text.substr(start, end - start));
    start = end + 1;
  }
  std::vector<std::string> out;
  std::vector<std::int64_t> bad_line_numbers;
  const auto stamp_of = [](const std::string& l) { return l.substr(1, l.find(')') - 1); };
  const std::string t200 = "(1700000000.200000)";
  const std::string t203 = "(1700000000.203000)";
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::string& l = lines[i];
    const std::string ts = "(" + stamp_of(l) + ")";
    if (ts >= t200 && ts < t203) continue;  // lost on the bus
    out.push_back(l);
    if (i == 10) {
      out.push_back("(1700000000.010500) vcan0 181#123");  // odd digits
      bad_line_numbers.push_back(static_cast<std::int64_t>(out.size()));
      out.push_back("garbage without a timestamp");
      bad_line_numbers.push_back(static_cast<std::int64_t>(out.size()));
      out.push_back("");  // blank: ignored, not an error
    }
    if (i == 300) {
      out.push_back("(1700000000.060000) vcan0 20000004#0004000000000000");  // CRTL error frame
      out.push_back("(1700000000.060001) vcan0 181#R");                      // RTR: codec rejects
      out.push_back("(1700000000.060002) vcan0 181##1AABB");                 // FD: codec rejects
      out.push_back("(1700000000.060003 vcan0 181#00");                      // malformed
      bad_line_numbers.push_back(static_cast<std::int64_t>(out.size()));
    }
  }
  std::string text;
  for (const auto& l : out) text += l + "\n";
  test::write_text(dir + "/bad.candump", text);

  ReplaySource src = make(dir + "/bad.candump");
  src.start();
  EXPECT_EQ(src.summary().bad_lines, 3);
  ASSERT_EQ(src.issues().size(), 3U);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(src.issues()[i].line, bad_line_numbers[i]) << src.issues()[i].what;
  }
  EXPECT_NE(src.issues()[0].what.find("bad data"), std::string::npos);
  EXPECT_NE(src.issues()[1].what.find("timestamp"), std::string::npos);
  EXPECT_GE(src.stats().bad_frames, 3 + 2);  // malformed lines + frames the codec rejected
  EXPECT_GE(src.stats().bus_errors, 1);
  EXPECT_EQ(src.stats().missing_samples, 3);
  // 400 cycles: 397 arrived, the 3 lost ones come back as missing samples.
  ASSERT_EQ(src.sample_count(), 400);
  EncoderSample s;
  int missing = 0;
  std::int64_t previous_mono = 0;
  for (int i = 0; i < 400; ++i) {
    ASSERT_NE(src.read(CycleTime{}, s), ReadStatus::kEndOfStream);
    if (!s.present) {
      ++missing;
      EXPECT_NE(s.flags & sample_flag::kMissing, 0U);
      EXPECT_EQ(s.mono_ns, kWallStart + i * 1'000'000LL);  // evenly spaced in the gap
    }
    EXPECT_GT(s.mono_ns, previous_mono);
    previous_mono = s.mono_ns;
  }
  EXPECT_EQ(missing, 3);
  EXPECT_EQ(src.read(CycleTime{}, s), ReadStatus::kEndOfStream);
}

// A recording of version 1 (protocol v1's frame), as the daemon wrote them
// before version 2: read as protocol v1's moduli.
TEST(ReplayLcm, DecodesEncoderRawVersion1FieldForField) {
  const std::string dir = temp_dir();
  std::vector<test::LogEvent> log;
  // The daemon's start-up warm-up: all zero.
  exodaq_v1::encoder_raw_t warm{};
  log.push_back(event("X_EXO_ENCODER_RAW", warm));
  log.push_back(event("OTHER", warm));
  std::vector<exodaq_v1::encoder_raw_t> sent;
  for (int k = 0; k < 50; ++k) {
    exodaq_v1::encoder_raw_t r{};
    r.utime = 1'700'000'000'000'000 + k * 1000 + 7;
    r.mono_ns = 5'000'000'000 + k * 1'000'017;
    r.seq = k < 20 ? k : k + 3;  // three cycles skipped by the live loop
    r.run_id = 0x1234;
    r.present = k != 30;
    r.board_seq = static_cast<std::int16_t>(k & 0xFF);
    for (int c = 0; c < 6; ++c) {
      r.count16[c] = static_cast<std::int16_t>(-32768 + k * 1000 + c);
      r.index_count16[c] = static_cast<std::int16_t>(c * 7 - k);
    }
    r.index_latched = k % 7;
    r.index_count_valid = k % 5;
    r.board_state = 2;
    r.board_errors = k == 40 ? 0x81 : 0;
    r.source_flags = k == 40 ? 16 : (k == 30 ? 1 : 0);
    r.wall_ns = r.utime * 1000 + 123;  // not what the replay uses
    if (k == 25) {
      // The loop's LATE bit lives in the recorded joint_state_t.
      exodaq::joint_state_t js{};
      js.utime = r.utime;
      js.seq = r.seq;
      js.run_id = r.run_id;
      js.sample_flags = 256;
      log.push_back(event("X_EXO_JOINT_STATE", js));
    }
    log.push_back(event("X_EXO_ENCODER_RAW", r));
    sent.push_back(r);
  }
  exodaq_v1::encoder_raw_t other = sent.back();
  other.run_id = 0x9999;
  other.seq = 0;
  log.push_back(event("X_EXO_ENCODER_RAW", other));
  test::write_log(dir + "/raw.lcm", log);

  ReplaySource src = make(dir + "/raw.lcm");  // finds X_EXO_ENCODER_RAW by its suffix
  src.start();
  EXPECT_EQ(src.summary().format, ReplayFormat::kLcm);
  EXPECT_EQ(src.summary().channel, "X_EXO_ENCODER_RAW");
  EXPECT_EQ(src.summary().prefix, "X_");
  EXPECT_EQ(src.summary().skipped_warmup, 1);
  EXPECT_EQ(src.summary().skipped_other_runs, 1);
  EXPECT_EQ(src.run_id(), 0x1234);
  EXPECT_EQ(src.issues().size(), 1U);  // the other run, named
  ASSERT_EQ(src.sample_count(), 50);

  EncoderSample s;
  for (const auto& r : sent) {
    ASSERT_EQ(src.next_sample_mono_ns(), r.mono_ns);
    const ReadStatus st = src.read(CycleTime{}, s);
    EXPECT_EQ(st, r.present ? ReadStatus::kSample : ReadStatus::kNoSample);
    EXPECT_EQ(src.recorded_seq(), r.seq);
    EXPECT_EQ(s.mono_ns, r.mono_ns);
    EXPECT_EQ(s.wall_ns, r.utime * 1000);
    EXPECT_EQ(s.present, r.present != 0);
    EXPECT_EQ(s.seq, r.board_seq);
    EXPECT_EQ(s.seq_modulus, 256);
    for (int c = 0; c < 6; ++c) {
      EXPECT_EQ(s.modulus[static_cast<std::size_t>(c)], 65536);
      EXPECT_EQ(static_cast<std::int16_t>(s.position[static_cast<std::size_t>(c)]), r.count16[c]);
      EXPECT_EQ(static_cast<std::int16_t>(s.index_position[static_cast<std::size_t>(c)]),
                r.index_count16[c]);
    }
    EXPECT_EQ(s.index_latched, static_cast<std::uint32_t>(r.index_latched));
    EXPECT_EQ(s.index_count_valid, static_cast<std::uint32_t>(r.index_count_valid));
    EXPECT_EQ(s.board_state, 2U);
    EXPECT_EQ(s.board_errors, static_cast<std::uint32_t>(r.board_errors));
    std::uint32_t expected = static_cast<std::uint32_t>(r.source_flags) | sample_flag::kReplay;
    if (r.seq == 25 + 3) expected |= sample_flag::kLate;  // k == 25
    EXPECT_EQ(s.flags, expected) << "seq " << r.seq;
  }
  EXPECT_EQ(src.read(CycleTime{}, s), ReadStatus::kEndOfStream);
}

// Version 2: any protocol's positions, moduli, references and fresh channels,
// field for field; a position outside its modulus is damage, counted and named.
TEST(ReplayLcm, DecodesEncoderRawVersion2FieldForField) {
  const std::string dir = temp_dir();
  std::vector<test::LogEvent> log;
  log.push_back(event("X_EXO_ENCODER_RAW", exodaq::encoder_raw_t{}));  // start-up
  std::vector<exodaq::encoder_raw_t> sent;
  constexpr std::int64_t k32 = std::int64_t{1} << 32;
  for (int k = 0; k < 20; ++k) {
    exodaq::encoder_raw_t r{};
    r.utime = 1'700'000'000'000'000 + k * 1000;
    r.mono_ns = 5'000'000'000 + k * 1'000'000;
    r.seq = k;
    r.run_id = 0x1234;
    r.present = 1;
    r.source_seq = (238 + k) % 240;
    r.source_seq_modulus = 240;
    for (int c = 0; c < 6; ++c) {
      r.modulus[c] = c < 3 ? k32 : 0;
      r.position[c] = c < 3 ? (k32 - 10 + k * (c + 1)) % k32 : -5'000'000'000 + k;
      r.index_position[c] = c == 1 ? 77 : 0;
    }
    r.index_count_valid = k == 7 ? 0x02 : 0;
    r.absolute = 0x38;
    r.channel_fresh = k == 9 ? 0x07 : 0x3F;
    r.source_flags = k == 9 ? static_cast<std::int32_t>(sample_flag::kPartial) : 0;
    log.push_back(event("X_EXO_ENCODER_RAW", r));
    sent.push_back(r);
  }
  exodaq::encoder_raw_t damaged = sent.back();
  damaged.seq = 20;
  damaged.position[0] = k32;  // not below its modulus
  log.push_back(event("X_EXO_ENCODER_RAW", damaged));
  test::write_log(dir + "/raw2.lcm", log);

  ReplaySource src = make(dir + "/raw2.lcm");
  src.start();
  ASSERT_EQ(src.sample_count(), 20);
  ASSERT_EQ(src.issues().size(), 1U);
  EXPECT_NE(src.issues()[0].what.find("outside its modulus"), std::string::npos)
      << src.issues()[0].what;
  EXPECT_TRUE(src.issues()[0].problem);
  EncoderSample s;
  for (const auto& r : sent) {
    ASSERT_EQ(src.read(CycleTime{}, s), ReadStatus::kSample);
    EXPECT_EQ(s.seq, r.source_seq);
    EXPECT_EQ(s.seq_modulus, 240);
    for (std::size_t c = 0; c < 6; ++c) {
      EXPECT_EQ(s.position[c], r.position[c]) << "seq " << r.seq << " channel " << c;
      EXPECT_EQ(s.modulus[c], r.modulus[c]);
      EXPECT_EQ(s.index_position[c], r.index_position[c]);
    }
    EXPECT_EQ(s.index_count_valid, static_cast<std::uint32_t>(r.index_count_valid));
    EXPECT_EQ(s.absolute, 0x38U);
    EXPECT_EQ(s.channel_fresh, static_cast<std::uint32_t>(r.channel_fresh));  // as recorded
  }
  EXPECT_EQ(src.read(CycleTime{}, s), ReadStatus::kEndOfStream);
}

TEST(ReplayLcm, WithoutJointStateASeqJumpMeansLate) {
  const std::string dir = temp_dir();
  std::vector<test::LogEvent> log;
  for (int k : {0, 1, 2, 5, 6}) {
    exodaq::encoder_raw_t r{};
    r.utime = 1'000'000 + k * 1000;
    r.mono_ns = 1'000'000'000 + k * 1'000'000LL;
    r.seq = k;
    r.run_id = 7;
    r.present = true;
    log.push_back(event("EXO_ENCODER_RAW", r));
  }
  test::write_log(dir + "/raw.lcm", log);
  ReplaySource src = make(dir + "/raw.lcm", "lcm");
  src.start();
  EncoderSample s;
  std::vector<bool> late;
  while (src.read(CycleTime{}, s) != ReadStatus::kEndOfStream) {
    late.push_back((s.flags & sample_flag::kLate) != 0);
  }
  EXPECT_EQ(late, (std::vector<bool>{false, false, false, true, false}));
}

TEST(ReplayErrors, SayWhatIsWrong) {
  const std::string dir = temp_dir();
  test::write_text(dir + "/junk.txt", "hello\nworld\n");
  ReplaySource junk = make(dir + "/junk.txt");
  try {
    junk.start();
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("neither an LCM log"), std::string::npos) << e.what();
  }
  ReplaySource missing = make(dir + "/nope.lcm");
  EXPECT_THROW(missing.start(), std::runtime_error);

  std::vector<test::LogEvent> log;
  exodaq::joint_state_t js{};
  js.utime = 1;
  log.push_back(event("A_EXO_JOINT_STATE", js));
  test::write_log(dir + "/noraw.lcm", log);
  ReplaySource noraw = make(dir + "/noraw.lcm");
  try {
    noraw.start();
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("A_EXO_JOINT_STATE"), std::string::npos) << e.what();
  }
  exodaq::encoder_raw_t r{};
  r.utime = 5;
  r.mono_ns = 5;
  r.run_id = 1;
  log.push_back(event("A_EXO_ENCODER_RAW", r));
  log.push_back(event("B_EXO_ENCODER_RAW", r));
  test::write_log(dir + "/two.lcm", log);
  ReplaySource two = make(dir + "/two.lcm");
  try {
    two.start();
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("--channel"), std::string::npos) << e.what();
  }
  ReplaySource chosen = make(dir + "/two.lcm", "lcm", "B_EXO_ENCODER_RAW");
  chosen.start();
  EXPECT_EQ(chosen.sample_count(), 1);
  EXPECT_THROW(make(dir + "/two.lcm", "csv"), std::runtime_error);
}

}  // namespace
}  // namespace exodaq::drivers
