#pragma once
// Names of the flag bits, reason bits and state codes of the messages, for
// people: "STALE|HELD", "-" for none; unknown bits print as 0x... so nothing
// is hidden.
#include <cstdint>
#include <string>
#include <string_view>

namespace exodaq::msg {

std::string joint_flag_names(std::int32_t flags);
std::string sample_flag_names(std::int32_t flags);
std::string invalid_reason_names(std::int32_t reasons);
std::string_view state_name(std::int8_t state);
std::string_view bus_state_name(std::int8_t bus);
std::string_view homing_name(std::int8_t homing);

}  // namespace exodaq::msg
