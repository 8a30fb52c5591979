#include "exodaq/common/files.hpp"

#include <fcntl.h>
#include <poll.h>
#include <pwd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <random>
#include <utility>

namespace exodaq::files {

namespace {

constexpr std::size_t kBufferBytes = 64 * 1024;

// A descriptor closed when it goes out of scope.
class Fd {
 public:
  explicit Fd(int fd = -1) noexcept : fd_(fd) {}
  ~Fd() { reset(); }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  Fd(Fd&& o) noexcept : fd_(o.release()) {}
  Fd& operator=(Fd&& o) noexcept {
    if (this != &o) {
      reset();
      fd_ = o.release();
    }
    return *this;
  }
  int get() const noexcept { return fd_; }
  int release() noexcept { return std::exchange(fd_, -1); }
  void reset() noexcept {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_;
};

std::string owner_text(uid_t uid) {
  std::string text = "uid " + std::to_string(uid);
  const long size = ::sysconf(_SC_GETPW_R_SIZE_MAX);
  std::vector<char> buf(static_cast<std::size_t>(size > 0 ? size : 16384));
  struct passwd pw {};
  struct passwd* found = nullptr;
  if (::getpwuid_r(uid, &pw, buf.data(), buf.size(), &found) == 0 && found != nullptr) {
    text += " ('" + std::string(found->pw_name) + "')";
  }
  return text;
}

// Whether a symbolic link `link` in the directory `dir` may be followed by
// this process (docs/robustness.md "Files"): the caller's own link always; a
// link of root's only in a directory of the caller's or root's, and, in a
// sticky world-writable directory, only in root's (the kernel's
// fs.protected_symlinks rule); anyone else's link never.
bool may_follow(const struct stat& dir, const struct stat& link) {
  const uid_t me = ::geteuid();
  if (link.st_uid == me) return true;
  if (link.st_uid != 0) return false;
  if (dir.st_uid != me && dir.st_uid != 0) return false;
  const bool sticky_world_writable = (dir.st_mode & (S_ISVTX | S_IWOTH)) == (S_ISVTX | S_IWOTH);
  return !sticky_world_writable || dir.st_uid == 0;
}

// `name` in the folder `dir` as text ("." is left out).
std::string child(const std::string& dir, const std::string& name) {
  if (dir == ".") return name;
  return dir == "/" ? "/" + name : dir + "/" + name;
}

// Where an output goes: its directory, held open (every later step is
// relative to it, so nothing swapped into the path afterwards is followed),
// and its name there.
struct Place {
  Fd dir;
  std::string dir_text;  // for messages
  std::string name;
  std::string target;  // the path as given, or as the links made it
};

// Walks `path` one component at a time, never letting the kernel follow a
// link: each link met (a folder on the way or the last name) is checked by
// may_follow() and then followed here. The last name need not exist.
Place resolve_output(const std::string& path) {
  if (path.size() > 1 && path.back() == '/')
    throw FileError(path, "ends with '/': name a file to write");
  // Components still to walk, the next one last.
  std::vector<std::string> todo;
  const auto push_path = [&todo](const std::string& p) {
    std::vector<std::string> parts;
    for (std::size_t at = 0; at <= p.size();) {
      const std::size_t slash = std::min(p.find('/', at), p.size());
      if (slash > at) parts.push_back(p.substr(at, slash - at));
      at = slash + 1;
    }
    if (parts.empty()) parts.push_back(".");  // "/" or a link to "/"
    todo.insert(todo.end(), parts.rbegin(), parts.rend());
  };
  const auto open_dir = [&path](int at, const char* name, const std::string& shown) {
    const int fd = ::openat(at, name, O_PATH | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
    if (fd < 0) throw FileError(path, "cannot write into '" + shown + "': " + errno_text(errno));
    return Fd(fd);
  };
  Place place;
  const bool absolute = path.front() == '/';
  place.dir_text = absolute ? "/" : ".";
  place.dir = open_dir(AT_FDCWD, absolute ? "/" : ".", place.dir_text);
  push_path(path);
  bool followed = false;
  for (int links = 0; !todo.empty();) {
    const std::string name = todo.back();
    todo.pop_back();
    const bool last = todo.empty();
    if (name == "." && !last) continue;
    const std::string shown = child(place.dir_text, name);
    struct stat st {};
    if (::fstatat(place.dir.get(), name.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0) {
      const int err = errno;
      if (last && err == ENOENT) {
        place.name = name;
        break;
      }
      if (last) throw FileError(path, errno_text(err));
      // The folder the output would go into, as named.
      std::string folder = shown;
      for (auto it = todo.rbegin(); it + 1 != todo.rend(); ++it) folder += "/" + *it;
      throw FileError(path, "cannot write into '" + folder + "': " + errno_text(err));
    }
    if (S_ISLNK(st.st_mode)) {
      struct stat dir_st {};
      if (::fstat(place.dir.get(), &dir_st) != 0) throw FileError(path, errno_text(errno));
      if (!may_follow(dir_st, st)) {
        const bool sticky = (dir_st.st_mode & S_ISVTX) != 0;
        throw FileError(path, "'" + shown + "' is a symbolic link of " + owner_text(st.st_uid) +
                                  " in " + (sticky ? "a sticky folder" : "a folder") + " of " +
                                  owner_text(dir_st.st_uid) +
                                  ": not followed (another user could have planted it; name "
                                  "the file it points to, or write elsewhere)");
      }
      if (++links > 40) throw FileError(path, "too many levels of symbolic links");
      std::string link(static_cast<std::size_t>(st.st_size > 0 ? st.st_size : 4096) + 1, '\0');
      const ssize_t n = ::readlinkat(place.dir.get(), name.c_str(), link.data(), link.size());
      if (n < 0) throw FileError(path, "cannot read the symbolic link: " + errno_text(errno));
      link.resize(static_cast<std::size_t>(n));
      if (link.empty()) throw FileError(path, "'" + shown + "' is an empty symbolic link");
      followed = true;
      if (link.front() == '/') {
        place.dir_text = "/";
        place.dir = open_dir(AT_FDCWD, "/", "/");
      }
      push_path(link);
      continue;
    }
    if (last) {
      place.name = name;
      break;
    }
    if (!S_ISDIR(st.st_mode)) throw FileError(path, "'" + shown + "' is not a directory");
    place.dir = open_dir(place.dir.get(), name.c_str(), shown);
    place.dir_text = shown;
  }
  place.target = followed ? child(place.dir_text, place.name) : path;
  return place;
}

// The checks of an output's target; true when it exists (then `st` holds it).
bool check_target(const std::string& path, const Place& place, const OutputOptions& o,
                  struct stat& st) {
  const std::string& target = place.target;
  const std::string shown = target == path ? "" : " (the target of the link, '" + target + "')";
  if (::fstatat(place.dir.get(), place.name.c_str(), &st, AT_SYMLINK_NOFOLLOW) != 0) {
    if (errno != ENOENT) throw FileError(path, errno_text(errno));
    return false;
  }
  if (!S_ISREG(st.st_mode)) {
    throw FileError(path, "is " + file_kind(st.st_mode) + shown +
                              ", not a regular file: not replaced (name a file to write)");
  }
  // A file the user may not write is not replaced behind its back by the
  // rename (the folder being writable is not the file being writable).
  if (::faccessat(place.dir.get(), place.name.c_str(), W_OK, 0) != 0) {
    throw FileError(path, "cannot write: " + errno_text(errno));
  }
  for (const std::string& in : o.inputs) {
    struct stat ist {};
    if (in != "-" && ::stat(in.c_str(), &ist) == 0 && ist.st_dev == st.st_dev &&
        ist.st_ino == st.st_ino) {
      throw FileError(path, "is also an input ('" + in +
                                "'): writing it would destroy what is being read; name "
                                "another output");
    }
  }
  return true;
}

// A new, empty file `.<name>.tmp-XXXXXX` in the place's folder (mode 0600,
// as mkstemp). Returns its descriptor and sets `temp_name`.
int create_temp(const std::string& path, const Place& place, std::string& temp_name) {
  static constexpr char kDigits[] =
      "0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ";
  std::random_device rng;
  for (int attempt = 0; attempt < 100; ++attempt) {
    std::string name = "." + place.name + ".tmp-";
    for (int i = 0; i < 6; ++i) name += kDigits[rng() % (sizeof kDigits - 1)];
    const int fd = ::openat(place.dir.get(), name.c_str(),
                            O_RDWR | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
    if (fd >= 0) {
      temp_name = name;
      return fd;
    }
    if (errno != EEXIST) {
      throw FileError(
          path, "cannot create a temporary file in '" + place.dir_text + "': " + errno_text(errno));
    }
  }
  throw FileError(
      path, "cannot create a temporary file in '" + place.dir_text + "': " + errno_text(EEXIST));
}

mode_t current_umask() {
  const mode_t m = ::umask(022);
  ::umask(m);
  return m;
}

}  // namespace

int edit_distance(std::string_view a, std::string_view b) {
  std::vector<int> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = static_cast<int>(j);
  for (std::size_t i = 1; i <= a.size(); ++i) {
    int diag = row[0];
    row[0] = static_cast<int>(i);
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const int up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

FileError::FileError(const std::string& file, const std::string& what)
    : std::runtime_error(file + ": " + what), file_(file), reason_(what) {}

std::string errno_text(int err) {
  const char* d = strerrordesc_np(err);
  return d != nullptr ? d : "error " + std::to_string(err);
}

std::string file_kind(mode_t mode) {
  if (S_ISREG(mode)) return "a regular file";
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISLNK(mode)) return "a symbolic link";
  return "a special file";
}

int open_input(const std::string& path, std::int64_t max_bytes, InputInfo* info) {
  if (path.empty()) throw FileError("''", "no file named");
  // O_NONBLOCK: opening a FIFO without a writer would wait forever.
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) throw FileError(path, "cannot open: " + errno_text(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    throw FileError(path, "cannot open: " + errno_text(e));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw FileError(path, "is " + file_kind(st.st_mode) + ", not a regular file");
  }
  if (max_bytes >= 0 && st.st_size > max_bytes) {
    ::close(fd);
    throw FileError(path, "is " + std::to_string(st.st_size) + " bytes, more than the " +
                              std::to_string(max_bytes) + "-byte limit for this input");
  }
  ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
  if (info != nullptr)
    *info = InputInfo{static_cast<std::int64_t>(st.st_size), st.st_dev, st.st_ino};
  return fd;
}

InputInfo check_input(const std::string& path, std::int64_t max_bytes) {
  InputInfo info;
  ::close(open_input(path, max_bytes, &info));
  return info;
}

std::string read_input(const std::string& path, std::int64_t max_bytes) {
  InputInfo info;
  const int fd = open_input(path, max_bytes, &info);
  std::string text(static_cast<std::size_t>(info.size), '\0');
  std::size_t got = 0;
  while (true) {
    if (got == text.size()) {
      // The file grew since fstat: read on, within the limit.
      if (max_bytes >= 0 && static_cast<std::int64_t>(got) >= max_bytes) break;
      text.resize(got + 4096);
    }
    const ssize_t n = ::read(fd, text.data() + got, text.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      const int e = errno;
      ::close(fd);
      throw FileError(path, "cannot read: " + errno_text(e));
    }
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
  text.resize(got);
  if (max_bytes >= 0 && static_cast<std::int64_t>(got) > max_bytes) {
    throw FileError(path,
                    "more than the " + std::to_string(max_bytes) + "-byte limit for this input");
  }
  return text;
}

std::optional<TextProblem> find_text_problem(std::string_view text) {
  int line = 1;
  std::size_t line_start = 0;
  const auto* s = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  for (std::size_t i = 0; i < n;) {
    const unsigned char c = s[i];
    const auto problem = [&](const std::string& what) {
      return TextProblem{line, static_cast<int>(i - line_start + 1), what};
    };
    if (c == 0) return problem("NUL byte (a binary file?)");
    if (c == '\n') {
      ++line;
      line_start = ++i;
      continue;
    }
    if (c < 0x80) {
      ++i;
      continue;
    }
    // UTF-8: lead byte, then 1-3 continuation bytes; no overlong forms, no
    // surrogates, nothing above U+10FFFF.
    int extra = 0;
    unsigned char lo = 0x80;
    unsigned char hi = 0xBF;
    if (c >= 0xC2 && c <= 0xDF) {
      extra = 1;
    } else if (c >= 0xE0 && c <= 0xEF) {
      extra = 2;
      if (c == 0xE0) lo = 0xA0;
      if (c == 0xED) hi = 0x9F;
    } else if (c >= 0xF0 && c <= 0xF4) {
      extra = 3;
      if (c == 0xF0) lo = 0x90;
      if (c == 0xF4) hi = 0x8F;
    } else {
      char b[8];
      std::snprintf(b, sizeof b, "0x%02x", c);
      return problem(std::string("invalid UTF-8 (byte ") + b + ")");
    }
    for (int k = 1; k <= extra; ++k) {
      const unsigned char cc = i + static_cast<std::size_t>(k) < n ? s[i + k] : 0;
      const unsigned char min = k == 1 ? lo : 0x80;
      const unsigned char max = k == 1 ? hi : 0xBF;
      if (cc < min || cc > max) {
        char b[8];
        std::snprintf(b, sizeof b, "0x%02x", c);
        return problem(std::string("invalid UTF-8 (byte ") + b + " starts a broken sequence)");
      }
    }
    i += static_cast<std::size_t>(extra) + 1;
  }
  return std::nullopt;
}

void check_output(const std::string& path, const OutputOptions& options) {
  if (path == "-") {
    if (!options.allow_stdout) {
      throw FileError("-", "this output cannot go to standard output: name a file");
    }
    return;
  }
  if (path.empty()) throw FileError("''", "no output file named");
  struct stat st {};
  check_target(path, resolve_output(path), options, st);
}

OutputFile::OutputFile(const std::string& path, const OutputOptions& options) : path_(path) {
  if (path == "-") {
    check_output(path, options);
    stdout_ = true;
    fd_ = STDOUT_FILENO;
    target_ = "standard output";
    return;
  }
  if (path.empty()) throw FileError("''", "no output file named");
  Place place = resolve_output(path);
  target_ = place.target;
  struct stat st {};
  const bool exists = check_target(path, place, options, st);
  fd_ = create_temp(path, place, temp_name_);
  temp_ = child(place.dir_text, temp_name_);
  name_ = place.name;
  dir_fd_ = place.dir.release();
  // The new file gets the old one's mode (and owner, as root); a new target
  // the usual 0666 less the umask.
  ::fchmod(fd_, exists ? (st.st_mode & 07777) : (0666 & ~current_umask()));
  if (exists && ::geteuid() == 0) (void)!::fchown(fd_, st.st_uid, st.st_gid);
  buffer_.reserve(kBufferBytes);
}

OutputFile::~OutputFile() {
  if (!done_) discard();
  if (dir_fd_ >= 0) ::close(dir_fd_);
}

void OutputFile::discard() noexcept {
  if (stdout_) {
    done_ = true;
    return;
  }
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (!temp_name_.empty()) ::unlinkat(dir_fd_, temp_name_.c_str(), 0);
  temp_name_.clear();
  temp_.clear();
  done_ = true;
}

void OutputFile::fail(const std::string& what, int err) {
  discard();
  throw FileError(stdout_ ? std::string("standard output") : path_, what + ": " + errno_text(err));
}

void OutputFile::write_all(const char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(fd_, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      if (errno == EAGAIN) {  // a non-blocking pipe on standard output
        pollfd pfd{fd_, POLLOUT, 0};
        ::poll(&pfd, 1, 1000);
        continue;
      }
      fail("cannot write", errno);
    }
    p += w;
    n -= static_cast<std::size_t>(w);
  }
}

void OutputFile::write(std::string_view bytes) {
  if (done_) throw FileError(path_, "write after the file was closed");
  bytes_ += static_cast<std::int64_t>(bytes.size());
  if (buffer_.size() + bytes.size() > kBufferBytes) {
    flush();
    if (bytes.size() >= kBufferBytes) {
      write_all(bytes.data(), bytes.size());
      return;
    }
  }
  buffer_.append(bytes);
}

void OutputFile::flush() {
  if (done_ || buffer_.empty()) return;
  write_all(buffer_.data(), buffer_.size());
  buffer_.clear();
}

void OutputFile::commit() {
  if (done_) throw FileError(path_, "commit after the file was closed");
  flush();
  if (stdout_) {
    done_ = true;
    return;
  }
  if (::fsync(fd_) != 0) fail("cannot write", errno);
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) fail("cannot write", errno);
  if (::renameat(dir_fd_, temp_name_.c_str(), dir_fd_, name_.c_str()) != 0) {
    fail("cannot rename '" + temp_ + "' to '" + target_ + "'", errno);
  }
  temp_name_.clear();
  temp_.clear();
  done_ = true;
  // The rename is durable once the directory is on disk too.
  const int dir = ::openat(dir_fd_, ".", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir >= 0) {
    ::fsync(dir);
    ::close(dir);
  }
}

void write_output(const std::string& path, std::string_view bytes, const OutputOptions& options) {
  OutputFile out(path, options);
  out.write(bytes);
  out.commit();
}

int typo_allowance(std::string_view word) {
  return std::clamp(static_cast<int>(word.size()) / 3, 1, 3);
}

std::string closest_match(std::string_view word, const std::vector<std::string>& candidates) {
  std::string best;
  int best_d = 1 << 30;
  const int allowed = typo_allowance(word);
  for (const std::string& c : candidates) {
    int d = edit_distance(word, c);
    // A word that is the start of a candidate (or the reverse) is a near miss too.
    const bool prefix = std::min(word.size(), c.size()) >= 3 &&
                        (c.rfind(word, 0) == 0 || std::string_view(word).rfind(c, 0) == 0);
    if (d > allowed && !prefix) continue;
    if (prefix) d = std::min(d, allowed);
    if (d < best_d) {
      best_d = d;
      best = c;
    }
  }
  return best;
}

}  // namespace exodaq::files
