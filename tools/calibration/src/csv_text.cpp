#include "csv_text.hpp"

#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <map>

#include "exodaq/common/files.hpp"
#include "exodaq/common/yaml_reader.hpp"
#include "exodaq/messages/csv.hpp"

namespace exodaq::calibration::detail {

using exodaq::ConfigError;

namespace {
constexpr std::size_t kBufferBytes = 64 * 1024;
}

LineReader LineReader::open_file(const std::string& path) {
  LineReader r;
  r.name_ = path;
  files::InputInfo info;
  try {
    r.fd_ = files::open_input(path, files::kMaxCsvBytes, &info);
  } catch (const files::FileError& e) {
    throw ConfigError(path, 0, e.reason());
  }
  r.size_ = info.size;
  r.buffer_.resize(kBufferBytes);
  return r;
}

LineReader LineReader::from_text(std::string_view text, std::string name) {
  LineReader r;
  r.name_ = std::move(name);
  r.text_ = text;
  r.size_ = static_cast<std::int64_t>(text.size());
  return r;
}

LineReader::LineReader(LineReader&& o) noexcept {
  *this = std::move(o);
}

LineReader& LineReader::operator=(LineReader&& o) noexcept {
  if (this != &o) {
    if (fd_ >= 0) ::close(fd_);
    name_ = std::move(o.name_);
    fd_ = o.fd_;
    o.fd_ = -1;
    text_ = o.text_;
    buffer_ = std::move(o.buffer_);
    pos_ = o.pos_;
    end_ = o.end_;
    eof_ = o.eof_;
    line_ = o.line_;
    size_ = o.size_;
  }
  return *this;
}

LineReader::~LineReader() {
  if (fd_ >= 0) ::close(fd_);
}

// Refills the buffer from the file; false at its end.
bool LineReader::fill() {
  if (eof_ || fd_ < 0) return false;
  while (true) {
    const ssize_t n = ::read(fd_, buffer_.data(), buffer_.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw ConfigError(name_, line_ + 1, "cannot read: " + files::errno_text(errno));
    pos_ = 0;
    end_ = static_cast<std::size_t>(n);
    if (n == 0) eof_ = true;
    return n > 0;
  }
}

bool LineReader::next(std::string& line) {
  line.clear();
  const int number = line_ + 1;
  auto take = [&](const char* p, std::size_t n) {
    if (std::memchr(p, '\0', n) != nullptr) {
      const auto col =
          line.size() +
          static_cast<std::size_t>(static_cast<const char*>(std::memchr(p, '\0', n)) - p) + 1;
      throw ConfigError(name_, number,
                        "NUL byte (a binary file?) at column " + std::to_string(col));
    }
    if (line.size() + n > kMaxLineBytes) {
      throw ConfigError(name_, number,
                        "line longer than " + std::to_string(kMaxLineBytes) +
                            " bytes (a binary or damaged file?)");
    }
    line.append(p, n);
  };
  bool any = false;
  if (fd_ < 0) {
    if (pos_ >= text_.size()) return false;
    const std::size_t nl = text_.find('\n', pos_);
    const std::size_t stop = nl == std::string_view::npos ? text_.size() : nl;
    take(text_.data() + pos_, stop - pos_);
    pos_ = nl == std::string_view::npos ? text_.size() : nl + 1;
    any = true;
  } else {
    while (true) {
      if (pos_ >= end_ && !fill()) break;
      any = true;
      const char* p = buffer_.data() + pos_;
      const auto* nl = static_cast<const char*>(std::memchr(p, '\n', end_ - pos_));
      if (nl == nullptr) {
        take(p, end_ - pos_);
        pos_ = end_;
        continue;
      }
      take(p, static_cast<std::size_t>(nl - p));
      pos_ += static_cast<std::size_t>(nl - p) + 1;
      break;
    }
    if (!any) return false;
  }
  if (!line.empty() && line.back() == '\r') line.pop_back();
  line_ = number;
  return true;
}

std::string trim(std::string_view s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string_view::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return std::string(s.substr(b, e - b + 1));
}

bool next_row(LineReader& in, std::string& line, std::vector<std::string>& fields) {
  while (in.next(line)) {
    const std::string t = trim(line);
    if (t.empty() || t[0] == '#') continue;
    fields = split_fields(t);
    return true;
  }
  return false;
}

std::vector<std::string> split_fields(std::string_view line) {
  std::vector<std::string> out;
  messages::csv::split(line, out, messages::csv::Spaces::kTrim);
  return out;
}

std::int64_t parse_int(const std::string& s, const std::string& name, int line,
                       const std::string& col) {
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(s.c_str(), &end, 10);
  if (s.empty() || *end != '\0' || errno == ERANGE) {
    throw ConfigError(name, line, "column '" + col + "': '" + s + "' is not an integer");
  }
  return v;
}

std::optional<double> parse_double(const std::string& s, const std::string& name, int line,
                                   const std::string& col, bool allow_missing) {
  if (allow_missing) {
    std::string l = s;
    std::transform(l.begin(), l.end(), l.begin(), [](unsigned char c) { return std::tolower(c); });
    if (l.empty() || l == "nan") return std::nullopt;
  }
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (s.empty() || *end != '\0') {
    throw ConfigError(name, line, "column '" + col + "': '" + s + "' is not a number");
  }
  if (!std::isfinite(v)) {
    throw ConfigError(name, line, "column '" + col + "': '" + s + "' is not a finite number");
  }
  return v;
}

// Header: column name -> index. Unknown columns are errors (a typo in a column
// name would otherwise silently fall back to a default).
std::map<std::string, std::size_t> csv_header(const std::vector<std::string>& fields, int line,
                                              const std::string& name,
                                              const std::vector<std::string>& required,
                                              const std::vector<std::string>& optional) {
  std::map<std::string, std::size_t> cols;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    const std::string& c = fields[i];
    const bool known = std::find(required.begin(), required.end(), c) != required.end() ||
                       std::find(optional.begin(), optional.end(), c) != optional.end();
    if (!known) {
      std::string all;
      for (const auto& r : required) all += (all.empty() ? "" : ", ") + r;
      for (const auto& o : optional) all += ", " + o + " (optional)";
      throw ConfigError(name, line, "unknown column '" + c + "' (expected " + all + ")");
    }
    if (cols.count(c)) throw ConfigError(name, line, "column '" + c + "' appears twice");
    cols[c] = i;
  }
  for (const auto& r : required) {
    if (!cols.count(r)) throw ConfigError(name, line, "missing column '" + r + "'");
  }
  return cols;
}

void wrong_field_count(const std::string& name, int line, std::size_t expected, std::size_t found) {
  throw ConfigError(
      name, line,
      "expected " + std::to_string(expected) + " fields, found " + std::to_string(found));
}

}  // namespace exodaq::calibration::detail
