#include "exodaq/daemon/instance_guard.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <pwd.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string_view>

#include "exodaq/common/clock_now.hpp"
#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/udpm_receiver.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq/messages/subscriber.hpp"
#include "exodaq/settings/service_config.hpp"

namespace exodaq::daemon {

namespace {

bool writable_dir(const std::string& dir) {
  struct stat st {};
  return !dir.empty() && ::stat(dir.c_str(), &st) == 0 && S_ISDIR(st.st_mode) &&
         access(dir.c_str(), W_OK | X_OK) == 0;
}

std::string owner_text(uid_t uid) {
  std::string text = "uid " + std::to_string(uid);
  char buf[4096];
  passwd pw{};
  passwd* found = nullptr;
  if (getpwuid_r(uid, &pw, buf, sizeof buf, &found) == 0 && found != nullptr)
    text += " ('" + std::string(found->pw_name) + "')";
  return text;
}

std::string parent_of(const std::string& path) {
  const auto slash = path.rfind('/');
  if (slash == std::string::npos) return ".";
  return slash == 0 ? "/" : path.substr(0, slash);
}

// Why a lock file may not be believed (empty: it may): not a regular file, a
// second name of another file, or owned by someone other than this user, root
// or the owner of its runtime directory (the service user of /run/exodaq).
std::string distrust(const struct stat& file, const std::string& path) {
  if (!S_ISREG(file.st_mode)) return "it is not a regular file";
  if (file.st_nlink != 1) return "it has " + std::to_string(file.st_nlink) + " names (hard links)";
  const uid_t me = geteuid();
  if (file.st_uid == me || file.st_uid == 0) return {};
  struct stat dir {};
  if (::stat(parent_of(path).c_str(), &dir) == 0 && file.st_uid == dir.st_uid) return {};
  return "it is owned by " + owner_text(file.st_uid) + ", not by this user (" + owner_text(me) +
         "), root or the owner of " + parent_of(path);
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
  // The holder takes the lock first and writes its pid just after: a loser
  // that lost by microseconds waits (up to 1 s, at start-up) to name it.
  auto holder = read_lock_file(fd);
  for (int tries = 0; tries < 200 && holder.count("pid") == 0; ++tries) {
    usleep(5000);
    holder = read_lock_file(fd);
  }
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
  constexpr const char* kSystemDir = "/run/exodaq";
  if (writable_dir(kSystemDir)) return kSystemDir;
  // root may make it: /run is root's alone, so nobody can have put it there first.
  if (geteuid() == 0 && (mkdir(kSystemDir, 0755) == 0 || errno == EEXIST) &&
      writable_dir(kSystemDir))
    return kSystemDir;
  if (const char* xdg = std::getenv("XDG_RUNTIME_DIR"); xdg != nullptr && writable_dir(xdg))
    return xdg;
  throw std::runtime_error(
      "no runtime directory for the instance lock: $RUNTIME_DIRECTORY and $XDG_RUNTIME_DIR are "
      "unset or not writable and /run/exodaq is not writable by this user; run it as the "
      "exodaqd unit, from a login session (which sets $XDG_RUNTIME_DIR), or set "
      "RUNTIME_DIRECTORY to a folder of this user's");
}

std::string channel_set_key(const std::string& url, const std::string& prefix) {
  const std::string network = url.substr(0, url.find('?'));
  constexpr std::string_view kUdpm = "udpm://";
  if (network.rfind(kUdpm, 0) != 0) return network + "\n" + prefix;
  std::string host = network.substr(kUdpm.size());
  std::string port = "0";  // LCM's port when none is given
  if (host.empty()) {
    host = "239.255.76.67";  // LCM's default group and port
    port = "7667";
  } else if (const auto colon = host.find(':'); colon != std::string::npos) {
    port = host.substr(colon + 1);
    host.resize(colon);
    char* end = nullptr;
    errno = 0;
    const unsigned long n = std::strtoul(port.c_str(), &end, 10);
    if (errno == 0 && end != port.c_str() && *end == '\0') port = std::to_string(n);
  }
  if (in_addr a{}; inet_aton(host.c_str(), &a) != 0) {
    char text[INET_ADDRSTRLEN];
    host = inet_ntop(AF_INET, &a, text, sizeof text);
  }
  return std::string(kUdpm) + host + ":" + port + "\n" + prefix;
}

std::string lock_path(const std::string& dir, const std::string& url, const std::string& prefix) {
  char name[48];
  std::snprintf(name, sizeof(name), "exodaqd-%016llx.lock",
                static_cast<unsigned long long>(fnv1a64(channel_set_key(url, prefix))));
  return dir + "/" + name;
}

InstanceLock::InstanceLock(const std::string& path, Identity who)
    : path_(path), who_(std::move(who)) {
  open_trusted();
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

void InstanceLock::open_trusted() {
  for (int attempt = 0;; ++attempt) {
    // O_NONBLOCK: a FIFO put in its place does not hang the open.
    constexpr int kFlags = O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK | O_NOCTTY;
    writable_ = true;
    fd_ = open(path_.c_str(), O_RDWR | O_CREAT | kFlags, 0644);
    if (fd_ < 0 && errno == EACCES) {
      // Another trusted user's (root's, the service user's): locking needs no
      // write access, naming the holder does.
      fd_ = open(path_.c_str(), O_RDONLY | kFlags);
      writable_ = false;
    }
    if (fd_ < 0) {
      throw std::runtime_error("cannot open the instance lock " + path_ + ": " +
                               strerrordesc_np(errno));
    }
    struct stat st {};
    if (fstat(fd_, &st) != 0) {
      throw std::runtime_error("cannot open the instance lock " + path_ + ": " +
                               strerrordesc_np(errno));
    }
    const std::string why = distrust(st, path_);
    if (why.empty()) return;
    close(fd_);
    fd_ = -1;
    // Not believed, whoever holds it: replaced by a file of this process's
    // own (a daemon of that user on the same channels is still heard by the
    // listening window).
    const int err =
        attempt == 0 && unlink(path_.c_str()) == 0 ? 0 : (attempt == 0 ? errno : EEXIST);
    if (err == 0) {
      spdlog::warn("instance lock {}: not trusted ({}): replaced by this daemon's own", path_, why);
      continue;
    }
    throw std::runtime_error("the instance lock " + path_ + " is not trusted: " + why +
                             "; it cannot be replaced (" + strerrordesc_np(err) +
                             "): remove it, or run with another runtime directory");
  }
}

InstanceLock::~InstanceLock() {
  if (fd_ >= 0) close(fd_);
}

void InstanceLock::record_run_id(std::int64_t run_id) {
  write_contents(messages::run_id_text(run_id));
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
    : channel_(messages::channel_name(prefix, messages::Kind::kStatus)) {
  if (const auto address = core::parse_udpm_url(url)) {
    udpm_ = std::make_unique<core::UdpmChannelReceiver>(*address, url, channel_);
    return;
  }
  sub_ = std::make_unique<messages::Subscriber>(url);
  sub_->subscribe(channel_, messages::Kind::kStatus,
                  [this](const messages::Received& r) { on_status(std::get<status_t>(r.msg)); });
}

// Waits up to timeout_ms and handles what arrived. < 0: the transport failed.
int ForeignRunListener::handle(int timeout_ms) {
  if (!udpm_) return sub_->handle(timeout_ms);
  const int size = udpm_->receive(timeout_ms);
  if (size <= 0) return size;
  if (messages::decode_into(status_, udpm_->payload(), static_cast<std::size_t>(size))) {
    on_status(status_);
  }
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

std::string ForeignRunListener::own_run_impostor(std::int64_t seq, std::int64_t last_own_seq,
                                                 std::int64_t published_seq) {
  if (seq > published_seq) {
    return "status seq " + std::to_string(seq) + ", beyond the last this daemon published (" +
           std::to_string(published_seq) + ")";
  }
  if (seq <= last_own_seq) {
    return "status seq " + std::to_string(seq) + " after this daemon's " +
           std::to_string(last_own_seq);
  }
  return {};
}

void ForeignRunListener::on_status(const status_t& status) {
  const std::int64_t run_id = status.run_id;
  if (run_id == 0) return;  // the all-zero start-up message
  if (acq_ == nullptr) {
    if (!first_heard_) first_heard_ = Heard{run_id, status.rig};
    return;
  }
  const std::int64_t own = acq_->run_id();
  std::string impostor;
  if (run_id == own) {
    impostor = own_run_impostor(status.seq, last_own_seq_, acq_->last_status_seq());
    if (impostor.empty()) {
      last_own_seq_ = status.seq;  // this loop's own status
      return;
    }
  }
  last_foreign_ns_ = mono_now_ns();
  if (episode_run_id_ != 0) return;  // one error per episode, even with several others
  episode_run_id_ = run_id;
  ++episodes_;
  acq_->set_foreign_run_id(run_id);
  const std::string rig = status.rig.empty() ? "?" : messages::printable(status.rig);
  if (run_id == own) {
    spdlog::error(
        "another publisher on {} uses this daemon's own run id {} ({}; source {}, rig {}): a "
        "replay of this run or a forged stream; every sample is flagged FOREIGN_RUN and the state "
        "is degraded while it is heard (episode {})",
        channel_, messages::run_id_text(run_id), impostor, messages::printable(status.source), rig,
        episodes_);
    return;
  }
  spdlog::error(
      "another publisher on {}: run id {} (rig {}) beside this daemon's run {}; every sample "
      "is flagged FOREIGN_RUN and the state is degraded while it is heard (episode {})",
      channel_, messages::run_id_text(run_id), rig, messages::run_id_text(own), episodes_);
}

void ForeignRunListener::end_episode_if_quiet() {
  if (episode_run_id_ == 0 || mono_now_ns() - last_foreign_ns_ < kEpisodeEndNs) return;
  acq_->set_foreign_run_id(0);
  spdlog::warn("run id {} no longer heard on {} for {} ms: FOREIGN_RUN cleared",
               messages::run_id_text(episode_run_id_), channel_, kEpisodeEndNs / 1'000'000);
  episode_run_id_ = 0;
}

ChannelClaim::ChannelClaim(const settings::ServiceConfig& config, const std::string& config_path)
    : lock_(lock_path(runtime_directory(), config.lcm.url, config.lcm.prefix),
            InstanceLock::Identity{config.lcm.url, config.lcm.prefix, config_path, config.rig}),
      listener_(config.lcm.url, config.lcm.prefix),
      listened_ms_(startup_listen_ms(config.loop.status_rate_hz)) {
  if (const auto heard = listener_.listen_before_start(listened_ms_)) {
    throw InstanceConflict(
        "another exodaqd already publishes on LCM " + config.lcm.url + " with prefix '" +
        config.lcm.prefix + "': run id " + messages::run_id_text(heard->run_id) + ", rig " +
        (heard->rig.empty() ? "?" : messages::printable(heard->rig)) + " heard on " +
        messages::channel_name(config.lcm.prefix, messages::Kind::kStatus) +
        " (another host, or a daemon with another runtime directory); stop "
        "it, or give this daemon another lcm.prefix or lcm.url");
  }
}

void ChannelClaim::attach(core::Acquisition& acq) {
  lock_.record_run_id(acq.run_id());
  listener_.watch(acq);
}

}  // namespace exodaq::daemon
