#pragma once
// A recording loaded for replay (private to the replay backend): the samples
// in order, what was not replayed and why, and the counters at its end.
#include <cstdint>
#include <string>
#include <vector>

#include "exodaq/drivers/replay_source.hpp"

namespace exodaq::drivers::replay {

struct Entry {
  EncoderSample sample;
  std::int64_t seq = -1;  // recorded seq (lcm); -1: the loop counts (candump)
};

struct Recording {
  std::vector<Entry> entries;
  std::vector<ReplayIssue> issues;
  ReplayLoadSummary summary;
  SourceStats stats;  // at the end of the input

  static constexpr std::size_t kMaxStoredIssues = 1000;
  void note(std::int64_t where, std::string what) {
    if (issues.size() < kMaxStoredIssues) issues.push_back({where, std::move(what)});
  }
};

// lcm-logger logs: the encoder_raw_t channel, with the loop's own flags from
// the recorded joint_state_t of the same cycle. Throws std::runtime_error.
void load_lcm(const ReplaySettings& settings, const SourceContext& context, Recording& out);

// candump -l / -L logs, decoded by the BoardDecoder. Throws std::runtime_error.
void load_candump(const std::string& path, Recording& out);

}  // namespace exodaq::drivers::replay
