#include "process.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

extern char** environ;

namespace exodaq::test {

namespace {
int decode_status(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}
}  // namespace

Process::Process(const std::vector<std::string>& argv, const std::string& stdout_file,
                 const std::string& stderr_file, const std::map<std::string, std::string>& env) {
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (!stdout_file.empty()) {
    posix_spawn_file_actions_addopen(&actions, 1, stdout_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                     0644);
  }
  if (!stderr_file.empty()) {
    posix_spawn_file_actions_addopen(&actions, 2, stderr_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC,
                                     0644);
  }
  posix_spawn_file_actions_addopen(&actions, 0, "/dev/null", O_RDONLY, 0);
  std::vector<std::string> envs;
  for (char** e = environ; *e != nullptr; ++e) {
    const std::string kv(*e);
    const std::string key = kv.substr(0, kv.find('='));
    if (env.count(key) == 0) envs.push_back(kv);
  }
  for (const auto& [k, v] : env) envs.push_back(k + "=" + v);
  std::vector<char*> cargv;
  for (const auto& a : argv) cargv.push_back(const_cast<char*>(a.c_str()));
  cargv.push_back(nullptr);
  std::vector<char*> cenv;
  for (auto& e : envs) cenv.push_back(e.data());
  cenv.push_back(nullptr);
  const int rc = posix_spawnp(&pid_, cargv[0], &actions, nullptr, cargv.data(), cenv.data());
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) throw std::runtime_error("cannot start " + argv[0] + ": " + std::strerror(rc));
}

Process::~Process() {
  if (running()) {
    ::kill(pid_, SIGKILL);
    wait(std::chrono::seconds(5));
  }
}

bool Process::running() {
  if (status_) return false;
  int status = 0;
  const pid_t r = waitpid(pid_, &status, WNOHANG);
  if (r == pid_) {
    status_ = decode_status(status);
    return false;
  }
  return r == 0;
}

void Process::signal(int sig) {
  if (running()) ::kill(pid_, sig);
}

std::optional<int> Process::wait(std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (running()) {
    if (std::chrono::steady_clock::now() > end) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return status_;
}

bool wait_until(const std::function<bool()>& done, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() > end) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  return true;
}

std::string read_file(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string make_temp_dir(const std::string& tag) {
  const char* base = std::getenv("TMPDIR");
  std::string tmpl = std::string(base != nullptr ? base : "/tmp") + "/exodaq-" + tag + "-XXXXXX";
  if (mkdtemp(tmpl.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
  return tmpl;
}

std::string unique_prefix(const std::string& tag) {
  return "T" + std::to_string(getpid()) + "_" + tag + "_";
}

RunResult run(const std::vector<std::string>& argv, std::chrono::milliseconds timeout,
              const std::map<std::string, std::string>& env) {
  const std::string dir = make_temp_dir("run");
  RunResult r;
  {
    Process p(argv, dir + "/out", dir + "/err", env);
    const auto code = p.wait(timeout);
    if (!code) {
      p.signal(SIGKILL);
      p.wait(std::chrono::seconds(5));
      r.exit_code = -1;
    } else {
      r.exit_code = *code;
    }
  }
  r.out = read_file(dir + "/out");
  r.err = read_file(dir + "/err");
  std::remove((dir + "/out").c_str());
  std::remove((dir + "/err").c_str());
  rmdir(dir.c_str());
  return r;
}

std::vector<UdpSocket> udp_sockets(pid_t pid) {
  const std::string proc = "/proc/" + std::to_string(pid);
  std::vector<std::string> inodes;
  std::error_code ec;
  for (std::filesystem::directory_iterator it(proc + "/fd", ec), end; !ec && it != end;
       it.increment(ec)) {
    std::error_code link_error;
    const std::string target = std::filesystem::read_symlink(it->path(), link_error).string();
    if (!link_error && target.rfind("socket:[", 0) == 0) {
      inodes.push_back(target.substr(8, target.size() - 9));
    }
  }
  std::vector<UdpSocket> out;
  for (const char* table : {"/net/udp", "/net/udp6"}) {
    std::ifstream in(proc + table);
    std::string line;
    std::getline(in, line);  // header
    while (std::getline(in, line)) {
      // sl local_address rem_address st tx:rx tr:when retrnsmt uid timeout inode ref pointer drops
      std::istringstream f(line);
      std::vector<std::string> col;
      for (std::string c; f >> c;) col.push_back(c);
      if (col.size() < 13) continue;
      if (std::find(inodes.begin(), inodes.end(), col[9]) == inodes.end()) continue;
      UdpSocket s;
      const std::string& local = col[1];
      s.local_port = static_cast<int>(std::stol(local.substr(local.find(':') + 1), nullptr, 16));
      s.drops = std::stoll(col.back());
      out.push_back(s);
    }
  }
  return out;
}

std::int64_t udp_drops(pid_t pid) {
  std::int64_t drops = 0;
  for (const UdpSocket& s : udp_sockets(pid)) drops += s.drops;
  return drops;
}

bool wait_for_udp_socket(pid_t pid, int port, std::chrono::milliseconds timeout) {
  return wait_until(
      [&] {
        for (const UdpSocket& s : udp_sockets(pid))
          if (s.local_port == port) return true;
        return false;
      },
      timeout);
}

std::vector<std::string> lcm_logger_argv(const std::string& url, const std::string& channels,
                                         const std::string& file) {
  std::vector<std::string> argv;
  if (::geteuid() == 0 && ::access("/usr/bin/chrt", X_OK) == 0) {
    argv = {"/usr/bin/chrt", "-f", "10"};
  }
  for (const std::string& a :
       {std::string("lcm-logger"), "--lcm-url=" + url, "--channel=" + channels, std::string("-q"),
        std::string("-f"), file}) {
    argv.push_back(a);
  }
  return argv;
}

}  // namespace exodaq::test
