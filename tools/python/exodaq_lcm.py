#!/usr/bin/env python3
"""Receive exodaq messages in Python without an LCM Python module.

Debian 12 packages LCM for C, C++ and Java but not for Python. The generated
Python types (lcm-gen --python, built into build/lcmtypes/python and installed
under /usr/share/exodaq/lcmtypes/python) only need ``struct``; what is missing
is the transport. This module is a small pure-Python receiver for LCM's UDP
multicast transport (``udpm://``), enough for a decoder process or a notebook:

    import exodaq_lcm
    with exodaq_lcm.Receiver(prefix="") as rx:          # default URL, ttl=0
        for channel, data in rx.messages(count=1000):
            msg = exodaq_lcm.decode(data)                # exodaq.joint_state_t, ...
            if channel.endswith("EXO_JOINT_STATE"):
                print(msg.seq, msg.position)

Run it as a script for a quick look at the traffic:

    python3 tools/python/exodaq_lcm.py --count 5
    python3 tools/python/exodaq_lcm.py --channel EXO_PALM_POSE --count 3 --fields

Wire format (LCM 1.x, all integers big-endian), one UDP datagram each:
  short message    'LC02' magic 0x4c433032, uint32 seqno, channel, NUL, payload
  fragment         'LC03' magic 0x4c433033, uint32 seqno, uint32 msg_size,
                   uint32 fragment_offset, uint16 fragment_no, uint16 fragments;
                   fragment 0 carries channel, NUL, then the first payload bytes.
The payload is the encoded message: an 8-byte type fingerprint, then the fields.
LCM sends messages up to about 64 kB as one LC02 datagram (IP fragments them),
larger ones as LC03 fragments; exodaq's messages are all short.

This receiver does not publish, and it only speaks udpm:// (not file:// or
tcpq://). Like LCM it joins the group on the default interface; on a host with
several interfaces set the multicast route (see docs/messages.md).
"""

import argparse
import os
import re
import select
import socket
import struct
import sys
import time

DEFAULT_URL = "udpm://239.255.76.67:7667?ttl=0"
MAGIC_SHORT = 0x4C433032  # 'LC02'
MAGIC_LONG = 0x4C433033  # 'LC03'
BASE_CHANNELS = ("EXO_JOINT_STATE", "EXO_PALM_POSE", "EXO_ENCODER_RAW", "EXO_STATUS")

_SHORT = struct.Struct(">II")
_LONG = struct.Struct(">IIIIHH")


def parse_url(url):
    """'udpm://239.255.76.67:7667?ttl=0' -> (group, port, {'ttl': '0'})."""
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
    """Receives LCM messages from a udpm:// URL and yields (channel, payload).

    channels: None for every channel, or a regular expression (matched against
    the whole channel name, as LCM does), or a list of literal channel names.
    prefix: only used with channels=None: keep the four exodaq channels of the
    rig with this prefix (the daemon's lcm.prefix).
    """

    def __init__(self, url=DEFAULT_URL, channels=None, prefix=None, recv_buf_size=None):
        self.group, self.port, opts = parse_url(url)
        if channels is None and prefix is not None:
            channels = [prefix + c for c in BASE_CHANNELS]
        if channels is None:
            self._match = None
        elif isinstance(channels, str):
            self._match = re.compile(channels).fullmatch
        else:
            names = frozenset(channels)
            self._match = names.__contains__
        if recv_buf_size is None:
            recv_buf_size = int(opts.get("recv_buf_size", 2 * 1024 * 1024))
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:  # the kernel caps this at net.core.rmem_max
            self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, recv_buf_size)
        except OSError:
            pass
        self.sock.bind(("", self.port))
        mreq = struct.pack("4s4s", socket.inet_aton(self.group), socket.inet_aton("0.0.0.0"))
        self.sock.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
        self._frags = {}  # sender -> [seqno, channel, bytearray, bytes_received, fragments_seen]
        self.received = 0  # complete messages passed the filter
        self.bad_packets = 0  # unknown magic or malformed
        self.dropped_fragmented = 0  # fragmented messages abandoned incomplete

    def close(self):
        self.sock.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def fileno(self):
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
        """The next message as (channel, payload bytes); None after `timeout` s."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            if deadline is not None:
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
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
        deadline = None if timeout is None else time.monotonic() + timeout
        n = 0
        while count is None or n < count:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            got = self.recv(left)
            if got is None:
                return
            n += 1
            yield got


def import_types(path=None):
    """Imports the generated `exodaq` package and returns it.

    Looks in `path`, $EXODAQ_LCMTYPES_PYTHONPATH, the build tree next to this
    file (build/lcmtypes/python) and the installed kit
    (/usr/share/exodaq/lcmtypes/python), in that order.
    """
    here = os.path.dirname(os.path.abspath(__file__))
    candidates = [path, os.environ.get("EXODAQ_LCMTYPES_PYTHONPATH"),
                  os.path.join(here, "..", "..", "build", "lcmtypes", "python"),
                  "/usr/share/exodaq/lcmtypes/python"]
    for c in candidates:
        if c and os.path.isfile(os.path.join(c, "exodaq", "__init__.py")):
            if c not in sys.path:
                sys.path.insert(0, c)
            break
    import exodaq  # noqa: E402 (the generated package)
    return exodaq


_by_fingerprint = None


def _normalise(msg):
    # lcm-gen 1.3.1 decodes boolean arrays as map(bool, ...), which in Python 3
    # is a one-shot iterator; make every array field a list.
    for name in msg.__slots__:
        v = getattr(msg, name)
        if isinstance(v, (map, tuple)):
            setattr(msg, name, list(v))
    return msg


def decode(data, types=None):
    """Decodes an encoded exodaq message by its fingerprint; None for other types."""
    global _by_fingerprint
    if _by_fingerprint is None:
        pkg = types or import_types()
        _by_fingerprint = {}
        for name in ("joint_state_t", "palm_pose_t", "encoder_raw_t", "status_t"):
            cls = getattr(pkg, name)
            _by_fingerprint[cls._get_packed_fingerprint()] = cls
    cls = _by_fingerprint.get(bytes(data[:8]))
    if cls is None:
        return None
    return _normalise(cls.decode(data))


def fields(msg):
    """[(name, value)] of a decoded message, arrays as lists, in declaration order."""
    return [(name, getattr(msg, name)) for name in msg.__slots__]


def _summary(channel, msg):
    if msg is None:
        return "%s: (not an exodaq type)" % channel
    t = type(msg).__name__
    if t == "joint_state_t":
        deg = " ".join("%8.3f" % (p * 57.29577951308232) for p in msg.position)
        return "%s seq %d deg [%s] homed %s flags %s" % (
            channel, msg.seq, deg, "".join("1" if h else "0" for h in msg.homed), list(msg.flags))
    if t == "palm_pose_t":
        return "%s seq %d valid %d mm [%s] manip %.3f" % (
            channel, msg.seq, msg.valid, " ".join("%8.2f" % (p * 1e3) for p in msg.position),
            msg.shoulder_manipulability)
    if t == "encoder_raw_t":
        return "%s seq %d present %d count16 %s" % (channel, msg.seq, msg.present,
                                                     list(msg.count16))
    return "%s seq %d rig %r state %d %r" % (channel, msg.seq, msg.rig, msg.state, msg.message)


def main(argv=None):
    ap = argparse.ArgumentParser(description="Print exodaq LCM messages (no LCM module needed).")
    ap.add_argument("--url", default=DEFAULT_URL)
    ap.add_argument("--prefix", default="", help="rig channel prefix (config lcm.prefix)")
    ap.add_argument("--channel", help="regular expression for the channel (default: the four "
                    "exodaq channels with --prefix)")
    ap.add_argument("--count", type=int, help="stop after N messages")
    ap.add_argument("--timeout", type=float, help="stop after S seconds")
    ap.add_argument("--fields", action="store_true", help="print every field")
    ap.add_argument("--types", help="directory holding the generated exodaq package")
    a = ap.parse_args(argv)
    types = import_types(a.types)
    if a.channel:
        rx = Receiver(a.url, channels=a.channel)
    else:
        rx = Receiver(a.url, prefix=a.prefix)
    n = 0
    with rx:
        try:
            for channel, data in rx.messages(count=a.count, timeout=a.timeout):
                msg = decode(data, types)
                n += 1
                if a.fields and msg is not None:
                    print(channel)
                    for name, v in fields(msg):
                        print("  %s = %r" % (name, v))
                else:
                    print(_summary(channel, msg))
                sys.stdout.flush()
        except KeyboardInterrupt:
            pass
    if a.count is not None and n < a.count:
        print("exodaq_lcm: %d of %d messages" % (n, a.count), file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
