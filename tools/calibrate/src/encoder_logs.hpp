#pragma once
// Private to the calibration library: the encoder readers of the project's
// own recordings (an `exodaq export` CSV, an LCM log's joint states), shared
// by inputs.cpp and encoder_logs.cpp.
#include <string>
#include <vector>

#include "exodaq/calibration/inputs.hpp"

namespace exodaq::calibration::detail {

// One CSV line: its 1-based number and its fields.
struct CsvRow {
  int number = 0;
  std::vector<std::string> fields;
};

// A whole input CSV (files::read_input within kMaxCsvBytes; ConfigError).
std::string read_csv_text(const std::string& path);

// `exodaq export`'s dialect: rows[0] is the header.
EncoderSeries parse_export_csv(const std::vector<CsvRow>& rows, const std::string& name,
                               const EncoderReadOptions& o);

}  // namespace exodaq::calibration::detail
