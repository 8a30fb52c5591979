#pragma once
// The error every exodaq file reader throws: "file:line: what". Kept apart
// from yaml_reader.hpp so that code which only reports or catches it does not
// include yaml-cpp.
#include <stdexcept>
#include <string>

namespace exodaq {

// "file:line: what" (line is 1-based; omitted when unknown).
class ConfigError : public std::runtime_error {
 public:
  ConfigError(std::string file, int line, const std::string& what);
  const std::string& file() const noexcept { return file_; }
  int line() const noexcept { return line_; }
  const std::string& reason() const noexcept { return reason_; }

 private:
  std::string file_;
  int line_;
  std::string reason_;
};

}  // namespace exodaq
