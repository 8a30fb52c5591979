#include "exodaq/messages/run_mix.hpp"

#include "exodaq/messages/message.hpp"

namespace exodaq::messages {

std::string describe(const RunMix& mix) {
  return "two runs interleaved on prefix '" + mix.prefix + "': run ids " + run_id_text(mix.first) +
         " and " + run_id_text(mix.second) +
         " (two daemons publish on one channel set; filter by run_id)";
}

std::optional<RunMix> RunMixDetector::observe(const std::string& prefix, std::int64_t run_id) {
  if (run_id == 0) return std::nullopt;
  Runs& r = by_prefix_[prefix];
  if (run_id == r.current) return std::nullopt;
  const std::int64_t previous = r.current;
  r.current = run_id;
  const bool back = !r.seen.insert(run_id).second;
  if (!back || r.reported) return std::nullopt;
  r.reported = true;
  mixed_ = true;
  return RunMix{prefix, run_id, previous};
}

}  // namespace exodaq::messages
