#pragma once
// What an encoder source delivers for one cycle. Plain values, no allocation:
// sources fill one in place on the loop thread.
#include <array>
#include <cstdint>

#include "exodaq/wire_constants.hpp"

namespace exodaq::drivers {

// One channel per joint of the published messages.
inline constexpr int kChannelCount = wire::kJointCount;

// Cycle-level flags: joint_state_t's SAMPLE_* bits (lcmtypes/exodaq/joint_state_t.lcm
// says what each means), so they pass straight into the published messages.
// Sources raise most; the clock, LATE, FOREIGN_RUN and NEW_SEGMENT bits are the loop's.
namespace sample_flag {
namespace w = wire::joint_state;
inline constexpr std::uint32_t kMissing = w::SAMPLE_MISSING;
inline constexpr std::uint32_t kSeqGap = w::SAMPLE_SEQ_GAP;
inline constexpr std::uint32_t kDuplicate = w::SAMPLE_DUPLICATE;
inline constexpr std::uint32_t kOutOfOrder = w::SAMPLE_OUT_OF_ORDER;
inline constexpr std::uint32_t kBoardError = w::SAMPLE_BOARD_ERROR;
inline constexpr std::uint32_t kBusError = w::SAMPLE_BUS_ERROR;
inline constexpr std::uint32_t kClockStep = w::SAMPLE_CLOCK_STEP;
inline constexpr std::uint32_t kClockUnsync = w::SAMPLE_CLOCK_UNSYNC;
inline constexpr std::uint32_t kLate = w::SAMPLE_LATE;
inline constexpr std::uint32_t kPartial = w::SAMPLE_PARTIAL;
inline constexpr std::uint32_t kReplay = w::SAMPLE_REPLAY;
inline constexpr std::uint32_t kForeignRun = w::SAMPLE_FOREIGN_RUN;
inline constexpr std::uint32_t kNewSegment = w::SAMPLE_NEW_SEGMENT;
}  // namespace sample_flag

// Bit c set for every channel.
inline constexpr std::uint32_t kAllChannels = (1U << kChannelCount) - 1U;

// One cycle as any protocol delivers it. Positions are encoder counts; a
// channel whose counter wraps states its modulus (protocol v1: 65536) and its
// position lies in [0, modulus); modulus 0: the position is the whole count.
// A channel is homed on index latches (incremental encoders) unless its
// `absolute` bit is set (no homing: its calibration offset applies from the
// first sample). The source's cycle sequence wraps at seq_modulus likewise.
struct EncoderSample {
  // The sample instant: kernel receive time of the count frame on SocketCAN, the
  // simulated sample instant on sim, the recorded instant on replay.
  std::int64_t mono_ns = 0;      // CLOCK_MONOTONIC
  std::int64_t wall_ns = 0;      // CLOCK_REALTIME as the source saw it, 0 when the source has none
  bool present = false;          // false: nothing arrived; positions repeat the last sample
  std::int64_t seq = -1;         // the source's cycle sequence, -1 before the first sample
  std::int64_t seq_modulus = 0;  // seq lies in [0, seq_modulus); 0: it does not wrap
  std::array<std::int64_t, kChannelCount> position{};        // counts, as sent
  std::array<std::int64_t, kChannelCount> modulus{};         // 0: not wrapped
  std::array<std::int64_t, kChannelCount> index_position{};  // latched at the index edge
  std::uint32_t index_latched = 0;      // bit c: index of channel c latched since last sample
  std::uint32_t index_count_valid = 0;  // bit c: index_position[c] came with this sample
  std::uint32_t absolute = 0;           // bit c: position[c] is absolute (no index homing)
  std::uint32_t channel_fresh = kAllChannels;  // bit c: position[c] arrived this cycle
  std::uint32_t board_state = 0;
  std::uint32_t board_errors = 0;
  std::uint32_t flags = 0;  // sample_flag bits
};

// status_t's BUS_* codes.
enum class BusState : std::int8_t {
  kUnknown = wire::status::BUS_UNKNOWN,
  kActive = wire::status::BUS_ACTIVE,
  kWarning = wire::status::BUS_WARNING,
  kPassive = wire::status::BUS_PASSIVE,
  kOff = wire::status::BUS_OFF,
  kDown = wire::status::BUS_DOWN,
};

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
  // Complete samples a reader replaced by a newer one (poll_newest: sync
  // master, the aligned sim); 0 with a free-running board, whose every
  // sample is delivered.
  std::int64_t superseded_samples = 0;
  // Sync master: SYNCs sent more than a tenth of a period after their
  // deadline (a late wake); each such sample is stamped at its true instant.
  std::int64_t late_syncs = 0;
  BusState bus_state = BusState::kUnknown;
  std::uint32_t board_errors = 0;
};

}  // namespace exodaq::drivers
