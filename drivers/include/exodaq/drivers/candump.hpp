#pragma once
// One line of a `candump -l` / `candump -L` log file, parsed into a CAN frame.
#include <cstdint>
#include <string_view>

#include "exodaq/drivers/can_codec.hpp"

namespace exodaq::drivers {

enum class CandumpError : std::uint8_t {
  kNone = 0,
  kBlank,      // empty or whitespace-only line (skipped, not an error)
  kTimestamp,  // no "(seconds.micros)" at the start
  kInterface,  // no interface name after the timestamp
  kId,         // identifier: not 3 or 8 hex digits, or flag bits that cannot be there
  kSeparator,  // no '#' / '##' after the identifier
  kData,       // odd number of hex digits, a non-hex character, or misplaced '.'
  kLength,     // more bytes than the frame type allows, or a bad RTR length / len8_dlc
  kFdFlags,    // CAN FD '##' without a hex flags digit
  kTrailing,   // something after the frame that candump does not write
};

std::string_view to_string(CandumpError e) noexcept;

// Parses one line of a candump log file. On kNone `out` holds the frame with
// wall_ns = mono_ns = the line's timestamp in ns (microsecond resolution).
// Understood: standard (3 hex digits) and extended (8 hex digits) IDs, error
// frames (8 digits with CAN_ERR_FLAG 0x20000000 set: kError, id = error
// classes), RTR ("#R", "#R5"), data with optional '.' separators and the
// optional "_<dlc>" len8_dlc suffix, CAN FD ("##<flags><data>", up to 64
// bytes; bytes beyond 8 are not kept), and the optional trailing " R"/" T"
// direction of newer candump versions. Pure and allocation-free: safe to fuzz.
CandumpError parse_candump_line(std::string_view line, can::CanFrame& out) noexcept;

}  // namespace exodaq::drivers
