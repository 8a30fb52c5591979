#pragma once
// The content hash that names a configuration, model or calibration file in
// the daemon's log, status_t and --print-config: SHA-256 of the bytes read,
// as 64 lower-case hex digits (what `sha256sum FILE` prints).
#include <string>
#include <string_view>

namespace exodaq::settings {

std::string sha256_hex(std::string_view bytes);

}  // namespace exodaq::settings
