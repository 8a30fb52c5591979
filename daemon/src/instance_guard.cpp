#include "exodaq/daemon/instance_guard.hpp"

#include <fcntl.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>

#include "exodaq/common/clock_now.hpp"
#include "exodaq/config/service_config.hpp"
#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/udpm_receiver.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/messages/subscriber.hpp"

namespace exodaq::daemon {

namespace {

bool writable_dir(const std::string& dir) {
  return !dir.empty() && access(dir.c_str(), W_OK | X_OK) == 0;
}

std::uint64_t fnv1a64(const std::string& text) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const unsigned char c : text) {
    h ^= c;
    h *= 0x100000001b3ULL;
  }
  return h;
}

// key=value lines of a lock file.
std::map<std::string, std::string> read_lock_file(int fd) {
  std::map<std::string, std::string> out;
  char buf[2048];
  const ssize_t n = pread(fd, buf, sizeof(buf) - 1, 0);
  if (n <= 0) return out;
  std::string text(buf, static_cast<std::size_t>(n));
  std::size_t start = 0;
  while (start < text.size()) {
    std::size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    const std::string line = text.substr(start, end - start);
    if (const auto eq = line.find('='); eq != std::string::npos)
      out[line.substr(0, eq)] = line.substr(eq + 1);
    start = end + 1;
  }
  return out;
}

std::string conflict_text(const std::string& path, const InstanceLock::Identity& who, int fd) {
  auto holder = read_lock_file(fd);
  const auto get = [&holder](const char* key) {
    const auto it = holder.find(key);
    return it == holder.end() || it->second.empty() ? std::string("?") : it->second;
  };
  return "another exodaqd already publishes on LCM " + who.url + " with prefix '" + who.prefix +
         "': pid " + get("pid") + ", run id " + get("run_id") + ", rig " + get("rig") +
         ", config " + get("config") + " (lock " + path +
         "); stop it, or give this daemon another lcm.prefix or lcm.url";
}

}  // namespace

std::string runtime_directory() {
  if (const char* rd = std::getenv("RUNTIME_DIRECTORY"); rd != nullptr && *rd != '\0') {
    std::string first(rd);
    first = first.substr(0, first.find(':'));
    if (writable_dir(first)) return first;
  }
  if (writable_dir("/run/exodaq")) return "/run/exodaq";
  if (const char* xdg = std::getenv("XDG_RUNTIME_DIR"); xdg != nullptr && writable_dir(xdg))
    return xdg;
  return "/tmp";
}

std::string lock_path(const std::string& dir, const std::string& url, const std::string& prefix) {
  char name[48];
  std::snprintf(name, sizeof(name), "exodaqd-%016llx.lock",
                static_cast<unsigned long long>(fnv1a64(url + "\n" + prefix)));
  return dir + "/" + name;
}

InstanceLock::InstanceLock(const std::string& path, Identity who)
    : path_(path), who_(std::move(who)) {
  fd_ = open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
  if (fd_ < 0 && errno == EACCES) {
    // Left by another user (a shared /tmp): locking needs no write access,
    // naming the holder does.
    fd_ = open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW);
    writable_ = false;
  }
  if (fd_ < 0) {
    throw std::runtime_error("cannot open the instance lock " + path + ": " +
                             strerrordesc_np(errno));
  }
  if (flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    std::string text = err == EWOULDBLOCK ? conflict_text(path_, who_, fd_)
                                          : "cannot lock " + path_ + ": " + strerrordesc_np(err);
    close(fd_);
    fd_ = -1;
    if (err == EWOULDBLOCK) throw InstanceConflict(text);
    throw std::runtime_error(text);
  }
  write_contents("(starting)");
}

InstanceLock::~InstanceLock() {
  if (fd_ >= 0) close(fd_);
}

void InstanceLock::record_run_id(std::int64_t run_id) {
  write_contents(msg::run_id_text(run_id));
}

void InstanceLock::write_contents(const std::string& run_id_text) {
  if (!writable_) return;
  const std::string text = "pid=" + std::to_string(getpid()) + "\nrun_id=" + run_id_text +
                           "\nrig=" + who_.rig + "\nconfig=" + who_.config_path +
                           "\nurl=" + who_.url + "\nprefix=" + who_.prefix + "\n";
  // Written over the old contents, then cut to length: a reader never sees an empty file.
  if (pwrite(fd_, text.data(), text.size(), 0) != static_cast<ssize_t>(text.size()) ||
      ftruncate(fd_, static_cast<off_t>(text.size())) != 0) {
    spdlog::warn("cannot write the instance lock {}: {}", path_, strerrordesc_np(errno));
  }
}

int startup_listen_ms(double status_rate_hz) {
  const double ms = status_rate_hz > 0.0 ? 2000.0 / status_rate_hz : 250.0;
  return static_cast<int>(std::max(250.0, ms));
}

ForeignRunListener::ForeignRunListener(const std::string& url, const std::string& prefix)
    : channel_(msg::channel_name(prefix, msg::Kind::kStatus)) {
  if (const auto address = core::parse_udpm_url(url)) {
    udpm_ = std::make_unique<core::UdpmChannelReceiver>(*address, url, channel_);
    return;
  }
  sub_ = std::make_unique<msg::Subscriber>(url);
  sub_->subscribe(channel_, msg::Kind::kStatus, [this](const msg::Received& r) {
    const auto& st = std::get<status_t>(r.msg);
    on_status(st.run_id, st.rig);
  });
}

// Waits up to timeout_ms and handles what arrived. < 0: the transport failed.
int ForeignRunListener::handle(int timeout_ms) {
  if (!udpm_) return sub_->handle(timeout_ms);
  const int size = udpm_->receive(timeout_ms);
  if (size <= 0) return size;
  if (status_.decode(udpm_->payload(), 0, size) >= 0) on_status(status_.run_id, status_.rig);
  return 1;
}

ForeignRunListener::~ForeignRunListener() {
  stop();
}

std::optional<ForeignRunListener::Heard> ForeignRunListener::listen_before_start(int window_ms) {
  const std::int64_t end = mono_now_ns() + std::int64_t{window_ms} * 1'000'000;
  for (std::int64_t now = mono_now_ns(); now < end && !first_heard_; now = mono_now_ns()) {
    handle(static_cast<int>(std::max<std::int64_t>(1, (end - now) / 1'000'000)));
  }
  return first_heard_;
}

void ForeignRunListener::watch(core::Acquisition& acq) {
  acq_ = &acq;
  thread_ = std::thread([this] { watch_loop(); });
}

void ForeignRunListener::stop() noexcept {
  stopping_.store(true);
  if (thread_.joinable()) thread_.join();
}

void ForeignRunListener::watch_loop() noexcept {
  pthread_setname_np(pthread_self(), "exodaq-foreign");
  while (!stopping_.load()) {
    try {
      if (handle(100) < 0) std::this_thread::sleep_for(std::chrono::milliseconds(100));
      end_episode_if_quiet();
    } catch (const std::exception& e) {
      spdlog::error("status listener: {}", e.what());
    }
  }
}

void ForeignRunListener::on_status(std::int64_t run_id, const std::string& rig) {
  if (run_id == 0) return;  // the all-zero start-up message
  if (acq_ == nullptr) {
    if (!first_heard_) first_heard_ = Heard{run_id, rig};
    return;
  }
  if (run_id == acq_->run_id()) return;
  last_foreign_ns_ = mono_now_ns();
  if (episode_run_id_ != 0) return;  // one error per episode, even with several others
  episode_run_id_ = run_id;
  ++episodes_;
  acq_->set_foreign_run_id(run_id);
  spdlog::error(
      "another publisher on {}: run id {} (rig {}) beside this daemon's run {}; every sample "
      "is flagged FOREIGN_RUN and the state is degraded while it is heard (episode {})",
      channel_, msg::run_id_text(run_id), rig.empty() ? "?" : rig, msg::run_id_text(acq_->run_id()),
      episodes_);
}

void ForeignRunListener::end_episode_if_quiet() {
  if (episode_run_id_ == 0 || mono_now_ns() - last_foreign_ns_ < kEpisodeEndNs) return;
  acq_->set_foreign_run_id(0);
  spdlog::warn("run id {} no longer heard on {} for {} ms: FOREIGN_RUN cleared",
               msg::run_id_text(episode_run_id_), channel_, kEpisodeEndNs / 1'000'000);
  episode_run_id_ = 0;
}

ChannelClaim::ChannelClaim(const config::ServiceConfig& config, const std::string& config_path)
    : lock_(lock_path(runtime_directory(), config.lcm.url, config.lcm.prefix),
            InstanceLock::Identity{config.lcm.url, config.lcm.prefix, config_path, config.rig}),
      listener_(config.lcm.url, config.lcm.prefix),
      listened_ms_(startup_listen_ms(config.loop.status_rate_hz)) {
  if (const auto heard = listener_.listen_before_start(listened_ms_)) {
    throw InstanceConflict("another exodaqd already publishes on LCM " + config.lcm.url +
                           " with prefix '" + config.lcm.prefix + "': run id " +
                           msg::run_id_text(heard->run_id) + ", rig " +
                           (heard->rig.empty() ? "?" : heard->rig) + " heard on " +
                           msg::channel_name(config.lcm.prefix, msg::Kind::kStatus) +
                           " (another host, or a daemon with another runtime directory); stop "
                           "it, or give this daemon another lcm.prefix or lcm.url");
  }
}

void ChannelClaim::attach(core::Acquisition& acq) {
  lock_.record_run_id(acq.run_id());
  listener_.watch(acq);
}

}  // namespace exodaq::daemon
