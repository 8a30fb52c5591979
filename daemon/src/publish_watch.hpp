#pragma once
// The publish path's failure episodes (core::PublishHealth) as log lines: a
// warning naming the cause (errno, URL) when messages start to be refused,
// one per transport re-creation while it lasts, and a recovery line with what
// was lost. Main thread; the caller adds the journal fields.
#include <cstdint>
#include <string>
#include <vector>

#include "exodaq/core/publisher.hpp"

namespace exodaq::daemon {

struct PublishLogLine {
  bool warning = true;
  std::string text;
  std::string event;  // EXODAQ_EVENT: publish_failing, publish_reopen, publish_recovered
  int error = 0;      // errno (0: none)
};

class PublishWatch {
 public:
  explicit PublishWatch(std::string url) : url_(std::move(url)) {}

  // What changed since the last call (usually nothing).
  std::vector<PublishLogLine> check(const core::PublishHealth& h, std::int64_t now_ns);

  // For systemd's STATUS=: "" or ", publishing FAILING since seq N (ENETUNREACH)".
  static std::string status_text(const core::PublishHealth& h);

 private:
  std::string url_;
  bool failing_logged_ = false;
  std::int64_t seen_recoveries_ = 0;
  std::int64_t seen_reopens_ = 0;
};

// "Network is unreachable (ENETUNREACH)".
std::string errno_text(int error);

}  // namespace exodaq::daemon
