// Fuzz target board_decoder: a BoardDecoder fed any sequence of frames (mostly
// well-formed protocol frames with fuzzed sequence numbers, counts and times,
// some raw), polls, flushes, missing cycles, bus states and resets.
//
// Oracle, besides "no crash, no sanitizer report": every sample has flags and
// channel bits that agree with each other, the queue stays within its
// capacity, counters never go down between resets, and every channel a sample
// marks fresh carries counts that really came in a COUNTS frame of the
// sample's board_seq (a decoder never gets a made-up value marked good).
#include <algorithm>
#include <array>
#include <vector>

#include "exodaq/drivers/board_decoder.hpp"
#include "fuzz_input.hpp"

namespace can = exodaq::drivers::can;
namespace drv = exodaq::drivers;
namespace flag = exodaq::drivers::sample_flag;

namespace {

struct Sent {
  // sent[seq][half]: every count triple sent with that seq since the last reset.
  std::array<std::array<std::vector<std::array<std::uint16_t, 3>>, 2>, 256> by_seq;
  void clear() {
    for (auto& s : by_seq) {
      s[0].clear();
      s[1].clear();
    }
  }
};

void check_sample(const drv::EncoderSample& s, const Sent& sent) {
  FUZZ_CHECK(s.seq >= -1 && s.seq <= 255);
  FUZZ_CHECK((s.channel_fresh & ~0x3FU) == 0);
  FUZZ_CHECK((s.index_latched & ~0x3FU) == 0);
  FUZZ_CHECK((s.index_count_valid & ~0x3FU) == 0);
  if (!s.present) {
    FUZZ_CHECK((s.flags & flag::kMissing) != 0);
    FUZZ_CHECK(s.channel_fresh == 0);
    return;
  }
  FUZZ_CHECK((s.flags & flag::kMissing) == 0);
  FUZZ_CHECK(s.seq >= 0);
  if ((s.flags & flag::kPartial) != 0) {
    FUZZ_CHECK(s.channel_fresh == 0x07U || s.channel_fresh == 0x38U);
  } else {
    FUZZ_CHECK(s.channel_fresh == 0x3FU);
  }
  const auto seq = static_cast<std::size_t>(s.seq);
  FUZZ_CHECK(s.seq_modulus == 256);
  for (std::size_t c = 0; c < 6; ++c) {
    FUZZ_CHECK(s.modulus[c] == 65536 && s.position[c] >= 0 && s.position[c] < 65536);
  }
  const auto u16 = [&s](int c) {
    return static_cast<std::uint16_t>(s.position[static_cast<std::size_t>(c)]);
  };
  for (int half = 0; half < 2; ++half) {
    const std::uint32_t bits = half == 0 ? 0x07U : 0x38U;
    if ((s.channel_fresh & bits) == 0) continue;
    const std::array<std::uint16_t, 3> got{u16(3 * half), u16(3 * half + 1), u16(3 * half + 2)};
    const auto& seen = sent.by_seq[seq][static_cast<std::size_t>(half)];
    FUZZ_CHECK(std::find(seen.begin(), seen.end(), got) != seen.end());
  }
}

void check_stats(const drv::BoardDecoder& d, const drv::BoardDecoderStats& before) {
  const auto& now = d.detail();
  FUZZ_CHECK(d.queued() >= 0 && d.queued() <= drv::BoardDecoder::kQueueCapacity);
  FUZZ_CHECK(now.source.frames >= before.source.frames);
  FUZZ_CHECK(now.source.bad_frames >= before.source.bad_frames);
  FUZZ_CHECK(now.source.missing_samples >= before.source.missing_samples);
  FUZZ_CHECK(now.source.seq_gaps >= before.source.seq_gaps);
  FUZZ_CHECK(now.source.duplicates >= before.source.duplicates);
  FUZZ_CHECK(now.source.out_of_order >= before.source.out_of_order);
  FUZZ_CHECK(now.samples >= before.samples);
  FUZZ_CHECK(now.lost_cycles >= before.lost_cycles);
  // Partial cycles are counted when closed, samples when delivered: the
  // difference is in the queue or was dropped by a queue overflow.
  FUZZ_CHECK(now.partial_samples <= now.samples + d.queued() + now.queue_overflows);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  exodaq::fuzz::Bytes in(data, size);
  static Sent sent;  // large: kept between runs, cleared for each input
  sent.clear();

  drv::BoardDecoderConfig config;
  config.ids.board = in.u8() & 0x03U;
  config.resync_after_rejects = 1 + in.u8() % 16;
  drv::BoardDecoder decoder(config);
  const can::ProtocolIds& ids = config.ids;

  std::int64_t mono = 1'000'000'000;
  drv::EncoderSample s;
  drv::BoardDecoderStats before = decoder.detail();
  int steps = 0;
  while (!in.empty() && ++steps < 4096) {
    const std::uint8_t op = in.u8();
    can::CanFrame f;
    bool feed = true;
    switch (op % 16) {
      case 0:
      case 1:
      case 2:
      case 3: {  // COUNTS_A / COUNTS_B
        const int which = op % 2;
        const std::uint8_t seq = in.u8();
        const std::array<std::uint16_t, 3> c{in.u16(), in.u16(), in.u16()};
        const std::uint8_t latched = in.u8();
        f = can::encode_counts(which, c, latched, seq, ids);
        auto& seen = sent.by_seq[seq][static_cast<std::size_t>(which)];
        if (seen.size() < 4096) seen.push_back(c);
        break;
      }
      case 4: {
        const int channel = in.u8() % can::kBoardChannels;
        const std::uint16_t count = in.u16();
        f = can::encode_index(channel, count, in.u8(), ids);
        break;
      }
      case 5: {
        can::HeartbeatPayload hb;
        hb.state = in.u8();
        hb.errors = in.u8();
        hb.channel_quadrature_errors = in.u8();
        hb.protocol_version = in.u8();
        f = can::encode_heartbeat(hb, static_cast<std::uint8_t>(2 + in.u8() % 7), ids);
        break;
      }
      case 6: {
        can::ErrorPayload e;
        e.classes = in.u32() & can::err_class::kMask;
        e.controller = in.u8();
        e.tx_error_count = in.u8();
        e.rx_error_count = in.u8();
        f = can::encode_error(e);
        break;
      }
      case 7: {  // anything
        f.id = in.u32();
        f.dlc = in.u8();
        f.flags = in.u8();
        in.copy(f.data.data(), f.data.size());
        const can::Decoded d = can::decode(f, ids);  // may be a valid COUNTS frame
        if (d.kind == can::FrameKind::kCountsA || d.kind == can::FrameKind::kCountsB) {
          auto& seen = sent.by_seq[d.counts.seq][d.kind == can::FrameKind::kCountsA ? 0U : 1U];
          if (seen.size() < 4096) seen.push_back(d.counts.count16);
        }
        break;
      }
      case 8:
        f = can::encode_sync(ids);
        break;
      case 9:
        feed = false;
        while (decoder.poll_sample(s)) check_sample(s, sent);
        break;
      case 10:
        feed = false;
        if (decoder.flush(s)) check_sample(s, sent);
        break;
      case 11:
        feed = false;
        decoder.make_missing(s, mono, mono);
        check_sample(s, sent);
        break;
      case 12:
        feed = false;
        decoder.set_bus_state(static_cast<drv::BusState>(in.u8() % 6));
        decoder.add_rx_overflows(in.u8());
        break;
      case 13:  // time jumps (a candump file's stamps can be anything)
        feed = false;
        if ((in.u8() & 1U) != 0) {
          mono = in.i64();
        } else {
          const std::int64_t step = std::int64_t{in.u16()} * 100'000;
          mono = mono < INT64_MAX - step ? mono + step : mono;
        }
        break;
      case 14:
        feed = false;
        if ((in.u8() & 0x0FU) == 0) {
          decoder.reset();
          sent.clear();
          before = decoder.detail();
        }
        break;
      default: {  // flush() delivers exactly when something is pending or queued
        feed = false;
        const bool expected = decoder.has_partial() || decoder.queued() > 0;
        const bool got = decoder.flush(s);
        FUZZ_CHECK(got == expected);
        if (got) check_sample(s, sent);
        break;
      }
    }
    if (feed) {
      f.mono_ns = mono;
      f.wall_ns = mono;
      decoder.on_frame(f);
      // Small step to the next frame; saturating so time never wraps.
      const std::int64_t step = in.u8() * 1000;
      if (mono < INT64_MAX - step) mono += step;
    }
    check_stats(decoder, before);
    before = decoder.detail();
  }
  while (decoder.poll_sample(s)) check_sample(s, sent);
  if (decoder.flush(s)) check_sample(s, sent);
  return 0;
}
