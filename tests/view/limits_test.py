#!/usr/bin/env python3
"""`exodaq view` as its own process against hostile clients (issue 25.9).

  limits_test.py EXODAQ SOURCE_DIR

1. DNS rebinding: only localhost, 127.0.0.1, [::1] (and the bound address)
   with an optional port are served; `Host: 127.0.0.1.evil.example` gets 403.
2. Lock-out: a page's event stream is open, then five other client addresses
   (127.0.0.2-6) open 20 connections each, half idle, half streaming: more
   than the 64 places. A new visitor is still served, the page's stream stays
   open, no client holds more than 16, and every connection the flood lost is
   counted in the view's summary line.
3. An idle connection (nothing sent) is closed by the server.
Before: the 65th connection got 503 until one of the 64 went away.
"""
import json
import os
import select
import signal
import socket
import subprocess
import sys
import time

failures = []
FLOOD_CLIENTS = ["127.0.0.%d" % i for i in range(2, 7)]
PER_CLIENT = 20
MAX_CONNECTIONS = 64  # HttpOptions defaults (tools/exodaq/view_http.hpp)
MAX_PER_CLIENT = 16


def check(cond, what):
    if not cond:
        failures.append(what)
        print("FAIL: " + what, file=sys.stderr)


def connect(port, source="127.0.0.1"):
    s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    s.bind((source, 0))
    s.settimeout(30)
    s.connect(("127.0.0.1", port))
    return s


def request(port, host_line, path="/state.json", source="127.0.0.1"):
    """Status code and body of one GET."""
    s = connect(port, source)
    s.sendall(("GET %s HTTP/1.1\r\n%s\r\n\r\n" % (path, host_line)).encode())
    data = b""
    while True:
        chunk = s.recv(65536)
        if not chunk:
            break
        data += chunk
    s.close()
    head, _, body = data.partition(b"\r\n\r\n")
    return int(head.split(b" ")[1]), body


def read_until(s, text, timeout=30):
    end = time.monotonic() + timeout
    got = b""
    while text not in got and time.monotonic() < end:
        r, _, _ = select.select([s], [], [], 1)
        if r:
            chunk = s.recv(65536)
            if not chunk:
                break
            got += chunk
    return text in got


def is_open(s):
    """False once the server closed the connection (end of stream or reset)."""
    s.setblocking(False)
    try:
        while True:
            chunk = s.recv(65536)
            if not chunk:
                return False
    except BlockingIOError:
        return True
    except ConnectionResetError:
        return False
    finally:
        s.setblocking(True)


def main():
    exodaq, src = sys.argv[1], sys.argv[2]
    model = os.path.join(src, "config", "models", "macaque_exo.yaml")
    view = subprocess.Popen([exodaq, "view", "--model", model, "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = view.stdout.readline()
        check(line.startswith("exodaq view: serving http://127.0.0.1:"), "first line %r" % line)
        port = int(line.split()[3].rsplit(":", 1)[1].strip("/"))

        # 1. Host names.
        for host in ("localhost", "localhost:%d" % port, "127.0.0.1", "127.0.0.1:%d" % port,
                     "[::1]", "[::1]:%d" % port):
            code, body = request(port, "Host: " + host)
            check(code == 200 and json.loads(body)["model"]["name"] == "macaque_exo",
                  "Host %s: %d" % (host, code))
        for host in ("127.0.0.1.evil.example", "localhost.evil.example", "evil.example",
                     "127.0.0.2", "localhost:8077x", "127.0.0.1:%d.evil.example" % port):
            code, body = request(port, "Host: " + host)
            check(code == 403, "Host %s: %d, %r" % (host, code, body[:80]))
        code, body = request(port, "Host: 127.0.0.1.evil.example")
        check(b"Host '127.0.0.1.evil.example' is not an address of this server" in body,
              "403 body %r" % body)

        # 2. The page's stream and an idle connection first, then the flood.
        page = connect(port)
        page.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1:%d\r\n\r\n" % port)
        check(read_until(page, b"event: hello"), "the page's stream did not start")
        idle = connect(port)
        flood = {}
        for client in FLOOD_CLIENTS:
            flood[client] = []
            for i in range(PER_CLIENT):
                s = connect(port, client)
                if i % 2:
                    s.sendall(b"GET /events HTTP/1.1\r\nHost: localhost\r\n\r\n")
                flood[client].append(s)
        # Answered after every flood connection was accepted (in order).
        code, body = request(port, "Host: localhost")
        check(code == 200 and b"macaque_exo" in body, "a new visitor during the flood: %d" % code)
        still = {c: sum(is_open(s) for s in socks) for c, socks in flood.items()}
        open_flood = sum(still.values())
        print("flood: %d connections from %d addresses, %d still open %s" %
              (len(FLOOD_CLIENTS) * PER_CLIENT, len(FLOOD_CLIENTS), open_flood, still))
        check(all(n <= MAX_PER_CLIENT for n in still.values()), "a client above its limit: %s" % still)
        check(open_flood + 2 <= MAX_CONNECTIONS, "%d open beside the page's two" % open_flood)
        check(open_flood > 0, "the flood kept nothing: the limits closed everything")
        check(is_open(page), "the page's stream was closed by the flood")

        # 3. Connections that sent nothing are closed by the server: the
        # test's own, and the flood's idle ones it had not closed already.
        silent = [idle] + [s for socks in flood.values() for s in socks[0::2]]
        end = time.monotonic() + 60
        waiting = [s for s in silent if is_open(s)]
        while waiting and time.monotonic() < end:
            select.select(waiting, [], [], 1)
            waiting = [s for s in waiting if is_open(s)]
        check(not waiting, "%d connections that sent nothing still open after 60 s" % len(waiting))
        open_end = sum(is_open(s) for socks in flood.values() for s in socks)

        view.send_signal(signal.SIGTERM)
        out, err = view.communicate(timeout=30)
        check(view.returncode == 0, "exit %d: %s" % (view.returncode, err))
        summary = [l for l in out.splitlines() if l.startswith("exodaq view: stopped:")]
        check(len(summary) == 1, "no summary line in %r" % out)
        if summary:
            print(summary[0])
            words = summary[0].replace(",", "").split()
            evicted = int(words[words.index("make") - 3])
            idle_closed = int(words[words.index("idle") - 1])
            stalled = int(words[words.index("stalled") - 1])
            lost = len(FLOOD_CLIENTS) * PER_CLIENT - open_end
            # Every flood connection gone, and the test's idle one, was closed
            # by one of the view's counted rules.
            check(evicted + idle_closed + stalled == lost + 1,
                  "evicted %d + idle %d + stalled %d != %d lost by the flood + 1" %
                  (evicted, idle_closed, stalled, lost))
            check(evicted >= len(FLOOD_CLIENTS) * (PER_CLIENT - MAX_PER_CLIENT) or idle_closed > 1,
                  "evicted %d: the per-client limit did not act" % evicted)
        for socks in flood.values():
            for s in socks:
                s.close()
        page.close()
    finally:
        if view.poll() is None:
            view.kill()
            view.wait()

    print("%d check(s) failed" % len(failures) if failures else "view limits test passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
