#pragma once
// One publisher per channel set (an LCM URL and a channel prefix;
// docs/operations.md, "Several daemons"):
// - InstanceLock: an flock on <runtime dir>/exodaqd-<hash of the group,
//   port and prefix>.lock, held for the life of the process (the kernel releases it when
//   the process dies, however it dies). The file names the holder: pid, run id,
//   config. A second daemon on the same host fails to take it and is refused.
// - ForeignRunListener: a daemon on another host shares the multicast group
//   but not the lock, so the own status channel is listened to: for a short
//   window before start (anything heard is another publisher), then on its own
//   thread while running (another run id, or this daemon's own run id on a
//   status this loop did not publish: the acquisition is told through one
//   atomic, an error is logged once per episode, and a recovery when it is no
//   longer heard).
#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>

#include "exodaq/status_t.hpp"

namespace exodaq::messages {
class Subscriber;
}
namespace exodaq::core {
class Acquisition;
class UdpmChannelReceiver;
}  // namespace exodaq::core
namespace exodaq::settings {
struct ServiceConfig;
}

namespace exodaq::daemon {

// Another daemon publishes on this channel set; what() names it.
class InstanceConflict : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Where lock files go: $RUNTIME_DIRECTORY (systemd's RuntimeDirectory=, the
// first of a colon-separated list), /run/exodaq if writable (root creates it
// when missing), then $XDG_RUNTIME_DIR. Never a folder any user can write
// (no /tmp): throws std::runtime_error saying what to set when none fits.
std::string runtime_directory();

// What identifies a channel set: "udpm://GROUP:PORT\nPREFIX" with the group
// as a dotted quad and the port as a number (LCM's defaults filled in) and
// the URL's options (ttl, recv_buf_size, ...) left out, since they change
// where datagrams go, not which channels they are; other providers: the URL
// without its options.
std::string channel_set_key(const std::string& url, const std::string& prefix);

// <dir>/exodaqd-<16 hex digits of FNV-1a 64 over channel_set_key()>.lock
std::string lock_path(const std::string& dir, const std::string& url, const std::string& prefix);

class InstanceLock {
 public:
  struct Identity {
    std::string url;
    std::string prefix;
    std::string config_path;
    std::string rig;
  };
  // Takes the lock at `path` (created if needed) and writes the holder's
  // identity (run id still unknown). A file there that is not to be believed
  // (not a regular file, hard-linked, or owned by a user other than this one,
  // root or the folder's owner) is replaced, with a warning, when it can be,
  // and refused with std::runtime_error saying why when not. Throws
  // InstanceConflict naming the holder (pid, run id, config) when another
  // process holds it, std::runtime_error when the file cannot be opened.
  InstanceLock(const std::string& path, Identity who);
  ~InstanceLock();  // closes the file: the lock is released (the file stays)
  InstanceLock(const InstanceLock&) = delete;
  InstanceLock& operator=(const InstanceLock&) = delete;

  // Rewrites the file with the run id once it is known.
  void record_run_id(std::int64_t run_id);
  const std::string& path() const noexcept { return path_; }

 private:
  void open_trusted();
  void write_contents(const std::string& run_id_text);

  std::string path_;
  Identity who_;
  int fd_ = -1;
  bool writable_ = true;
};

// Listens on <prefix>EXO_STATUS.
class ForeignRunListener {
 public:
  struct Heard {
    std::int64_t run_id = 0;
    std::string rig;
  };
  // A run id not heard for this long ends an episode (10 status periods at 10 Hz).
  static constexpr std::int64_t kEpisodeEndNs = 1'000'000'000;

  // Throws std::runtime_error if LCM cannot be set up on `url`.
  ForeignRunListener(const std::string& url, const std::string& prefix);
  ~ForeignRunListener();  // stops the watch thread
  ForeignRunListener(const ForeignRunListener&) = delete;
  ForeignRunListener& operator=(const ForeignRunListener&) = delete;

  // Before this daemon publishes anything: listens for `window_ms`; the first
  // status with a run id heard is another publisher's.
  std::optional<Heard> listen_before_start(int window_ms);

  // While running: a thread handles the channel; a status that is not this
  // loop's sets acq.set_foreign_run_id() to the run id it carries until none
  // was heard for kEpisodeEndNs. Not this loop's: another run id, or
  // acq.run_id() with a seq this loop has not published yet
  // (acq.last_status_seq()) or not after the last own status heard (a replay
  // of this run, a forged stream: own_run_impostor()). `acq` must outlive
  // this listener (or its stop()).
  void watch(core::Acquisition& acq);
  void stop() noexcept;

  // Why a status carrying this daemon's own run id is not this loop's
  // (empty: it is). `last_own_seq`: the last own status heard (-1: none).
  static std::string own_run_impostor(std::int64_t seq, std::int64_t last_own_seq,
                                      std::int64_t published_seq);

 private:
  int handle(int timeout_ms);
  void on_status(const status_t& status);
  void watch_loop() noexcept;
  void end_episode_if_quiet();

  std::string channel_;
  // udpm:// : a socket that the kernel wakes only for the status channel
  // (udpm_receiver.hpp); any other URL: an LCM subscription.
  std::unique_ptr<core::UdpmChannelReceiver> udpm_;
  std::unique_ptr<messages::Subscriber> sub_;
  status_t status_;                   // decoded into, on the listening thread
  core::Acquisition* acq_ = nullptr;  // null before watch(): start-up window
  std::optional<Heard> first_heard_;
  std::int64_t episode_run_id_ = 0;  // 0: no episode
  std::int64_t last_own_seq_ = -1;   // the seq of the last status of this loop heard
  std::int64_t last_foreign_ns_ = 0;
  std::int64_t episodes_ = 0;
  std::atomic<bool> stopping_{false};
  std::thread thread_;
};

// The start-up listening window: two status periods of `status_rate_hz`, at
// least 250 ms.
int startup_listen_ms(double status_rate_hz);

// The lock and the listener as the daemon uses them.
class ChannelClaim {
 public:
  // Takes the lock, then listens for startup_listen_ms(). Throws
  // InstanceConflict naming the other publisher (lock holder, or a run id
  // heard), std::runtime_error when the lock or LCM cannot be set up.
  ChannelClaim(const settings::ServiceConfig& config, const std::string& config_path);
  // Before acq.start(): the lock file names the run id; the listener watches.
  void attach(core::Acquisition& acq);
  // Before the acquisition goes away (and before logging shuts down).
  void detach() noexcept { listener_.stop(); }
  const std::string& lock_file() const noexcept { return lock_.path(); }
  int listened_ms() const noexcept { return listened_ms_; }

 private:
  InstanceLock lock_;
  ForeignRunListener listener_;
  int listened_ms_ = 0;
};

}  // namespace exodaq::daemon
