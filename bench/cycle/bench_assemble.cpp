// One cycle's frames into one sample, for each CAN protocol, side by side in
// one run: what a protocol adds to a cycle on the SocketCAN path (the
// transport, CanLink, is the same for both). The frames of a cycle are made
// once; the benchmarks feed them with advancing stamps and sequence numbers
// through each protocol's FrameAssembler (the candump replay's, the same
// assembly and conversion as the live source's) and take the sample.
//
//   protocol v1: COUNTS_A + COUNTS_B (6 channels, 16-bit counts)
//   canopen:     SYNC + six TPDOs (CiA 406 position 0x6004, 32 bits)
#include <benchmark/benchmark.h>

#include <array>
#include <cstdint>

#include "exodaq/drivers/board_decoder.hpp"
#include "exodaq/drivers/can_codec.hpp"
#include "exodaq/drivers/canopen/canopen_source.hpp"

namespace {

using namespace exodaq::drivers;
namespace co = exodaq::drivers::canopen;

constexpr std::int64_t kPeriod = 1'000'000;

void BM_AssembleCycleProtocolV1(benchmark::State& state) {
  const auto assembler = make_board_frame_assembler(BoardDecoderConfig{});
  EncoderSample out;
  std::int64_t k = 0;
  for (auto _ : state) {
    const auto seq = static_cast<std::uint8_t>(k & 0xFF);
    const auto c = static_cast<std::uint16_t>(k);
    can::CanFrame a = can::encode_counts(0, {c, static_cast<std::uint16_t>(c + 1), c}, 0, seq);
    can::CanFrame b = can::encode_counts(1, {c, c, static_cast<std::uint16_t>(c + 2)}, 0, seq);
    a.mono_ns = a.wall_ns = k * kPeriod + 100'000;
    b.mono_ns = b.wall_ns = a.mono_ns + 150'000;
    assembler->on_frame(a);
    assembler->on_frame(b);
    benchmark::DoNotOptimize(assembler->poll(out));
    ++k;
  }
  state.counters["frames_per_cycle"] = 2;
}
BENCHMARK(BM_AssembleCycleProtocolV1);

co::CanopenSourceConfig canopen_config() {
  co::CanopenSourceConfig c;
  c.joint_count = kChannelCount;
  for (int j = 0; j < kChannelCount; ++j) {
    co::CanopenJoint& joint = c.joints[static_cast<std::size_t>(j)];
    joint.node = static_cast<co::NodeId>(j + 1);
    joint.total_range = 1U << 25;
  }
  return c;
}

void BM_AssembleCycleCanopen(benchmark::State& state) {
  const co::CanopenSourceConfig config = canopen_config();
  const auto assembler = co::make_frame_assembler(config, kPeriod);
  std::array<can::CanFrame, kChannelCount> tpdo{};
  for (int j = 0; j < kChannelCount; ++j) {
    const co::CanopenJoint& joint = config.joints[static_cast<std::size_t>(j)];
    tpdo[static_cast<std::size_t>(j)].id = co::tpdo_cob_id(joint.node, joint.tpdo);
    tpdo[static_cast<std::size_t>(j)].dlc = 4;
  }
  EncoderSample out;
  std::int64_t k = 0;
  for (auto _ : state) {
    can::CanFrame sync = co::encode_sync();
    sync.mono_ns = sync.wall_ns = k * kPeriod;
    assembler->on_frame(sync);
    const auto position = static_cast<std::uint32_t>(k & 0xFFFFFF);
    for (std::size_t j = 0; j < tpdo.size(); ++j) {
      can::CanFrame& f = tpdo[j];
      for (int b = 0; b < 4; ++b)
        f.data[static_cast<std::size_t>(b)] = static_cast<std::uint8_t>((position + j) >> (8 * b));
      f.mono_ns = f.wall_ns = sync.mono_ns + 100'000 + static_cast<std::int64_t>(j) * 20'000;
      assembler->on_frame(f);  // the sixth closes the cycle
    }
    benchmark::DoNotOptimize(assembler->poll(out));
    ++k;
  }
  state.counters["frames_per_cycle"] = 1 + kChannelCount;
}
BENCHMARK(BM_AssembleCycleCanopen);

}  // namespace
