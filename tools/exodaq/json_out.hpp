#pragma once
// JSON output shared by the commands that print --json (fk, ik, status): one
// object, one key per line, arrays of numbers on one line. Numbers are the
// shortest text that reads back to the same double (-0.297, not
// -0.29699999999999999; -0 as 0); json_measure(), for computed geometry, also
// writes magnitudes below 1e-12 (floating-point noise of the trigonometry,
// -5e-17) as 0. NaN and infinities are null.
#include <cmath>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "exodaq/messages/csv.hpp"

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

inline std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  return messages::csv::number(v);
}

inline constexpr double kJsonNoise = 1e-12;

inline std::string json_measure(double v) {
  if (!std::isfinite(v)) return "null";
  return std::abs(v) < kJsonNoise ? "0" : messages::csv::number(v);
}

// A number already written as text (the CSV schema's values): as it is, or
// null for nan/inf.
inline std::string json_value(const std::string& number_text) {
  if (number_text == "nan" || number_text == "inf" || number_text == "-inf") return "null";
  return number_text.empty() ? "null" : number_text;
}

// Any vector with size() and operator[] (Eigen vectors included).
template <typename V, typename F = std::string (*)(double)>
std::string json_array(const V& v, F format = json_measure) {
  std::string out = "[";
  for (decltype(v.size()) i = 0; i < v.size(); ++i) out += (i ? ", " : "") + format(v[i]);
  return out + "]";
}

inline std::string json_strings(const std::vector<std::string>& v) {
  std::string out = "[";
  for (std::size_t i = 0; i < v.size(); ++i) out += (i ? ", " : "") + json_string(v[i]);
  return out + "]";
}

inline std::string json_bool(bool b) {
  return b ? "true" : "false";
}

// An object built key by key; text() lays it out one key per line.
class JsonObject {
 public:
  JsonObject& add(const std::string& key, std::string json) {
    fields_.emplace_back(key, std::move(json));
    return *this;
  }
  // `indent`: the column of the closing brace.
  std::string text(int indent = 0) const {
    const std::string pad(static_cast<std::size_t>(indent) + 2, ' ');
    std::string out = "{";
    for (std::size_t i = 0; i < fields_.size(); ++i) {
      out += (i ? ",\n" : "\n") + pad + json_string(fields_[i].first) + ": " + fields_[i].second;
    }
    return out + "\n" + std::string(static_cast<std::size_t>(indent), ' ') + "}";
  }

 private:
  std::vector<std::pair<std::string, std::string>> fields_;
};

// A list of objects, one per line block.
inline std::string json_objects(const std::vector<JsonObject>& v, int indent) {
  if (v.empty()) return "[]";
  const std::string pad(static_cast<std::size_t>(indent) + 2, ' ');
  std::string out = "[";
  for (std::size_t i = 0; i < v.size(); ++i) {
    out += (i ? ",\n" : "\n") + pad + v[i].text(indent + 2);
  }
  return out + "\n" + std::string(static_cast<std::size_t>(indent), ' ') + "]";
}

}  // namespace exodaq::tools
