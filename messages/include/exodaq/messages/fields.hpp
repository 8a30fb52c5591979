#pragma once
// A message flattened to named scalar fields, for CSV and tables. Arrays
// become name_0 .. name_N-1; values are exact: integers in decimal, doubles in
// the shortest text that reads back to the same double, booleans 0/1, strings
// as they are. The names of a kind do not depend on the values.
#include <string>
#include <string_view>
#include <vector>

#include "exodaq/messages/message.hpp"

namespace exodaq::msg {

struct Field {
  std::string name;
  std::string value;
};
std::vector<Field> fields(const Message& m);
std::vector<std::string> field_names(Kind k);

// CSV (RFC 4180): quotes a value that holds a comma, quote or line break.
std::string csv_escape(std::string_view v);
std::string csv_line(const std::vector<std::string>& values);

// Exact shortest round-trip text of a double ("0.1", "1e-06", "nan", "inf").
std::string format_double(double v);

}  // namespace exodaq::msg
