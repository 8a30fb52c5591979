#pragma once
// Two publishers on one channel set, seen from a subscriber: their run ids
// interleave. A run id that comes back after another one was heard on the same
// prefix is a mix; one run followed by another (a daemon restarted) is not.
// Subscribers say so loudly instead of joining the two streams
// (docs/messages.md, "Run ids").
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <string>

namespace exodaq::messages {

struct RunMix {
  std::string prefix;
  std::int64_t first = 0;   // the run heard before
  std::int64_t second = 0;  // the run heard in between
};

// "two runs interleaved on prefix 'P': run ids <a> and <b> (two daemons
// publish on one channel set)".
std::string describe(const RunMix& mix);

class RunMixDetector {
 public:
  // One message's run id on `prefix` (0, the start-up messages: ignored).
  // Returns the mix the first time this prefix's run ids interleave.
  std::optional<RunMix> observe(const std::string& prefix, std::int64_t run_id);
  bool mixed() const noexcept { return mixed_; }

 private:
  struct Runs {
    std::int64_t current = 0;
    std::set<std::int64_t> seen;
    bool reported = false;
  };
  std::map<std::string, Runs> by_prefix_;
  bool mixed_ = false;
};

}  // namespace exodaq::messages
