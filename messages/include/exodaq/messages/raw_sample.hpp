#pragma once
// A source's sample <-> encoder_raw_t, field for field: the raw channel is
// what a replay runs the pipeline on again. Allocation-free (loop thread).
#include "exodaq/drivers/encoder_sample.hpp"
#include "exodaq/encoder_raw_t.hpp"

namespace exodaq::messages {

// The sample's content (presence, board sequence, counts, index latches,
// board state and errors, source flags, wall_ns). The header (utime, mono_ns,
// seq, run_id) is the caller's: it belongs to the cycle, not the sample.
void to_encoder_raw(const drivers::EncoderSample& sample, encoder_raw_t& out) noexcept;

// The recorded sample: mono_ns and the content as recorded, wall_ns =
// utime * 1000 (so utime maps back exactly), every channel fresh when present.
void from_encoder_raw(const encoder_raw_t& raw, drivers::EncoderSample& out) noexcept;

}  // namespace exodaq::messages
