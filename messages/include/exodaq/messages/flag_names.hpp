#pragma once
// Names of the flag bits, reason bits and state codes of the messages, for
// people: "STALE|HELD", "-" for none; unknown bits print as 0x... so nothing
// is hidden. The one home of these names: JSON output, the status text and
// the tools take them from here.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace exodaq::messages {

std::string joint_flag_names(std::int32_t flags);
std::string sample_flag_names(std::int32_t flags);
std::string invalid_reason_names(std::int32_t reasons);
std::string_view state_name(std::int8_t state);
std::string_view bus_state_name(std::int8_t bus);
std::string_view homing_name(std::int8_t homing);

// The names above written into `out` (NUL-terminated, cut short when `cap`
// is too small), without allocating: for the loop thread. Returns the
// length written.
std::size_t write_joint_flag_names(std::int32_t flags, char* out, std::size_t cap) noexcept;
std::size_t write_sample_flag_names(std::int32_t flags, char* out, std::size_t cap) noexcept;

// One name per set bit, in bit order (empty for none): JSON arrays.
std::vector<std::string> joint_flag_list(std::int32_t flags);

}  // namespace exodaq::messages
