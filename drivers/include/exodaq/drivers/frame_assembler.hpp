#pragma once
// A CAN protocol's assembly of recorded frames into samples, for the replay
// of candump logs: every frame of the log in order, one sample per cycle out,
// with the same assembly and flags as the protocol's live source. Each CAN
// backend offers one (Backend::assembler); the replay of a candump log uses
// the configured protocol's. One owner; allocation-free after construction.
#include <cstdint>

#include "exodaq/drivers/can_frame.hpp"
#include "exodaq/drivers/encoder_sample.hpp"

namespace exodaq::drivers {

class FrameAssembler {
 public:
  virtual ~FrameAssembler() = default;

  // Every frame of the log; mono_ns and wall_ns are its recorded stamp.
  virtual void on_frame(const can::CanFrame& frame) noexcept = 0;
  // The oldest completed cycle; false: none.
  virtual bool poll(EncoderSample& out) noexcept = 0;
  // At the end of the log: the cycle still being assembled; false: none.
  virtual bool finish(EncoderSample& out) noexcept = 0;
  // What the protocol counted (frames, bad frames, gaps, bus errors...).
  virtual SourceStats stats() const noexcept = 0;
};

}  // namespace exodaq::drivers
