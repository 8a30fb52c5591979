// parse_candump_line(): one line of a `candump -l` / `candump -L` log file.
// Pure, allocation-free, never reads outside the view (fuzzed in
// tests/replay/test_candump_parser.cpp).
#include <cstdint>
#include <string_view>

#include "exodaq/drivers/candump.hpp"

namespace exodaq::drivers {

namespace {

constexpr std::uint32_t kCanErrFlag = 0x20000000U;
constexpr std::uint32_t kCanRtrFlag = 0x40000000U;
constexpr std::uint32_t kCanEffFlag = 0x80000000U;
constexpr std::uint32_t kCanSffMask = 0x7FFU;
constexpr std::uint32_t kCanEffMask = 0x1FFFFFFFU;
constexpr int kCanFdMaxLen = 64;

int hex_value(char c) noexcept {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool is_space(char c) noexcept {
  return c == ' ' || c == '\t';
}

bool is_digit(char c) noexcept {
  return c >= '0' && c <= '9';
}

// Data bytes "1122.33" until the end of `s` or a '_' (len8_dlc suffix).
// Returns kNone and the byte count, keeping at most 8 in `out`.
CandumpError parse_data(std::string_view s, std::size_t& pos, int max_len, can::CanFrame& out,
                        int& len) noexcept {
  len = 0;
  bool last_was_dot = false;
  while (pos < s.size() && s[pos] != '_') {
    if (s[pos] == '.') {
      // Separators only between bytes ("11.22"), as candump -x... writes them.
      if (len == 0 || last_was_dot) return CandumpError::kData;
      last_was_dot = true;
      ++pos;
      continue;
    }
    const int hi = hex_value(s[pos]);
    if (hi < 0) return CandumpError::kData;
    if (pos + 1 >= s.size()) return CandumpError::kData;  // odd number of digits
    const int lo = hex_value(s[pos + 1]);
    if (lo < 0) return CandumpError::kData;
    if (len >= max_len) return CandumpError::kLength;
    if (len < can::kMaxClassicDlc) {
      out.data[static_cast<std::size_t>(len)] = static_cast<std::uint8_t>((hi << 4) | lo);
    }
    ++len;
    pos += 2;
    last_was_dot = false;
  }
  if (last_was_dot) return CandumpError::kData;
  return CandumpError::kNone;
}

// Optional "_<dlc>" after 8 data bytes of a classic frame: len8_dlc 9..F.
CandumpError parse_len8_dlc(std::string_view s, std::size_t& pos, int len) noexcept {
  if (pos >= s.size() || s[pos] != '_') return CandumpError::kNone;
  if (len != can::kMaxClassicDlc || pos + 1 >= s.size()) return CandumpError::kLength;
  const int dlc = hex_value(s[pos + 1]);
  if (dlc < 9) return CandumpError::kLength;
  pos += 2;
  return CandumpError::kNone;
}

}  // namespace

std::string_view to_string(CandumpError e) noexcept {
  switch (e) {
    case CandumpError::kNone:
      return "ok";
    case CandumpError::kBlank:
      return "blank line";
    case CandumpError::kTimestamp:
      return "bad or missing timestamp (expected \"(seconds.microseconds)\")";
    case CandumpError::kInterface:
      return "missing interface name";
    case CandumpError::kId:
      return "bad CAN identifier (3 or 8 hex digits)";
    case CandumpError::kSeparator:
      return "missing '#' after the identifier";
    case CandumpError::kData:
      return "bad data bytes (hex pairs, optionally separated by '.')";
    case CandumpError::kLength:
      return "bad length (too many bytes, bad RTR length or len8_dlc)";
    case CandumpError::kFdFlags:
      return "CAN FD frame without a hex flags digit after '##'";
    case CandumpError::kTrailing:
      return "unexpected text after the frame";
  }
  return "unknown error";
}

namespace {

// "(seconds.fraction)" at `pos`.
CandumpError parse_timestamp(std::string_view line, std::size_t& pos,
                             std::int64_t& stamp_ns) noexcept {
  if (line[pos] != '(') return CandumpError::kTimestamp;
  ++pos;
  std::int64_t seconds = 0;
  int digits = 0;
  while (pos < line.size() && is_digit(line[pos])) {
    if (++digits > 10) return CandumpError::kTimestamp;  // beyond year 2286: not a timestamp
    seconds = seconds * 10 + (line[pos] - '0');
    ++pos;
  }
  if (digits == 0 || pos >= line.size() || line[pos] != '.') return CandumpError::kTimestamp;
  // The stamp in int64 nanoseconds ends in 2262: later ones would overflow.
  if (seconds > (INT64_MAX - 999'999'999) / 1'000'000'000) return CandumpError::kTimestamp;
  ++pos;
  std::int64_t fraction_ns = 0;
  int fraction_digits = 0;
  while (pos < line.size() && is_digit(line[pos])) {
    if (++fraction_digits > 9) return CandumpError::kTimestamp;
    fraction_ns = fraction_ns * 10 + (line[pos] - '0');
    ++pos;
  }
  if (fraction_digits == 0 || pos >= line.size() || line[pos] != ')') {
    return CandumpError::kTimestamp;
  }
  ++pos;
  for (int d = fraction_digits; d < 9; ++d) fraction_ns *= 10;
  stamp_ns = seconds * 1'000'000'000 + fraction_ns;
  return CandumpError::kNone;
}

// " iface frame [R|T]" from `pos`: the frame token.
CandumpError parse_interface_and_frame(std::string_view line, std::size_t pos,
                                       std::string_view& frame) noexcept {
  const std::size_t before_iface = pos;
  while (pos < line.size() && is_space(line[pos])) ++pos;
  if (pos == before_iface || pos == line.size()) return CandumpError::kInterface;
  while (pos < line.size() && !is_space(line[pos])) ++pos;
  const std::size_t before_frame = pos;
  while (pos < line.size() && is_space(line[pos])) ++pos;
  if (pos == before_frame || pos == line.size()) return CandumpError::kInterface;
  // The frame token, then an optional direction annotation (" R" / " T").
  std::size_t end = pos;
  while (end < line.size() && !is_space(line[end])) ++end;
  frame = line.substr(pos, end - pos);
  std::size_t rest = end;
  while (rest < line.size() && is_space(line[rest])) ++rest;
  if (rest < line.size()) {
    const std::string_view tail = line.substr(rest);
    if (tail != "R" && tail != "T") return CandumpError::kTrailing;
  }
  return CandumpError::kNone;
}

// The identifier up to '#' (3 or 8 hex digits); `p` ends past the '#'.
CandumpError parse_id(std::string_view frame, std::size_t& p, can::CanFrame& out) noexcept {
  std::uint32_t id = 0;
  int id_digits = 0;
  while (p < frame.size() && frame[p] != '#') {
    const int v = hex_value(frame[p]);
    if (v < 0 || ++id_digits > 8) return CandumpError::kId;
    id = (id << 4) | static_cast<std::uint32_t>(v);
    ++p;
  }
  if (p == frame.size()) return id_digits == 0 ? CandumpError::kId : CandumpError::kSeparator;
  if (id_digits == 3) {
    if (id > kCanSffMask) return CandumpError::kId;
    out.id = id;
  } else if (id_digits == 8) {
    // candump prints the EFF and RTR flags as frame syntax, never as ID bits;
    // CAN_ERR_FLAG marks an error frame (id = error classes).
    if ((id & (kCanEffFlag | kCanRtrFlag)) != 0) return CandumpError::kId;
    out.flags |= (id & kCanErrFlag) != 0 ? can::frame_flag::kError : can::frame_flag::kExtended;
    out.id = id & kCanEffMask;
  } else {
    return CandumpError::kId;
  }
  ++p;  // '#'
  return CandumpError::kNone;
}

// After "id#": CAN FD "#<flags><data>", a remote request "R[len][_dlc]", or data.
CandumpError parse_payload(std::string_view frame, std::size_t p, can::CanFrame& out,
                           int& len) noexcept {
  len = 0;
  if (p < frame.size() && frame[p] == '#') {
    ++p;
    if (p >= frame.size() || hex_value(frame[p]) < 0) return CandumpError::kFdFlags;
    ++p;
    out.flags |= can::frame_flag::kFd;
    const CandumpError e = parse_data(frame, p, kCanFdMaxLen, out, len);
    if (e != CandumpError::kNone) return e;
    return p < frame.size() ? CandumpError::kData : CandumpError::kNone;  // no len8_dlc on FD
  }
  if (p < frame.size() && (frame[p] == 'R' || frame[p] == 'r')) {
    ++p;
    out.flags |= can::frame_flag::kRtr;
    if (p < frame.size() && is_digit(frame[p])) {
      len = frame[p] - '0';
      if (len > can::kMaxClassicDlc) return CandumpError::kLength;
      ++p;
    }
    if (parse_len8_dlc(frame, p, len) != CandumpError::kNone) return CandumpError::kLength;
    return p < frame.size() ? CandumpError::kLength : CandumpError::kNone;
  }
  const CandumpError e = parse_data(frame, p, can::kMaxClassicDlc, out, len);
  if (e != CandumpError::kNone) return e;
  if (parse_len8_dlc(frame, p, len) != CandumpError::kNone) return CandumpError::kLength;
  return p < frame.size() ? CandumpError::kData : CandumpError::kNone;
}

}  // namespace

CandumpError parse_candump_line(std::string_view line, can::CanFrame& out) noexcept {
  out = can::CanFrame{};
  // Trim: candump writes '\n'; files edited elsewhere may carry '\r'.
  while (!line.empty() && (is_space(line.back()) || line.back() == '\n' || line.back() == '\r')) {
    line.remove_suffix(1);
  }
  std::size_t pos = 0;
  while (pos < line.size() && is_space(line[pos])) ++pos;
  if (pos == line.size()) return CandumpError::kBlank;
  std::int64_t stamp_ns = 0;
  if (const CandumpError e = parse_timestamp(line, pos, stamp_ns); e != CandumpError::kNone) {
    return e;
  }
  std::string_view frame;
  if (const CandumpError e = parse_interface_and_frame(line, pos, frame);
      e != CandumpError::kNone) {
    return e;
  }
  std::size_t p = 0;
  if (const CandumpError e = parse_id(frame, p, out); e != CandumpError::kNone) return e;
  int len = 0;
  if (const CandumpError e = parse_payload(frame, p, out, len); e != CandumpError::kNone) return e;
  out.dlc = static_cast<std::uint8_t>(len);
  out.wall_ns = stamp_ns;
  out.mono_ns = stamp_ns;
  return CandumpError::kNone;
}

}  // namespace exodaq::drivers
