#pragma once
// Private to the calibration library: the marker file readers (marker_files.cpp
// for the text formats, c3d_reader.cpp for C3D) and what they share.
#include <string>
#include <vector>

#include "exodaq/calibration/inputs.hpp"

namespace exodaq::calibration::detail {

// The 1-based ids of `wanted` among a labelled file's labels (MarkerRef's
// rules); empty `wanted`: the file's one marker. Errors name the file and
// list its labels.
std::vector<int> resolve_labels(const std::vector<std::string>& labels,
                                const std::vector<MarkerRef>& wanted, const std::string& name);

// The first bytes of a C3D file: byte 2 is 0x50 and byte 1 points at the
// parameter section.
bool looks_like_c3d(const unsigned char* bytes, std::size_t n) noexcept;

// A C3D file's points `wanted` (labels from POINT:LABELS, LABELS2, ...).
MarkerSeries read_c3d(const std::string& path, const std::vector<MarkerRef>& wanted);

}  // namespace exodaq::calibration::detail
