#pragma once
// What an encoder source delivers for one cycle. Plain values, no allocation:
// sources fill one in place on the loop thread.
#include <array>
#include <cstdint>

namespace exodaq::drivers {

inline constexpr int kChannelCount = 6;

// Cycle-level flags a source raises. Same bit values as joint_state_t SAMPLE_*,
// so they pass straight into the published messages.
namespace sample_flag {
inline constexpr std::uint32_t kMissing = 1U << 0;      // nothing arrived for this cycle
inline constexpr std::uint32_t kSeqGap = 1U << 1;       // board sequence skipped before this sample
inline constexpr std::uint32_t kDuplicate = 1U << 2;    // a repeated board sequence was dropped
inline constexpr std::uint32_t kOutOfOrder = 1U << 3;   // an older board sequence was dropped
inline constexpr std::uint32_t kBoardError = 1U << 4;   // heartbeat reports error bits
inline constexpr std::uint32_t kBusError = 1U << 5;     // error frame, bus-off, interface down
inline constexpr std::uint32_t kClockStep = 1U << 6;    // set by the daemon's clock, not sources
inline constexpr std::uint32_t kClockUnsync = 1U << 7;  // set by the daemon's clock, not sources
inline constexpr std::uint32_t kLate = 1U << 8;         // set by the loop, not sources
inline constexpr std::uint32_t kPartial = 1U << 9;      // only one of COUNTS_A / COUNTS_B arrived
inline constexpr std::uint32_t kReplay = 1U << 10;      // produced offline
}  // namespace sample_flag

struct EncoderSample {
  // The sample instant: kernel receive time of the count frame on SocketCAN, the
  // simulated sample instant on sim, the recorded instant on replay.
  std::int64_t mono_ns = 0;     // CLOCK_MONOTONIC
  std::int64_t wall_ns = 0;     // CLOCK_REALTIME as the source saw it, 0 when the source has none
  bool present = false;         // false: nothing arrived; counts repeat the last sample
  std::int16_t board_seq = -1;  // 0..255, -1 before the first sample
  std::array<std::uint16_t, kChannelCount> count16{};        // low 16 bits as sent
  std::array<std::uint16_t, kChannelCount> index_count16{};  // latched at the index edge
  std::uint32_t index_latched = 0;      // bit c: index of channel c latched since last sample
  std::uint32_t index_count_valid = 0;  // bit c: index_count16[c] came with this sample
  std::uint32_t channel_fresh = 0x3F;   // bit c: count16[c] arrived this cycle (partial samples)
  std::uint32_t board_state = 0;
  std::uint32_t board_errors = 0;
  std::uint32_t flags = 0;  // sample_flag bits
};

enum class BusState : std::int8_t { kUnknown = 0, kActive, kWarning, kPassive, kOff, kDown };

// Counters since start; values only grow. Copied out at 10 Hz for the status.
struct SourceStats {
  std::int64_t frames = 0;
  std::int64_t bad_frames = 0;
  std::int64_t missing_samples = 0;
  std::int64_t seq_gaps = 0;
  std::int64_t duplicates = 0;
  std::int64_t out_of_order = 0;
  std::int64_t bus_errors = 0;
  std::int64_t rx_overflows = 0;
  BusState bus_state = BusState::kUnknown;
  std::uint32_t board_errors = 0;
};

}  // namespace exodaq::drivers
