#pragma once
// Waiting for a running exodaqd to get somewhere, by its own status channel
// (10 Hz), instead of sleeping for a time a loaded machine may not honour:
// "until seq 12000", "until joint 1 is homed". The timeout only guards
// against a daemon that never gets there. Needs exodaq_messages.
#include <chrono>
#include <cstdint>
#include <functional>
#include <string>
#include <variant>

#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/status_t.hpp"

namespace exodaq::test {

// Until a status_t on `prefix`EXO_STATUS at `url` satisfies `done`; that
// status, or the default status_t (run_id 0) after `timeout`.
inline status_t wait_for_status(const std::string& url, const std::string& prefix,
                                const std::function<bool(const status_t&)>& done,
                                std::chrono::seconds timeout = std::chrono::seconds(120)) {
  messages::Subscriber sub(url);
  status_t found{};
  bool got = false;
  sub.subscribe(messages::channel_name(prefix, messages::Kind::kStatus), messages::Kind::kStatus,
                [&](const messages::Received& r) {
                  const auto& s = std::get<status_t>(r.msg);
                  if (!got && done(s)) {
                    found = s;
                    got = true;
                  }
                });
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!got && std::chrono::steady_clock::now() < end) sub.handle(100);
  return found;
}

// Until the daemon has used seq `seq` (run or skipped): the rig's time since
// start is seq / rate whatever the machine's speed. True when it got there.
inline bool wait_for_seq(const std::string& url, const std::string& prefix, std::int64_t seq,
                         std::chrono::seconds timeout = std::chrono::seconds(120)) {
  return wait_for_status(
             url, prefix, [seq](const status_t& s) { return s.seq >= seq; }, timeout)
             .run_id != 0;
}

}  // namespace exodaq::test
