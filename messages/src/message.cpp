#include "exodaq/messages/message.hpp"

#include <cstdio>

#include "exodaq/messages/raw_sample.hpp"

namespace exodaq::messages {

Kind kind_of(const Message& m) noexcept {
  return static_cast<Kind>(m.index());
}

namespace {
template <typename T>
std::optional<Message> decode_as(const void* data, std::size_t size) {
  T msg;
  if (!decode_into(msg, data, size)) return std::nullopt;
  return Message{std::move(msg)};
}

// Either version, as version 2 (raw_sample.hpp).
template <>
std::optional<Message> decode_as<encoder_raw_t>(const void* data, std::size_t size) {
  encoder_raw_t msg;
  if (decode_encoder_raw(msg, data, size) == RawVersion::kNone) return std::nullopt;
  return Message{std::move(msg)};
}
}  // namespace

std::optional<Message> decode(Kind k, const void* data, std::size_t size) {
  switch (k) {
#define EXODAQ_MESSAGE(kind, type, channel, per_cycle, aliases) \
  case Kind::kind:                                              \
    return decode_as<type>(data, size);
#include "exodaq/messages/message_list.def"
#undef EXODAQ_MESSAGE
  }
  return std::nullopt;
}

Stamp stamp_of(const Message& m) noexcept {
  return std::visit([](const auto& v) { return Stamp{v.utime, v.mono_ns, v.seq, v.run_id}; }, m);
}

std::optional<KindStamp> peek_stamp(const void* data, std::size_t size) noexcept {
  constexpr std::size_t kFingerprint = 8;
  if (size < kFingerprint + 4 * 8) return std::nullopt;
  const auto k = kind_of_payload(data, size);
  if (!k) return std::nullopt;
  const auto* p = static_cast<const std::uint8_t*>(data) + kFingerprint;
  const auto field = [p](int i) {
    std::uint64_t v = 0;
    for (int b = 0; b < 8; ++b) v = (v << 8) | p[i * 8 + b];
    return static_cast<std::int64_t>(v);
  };
  return KindStamp{*k, Stamp{field(0), field(1), field(2), field(3)}};
}

std::string run_id_text(std::int64_t run_id) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%016llx",
                static_cast<unsigned long long>(static_cast<std::uint64_t>(run_id)));
  return buf;
}

namespace {
// The length of the valid UTF-8 sequence at text[at] (0: not one).
std::size_t utf8_length(std::string_view text, std::size_t at) noexcept {
  const auto byte = [&text](std::size_t i) { return static_cast<unsigned char>(text[i]); };
  const unsigned char c = byte(at);
  std::size_t n = 0;
  std::uint32_t cp = 0;
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2;
    cp = c & 0x1Fu;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3;
    cp = c & 0x0Fu;
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4;
    cp = c & 0x07u;
  } else {
    return 0;
  }
  if (at + n > text.size()) return 0;
  for (std::size_t i = 1; i < n; ++i) {
    if ((byte(at + i) & 0xC0u) != 0x80u) return 0;
    cp = (cp << 6) | (byte(at + i) & 0x3Fu);
  }
  const bool overlong = (n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000);
  const bool surrogate = cp >= 0xD800 && cp <= 0xDFFF;
  // C1 controls (U+0080..U+009F) act on terminals as ESC sequences do.
  const bool c1 = cp >= 0x80 && cp <= 0x9F;
  return overlong || surrogate || c1 || cp > 0x10FFFF ? 0 : n;
}
}  // namespace

std::string printable(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c >= 0x20 && c < 0x7F) {
      out += static_cast<char>(c);
      ++i;
      continue;
    }
    if (const std::size_t n = c >= 0x80 ? utf8_length(text, i) : 0; n > 0) {
      out.append(text.substr(i, n));
      i += n;
      continue;
    }
    char buf[8];
    if (c == '\n' || c == '\r' || c == '\t') {
      buf[0] = '\\';
      buf[1] = c == '\n' ? 'n' : c == '\r' ? 'r' : 't';
      buf[2] = '\0';
    } else {
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
    }
    out += buf;
    ++i;
  }
  return out;
}

std::optional<std::int64_t> parse_run_id(std::string_view text) {
  if (text.size() != 16) return std::nullopt;
  std::uint64_t v = 0;
  for (const char c : text) {
    int d = -1;
    if (c >= '0' && c <= '9') d = c - '0';
    if (c >= 'a' && c <= 'f') d = c - 'a' + 10;
    if (c >= 'A' && c <= 'F') d = c - 'A' + 10;
    if (d < 0) return std::nullopt;
    v = (v << 4) | static_cast<std::uint64_t>(d);
  }
  return static_cast<std::int64_t>(v);
}

bool is_startup_message(const Stamp& s) noexcept {
  return s.utime == 0 && s.mono_ns == 0 && s.seq == 0;
}

}  // namespace exodaq::messages
