#pragma once
// Private to the calibration library: reading the CSV inputs line by line in
// bounded memory (docs/robustness.md "Memory"), splitting fields and parsing
// numbers, with errors "file:line: what" (exodaq::ConfigError).
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace exodaq::calibration::detail {

// Longest line read: a CSV line of a motion-capture export with a thousand
// markers is under 64 KiB. A longer one is a binary or damaged file.
inline constexpr std::size_t kMaxLineBytes = 1U << 20;

// Streams lines from a file (checked as files::open_input within
// files::kMaxCsvBytes) or from text: one buffer of 64 KiB plus the current
// line, whatever the input's size. A NUL byte or a line longer than
// kMaxLineBytes is an error naming the line: a binary file is refused at its
// first line, not read whole.
class LineReader {
 public:
  static LineReader open_file(const std::string& path);
  static LineReader from_text(std::string_view text, std::string name);
  LineReader(LineReader&&) noexcept;
  LineReader& operator=(LineReader&&) noexcept;
  ~LineReader();

  // The next line without its end ("\n" or "\r\n"); false at the end.
  bool next(std::string& line);
  int line() const noexcept { return line_; }  // 1-based number of the last line returned
  const std::string& name() const noexcept { return name_; }
  std::int64_t size() const noexcept { return size_; }  // input bytes

 private:
  LineReader() = default;
  bool fill();

  std::string name_;
  int fd_ = -1;
  std::string_view text_;  // from_text
  std::string buffer_;
  std::size_t pos_ = 0, end_ = 0;
  bool eof_ = false;
  int line_ = 0;
  std::int64_t size_ = 0;
};

std::string trim(std::string_view s);

// The next line of the project's CSVs that is not blank or a '#' comment, split
// into fields (LineReader::line() is its number); false at the end.
bool next_row(LineReader& in, std::string& line, std::vector<std::string>& fields);
// Comma-separated fields, trimmed; "double quoted" fields may hold commas
// ("" is a quote inside them). A line ending in ',' has an empty last field.
// messages::csv::split with Spaces::kTrim: the project's one CSV splitter.
std::vector<std::string> split_fields(std::string_view line);

// Integer / finite number of a field; errors name the file, line and column.
std::int64_t parse_int(const std::string& s, const std::string& name, int line,
                       const std::string& col);
// With allow_missing, "" / nan / NaN give nullopt.
std::optional<double> parse_double(const std::string& s, const std::string& name, int line,
                                   const std::string& col, bool allow_missing);

// Header: column name -> index. Unknown, repeated and missing columns are
// errors (a typo in a column name would otherwise silently fall back to a default).
std::map<std::string, std::size_t> csv_header(const std::vector<std::string>& fields, int line,
                                              const std::string& name,
                                              const std::vector<std::string>& required,
                                              const std::vector<std::string>& optional);

// The error for a row whose field count differs from the header's.
[[noreturn]] void wrong_field_count(const std::string& name, int line, std::size_t expected,
                                    std::size_t found);

}  // namespace exodaq::calibration::detail
