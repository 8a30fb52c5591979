#include "publish_watch.hpp"

#include <cstdio>
#include <cstring>

namespace exodaq::daemon {

std::string errno_text(int error) {
  const char* name = strerrorname_np(error);
  const char* text = strerrordesc_np(error);
  return std::string(text != nullptr ? text : "unknown error") + " (" +
         (name != nullptr ? name : std::to_string(error)) + ")";
}

std::vector<PublishLogLine> PublishWatch::check(const core::PublishHealth& h, std::int64_t now_ns) {
  std::vector<PublishLogLine> out;
  char text[400];
  // A recovery first: an episode that ended between two looks is still reported.
  if (h.recoveries != seen_recoveries_) {
    seen_recoveries_ = h.recoveries;
    std::snprintf(text, sizeof text,
                  "publishing on %s recovered at seq %lld: %lld messages lost from seq %lld over "
                  "%.3f s",
                  url_.c_str(), static_cast<long long>(h.recovered_to_seq),
                  static_cast<long long>(h.recovered_lost),
                  static_cast<long long>(h.recovered_from_seq),
                  static_cast<double>(h.recovered_after_ns) / 1e9);
    out.push_back({false, text, "publish_recovered", 0});
    failing_logged_ = false;
  }
  if (h.failing_since_ns != 0 && !failing_logged_) {
    failing_logged_ = true;
    std::snprintf(text, sizeof text,
                  "publishing on %s failing since seq %lld: %s; messages are lost until it "
                  "recovers (the LCM socket is re-created after 1 s, then with backoff)",
                  url_.c_str(), static_cast<long long>(h.failing_since_seq),
                  errno_text(h.last_errno).c_str());
    out.push_back({true, text, "publish_failing", h.last_errno});
  }
  if (h.reopens != seen_reopens_) {
    seen_reopens_ = h.reopens;
    if (h.failing_since_ns != 0) {
      std::snprintf(text, sizeof text,
                    "publishing on %s still failing after %.1f s (%lld messages lost, %s): "
                    "re-created the LCM socket (%s)",
                    url_.c_str(), static_cast<double>(now_ns - h.failing_since_ns) / 1e9,
                    static_cast<long long>(h.lost_in_episode), errno_text(h.last_errno).c_str(),
                    h.last_reopen_errno == 0 ? "ok" : errno_text(h.last_reopen_errno).c_str());
      out.push_back({true, text, "publish_reopen", h.last_errno});
    }
  }
  return out;
}

std::string PublishWatch::status_text(const core::PublishHealth& h) {
  if (h.failing_since_ns == 0) return "";
  const char* name = strerrorname_np(h.last_errno);
  return ", publishing FAILING since seq " + std::to_string(h.failing_since_seq) + " (" +
         (name != nullptr ? name : "error") + ", " + std::to_string(h.lost_in_episode) + " lost)";
}

}  // namespace exodaq::daemon
