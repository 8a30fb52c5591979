#pragma once
// Private to the calibration library: the encoder readers of the project's
// own recordings (an `exodaq export` CSV, an LCM log's joint states), shared
// by inputs.cpp and encoder_logs.cpp.
#include <string>
#include <vector>

#include "csv_text.hpp"
#include "exodaq/calibration/inputs.hpp"

namespace exodaq::calibration::detail {

// `exodaq export`'s dialect: the rows after the header `head` (line head_line).
EncoderSeries parse_export_csv(LineReader& in, const std::vector<std::string>& head, int head_line,
                               const EncoderReadOptions& o);

}  // namespace exodaq::calibration::detail
