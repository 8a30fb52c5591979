#pragma once
// The small HTTP/1.1 server of `exodaq view`: GET/HEAD of registered paths
// (one request per connection, then close) and Server-Sent Event streams.
// One thread, non-blocking sockets, driven by the caller's poll(): it never
// blocks, so the LCM handling in the same loop never waits for a browser.
// A stream client that does not keep up has events skipped (counted) once its
// backlog is full, and is closed when it accepts no byte for stall_timeout; a
// connection that does not finish its request within request_timeout is
// closed; a connection that sends nothing within idle_timeout is closed, and
// a new connection beyond the total or per-client limit closes an older one
// of the busiest client, so a few clients holding connections cannot lock
// the page out. Requests naming a Host other than localhost, 127.0.0.1,
// [::1] or the bound address (any address literal when bound to a wildcard)
// are refused: DNS rebinding. Not for the daemon: allocation is fine here.
// docs/operations.md.
#include <poll.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace exodaq::tools::view {

struct HttpOptions {
  std::string bind = "127.0.0.1";  // numeric IPv4 or IPv6 address
  int port = 8077;                 // 0: any free port (see port())
  // Connections open at once, all clients together and from one client
  // address: a new one beyond either closes an older one (the busiest
  // client's oldest idle, else its oldest), so new visitors always get in.
  std::size_t max_connections = 64;
  std::size_t max_per_client = 16;
  std::size_t max_request_bytes = 8192;
  // Bytes queued for one stream client beyond which skippable events are not
  // queued for it.
  std::size_t stream_backlog_bytes = 256 * 1024;
  std::int64_t stall_timeout_ns = 10'000'000'000;    // output pending, none accepted: close
  std::int64_t request_timeout_ns = 10'000'000'000;  // request not complete: close
  std::int64_t idle_timeout_ns = 5'000'000'000;      // nothing received at all: close
};

struct HttpResponse {
  int status = 200;
  std::string content_type = "text/plain; charset=utf-8";
  std::string body;
};

struct HttpStats {
  std::int64_t accepted = 0;
  std::int64_t requests = 0;
  std::int64_t bad_requests = 0;          // malformed, too large, wrong method, timed out
  std::int64_t evicted = 0;               // closed to make room (max_connections, max_per_client)
  std::int64_t idle_closed = 0;           // closed for sending nothing within idle_timeout
  std::int64_t stream_clients = 0;        // open now
  std::int64_t skipped_events = 0;        // not queued for a client whose backlog was full
  std::int64_t stalled_closed = 0;        // closed for accepting nothing within stall_timeout
  std::int64_t stream_backlog_bytes = 0;  // queued for stream clients now
};

class HttpServer {
 public:
  using Handler = std::function<HttpResponse()>;
  // Returns the first bytes of a new stream (already in SSE form, e.g. from
  // sse_event()).
  using StreamOpen = std::function<std::string()>;

  // Binds and listens. Throws std::runtime_error naming the address and the
  // reason (address in use, not an address, permission).
  explicit HttpServer(HttpOptions options);
  ~HttpServer();
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  int port() const { return port_; }
  // "http://127.0.0.1:8077/" ("[::1]" for IPv6).
  std::string url() const;

  void add_handler(const std::string& path, Handler handler);
  void add_event_stream(const std::string& path, StreamOpen on_open);

  // Appends the descriptors to poll (listening socket and connections) to
  // `fds`; service() must then get the same vector after poll().
  void add_pollfds(std::vector<pollfd>& fds);
  // Accepts, reads, answers, writes and expires, from poll()'s results.
  void service(const std::vector<pollfd>& fds, std::int64_t now_ns);

  // Queues one event for every open stream. `skippable`: may be skipped for a
  // client whose backlog is full (a later event supersedes it).
  void publish(std::string_view event, std::string_view data, bool skippable, std::int64_t now_ns);

  HttpStats stats() const;

 private:
  struct Conn;
  void accept_all(std::int64_t now_ns);
  void make_room(const std::string& client);
  bool host_allowed(std::string_view host_value) const;
  void read_from(Conn& c, std::int64_t now_ns);
  void answer(Conn& c, std::int64_t now_ns);
  void respond(Conn& c, int status, std::string_view content_type, std::string_view body, bool head,
               std::int64_t now_ns);
  void write_to(Conn& c, std::int64_t now_ns);
  void expire(Conn& c, std::int64_t now_ns);
  void close_conn(Conn& c);

  HttpOptions options_;
  int listen_fd_ = -1;
  int port_ = 0;
  bool ipv6_ = false;
  std::map<std::string, Handler, std::less<>> handlers_;
  std::map<std::string, StreamOpen, std::less<>> streams_;
  std::vector<std::unique_ptr<Conn>> conns_;
  std::size_t poll_base_ = 0;  // index of the listening socket in the last add_pollfds()
  std::size_t polled_conns_ = 0;
  HttpStats stats_;
};

// One SSE event: "event: NAME\ndata: DATA\n\n". `data` must hold no line
// break (JSON from JsonWriter does not).
std::string sse_event(std::string_view event, std::string_view data);

// The reason phrase of a status code ("Not Found").
std::string_view http_reason(int status);

}  // namespace exodaq::tools::view
