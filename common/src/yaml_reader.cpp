#include "exodaq/common/yaml_reader.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "exodaq/common/files.hpp"

namespace exodaq {

namespace {
std::string format(const std::string& file, int line, const std::string& what) {
  if (line > 0) return file + ":" + std::to_string(line) + ": " + what;
  return file + ": " + what;
}

// Whether `unknown` (a key nobody asked for) is most likely `known`
// misspelled. Long keys: within files::typo_allowance, unless they differ
// only in digits (dtheta1_deg/dtheta4_deg are siblings). Short keys (up to 6
// characters) are often siblings (a3/d3, dx_mm/dd5_mm, x_mm/y_mm): only one
// letter added or dropped (rigg/rig), or two letters swapped (modle/model).
bool likely_misspelling(const std::string& unknown, const std::string& known) {
  const int d = files::edit_distance(unknown, known);
  if (d == 0) return false;
  if (unknown.size() == known.size()) {
    bool digits_only = true;
    for (std::size_t i = 0; i < known.size(); ++i) {
      if (unknown[i] != known[i]) {
        digits_only = digits_only && std::isdigit(static_cast<unsigned char>(unknown[i])) &&
                      std::isdigit(static_cast<unsigned char>(known[i]));
      }
    }
    if (digits_only) return false;
  }
  if (known.size() > 6) return d <= files::typo_allowance(known);
  if (unknown.size() != known.size()) return d == 1;
  std::string a = unknown;
  std::string b = known;
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  return a == b && d <= 2;
}

const char* kind_name(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Null:
      return "nothing";
    case YAML::NodeType::Scalar:
      return "a scalar";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Map:
      return "a mapping";
    default:
      return "undefined";
  }
}
}  // namespace

ConfigError::ConfigError(std::string file, int line, const std::string& what)
    : std::runtime_error(format(file, line, what)),
      file_(std::move(file)),
      line_(line),
      reason_(what) {}

int line_of(const YAML::Node& node) noexcept {
  try {
    const auto mark = node.Mark();
    return mark.line >= 0 ? mark.line + 1 : 0;
  } catch (...) {
    return 0;
  }
}

YAML::Node load_yaml_text(const std::string& text, const std::string& name) {
  // yaml-cpp reads a NUL as the end of the text and passes invalid UTF-8 on.
  if (const auto problem = files::find_text_problem(text)) {
    throw ConfigError(name, problem->line, problem->what_and_column());
  }
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw ConfigError(name, e.mark.line >= 0 ? e.mark.line + 1 : 0, "YAML syntax: " + e.msg);
  }
  if (!root || root.IsNull()) throw ConfigError(name, 0, "empty document");
  if (!root.IsMap()) {
    throw ConfigError(name, line_of(root),
                      std::string("top level must be a mapping, found ") + kind_name(root));
  }
  return root;
}

YAML::Node load_yaml_file(const std::string& path) {
  std::string text;
  try {
    text = files::read_input(path, files::kMaxYamlBytes);
  } catch (const files::FileError& e) {
    throw ConfigError(path, 0, e.reason());
  }
  return load_yaml_text(text, path);
}

MapReader::MapReader(std::string file, const YAML::Node& node, std::string context)
    : file_(std::move(file)), node_(node), context_(std::move(context)) {
  if (!node_.IsMap()) {
    fail(node_, context_ + " must be a mapping, found " + kind_name(node_));
  }
  // YAML forbids duplicate keys, but yaml-cpp keeps them and its lookups see
  // only the first: a second 'rate_hz:' would be ignored without a word.
  std::set<std::string> seen;
  for (const auto& kv : node_) {
    if (kv.first.IsScalar() && !seen.insert(kv.first.Scalar()).second) {
      fail(kv.first, "duplicate key '" + kv.first.Scalar() + "' in " + context_);
    }
  }
}

void MapReader::fail(const YAML::Node& at, const std::string& what) const {
  int line = line_of(at);
  if (line == 0) line = line_of(node_);
  throw ConfigError(file_, line, what);
}

void MapReader::fail_key(const std::string& key, const std::string& what) const {
  if (has(key)) fail(node_[key], what);
  fail(node_, what);
}

bool MapReader::has(const std::string& key) const {
  return static_cast<bool>(node_[key]);
}

YAML::Node MapReader::child(const std::string& key) {
  consumed_.insert(key);
  const YAML::Node n = node_[key];
  if (!n) {
    // A key nobody asked for that is close to this one is most likely it,
    // misspelled: name it rather than only the missing field.
    for (auto it = node_.begin(); it != node_.end(); ++it) {
      if (!it->first.IsScalar() || consumed_.count(it->first.Scalar()) > 0) continue;
      if (likely_misspelling(it->first.Scalar(), key)) {
        fail(it->first, "unknown key '" + it->first.Scalar() + "' in " + context_ +
                            ": did you mean '" + key + "'? (missing field '" + key + "')");
      }
    }
    fail(node_, "missing field '" + key + "' in " + context_);
  }
  return n;
}

std::optional<YAML::Node> MapReader::optional_child(const std::string& key) {
  consumed_.insert(key);
  const YAML::Node n = node_[key];
  if (!n) return std::nullopt;
  return n;
}

MapReader MapReader::map(const std::string& key) {
  const YAML::Node n = child(key);
  if (!n.IsMap()) fail(n, "'" + key + "' must be a mapping, found " + kind_name(n));
  return MapReader(file_, n, context_ + "." + key);
}

std::optional<MapReader> MapReader::optional_map(const std::string& key) {
  auto n = optional_child(key);
  if (!n) return std::nullopt;
  if (!n->IsMap()) fail(*n, "'" + key + "' must be a mapping, found " + kind_name(*n));
  return MapReader(file_, *n, context_ + "." + key);
}

std::string MapReader::string(const std::string& key) {
  return to_string(child(key), key);
}

std::string MapReader::to_string(const YAML::Node& n, const std::string& what) const {
  if (!n.IsScalar()) fail(n, "'" + what + "' must be a string, found " + kind_name(n));
  if (const auto problem = files::find_text_problem(n.Scalar())) {
    fail(n, "'" + what + "' decodes to " + problem->what +
                ": write the character itself, not the escape \\_ or \\N");
  }
  return n.Scalar();
}

std::string MapReader::path(const std::string& key) {
  namespace fs = std::filesystem;
  const fs::path p(string(key));
  if (p.is_absolute()) return p.string();
  return (fs::path(file_).parent_path() / p).lexically_normal().string();
}

std::string MapReader::string_or(const std::string& key, const std::string& fallback) {
  return has(key) ? string(key) : (allow(key), fallback);
}

double MapReader::to_number(const YAML::Node& n, const std::string& what) const {
  if (!n.IsScalar()) fail(n, "'" + what + "' must be a number, found " + kind_name(n));
  const std::string& s = n.Scalar();
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || end == s.c_str() || *end != '\0') {
    // YAML spellings of infinity / NaN are numbers, but not finite ones.
    if (s == ".inf" || s == "-.inf" || s == ".nan" || s == ".NaN" || s == ".Inf" || s == "-.Inf") {
      fail(n, "'" + what + "' must be a finite number, found '" + s + "'");
    }
    fail(n, "'" + what + "' must be a number, found '" + s + "'");
  }
  if (!std::isfinite(v)) fail(n, "'" + what + "' must be a finite number, found '" + s + "'");
  return v;
}

std::int64_t MapReader::to_integer(const YAML::Node& n, const std::string& what) const {
  if (!n.IsScalar()) fail(n, "'" + what + "' must be an integer, found " + kind_name(n));
  const std::string& s = n.Scalar();
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(s.c_str(), &end, 0);
  if (s.empty() || end == s.c_str() || *end != '\0' || errno == ERANGE) {
    fail(n, "'" + what + "' must be an integer, found '" + s + "'");
  }
  return v;
}

std::vector<double> MapReader::to_numbers(const YAML::Node& n, const std::string& what) const {
  if (!n.IsSequence()) fail(n, "'" + what + "' must be a list of numbers, found " + kind_name(n));
  std::vector<double> out;
  out.reserve(n.size());
  for (std::size_t i = 0; i < n.size(); ++i) {
    out.push_back(to_number(n[i], what + "[" + std::to_string(i) + "]"));
  }
  return out;
}

double MapReader::number(const std::string& key) {
  return to_number(child(key), key);
}

double MapReader::number_or(const std::string& key, double fallback) {
  return has(key) ? number(key) : (allow(key), fallback);
}

std::int64_t MapReader::integer(const std::string& key) {
  return to_integer(child(key), key);
}

std::int64_t MapReader::integer_or(const std::string& key, std::int64_t fallback) {
  return has(key) ? integer(key) : (allow(key), fallback);
}

bool MapReader::boolean(const std::string& key) {
  const YAML::Node n = child(key);
  if (n.IsScalar()) {
    const std::string& s = n.Scalar();
    if (s == "true" || s == "True" || s == "yes" || s == "on") return true;
    if (s == "false" || s == "False" || s == "no" || s == "off") return false;
  }
  fail(n, "'" + key + "' must be true or false");
}

bool MapReader::boolean_or(const std::string& key, bool fallback) {
  return has(key) ? boolean(key) : (allow(key), fallback);
}

std::vector<double> MapReader::numbers(const std::string& key) {
  return to_numbers(child(key), key);
}

std::string MapReader::choice(const std::string& key, const std::vector<std::string>& choices) {
  const YAML::Node n = child(key);
  if (n.IsScalar()) {
    for (const auto& c : choices) {
      if (n.Scalar() == c) return c;
    }
  }
  std::string list;
  for (const auto& c : choices) list += (list.empty() ? "" : ", ") + c;
  fail(n, "'" + key + "' must be one of " + list + ", found '" +
              (n.IsScalar() ? n.Scalar() : std::string(kind_name(n))) + "'");
}

std::string MapReader::choice_or(const std::string& key, const std::vector<std::string>& choices,
                                 const std::string& fallback) {
  return has(key) ? choice(key, choices) : (allow(key), fallback);
}

void MapReader::finish() const {
  for (auto it = node_.begin(); it != node_.end(); ++it) {
    const std::string key = it->first.IsScalar() ? it->first.Scalar() : std::string("?");
    if (consumed_.count(key) == 0) {
      std::string known;
      for (const auto& k : consumed_) known += (known.empty() ? "" : ", ") + k;
      std::string near =
          files::closest_match(key, std::vector<std::string>(consumed_.begin(), consumed_.end()));
      if (!near.empty() && !likely_misspelling(key, near)) near.clear();  // a6: a3 or a5?
      throw ConfigError(file_, line_of(it->first),
                        "unknown key '" + key + "' in " + context_ +
                            (near.empty() ? std::string() : ": did you mean '" + near + "'?") +
                            (known.empty() ? std::string() : " (expected one of: " + known + ")"));
    }
  }
}

}  // namespace exodaq
