#include "view_http.hpp"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <optional>
#include <stdexcept>
#include <utility>

namespace exodaq::tools::view {

namespace {

// Every response: the page may load only from this server (no fetch from
// anywhere else at run time), and nothing is cached across daemon runs.
constexpr std::string_view kCommonHeaders =
    "Cache-Control: no-store\r\n"
    "X-Content-Type-Options: nosniff\r\n"
    "Content-Security-Policy: default-src 'self'; img-src 'self' data:\r\n";

std::string errno_text(int e) {
  return std::strerror(e);
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (auto& ch : out) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return out;
}

// The Host header's value, trimmed; `count` is set to how many there are.
std::string_view host_header(std::string_view head, int& count) {
  std::string_view found;
  count = 0;
  for (std::size_t at = head.find('\n'); at != std::string_view::npos;) {
    const std::size_t next = head.find('\n', at + 1);
    std::string_view line =
        head.substr(at + 1, next == std::string_view::npos ? next : next - at - 1);
    at = next;
    if (line.size() < 5 || lower(line.substr(0, 5)) != "host:") continue;
    line.remove_prefix(5);
    while (!line.empty() && (line.front() == ' ' || line.front() == '\t')) line.remove_prefix(1);
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t'))
      line.remove_suffix(1);
    if (++count == 1) found = line;
  }
  return found;
}

// An IP address literal ("127.0.0.1", "[::1]") as 16 bytes (IPv4 mapped);
// nullopt for a name or anything else.
std::optional<std::array<unsigned char, 16>> ip_literal(std::string_view name) {
  std::array<unsigned char, 16> a{};
  const std::string text(name);
  if (text.size() > 2 && text.front() == '[' && text.back() == ']') {
    if (inet_pton(AF_INET6, text.substr(1, text.size() - 2).c_str(), a.data()) == 1) return a;
    return std::nullopt;
  }
  in_addr v4{};
  if (inet_pton(AF_INET, text.c_str(), &v4) != 1) return std::nullopt;
  a[10] = a[11] = 0xff;
  std::memcpy(a.data() + 12, &v4, 4);
  return a;
}

// The name part of a Host value ("name", "name:port", "[v6]", "[v6]:port"),
// lower-case; nullopt when the value is not of that form (a port that is not
// 1-5 digits, a bare IPv6 address, anything after the port).
std::optional<std::string> host_name(std::string_view value) {
  std::size_t end = value.find(':');
  if (!value.empty() && value.front() == '[') {
    end = value.find(']');
    if (end == std::string_view::npos) return std::nullopt;
    ++end;
  }
  const std::string_view name = value.substr(0, end);
  if (name.empty()) return std::nullopt;
  if (end < value.size()) {
    const std::string_view port = value.substr(end);
    if (port.size() < 2 || port.size() > 6 || port.front() != ':') return std::nullopt;
    for (const char c : port.substr(1)) {
      if (c < '0' || c > '9') return std::nullopt;
    }
  }
  for (const char c : name) {
    if (c <= ' ' || c == '/' || c == '@') return std::nullopt;
  }
  return lower(name);
}

// The client's address, for the per-client limit.
std::string peer_text(const sockaddr_storage& a) {
  char text[INET6_ADDRSTRLEN] = "?";
  if (a.ss_family == AF_INET) {
    inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(&a)->sin_addr, text, sizeof text);
  } else if (a.ss_family == AF_INET6) {
    inet_ntop(AF_INET6, &reinterpret_cast<const sockaddr_in6*>(&a)->sin6_addr, text, sizeof text);
  }
  return text;
}

}  // namespace

struct HttpServer::Conn {
  enum class State { kRequest, kResponse, kStream };
  int fd = -1;
  std::string client;  // the peer's address
  State state = State::kRequest;
  std::string in;
  std::string out;
  std::size_t out_pos = 0;
  std::int64_t opened_ns = 0;
  std::int64_t last_progress_ns = 0;  // last byte accepted, or output queued into an empty buffer
  bool read_closed = false;           // the peer closed its side: no more POLLIN
  bool closed = false;
  std::size_t pending() const { return out.size() - out_pos; }
  // Connected, nothing received yet (a browser's spare connection, or a
  // client holding a place).
  bool idle() const { return state == State::kRequest && in.empty(); }
  void queue(std::string_view bytes, std::int64_t now_ns) {
    if (pending() == 0) last_progress_ns = now_ns;
    out += bytes;
  }
};

std::string sse_event(std::string_view event, std::string_view data) {
  std::string s;
  s.reserve(event.size() + data.size() + 16);
  s += "event: ";
  s += event;
  s += "\ndata: ";
  s += data;
  s += "\n\n";
  return s;
}

std::string_view http_reason(int status) {
  switch (status) {
    case 200:
      return "OK";
    case 400:
      return "Bad Request";
    case 403:
      return "Forbidden";
    case 404:
      return "Not Found";
    case 405:
      return "Method Not Allowed";
    case 408:
      return "Request Timeout";
    case 431:
      return "Request Header Fields Too Large";
    case 500:
      return "Internal Server Error";
    case 503:
      return "Service Unavailable";
    case 505:
      return "HTTP Version Not Supported";
    default:
      return "Unknown";
  }
}

HttpServer::HttpServer(HttpOptions options) : options_(std::move(options)) {
  const std::string where = options_.bind + " port " + std::to_string(options_.port);
  if (options_.port < 0 || options_.port > 65535) {
    throw std::runtime_error("cannot listen on " + where + ": not a port number");
  }
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE | AI_NUMERICHOST | AI_NUMERICSERV;
  addrinfo* res = nullptr;
  const int gai =
      getaddrinfo(options_.bind.c_str(), std::to_string(options_.port).c_str(), &hints, &res);
  if (gai != 0 || res == nullptr) {
    throw std::runtime_error("cannot listen on " + where + ": '" + options_.bind +
                             "' is not a numeric IPv4 or IPv6 address");
  }
  std::unique_ptr<addrinfo, decltype(&freeaddrinfo)> guard(res, &freeaddrinfo);
  ipv6_ = res->ai_family == AF_INET6;
  listen_fd_ = socket(res->ai_family, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (listen_fd_ < 0)
    throw std::runtime_error("cannot listen on " + where + ": " + errno_text(errno));
  const int one = 1;
  setsockopt(listen_fd_, SOL_SOCKET, SO_REUSEADDR, &one, sizeof one);
  if (bind(listen_fd_, res->ai_addr, res->ai_addrlen) != 0 || listen(listen_fd_, 64) != 0) {
    const int e = errno;
    ::close(listen_fd_);
    listen_fd_ = -1;
    throw std::runtime_error("cannot listen on " + where + ": " + errno_text(e));
  }
  sockaddr_storage addr{};
  socklen_t len = sizeof addr;
  getsockname(listen_fd_, reinterpret_cast<sockaddr*>(&addr), &len);
  port_ = addr.ss_family == AF_INET6 ? ntohs(reinterpret_cast<sockaddr_in6*>(&addr)->sin6_port)
                                     : ntohs(reinterpret_cast<sockaddr_in*>(&addr)->sin_port);
}

HttpServer::~HttpServer() {
  for (auto& c : conns_) close_conn(*c);
  if (listen_fd_ >= 0) ::close(listen_fd_);
}

bool HttpServer::host_allowed(std::string_view value) const {
  if (value.empty()) return true;  // HTTP/1.0 without Host: not a browser, no rebinding
  const auto name = host_name(value);
  if (!name) return false;
  if (*name == "localhost") return true;
  const auto ip = ip_literal(*name);
  if (!ip) return false;  // any other name
  const auto v4 = ip_literal("127.0.0.1");
  const auto v6 = ip_literal("[::1]");
  if (ip == v4 || ip == v6) return true;
  const auto bound = ip_literal(ipv6_ ? "[" + options_.bind + "]" : options_.bind);
  if (!bound) return false;
  // Listening on every interface: any of this host's addresses, which a
  // rebinding cannot give (it needs a name).
  if (bound == ip_literal("0.0.0.0") || bound == ip_literal("[::]")) return true;
  return ip == bound;
}

std::string HttpServer::url() const {
  const std::string host = ipv6_ ? "[" + options_.bind + "]" : options_.bind;
  return "http://" + host + ":" + std::to_string(port_) + "/";
}

void HttpServer::add_handler(const std::string& path, Handler handler) {
  handlers_[path] = std::move(handler);
}

void HttpServer::add_event_stream(const std::string& path, StreamOpen on_open) {
  streams_[path] = std::move(on_open);
}

void HttpServer::add_pollfds(std::vector<pollfd>& fds) {
  std::erase_if(conns_, [](const auto& c) { return c->closed; });
  poll_base_ = fds.size();
  fds.push_back(pollfd{listen_fd_, POLLIN, 0});
  for (const auto& c : conns_) {
    short events = 0;
    if (!c->read_closed) events |= POLLIN;
    if (c->pending() > 0) events |= POLLOUT;
    fds.push_back(pollfd{c->fd, events, 0});
  }
  polled_conns_ = conns_.size();
}

void HttpServer::service(const std::vector<pollfd>& fds, std::int64_t now_ns) {
  const std::size_t n = std::min(polled_conns_, conns_.size());
  for (std::size_t i = 0; i < n && poll_base_ + 1 + i < fds.size(); ++i) {
    Conn& c = *conns_[i];
    const short re = fds[poll_base_ + 1 + i].revents;
    if (c.closed) continue;
    if (re & POLLNVAL) {
      close_conn(c);
      continue;
    }
    if (re & (POLLIN | POLLHUP | POLLERR)) read_from(c, now_ns);
    if (!c.closed && (re & POLLOUT)) write_to(c, now_ns);
  }
  for (auto& c : conns_) {
    if (!c->closed) expire(*c, now_ns);
  }
  if (poll_base_ < fds.size() && (fds[poll_base_].revents & POLLIN)) accept_all(now_ns);
  polled_conns_ = 0;
  std::erase_if(conns_, [](const auto& c) { return c->closed; });
}

void HttpServer::accept_all(std::int64_t now_ns) {
  for (;;) {
    sockaddr_storage peer{};
    socklen_t len = sizeof peer;
    const int fd =
        accept4(listen_fd_, reinterpret_cast<sockaddr*>(&peer), &len, SOCK_NONBLOCK | SOCK_CLOEXEC);
    if (fd < 0) {
      if (errno == EINTR || errno == ECONNABORTED) continue;
      return;  // EAGAIN, or out of descriptors: the rest wait in the backlog
    }
    ++stats_.accepted;
    auto c = std::make_unique<Conn>();
    c->fd = fd;
    c->client = peer_text(peer);
    c->opened_ns = now_ns;
    c->last_progress_ns = now_ns;
    make_room(c->client);
    conns_.push_back(std::move(c));
  }
}

void HttpServer::make_room(const std::string& client) {
  std::map<std::string_view, std::size_t> held;
  std::size_t open = 0;
  for (const auto& c : conns_) {
    if (c->closed) continue;
    ++held[c->client];
    ++open;
  }
  std::string_view from;
  if (options_.max_per_client > 0 && held[client] >= options_.max_per_client) {
    from = client;  // at its own limit: its own oldest place goes
  } else if (options_.max_connections > 0 && open >= options_.max_connections) {
    std::size_t most = 0;  // full: a place of the client holding the most
    for (const auto& [who, n] : held) {
      if (n > most) {
        most = n;
        from = who;
      }
    }
  } else {
    return;
  }
  // That client's oldest idle connection, else its oldest.
  Conn* victim = nullptr;
  for (const auto& c : conns_) {
    if (c->closed || c->client != from) continue;
    if (c->idle()) {
      victim = c.get();
      break;
    }
    if (victim == nullptr) victim = c.get();
  }
  if (victim == nullptr) return;
  ++stats_.evicted;
  if (!victim->idle() && victim->state == Conn::State::kRequest) {
    ++stats_.bad_requests;  // an unfinished request: told why, once, without waiting
    static constexpr std::string_view kBusy =
        "HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\nConnection: close\r\n\r\n";
    [[maybe_unused]] const auto r =
        send(victim->fd, kBusy.data(), kBusy.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
  }
  close_conn(*victim);
}

void HttpServer::read_from(Conn& c, std::int64_t now_ns) {
  char buf[4096];
  // Bounded: a client that floods its socket cannot keep the loop here.
  for (int reads = 0; reads < 64; ++reads) {
    const ssize_t n = recv(c.fd, buf, sizeof buf, MSG_DONTWAIT);
    if (n > 0) {
      // Only the request is kept; anything a client sends later is read and dropped.
      if (c.state == Conn::State::kRequest) c.in.append(buf, static_cast<std::size_t>(n));
      if (c.state == Conn::State::kRequest && c.in.size() > options_.max_request_bytes) break;
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
    // End of stream or error. A client may half-close after its request and
    // still read the answer; a stream or an unfinished request ends here.
    if (n == 0 && c.state == Conn::State::kResponse) {
      c.read_closed = true;
      return;
    }
    close_conn(c);
    return;
  }
  if (c.state == Conn::State::kRequest) answer(c, now_ns);
}

void HttpServer::answer(Conn& c, std::int64_t now_ns) {
  std::size_t end = c.in.find("\r\n\r\n");
  if (end == std::string::npos) end = c.in.find("\n\n");
  if ((end == std::string::npos ? c.in.size() : end) > options_.max_request_bytes) {
    ++stats_.bad_requests;
    respond(c, 431, "text/plain; charset=utf-8", "request header too large\n", false, now_ns);
    write_to(c, now_ns);
    return;
  }
  if (end == std::string::npos) return;  // not complete yet
  ++stats_.requests;
  std::string_view line(c.in);
  line = line.substr(0, line.find('\n'));
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  // METHOD SP request-target SP HTTP-version
  const std::size_t sp1 = line.find(' ');
  const std::size_t sp2 = sp1 == std::string_view::npos ? sp1 : line.find(' ', sp1 + 1);
  if (sp2 == std::string_view::npos || line.find(' ', sp2 + 1) != std::string_view::npos) {
    ++stats_.bad_requests;
    respond(c, 400, "text/plain; charset=utf-8", "malformed request line\n", false, now_ns);
    write_to(c, now_ns);
    return;
  }
  const std::string_view method = line.substr(0, sp1);
  std::string_view target = line.substr(sp1 + 1, sp2 - sp1 - 1);
  const std::string_view version = line.substr(sp2 + 1);
  const bool head = method == "HEAD";
  int hosts = 0;
  const std::string_view host = host_header(std::string_view(c.in).substr(0, end), hosts);
  if (version.substr(0, 7) != "HTTP/1.") {
    ++stats_.bad_requests;
    respond(c, version.substr(0, 5) == "HTTP/" ? 505 : 400, "text/plain; charset=utf-8",
            "HTTP/1.x only\n", head, now_ns);
  } else if (method != "GET" && !head) {
    ++stats_.bad_requests;
    respond(c, 405, "text/plain; charset=utf-8", "GET or HEAD only\n", false, now_ns);
  } else if (target.empty() || target.front() != '/') {
    ++stats_.bad_requests;
    respond(c, 400, "text/plain; charset=utf-8", "the request target must be a path\n", head,
            now_ns);
  } else if (hosts > 1 || !host_allowed(host)) {
    // Asked for a name that is not this server's: a page elsewhere whose name
    // was made to resolve to this address (DNS rebinding).
    ++stats_.bad_requests;
    respond(c, 403, "text/plain; charset=utf-8",
            (hosts > 1 ? std::string("more than one Host header")
                       : "Host '" + std::string(host) + "' is not an address of this server") +
                ": open " + url() + "\n",
            head, now_ns);
  } else {
    target = target.substr(0, target.find_first_of("?#"));
    if (auto s = streams_.find(target); s != streams_.end() && !head) {
      c.state = Conn::State::kStream;
      c.in.clear();
      c.queue(
          "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream; charset=utf-8\r\n"
          "Connection: keep-alive\r\nX-Accel-Buffering: no\r\n",
          now_ns);
      c.out += kCommonHeaders;
      c.out += "\r\nretry: 1000\n\n";
      c.out += s->second();
      ++stats_.stream_clients;
    } else if (s != streams_.end()) {
      respond(c, 200, "text/event-stream; charset=utf-8", "", true, now_ns);
    } else if (auto h = handlers_.find(target); h != handlers_.end()) {
      const HttpResponse r = h->second();
      respond(c, r.status, r.content_type, r.body, head, now_ns);
    } else {
      respond(c, 404, "text/plain; charset=utf-8", "not found\n", head, now_ns);
    }
  }
  write_to(c, now_ns);
}

void HttpServer::respond(Conn& c, int status, std::string_view content_type, std::string_view body,
                         bool head, std::int64_t now_ns) {
  c.state = Conn::State::kResponse;
  c.in.clear();
  std::string h = "HTTP/1.1 " + std::to_string(status) + " " + std::string(http_reason(status)) +
                  "\r\nContent-Type: " + std::string(content_type) +
                  "\r\nContent-Length: " + std::to_string(body.size()) +
                  "\r\nConnection: close\r\n";
  if (status == 405) h += "Allow: GET, HEAD\r\n";
  h += kCommonHeaders;
  h += "\r\n";
  c.queue(h, now_ns);
  if (!head) c.out += body;
}

void HttpServer::write_to(Conn& c, std::int64_t now_ns) {
  while (c.pending() > 0) {
    const ssize_t n =
        send(c.fd, c.out.data() + c.out_pos, c.pending(), MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      c.out_pos += static_cast<std::size_t>(n);
      c.last_progress_ns = now_ns;
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
    close_conn(c);  // EPIPE, ECONNRESET: the client is gone
    return;
  }
  if (c.pending() == 0) {
    c.out.clear();
    c.out_pos = 0;
    if (c.state == Conn::State::kResponse) close_conn(c);
  } else if (c.out_pos > 65536 && c.out_pos > c.out.size() / 2) {
    c.out.erase(0, c.out_pos);
    c.out_pos = 0;
  }
}

void HttpServer::expire(Conn& c, std::int64_t now_ns) {
  if (c.idle() && now_ns - c.opened_ns > options_.idle_timeout_ns) {
    ++stats_.idle_closed;
    close_conn(c);  // a connection opened and never used (a browser's spare): no answer
    return;
  }
  if (c.state == Conn::State::kRequest && now_ns - c.opened_ns > options_.request_timeout_ns) {
    if (c.in.empty()) {
      close_conn(c);  // a connection opened and never used (a browser's spare): no answer
      return;
    }
    ++stats_.bad_requests;
    respond(c, 408, "text/plain; charset=utf-8", "request not completed in time\n", false, now_ns);
    write_to(c, now_ns);
    return;
  }
  if (c.pending() > 0 && now_ns - c.last_progress_ns > options_.stall_timeout_ns) {
    ++stats_.stalled_closed;
    close_conn(c);
  }
}

void HttpServer::publish(std::string_view event, std::string_view data, bool skippable,
                         std::int64_t now_ns) {
  const std::string text = sse_event(event, data);
  for (auto& c : conns_) {
    if (c->closed || c->state != Conn::State::kStream) continue;
    if (skippable && c->pending() >= options_.stream_backlog_bytes) {
      ++stats_.skipped_events;
      continue;
    }
    c->queue(text, now_ns);
    write_to(*c, now_ns);
  }
}

void HttpServer::close_conn(Conn& c) {
  if (c.closed) return;
  if (c.state == Conn::State::kStream) --stats_.stream_clients;
  ::close(c.fd);
  c.fd = -1;
  c.closed = true;
}

HttpStats HttpServer::stats() const {
  HttpStats s = stats_;
  for (const auto& c : conns_) {
    if (!c->closed && c->state == Conn::State::kStream)
      s.stream_backlog_bytes += static_cast<std::int64_t>(c->pending());
  }
  return s;
}

}  // namespace exodaq::tools::view
