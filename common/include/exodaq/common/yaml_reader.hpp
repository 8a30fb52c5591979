#pragma once
// Strict YAML reading for every exodaq file (service config, model,
// calibration): each error names the file, the line and what is wrong, and
// unknown keys are errors. Start-up only; never on the loop thread.
#include <yaml-cpp/yaml.h>

#include <array>
#include <cstdint>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "exodaq/common/config_error.hpp"

namespace exodaq {

// Parses a whole file. Throws ConfigError for unreadable files, YAML syntax
// errors (with the parser's line) and empty documents.
YAML::Node load_yaml_file(const std::string& path);
// Same for text already in memory (tests, fuzzing); `name` stands in for the file.
YAML::Node load_yaml_text(const std::string& text, const std::string& name);

int line_of(const YAML::Node& node) noexcept;  // 1-based, 0 if unknown

// Reads one mapping. Every key must be consumed by required()/optional()/child()
// or named in allow(); finish() reports the first key nobody asked for.
class MapReader {
 public:
  MapReader(std::string file, const YAML::Node& node, std::string context);

  const std::string& file() const noexcept { return file_; }
  const std::string& context() const noexcept { return context_; }
  const YAML::Node& node() const noexcept { return node_; }
  bool has(const std::string& key) const;

  YAML::Node child(const std::string& key);  // required, any kind
  std::optional<YAML::Node> optional_child(const std::string& key);
  MapReader map(const std::string& key);  // required mapping
  std::optional<MapReader> optional_map(const std::string& key);

  std::string string(const std::string& key);
  std::string string_or(const std::string& key, const std::string& fallback);
  // A file path, as written or, when relative, relative to this file's folder.
  std::string path(const std::string& key);
  double number(const std::string& key);  // finite double
  double number_or(const std::string& key, double fallback);
  std::int64_t integer(const std::string& key);
  std::int64_t integer_or(const std::string& key, std::int64_t fallback);
  bool boolean(const std::string& key);
  bool boolean_or(const std::string& key, bool fallback);
  std::vector<double> numbers(const std::string& key);  // a sequence of finite doubles
  template <std::size_t N>
  std::array<double, N> numbers_fixed(const std::string& key) {
    const YAML::Node n = child(key);
    const auto v = to_numbers(n, key);
    if (v.size() != N) {
      fail(n, "'" + key + "' must have " + std::to_string(N) + " numbers, has " +
                  std::to_string(v.size()));
    }
    std::array<double, N> out{};
    for (std::size_t i = 0; i < N; ++i) out[i] = v[i];
    return out;
  }
  // One of `choices`; the error lists them.
  std::string choice(const std::string& key, const std::vector<std::string>& choices);
  std::string choice_or(const std::string& key, const std::vector<std::string>& choices,
                        const std::string& fallback);

  void allow(const std::string& key) { consumed_.insert(key); }
  void finish() const;  // throws on the first unknown key

  [[noreturn]] void fail(const YAML::Node& at, const std::string& what) const;
  [[noreturn]] void fail_key(const std::string& key, const std::string& what) const;

  // Scalar conversion helpers usable on any node of this file.
  // A string scalar as decoded, valid UTF-8 (yaml-cpp decodes the escapes \_
  // and \N to single bytes that are not).
  std::string to_string(const YAML::Node& n, const std::string& what) const;
  double to_number(const YAML::Node& n, const std::string& what) const;
  std::int64_t to_integer(const YAML::Node& n, const std::string& what) const;
  std::vector<double> to_numbers(const YAML::Node& n, const std::string& what) const;

 private:
  std::string file_;
  YAML::Node node_;
  std::string context_;
  std::set<std::string> consumed_;
};

// Angles in files may be written in degrees with a `_deg` key suffix or in
// radians with `_rad`; helpers for that live with each loader.
inline constexpr double kDegToRad = 0.017453292519943295;

}  // namespace exodaq
