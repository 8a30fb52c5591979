"""LCM's UDP multicast transport (``udpm://``), receive side, in pure Python.

Debian 12 packages LCM for C, C++ and Java but not for Python; the generated
exodaq types only need ``struct``. This module is the missing transport:
enough for a decoder process or a notebook. It does not publish, and it only
speaks udpm:// (not file:// or tcpq://). Like LCM it joins the group on the
default interface; on a host with several interfaces set the multicast route
(docs/messages.md, *Network*).

Wire format (LCM 1.x, all integers big-endian), one UDP datagram each:
  short message    'LC02' magic 0x4c433032, uint32 seqno, channel, NUL, payload
  fragment         'LC03' magic 0x4c433033, uint32 seqno, uint32 msg_size,
                   uint32 fragment_offset, uint16 fragment_no, uint16 fragments;
                   fragment 0 carries channel, NUL, then the first payload bytes.
LCM sends messages up to about 64 kB as one LC02 datagram (IP fragments them),
larger ones as LC03 fragments; exodaq's messages are all short.
"""

import re
import select
import socket
import struct
import time

DEFAULT_URL = "udpm://239.255.76.67:7667?ttl=0"  # the daemon's default lcm.url
MAGIC_SHORT = 0x4C433032  # 'LC02'
MAGIC_LONG = 0x4C433033  # 'LC03'

_SHORT = struct.Struct(">II")
_LONG = struct.Struct(">IIIIHH")


def parse_url(url):
    """'udpm://239.255.76.67:7667?ttl=0' -> ('239.255.76.67', 7667, {'ttl': '0'})."""
    m = re.fullmatch(r"udpm://([0-9.]+)(?::(\d+))?/?(?:\?(.*))?", url or DEFAULT_URL)
    if not m:
        raise ValueError("not a udpm:// LCM URL: %r" % url)
    opts = {}
    if m.group(3):
        for kv in m.group(3).split("&"):
            k, _, v = kv.partition("=")
            opts[k] = v
    return m.group(1), int(m.group(2) or 7667), opts


class Receiver:
    """Receives LCM messages from a udpm:// URL as (channel, payload bytes).

    channels: None for every channel, a regular expression (matched against
    the whole channel name, as LCM does), or a list of literal channel names.
    recv_buf_size: the socket buffer to ask for (default: the URL's
    recv_buf_size, else 2 MB; the kernel caps it at net.core.rmem_max).
    Counters: received (messages passed on), bad_packets (unknown magic or
    malformed), dropped_fragmented (fragmented messages abandoned incomplete).
    """

    def __init__(self, url=DEFAULT_URL, channels=None, recv_buf_size=None):
        self.url = url or DEFAULT_URL
        self.group, self.port, opts = parse_url(self.url)
        if channels is None:
            self._match = None
        elif isinstance(channels, str):
            self._match = re.compile(channels).fullmatch
        else:
            self._match = frozenset(channels).__contains__
        if recv_buf_size is None:
            recv_buf_size = int(opts.get("recv_buf_size", 2 * 1024 * 1024))
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
        try:
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            try:
                self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, recv_buf_size)
            except OSError:
                pass
            self.sock.bind(("", self.port))
            mreq = struct.pack("4s4s", socket.inet_aton(self.group), socket.inet_aton("0.0.0.0"))
            self.sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
        except OSError as e:
            self.sock.close()
            raise OSError(e.errno, "cannot join %s: %s (no multicast route? see "
                          "docs/messages.md, Network)" % (self.url, e.strerror)) from e
        self._frags = {}  # sender -> [seqno, channel, bytearray, bytes_received, fragments_seen]
        self.received = 0
        self.bad_packets = 0
        self.dropped_fragmented = 0

    def close(self):
        self.sock.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def fileno(self):
        """The socket, readable when a datagram waits (for select/poll loops)."""
        return self.sock.fileno()

    def _parse(self, pkt, sender):
        """One datagram -> (channel, payload) when it completes a message, else None."""
        if len(pkt) < 8:
            self.bad_packets += 1
            return None
        magic = _SHORT.unpack_from(pkt)[0]
        if magic == MAGIC_SHORT:
            end = pkt.find(b"\0", 8)
            if end < 0:
                self.bad_packets += 1
                return None
            return pkt[8:end].decode("utf-8", "replace"), pkt[end + 1:]
        if magic != MAGIC_LONG or len(pkt) < _LONG.size:
            self.bad_packets += 1
            return None
        _, seqno, size, offset, frag_no, nfrags = _LONG.unpack_from(pkt)
        body = pkt[_LONG.size:]
        state = self._frags.get(sender)
        if frag_no == 0:
            end = body.find(b"\0")
            if end < 0:
                self.bad_packets += 1
                return None
            channel = body[:end].decode("utf-8", "replace")
            body = body[end + 1:]
            if state is not None and state[0] != seqno:
                self.dropped_fragmented += 1
            state = [seqno, channel, bytearray(size), 0, 0]
            self._frags[sender] = state
        elif state is None or state[0] != seqno:
            if state is not None:  # a newer message started before the old one completed
                self.dropped_fragmented += 1
                del self._frags[sender]
            return None  # fragment 0 lost: this message cannot be completed
        if offset + len(body) > len(state[2]):
            self.bad_packets += 1
            return None
        state[2][offset:offset + len(body)] = body
        state[3] += len(body)
        state[4] += 1
        if state[4] == nfrags and state[3] == len(state[2]):
            del self._frags[sender]
            return state[1], bytes(state[2])
        return None

    def recv(self, timeout=None):
        """The next message as (channel, payload bytes); None after `timeout` s
        (0: only what is already waiting; None: wait for ever)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            if deadline is not None:
                left = max(0.0, deadline - time.monotonic())
                if not select.select([self.sock], [], [], left)[0]:
                    return None
            pkt, sender = self.sock.recvfrom(65536)
            got = self._parse(pkt, sender)
            if got is None:
                continue
            if self._match is None or self._match(got[0]):
                self.received += 1
                return got

    def messages(self, count=None, timeout=None):
        """Yields (channel, payload) until `count` messages or `timeout` s in total."""
        return take(self.recv, count, timeout)


def take(recv, count=None, timeout=None):
    """Yields what recv(seconds left) returns until `count` items, `timeout` s
    in total (None: no limit) or recv returns None."""
    deadline = None if timeout is None else time.monotonic() + timeout
    n = 0
    while count is None or n < count:
        left = None if deadline is None else max(0.0, deadline - time.monotonic())
        got = recv(left)
        if got is None:
            return
        n += 1
        yield got
