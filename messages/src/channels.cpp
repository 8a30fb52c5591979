#include "exodaq/messages/channels.hpp"

#include <cctype>
#include <cstring>

#include "exodaq/message_types.hpp"
#include "exodaq_v1/encoder_raw_t.hpp"

namespace exodaq::messages {

namespace {

struct KindInfo {
  Kind kind;
  std::string_view base;
  std::string_view type;
  bool per_cycle;
  std::string_view aliases;  // space-separated

  // The type without its "_t": "joint_state".
  constexpr std::string_view short_name() const { return type.substr(0, type.size() - 2); }
};

constexpr std::array<KindInfo, kKindCount> kInfo = {{
#define EXODAQ_MESSAGE(kind, type, channel, per_cycle, aliases) \
  {Kind::kind, channel, #type, per_cycle, aliases},
#include "exodaq/messages/message_list.def"
#undef EXODAQ_MESSAGE
}};

// kInfo and kAllKinds hold every kind once, at its own index.
constexpr bool in_kind_order() {
  for (std::size_t i = 0; i < kInfo.size(); ++i) {
    if (static_cast<std::size_t>(kInfo[i].kind) != i) return false;
    if (static_cast<std::size_t>(kAllKinds[i]) != i) return false;
    if (!kInfo[i].type.ends_with("_t") || kInfo[i].type.size() < 3) return false;
  }
  return true;
}
static_assert(in_kind_order(), "message_list.def: every kind once, in order, types ending in _t");

const KindInfo& info(Kind k) noexcept {
  return kInfo[static_cast<std::size_t>(k)];
}

std::string upper(std::string_view s) {
  std::string out(s);
  for (auto& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

// Whether `upper_text` is one of the space-separated `aliases`, in any case.
bool is_alias(std::string_view aliases, const std::string& upper_text) {
  while (!aliases.empty()) {
    const std::size_t end = aliases.find(' ');
    if (upper(aliases.substr(0, end)) == upper_text) return true;
    if (end == std::string_view::npos) break;
    aliases.remove_prefix(end + 1);
  }
  return false;
}

template <typename T>
std::uint64_t fingerprint() noexcept {
  return static_cast<std::uint64_t>(T::getHash());
}

}  // namespace

std::string_view base_channel(Kind k) noexcept {
  return info(k).base;
}

std::string_view type_name(Kind k) noexcept {
  return info(k).type;
}

std::string channel_name(std::string_view prefix, Kind k) {
  return std::string(prefix) + std::string(base_channel(k));
}

bool is_per_cycle(Kind k) noexcept {
  return info(k).per_cycle;
}

std::optional<ChannelParts> split_channel(std::string_view channel) {
  for (const auto& i : kInfo) {
    if (channel.size() >= i.base.size() &&
        channel.substr(channel.size() - i.base.size()) == i.base) {
      return ChannelParts{std::string(channel.substr(0, channel.size() - i.base.size())), i.kind};
    }
  }
  return std::nullopt;
}

std::optional<Kind> parse_kind(std::string_view text) {
  const std::string u = upper(text);
  if (u.empty()) return std::nullopt;
  for (const auto& i : kInfo) {
    if (u == upper(i.base) || u == upper(i.type) || u == upper(i.short_name())) return i.kind;
    if (is_alias(i.aliases, u)) return i.kind;
  }
  return std::nullopt;
}

std::optional<Kind> kind_of_payload(const void* data, std::size_t size) noexcept {
  if (size < 8) return std::nullopt;
  const auto* b = static_cast<const unsigned char*>(data);
  std::uint64_t fp = 0;
  for (int i = 0; i < 8; ++i) fp = (fp << 8) | b[i];
#define EXODAQ_MESSAGE(kind, type, channel, per_cycle, aliases) \
  if (fp == fingerprint<type>()) return Kind::kind;
#include "exodaq/messages/message_list.def"
#undef EXODAQ_MESSAGE
  // Earlier versions still read (lcmtypes/v1; decode() upgrades them).
  if (fp == fingerprint<exodaq_v1::encoder_raw_t>()) return Kind::kEncoderRaw;
  return std::nullopt;
}

std::string regex_escape(std::string_view literal) {
  std::string out;
  for (char c : literal) {
    if (std::strchr(".[]{}()\\*+?^$|", c) != nullptr) out += '\\';
    out += c;
  }
  return out;
}

}  // namespace exodaq::messages
