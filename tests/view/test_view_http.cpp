// The HTTP/SSE server of `exodaq view` over real loopback sockets, driven
// like cmd_view.cpp drives it (poll, then service) with a virtual clock for
// its timeouts: answers, refusals, event streams, slow and vanished clients.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <arpa/inet.h>

#include <chrono>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "view_http.hpp"

namespace exodaq::tools::view {
namespace {

constexpr int64_t kSecond = 1'000'000'000;

struct Harness {
  explicit Harness(HttpOptions o = {}) : server(with_any_port(std::move(o))) {
    server.add_handler("/a", [] { return HttpResponse{200, "text/plain", "hello"}; });
    server.add_event_stream("/events", [] { return sse_event("hello", "{\"n\":0}"); });
  }
  static HttpOptions with_any_port(HttpOptions o) {
    o.port = 0;
    return o;
  }
  // One round of the tool's loop: poll (up to timeout_ms), then service.
  void step(int timeout_ms = 2) {
    std::vector<pollfd> fds;
    server.add_pollfds(fds);
    poll(fds.data(), fds.size(), timeout_ms);
    server.service(fds, now_ns);
  }
  int64_t now_ns = kSecond;  // virtual: only the server's timeouts read it
  HttpServer server;
};

class Client {
 public:
  // `from`: the client's own address (any of 127.0.0.0/8 is this host's).
  explicit Client(int port, int rcvbuf = 0, const char* from = nullptr,
                  const char* to = "127.0.0.1") {
    fd_ = socket(AF_INET, SOCK_STREAM, 0);
    if (rcvbuf > 0) setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &rcvbuf, sizeof rcvbuf);
    if (from != nullptr) {
      sockaddr_in src{};
      src.sin_family = AF_INET;
      inet_pton(AF_INET, from, &src.sin_addr);
      if (bind(fd_, reinterpret_cast<sockaddr*>(&src), sizeof src) != 0) {
        throw std::runtime_error("bind to a client address failed");
      }
    }
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_port = htons(static_cast<uint16_t>(port));
    inet_pton(AF_INET, to, &a.sin_addr);
    if (connect(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) {
      throw std::runtime_error("connect failed");
    }
  }
  ~Client() { close(); }
  void close() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  void send_text(const std::string& s) {
    ASSERT_EQ(::send(fd_, s.data(), s.size(), MSG_NOSIGNAL), static_cast<ssize_t>(s.size()));
  }
  // Reads what is there; false once the server closed the connection.
  bool poll_read() {
    char buf[65536];
    for (;;) {
      const ssize_t n = recv(fd_, buf, sizeof buf, MSG_DONTWAIT);
      if (n > 0) {
        got.append(buf, static_cast<std::size_t>(n));
        continue;
      }
      return n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK);
    }
  }
  // Steps the server until it closes the connection (2 s at most).
  std::string until_closed(Harness& h) {
    for (int i = 0; i < 1000; ++i) {
      h.step();
      if (!poll_read()) return got;
    }
    ADD_FAILURE() << "the server did not close the connection; got: " << got;
    return got;
  }
  // Steps the server until `text` has arrived (2 s at most).
  bool until_received(Harness& h, const std::string& text) {
    for (int i = 0; i < 1000; ++i) {
      h.step();
      poll_read();
      if (got.find(text) != std::string::npos) return true;
    }
    return false;
  }
  std::string got;

 private:
  int fd_ = -1;
};

std::string request(Harness& h, const std::string& text) {
  Client c(h.server.port());
  c.send_text(text);
  return c.until_closed(h);
}

TEST(ViewHttp, ServesARegisteredPathWithItsHeaders) {
  Harness h;
  const std::string r = request(h, "GET /a HTTP/1.1\r\nHost: localhost\r\n\r\n");
  EXPECT_EQ(r.rfind("HTTP/1.1 200 OK\r\n", 0), 0u) << r;
  EXPECT_NE(r.find("Content-Type: text/plain\r\n"), std::string::npos) << r;
  EXPECT_NE(r.find("Content-Length: 5\r\n"), std::string::npos) << r;
  EXPECT_NE(r.find("Connection: close\r\n"), std::string::npos) << r;
  // The page may load nothing from anywhere else.
  EXPECT_NE(r.find("Content-Security-Policy: default-src 'self'"), std::string::npos) << r;
  EXPECT_EQ(r.substr(r.size() - 9), "\r\n\r\nhello") << r;
  EXPECT_EQ(h.server.stats().requests, 1);
}

TEST(ViewHttp, HeadAnswersWithoutTheBody) {
  Harness h;
  const std::string r = request(h, "HEAD /a HTTP/1.1\r\n\r\n");
  EXPECT_EQ(r.rfind("HTTP/1.1 200 OK\r\n", 0), 0u) << r;
  EXPECT_NE(r.find("Content-Length: 5\r\n"), std::string::npos) << r;
  EXPECT_EQ(r.substr(r.size() - 4), "\r\n\r\n") << r;
}

TEST(ViewHttp, UnknownPathIs404AndTheQueryIsIgnored) {
  Harness h;
  EXPECT_EQ(request(h, "GET /b HTTP/1.1\r\n\r\n").rfind("HTTP/1.1 404 Not Found\r\n", 0), 0u);
  EXPECT_EQ(request(h, "GET /a?x=1#y HTTP/1.1\r\n\r\n").rfind("HTTP/1.1 200 OK\r\n", 0), 0u);
}

TEST(ViewHttp, RejectsWhatItDoesNotSpeak) {
  Harness h;
  const std::string post = request(h, "POST /a HTTP/1.1\r\nContent-Length: 0\r\n\r\n");
  EXPECT_EQ(post.rfind("HTTP/1.1 405 Method Not Allowed\r\n", 0), 0u) << post;
  EXPECT_NE(post.find("Allow: GET, HEAD\r\n"), std::string::npos) << post;
  EXPECT_EQ(request(h, "garbage\r\n\r\n").rfind("HTTP/1.1 400 ", 0), 0u);
  EXPECT_EQ(request(h, "GET /a HTTP/2.0\r\n\r\n").rfind("HTTP/1.1 505 ", 0), 0u);
  EXPECT_EQ(request(h, "GET http://x/a HTTP/1.1\r\n\r\n").rfind("HTTP/1.1 400 ", 0), 0u);
  EXPECT_EQ(request(h, "GET /a  HTTP/1.1\r\n\r\n").rfind("HTTP/1.1 400 ", 0), 0u);
  EXPECT_EQ(h.server.stats().bad_requests, 5);
}

int status_of(Harness& h, const std::string& host_line, const char* to = "127.0.0.1") {
  Client c(h.server.port(), 0, nullptr, to);
  c.send_text("GET /a HTTP/1.1\r\n" + host_line + "\r\n\r\n");
  const std::string r = c.until_closed(h);
  return r.size() > 12 ? std::stoi(r.substr(9, 3)) : 0;
}

// Issue 25.9: only this server's own names, exactly, with an optional port.
TEST(ViewHttp, OnlyThisServersOwnHostNamesAreServed) {
  Harness h;
  for (const char* ok : {"Host: localhost:8077", "host:127.0.0.1", "HOST: [::1]:80",
                         "Host: LOCALHOST", "Host: [0:0:0:0:0:0:0:1]"}) {
    EXPECT_EQ(status_of(h, ok), 200) << ok;
  }
  // A page elsewhere whose name was made to resolve to 127.0.0.1 (DNS rebinding).
  for (const char* bad : {"Host: evil.example:8077", "Host: 127.0.0.1.evil.example",
                          "Host: localhost.evil.example", "Host: 127.0.0.2", "Host: localhost:80x",
                          "Host: localhost:", "Host: ::1", "Host: 127.0.0.1:8077/x",
                          "Host: user@localhost", "Host: localhost\r\nHost: evil.example"}) {
    EXPECT_EQ(status_of(h, bad), 403) << bad;
  }
  const std::string r = request(h, "GET /a HTTP/1.1\r\nHost: 127.0.0.1.evil.example\r\n\r\n");
  EXPECT_EQ(r.rfind("HTTP/1.1 403 Forbidden\r\n", 0), 0u) << r;
  EXPECT_NE(r.find("Host '127.0.0.1.evil.example' is not an address of this server: open http://"),
            std::string::npos)
      << r;
}

TEST(ViewHttp, TheBoundAddressIsOneOfItsNamesAndAWildcardTakesAnyAddress) {
  HttpOptions o;
  o.bind = "127.0.0.2";
  Harness h(o);
  EXPECT_EQ(status_of(h, "Host: 127.0.0.2:8077", "127.0.0.2"), 200);
  EXPECT_EQ(status_of(h, "Host: localhost", "127.0.0.2"), 200);
  EXPECT_EQ(status_of(h, "Host: 127.0.0.3", "127.0.0.2"), 403);
  HttpOptions any;
  any.bind = "0.0.0.0";
  Harness w(any);
  EXPECT_EQ(status_of(w, "Host: 10.1.2.3:8077"), 200);  // an address: no rebinding
  EXPECT_EQ(status_of(w, "Host: rig-pc.lab:8077"), 403);
}

TEST(ViewHttp, RequestHeaderTooLargeIs431) {
  HttpOptions o;
  o.max_request_bytes = 1024;
  Harness h(o);
  const std::string r =
      request(h, "GET /a HTTP/1.1\r\nX-Filler: " + std::string(4000, 'x') + "\r\n\r\n");
  EXPECT_EQ(r.rfind("HTTP/1.1 431 ", 0), 0u) << r.substr(0, 80);
}

TEST(ViewHttp, RequestArrivingInPiecesIsAnswered) {
  Harness h;
  Client c(h.server.port());
  c.send_text("GE");
  h.step();
  c.send_text("T /a HTTP/1.1\r\nHost: localhost\r\n");
  h.step();
  EXPECT_TRUE(c.poll_read());
  EXPECT_EQ(c.got, "");  // not complete yet: no answer
  c.send_text("\r\n");
  EXPECT_EQ(c.until_closed(h).rfind("HTTP/1.1 200 OK\r\n", 0), 0u);
}

TEST(ViewHttp, UnfinishedRequestTimesOutAndAnIdleConnectionIsClosed) {
  HttpOptions o;
  o.request_timeout_ns = 5 * kSecond;
  Harness h(o);
  Client partial(h.server.port());
  Client idle(h.server.port());
  partial.send_text("GET /a HT");
  h.step();
  h.step();
  EXPECT_TRUE(partial.poll_read());
  EXPECT_TRUE(idle.poll_read());
  h.now_ns += 6 * kSecond;
  EXPECT_EQ(partial.until_closed(h).rfind("HTTP/1.1 408 ", 0), 0u) << partial.got;
  EXPECT_EQ(idle.until_closed(h), "");  // a browser's spare connection: closed, no answer
  EXPECT_EQ(h.server.stats().bad_requests, 1);
}

TEST(ViewHttp, EventStreamStartsWithTheOpeningEventThenGetsPublishedOnes) {
  Harness h;
  Client c(h.server.port());
  c.send_text("GET /events HTTP/1.1\r\nAccept: text/event-stream\r\n\r\n");
  ASSERT_TRUE(c.until_received(h, "data: {\"n\":0}\n\n")) << c.got;
  EXPECT_EQ(c.got.rfind("HTTP/1.1 200 OK\r\nContent-Type: text/event-stream", 0), 0u) << c.got;
  EXPECT_NE(c.got.find("\r\n\r\nretry: 1000\n\nevent: hello\ndata: {\"n\":0}\n\n"),
            std::string::npos)
      << c.got;
  EXPECT_EQ(h.server.stats().stream_clients, 1);
  h.server.publish("frame", "{\"seq\":7}", true, h.now_ns);
  EXPECT_TRUE(c.until_received(h, "event: frame\ndata: {\"seq\":7}\n\n")) << c.got;
  // HEAD of a stream: headers only, then closed.
  const std::string head = request(h, "HEAD /events HTTP/1.1\r\n\r\n");
  EXPECT_EQ(head.rfind("HTTP/1.1 200 OK\r\n", 0), 0u) << head;
  EXPECT_EQ(head.find("retry:"), std::string::npos) << head;
}

TEST(ViewHttp, ClientThatDoesNotReadHasEventsSkippedThenIsClosed) {
  HttpOptions o;
  o.stream_backlog_bytes = 64 * 1024;
  o.stall_timeout_ns = 10 * kSecond;
  Harness h(o);
  Client slow(h.server.port(), 4096);
  Client fast(h.server.port());
  slow.send_text("GET /events HTTP/1.1\r\n\r\n");
  fast.send_text("GET /events HTTP/1.1\r\n\r\n");
  ASSERT_TRUE(slow.until_received(h, "event: hello"));
  ASSERT_TRUE(fast.until_received(h, "event: hello"));
  ASSERT_EQ(h.server.stats().stream_clients, 2);

  // 32 MiB of events, far beyond what the kernel buffers for a client that
  // does not read: publish() never blocks, and skips for that client only.
  const std::string data(8192, 'x');
  for (int i = 0; i < 4096; ++i) {
    h.server.publish("frame", data + std::to_string(i), true, h.now_ns);
    fast.poll_read();
    fast.got.clear();  // keep the test's memory small
    h.step(0);
  }
  const int64_t skipped = h.server.stats().skipped_events;
  EXPECT_GT(skipped, 0);
  EXPECT_LT(skipped, 4096);  // it got some before its backlog filled
  h.server.publish("frame", "{\"last\":1}", true, h.now_ns);
  EXPECT_TRUE(fast.until_received(h, "data: {\"last\":1}\n\n"));
  // A state change is never skipped (it only grows the slow backlog).
  h.server.publish("stream", "{\"state\":\"stopped\"}", false, h.now_ns);
  EXPECT_EQ(h.server.stats().skipped_events, skipped + 1);  // just the "last" frame
  EXPECT_TRUE(fast.until_received(h, "data: {\"state\":\"stopped\"}\n\n"));

  // Fill the slow client's kernel buffers for good (they grow to a few MiB)
  // with events that are never skipped, until output stays queued here.
  const std::string big(65536, 'z');
  int rounds = 0;
  for (int still = 0; still < 3 && rounds < 1000; ++rounds) {
    h.server.publish("stream", big, false, h.now_ns);
    for (int k = 0; k < 5; ++k) {
      h.step(1);
      fast.poll_read();
      fast.got.clear();
    }
    still = h.server.stats().stream_backlog_bytes > 0 ? still + 1 : 0;
  }
  ASSERT_GT(h.server.stats().stream_backlog_bytes, 0) << "after " << rounds << " rounds";

  // No byte accepted for longer than the stall timeout: closed; the fast one stays.
  h.now_ns += 11 * kSecond;
  h.step();
  EXPECT_EQ(h.server.stats().stalled_closed, 1);
  EXPECT_EQ(h.server.stats().stream_clients, 1);
  EXPECT_EQ(h.server.stats().stream_backlog_bytes, 0);
  h.server.publish("frame", "{\"after\":1}", true, h.now_ns);
  EXPECT_TRUE(fast.until_received(h, "data: {\"after\":1}\n\n"));
}

TEST(ViewHttp, VanishedStreamClientIsDroppedWithoutSigpipe) {
  Harness h;
  {
    Client c(h.server.port());
    c.send_text("GET /events HTTP/1.1\r\n\r\n");
    ASSERT_TRUE(c.until_received(h, "event: hello"));
  }  // closed by the client
  for (int i = 0; i < 100 && h.server.stats().stream_clients > 0; ++i) {
    h.server.publish("frame", std::string(4096, 'y'), true, h.now_ns);  // EPIPE, not SIGPIPE
    h.step();
  }
  EXPECT_EQ(h.server.stats().stream_clients, 0);
}

// Issue 25.9: connections held open by some clients never lock others out.
// Beyond its own limit a client loses its oldest connection (idle first);
// when all places are taken, the client holding the most loses one.
TEST(ViewHttp, ANewConnectionBeyondALimitClosesTheBusiestClientsOldest) {
  HttpOptions o;
  o.max_connections = 6;
  o.max_per_client = 4;
  Harness h(o);
  Client page(h.server.port(), 0, "127.0.0.1");
  page.send_text("GET /events HTTP/1.1\r\n\r\n");
  ASSERT_TRUE(page.until_received(h, "event: hello"));
  // One client opens 10: 4 stay (its last 4), 6 are closed.
  std::vector<std::unique_ptr<Client>> flood;
  for (int i = 0; i < 10; ++i) {
    flood.push_back(std::make_unique<Client>(h.server.port(), 0, "127.0.0.2"));
    h.step();
  }
  h.step();
  int open = 0;
  for (std::size_t i = 0; i < flood.size(); ++i) {
    const bool alive = flood[i]->poll_read();
    open += alive ? 1 : 0;
    EXPECT_EQ(alive, i >= 6) << i;
  }
  EXPECT_EQ(open, 4);
  EXPECT_EQ(h.server.stats().evicted, 6);
  // Another client with 2 fills the server (4 + 2 + the page's stream = 7 > 6):
  // a place is taken from the busiest client, not from the page.
  Client c1(h.server.port(), 0, "127.0.0.3");
  Client c2(h.server.port(), 0, "127.0.0.3");
  h.step();
  h.step();
  EXPECT_EQ(h.server.stats().evicted, 7);
  EXPECT_FALSE(flood[6]->poll_read());  // the busiest client's oldest
  EXPECT_TRUE(page.poll_read());
  EXPECT_EQ(h.server.stats().stream_clients, 1);
  // A new visitor is served, not refused.
  const std::string r = request(h, "GET /a HTTP/1.1\r\n\r\n");
  EXPECT_EQ(r.rfind("HTTP/1.1 200 OK\r\n", 0), 0u) << r;
  h.server.publish("frame", "{\"seq\":1}", true, h.now_ns);
  EXPECT_TRUE(page.until_received(h, "data: {\"seq\":1}"));
}

TEST(ViewHttp, ConnectionsThatSendNothingAreClosedAfterTheIdleTimeout) {
  HttpOptions o;
  o.idle_timeout_ns = 2 * kSecond;
  Harness h(o);
  Client idle(h.server.port());
  Client started(h.server.port());
  started.send_text("GET /a HT");
  h.step();
  h.step();
  h.now_ns += 3 * kSecond;
  EXPECT_EQ(idle.until_closed(h), "");
  EXPECT_TRUE(started.poll_read());  // a request under way has request_timeout
  EXPECT_EQ(h.server.stats().idle_closed, 1);
}

TEST(ViewHttp, ListeningErrorsNameTheAddressAndTheReason) {
  Harness h;
  HttpOptions same;
  same.port = h.server.port();
  try {
    HttpServer again(same);
    FAIL() << "a second server on port " << same.port;
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("127.0.0.1 port " + std::to_string(same.port)),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("in use"), std::string::npos) << e.what();
  }
  HttpOptions name;
  name.bind = "localhost";
  EXPECT_THROW(HttpServer{name}, std::runtime_error);
  HttpOptions port;
  port.port = 70000;
  EXPECT_THROW(HttpServer{port}, std::runtime_error);
  EXPECT_EQ(h.server.url(), "http://127.0.0.1:" + std::to_string(h.server.port()) + "/");
}

}  // namespace
}  // namespace exodaq::tools::view
