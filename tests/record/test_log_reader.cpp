// The LCM log reader on damaged logs (issue 25 item 2): one damaged header
// costs its own event only; the reader re-synchronises on the next plausible
// event, names the damaged bytes and counts the events lost there from the
// event numbers on either side. Logs are written with messages::LogWriter (the
// lcm-logger format) and damaged byte by byte.
#include <gtest/gtest.h>

#include <cstdint>
#include <fstream>
#include <iterator>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "exodaq/messages/lcm_log.hpp"
#include "exodaq/messages/message.hpp"
#include "process.hpp"
#include "sample_messages.hpp"

namespace exodaq::test {
namespace {

using Bytes = std::vector<std::uint8_t>;

constexpr std::int64_t kT0 = 1'700'000'000'000'000;

struct Log {
  std::string path;
  Bytes bytes;
  std::vector<std::int64_t> offsets;  // each event's header
  std::vector<Bytes> data;            // each event's data
};

Bytes read_bytes(const std::string& p) {
  std::ifstream in(p, std::ios::binary);
  return Bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

void write_bytes(const std::string& p, const Bytes& b) {
  std::ofstream(p, std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}

// `n` encoder_raw_t events 1 ms apart (timestamps from `t0`).
Log make_log(const std::string& dir, const std::string& name, int n, std::int64_t t0 = kT0) {
  Log log;
  log.path = dir + "/" + name;
  {
    messages::LogWriter w(log.path);
    for (int i = 0; i < n; ++i) {
      log.data.push_back(messages::encode(raw_message(i)));
      w.write("EXO_ENCODER_RAW", t0 + i * 1000, log.data.back().data(), log.data.back().size());
    }
    w.close();
  }
  log.bytes = read_bytes(log.path);
  std::int64_t at = 0;
  for (int i = 0; i < n; ++i) {
    log.offsets.push_back(at);
    at += 28 + 15 + static_cast<std::int64_t>(log.data[static_cast<std::size_t>(i)].size());
  }
  EXPECT_EQ(at, static_cast<std::int64_t>(log.bytes.size()));
  return log;
}

void put_be32(Bytes& b, std::int64_t at, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) b[static_cast<std::size_t>(at + k)] = (v >> (24 - 8 * k)) & 0xFF;
}

struct Read {
  std::vector<messages::LogEvent> events;  // views not kept: data copied below
  std::vector<Bytes> data;
  std::vector<messages::LogDamage> damage;
  std::string text;
};

Read read_all(const std::string& path) {
  Read r;
  messages::LogReader reader(path);
  messages::LogEvent ev;
  while (reader.next(ev)) {
    r.events.push_back(ev);
    r.data.emplace_back(ev.data, ev.data + ev.size);
  }
  r.damage = reader.damage();
  r.text = reader.damage_text();
  return r;
}

class LogReaderDamage : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = make_temp_dir("logreader");
    log_ = make_log(dir_, "good.lcm", 200);
  }
  // The log with `edit` applied, read back.
  template <typename Edit>
  Read damaged(Edit edit) {
    Bytes b = log_.bytes;
    edit(b);
    const std::string p = dir_ + "/damaged.lcm";
    write_bytes(p, b);
    return read_all(p);
  }
  // Every event but `lost` read, with its own bytes.
  void expect_all_but(const Read& r, const std::set<int>& lost) {
    std::size_t k = 0;
    for (int i = 0; i < static_cast<int>(log_.data.size()); ++i) {
      if (lost.count(i) != 0) continue;
      ASSERT_LT(k, r.events.size()) << "event " << i << " not read";
      EXPECT_EQ(r.events[k].number, i);
      EXPECT_EQ(r.data[k], log_.data[static_cast<std::size_t>(i)]) << "event " << i;
      ++k;
    }
    EXPECT_EQ(k, r.events.size());
  }
  std::int64_t at(int event) const { return log_.offsets[static_cast<std::size_t>(event)]; }

  std::string dir_;
  Log log_;
};

TEST_F(LogReaderDamage, AGoodLogReadsWhole) {
  const Read r = read_all(log_.path);
  EXPECT_TRUE(r.damage.empty()) << r.text;
  expect_all_but(r, {});
}

// The reproduction: one event's data length 345 -> 9,437,529 (under
// the 64 MiB cap) cost half the log; now it costs that event.
TEST_F(LogReaderDamage, ADataLengthPastTheNextEventCostsOnlyThatEvent) {
  const Read r = damaged([&](Bytes& b) { put_be32(b, at(77) + 24, 9'437'529); });
  expect_all_but(r, {77});
  ASSERT_EQ(r.damage.size(), 1u) << r.text;
  EXPECT_EQ(r.damage[0].from, at(77));
  EXPECT_EQ(r.damage[0].to, at(78));
  EXPECT_EQ(r.damage[0].events_lost, 1);
  EXPECT_EQ(r.damage[0].after_event, 77);
  EXPECT_EQ(r.text,
            dir_ + "/damaged.lcm, bytes " + std::to_string(at(77)) + ".." + std::to_string(at(78)) +
                ": data length 9437529 runs past the next event at byte " + std::to_string(at(78)) +
                " (a damaged length); 1 event lost (after event 77)");
  EXPECT_TRUE(r.events[77].follows_damage);
  EXPECT_FALSE(r.events[76].follows_damage);
}

TEST_F(LogReaderDamage, AShorterDataLengthCostsOnlyThatEvent) {
  const Read r = damaged([&](Bytes& b) { put_be32(b, at(10) + 24, 20); });
  expect_all_but(r, {10});
  ASSERT_EQ(r.damage.size(), 1u) << r.text;
  EXPECT_EQ(r.damage[0].from, at(10));
  EXPECT_EQ(r.damage[0].to, at(11));
  EXPECT_EQ(r.damage[0].events_lost, 1);
}

TEST_F(LogReaderDamage, AnImpossibleChannelLengthCostsOnlyThatEvent) {
  const Read r = damaged([&](Bytes& b) { put_be32(b, at(150) + 20, 70'000); });
  expect_all_but(r, {150});
  ASSERT_EQ(r.damage.size(), 1u) << r.text;
  EXPECT_EQ(r.damage[0].what, "impossible channel length 70000");
  EXPECT_EQ(r.damage[0].to, at(151));
}

TEST_F(LogReaderDamage, AChannelNameWithAControlByteCostsOnlyThatEvent) {
  const Read r = damaged([&](Bytes& b) { b[static_cast<std::size_t>(at(3) + 28 + 2)] = 0x01; });
  expect_all_but(r, {3});
  ASSERT_EQ(r.damage.size(), 1u) << r.text;
  EXPECT_EQ(r.damage[0].what, "a channel name with control bytes (damaged)");
}

// A timestamp far from both neighbours: a damaged header.
TEST_F(LogReaderDamage, ATimestampOutOfOrderCostsOnlyThatEvent) {
  const Read r = damaged([&](Bytes& b) { b[static_cast<std::size_t>(at(40) + 12 + 2)] ^= 0x40; });
  expect_all_but(r, {40});
  ASSERT_EQ(r.damage.size(), 1u) << r.text;
  EXPECT_NE(r.damage[0].what.find("out of order by more than the file's span"), std::string::npos)
      << r.damage[0].what;
  EXPECT_EQ(r.damage[0].to, at(41));
}

// A damaged sync word in front of an event whose number follows: the event
// is read, the four bytes named, nothing lost.
TEST_F(LogReaderDamage, ADamagedSyncWordAloneLosesNothing) {
  const Read r = damaged([&](Bytes& b) { b[static_cast<std::size_t>(at(120) + 1)] ^= 0xFF; });
  expect_all_but(r, {});
  ASSERT_EQ(r.damage.size(), 1u) << r.text;
  EXPECT_EQ(r.damage[0].from, at(120));
  EXPECT_EQ(r.damage[0].to, at(120) + 4);
  EXPECT_EQ(r.damage[0].events_lost, 0);
}

TEST_F(LogReaderDamage, OverwrittenBytesCostTheEventsTheyCover) {
  const Read r = damaged([&](Bytes& b) {
    for (std::int64_t k = at(60) + 5; k < at(63) + 9; ++k) b[static_cast<std::size_t>(k)] = 'x';
  });
  expect_all_but(r, {60, 61, 62, 63});
  ASSERT_EQ(r.damage.size(), 1u) << r.text;
  EXPECT_EQ(r.damage[0].from, at(60));
  EXPECT_EQ(r.damage[0].to, at(64));
  EXPECT_EQ(r.damage[0].events_lost, 4);
}

// A whole header overwritten: the event before it, whose end no longer
// meets a sync word, is kept (the next event found is not its successor by
// number: the damaged one lies between).
TEST_F(LogReaderDamage, AnOverwrittenHeaderCostsItsEventNotTheOneBefore) {
  const Read r = damaged([&](Bytes& b) {
    for (std::int64_t k = at(90); k < at(90) + 64; ++k) b[static_cast<std::size_t>(k)] = 'x';
  });
  expect_all_but(r, {90});
  ASSERT_EQ(r.damage.size(), 1u) << r.text;
  EXPECT_EQ(r.damage[0].from, at(90));
  EXPECT_EQ(r.damage[0].to, at(91));
  EXPECT_EQ(r.damage[0].events_lost, 1);
}

TEST_F(LogReaderDamage, ACutLastEventIsOneEventLostAtTheEnd) {
  const Read r = damaged([&](Bytes& b) { b.erase(b.end() - 10, b.end()); });
  expect_all_but(r, {199});
  ASSERT_EQ(r.damage.size(), 1u) << r.text;
  EXPECT_EQ(r.damage[0].from, at(199));
  EXPECT_EQ(r.damage[0].to, static_cast<std::int64_t>(log_.bytes.size()) - 10);
  EXPECT_EQ(r.damage[0].events_lost, 1);
  EXPECT_NE(r.damage[0].what.find("cut by the end of the file"), std::string::npos);
}

TEST_F(LogReaderDamage, GarbageAfterTheLastEventLosesNothing) {
  const Read r = damaged([&](Bytes& b) {
    const std::string g = "\xde\xad\xbe\xef garbage after the last event";
    b.insert(b.end(), g.begin(), g.end());
  });
  expect_all_but(r, {});
  ASSERT_EQ(r.damage.size(), 1u) << r.text;
  EXPECT_EQ(r.damage[0].from, static_cast<std::int64_t>(log_.bytes.size()));
  EXPECT_EQ(r.damage[0].events_lost, -1);
}

// Logs joined with cat (the second one recorded an hour earlier, its event
// numbers restarting) are not damage.
TEST_F(LogReaderDamage, LogsJoinedWithCatAreNotDamage) {
  const Log older = make_log(dir_, "older.lcm", 50, kT0 - 3'600'000'000LL);
  Bytes joined = log_.bytes;
  joined.insert(joined.end(), older.bytes.begin(), older.bytes.end());
  const std::string p = dir_ + "/joined.lcm";
  write_bytes(p, joined);
  const Read r = read_all(p);
  EXPECT_TRUE(r.damage.empty()) << r.text;
  ASSERT_EQ(r.events.size(), 250u);
  EXPECT_EQ(r.events[200].number, 0);
  EXPECT_EQ(r.events[200].timestamp, kT0 - 3'600'000'000LL);
}

// Twenty random byte corruptions: every event the damage did not touch is
// read with its bytes; every reported stretch holds a corrupted byte; every
// corruption of the sync word or a length lies in a reported stretch (a
// channel byte changed into another printable one, an event number or a
// timestamp's low bytes are plausible: the event is read as it stands).
TEST_F(LogReaderDamage, TwentyRandomCorruptionsCostOnlyTheEventsTheyHit) {
  const Log big = make_log(dir_, "big.lcm", 20'000);
  for (const unsigned seed : {1U, 2U, 3U, 4U, 5U}) {
    std::mt19937_64 rng(seed);
    Bytes b = big.bytes;
    std::set<std::int64_t> hit;
    while (hit.size() < 20) {
      const auto k = static_cast<std::int64_t>(rng() % b.size());
      if (!hit.insert(k).second) continue;
      b[static_cast<std::size_t>(k)] ^= static_cast<std::uint8_t>(1 + rng() % 255);
    }
    const std::string p = dir_ + "/random.lcm";
    write_bytes(p, b);
    const Read r = read_all(p);
    // Which event each corrupted byte is in, and where in it.
    std::set<int> touched;
    std::set<std::int64_t> checked_field;  // bytes of the sync word and the lengths
    for (const std::int64_t k : hit) {
      const auto e = static_cast<int>(std::upper_bound(big.offsets.begin(), big.offsets.end(), k) -
                                      big.offsets.begin() - 1);
      touched.insert(e);
      const std::int64_t in = k - big.offsets[static_cast<std::size_t>(e)];
      if (in < 4 || (in >= 20 && in < 28)) checked_field.insert(k);
    }
    const auto in_damage = [&](std::int64_t k) {
      for (const auto& d : r.damage) {
        if (k >= d.from && k < d.to) return true;
      }
      return false;
    };
    for (const auto& d : r.damage) {
      bool holds = false;
      for (const std::int64_t k : hit) holds = holds || (k >= d.from && k < d.to);
      EXPECT_TRUE(holds) << "seed " << seed << ": a damaged stretch without a corrupted byte: "
                         << messages::LogReader::damage_line(p, d);
    }
    for (const std::int64_t k : checked_field) {
      EXPECT_TRUE(in_damage(k)) << "seed " << seed << ": byte " << k << " not reported";
    }
    // Every untouched event read, with its own bytes.
    std::set<std::int64_t> read_numbers;
    for (std::size_t i = 0; i < r.events.size(); ++i) read_numbers.insert(r.events[i].number);
    std::int64_t kept = 0;
    for (int e = 0; e < 20'000; ++e) {
      if (touched.count(e) != 0) continue;
      EXPECT_EQ(read_numbers.count(e), 1u) << "seed " << seed << ": untouched event " << e;
      ++kept;
    }
    std::int64_t lost_reported = 0;
    for (const auto& d : r.damage) lost_reported += std::max<std::int64_t>(0, d.events_lost);
    EXPECT_EQ(static_cast<std::int64_t>(r.events.size()) + lost_reported, 20'000)
        << "seed " << seed << "\n"
        << r.text;
    EXPECT_GE(static_cast<std::int64_t>(r.events.size()), kept);
  }
}

}  // namespace
}  // namespace exodaq::test
