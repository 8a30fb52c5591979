#include "exodaq/settings/content_hash.hpp"

#include <gcrypt.h>

#include <array>
#include <stdexcept>

namespace exodaq::settings {

std::string sha256_hex(std::string_view bytes) {
  // libgcrypt (already loaded by libsystemd) wants its version check once
  // before first use; a static's initialisation is thread-safe.
  static const bool ready = gcry_check_version(nullptr) != nullptr;
  if (!ready) throw std::runtime_error("libgcrypt cannot be initialised");
  std::array<unsigned char, 32> digest{};
  gcry_md_hash_buffer(GCRY_MD_SHA256, digest.data(), bytes.data(), bytes.size());
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out;
  out.reserve(64);
  for (const unsigned char b : digest) {
    out += kHex[b >> 4];
    out += kHex[b & 15];
  }
  return out;
}

}  // namespace exodaq::settings
