#pragma once
// One pass over a recording (private to the replay backend): the readers hand
// each sample to a sink as they decode it, in order, and note in the pass what
// was not replayed and why, and the counters at its end. Nothing is kept per
// sample: the first pass counts, the second feeds the read-ahead ring.
#include <cstdint>
#include <string>
#include <vector>

#include "exodaq/drivers/frame_assembler.hpp"
#include "exodaq/drivers/replay_source.hpp"

namespace exodaq::drivers::replay {

struct Entry {
  EncoderSample sample;
  std::int64_t seq = -1;  // recorded seq (lcm); -1: the loop counts (candump)
};

// Receives the samples of a pass; false stops the pass (the reader returns).
class EntrySink {
 public:
  virtual bool put(const Entry& entry) = 0;

 protected:
  ~EntrySink() = default;
};

struct Pass {
  std::vector<ReplayIssue> issues;
  ReplayLoadSummary summary;
  SourceStats stats;           // at the end of the input
  std::string joint_channel;   // lcm: the joint_state_t channel beside the raw one ("": none)
  std::string homing_channel;  // lcm: the homing_t channel beside the raw one ("": none)
  JointResumeSet resume{};     // lcm: valid when summary.resumed_at_seq >= 0

  static constexpr std::size_t kMaxStoredIssues = 1000;
  void note(std::int64_t where, std::string what, bool problem = true) {
    if (issues.size() < kMaxStoredIssues) issues.push_back({where, std::move(what), problem});
  }
};

// lcm-logger logs: the encoder_raw_t channel, with the loop's own flags from
// the recorded joint_state_t of the same cycle. `counted`: the first pass's
// results, for the second (its channels, not looked for again); nullptr for
// the first, which does without the loop's flags (they change no counter).
// Throws std::runtime_error.
void read_lcm(const ReplaySettings& settings, const SourceContext& context, const Pass* counted,
              Pass& out, EntrySink& sink);

// candump -l / -L logs, their frames assembled by the protocol's assembler
// (a fresh one per pass). Throws std::runtime_error.
void read_candump(const std::string& path, FrameAssembler& assembler, Pass& out, EntrySink& sink);

}  // namespace exodaq::drivers::replay
