#pragma once
// JSON output helpers shared by the commands that print --json (fk, ik).
#include <cmath>
#include <cstdio>
#include <string>

namespace exodaq::tools {

inline std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (const char ch : s) {
    const auto c = static_cast<unsigned char>(ch);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += ch;
    } else if (c < 0x20) {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\u%04x", c);
      out += buf;
    } else {
      out += ch;
    }
  }
  return out + "\"";
}

// Full precision; NaN and infinities as null.
inline std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Any vector with size() and operator[] (Eigen vectors included).
template <typename V>
std::string json_array(const V& v) {
  std::string out = "[";
  for (decltype(v.size()) i = 0; i < v.size(); ++i) out += (i ? ", " : "") + json_number(v[i]);
  return out + "]";
}

}  // namespace exodaq::tools
