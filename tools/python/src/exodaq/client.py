"""Receiving exodaq messages in a decoder: decode by fingerprint, and a
Subscriber for the channels of one rig.

    import exodaq
    with exodaq.Subscriber(prefix="") as sub:       # the daemon's lcm.url and lcm.prefix
        for m in sub.messages(timeout=10):          # exodaq.Message(channel, kind, msg)
            if m.kind == "joint_state":
                print(m.msg.seq, m.msg.position, exodaq.joint_flag_names(m.msg.flags[0]))

Also a command: ``python3 -m exodaq --count 5`` prints what arrives (--help).
"""

import argparse
import collections
import io
import math
import struct
import sys

from . import names
from .udpm import DEFAULT_URL, Receiver, take

Message = collections.namedtuple("Message", "channel kind msg")
Message.__doc__ = """A received message: its channel, its kind's short name
("joint_state", "palm_pose", "encoder_raw", "status", "homing", "source_status") and the
decoded object
(exodaq.joint_state_t, ...; every array field a list)."""

DEFAULT_KINDS = ("joint_state", "palm_pose", "status")


def _normalise(msg):
    # lcm-gen 1.3.1 decodes arrays as tuples and boolean arrays as map(bool, ...),
    # which in Python 3 is a one-shot iterator: make every array field a list.
    for name in msg.__slots__:
        v = getattr(msg, name)
        if isinstance(v, (map, tuple)):
            setattr(msg, name, list(v))
    return msg


def decode(data):
    """The exodaq message encoded in `data` (bytes), recognised by its fingerprint,
    with every array field a list; None when the fingerprint is not an exodaq
    type. ValueError when the bytes are not exactly one complete message of its
    type (truncated, damaged, trailing bytes)."""
    k = names.kind_of_payload(data)
    if k is None:
        return None
    buf = io.BytesIO(data)
    buf.seek(8)
    try:
        msg = k.type._decode_one(buf)
    except (struct.error, ValueError) as e:
        raise ValueError("%s: %d bytes do not decode: %s" % (k.type.__name__, len(data), e)) from e
    if buf.tell() != len(data):
        raise ValueError("%s: %d bytes, one message is %d" % (k.type.__name__, len(data), buf.tell()))
    return _normalise(msg)


def fields(msg):
    """[(name, value)] of a decoded message in declaration order."""
    return [(name, getattr(msg, name)) for name in msg.__slots__]


class Subscriber:
    """The exodaq channels of one rig, received and decoded.

    url: the daemon's lcm.url (udpm:// only; the receiver's ttl does not matter).
    prefix: the daemon's lcm.prefix, used literally.
    kinds: which messages, by short name (default joint_state, palm_pose, status).
    Counters, for checking nothing was lost (per-cycle kinds, counted per run;
    the rule of the C++ messages::RunAccount, docs/messages.md "Counting what was
    lost"):
      lost[kind]     cycles the daemon published that did not arrive: lost on
                     the way to this process (socket buffer full, network)
      skipped[kind]  seq numbers the daemon itself never published (deadlines
                     it skipped, publishes it counted as failed), from its
                     status counters: not a loss
      pending[kind]  holes not yet covered by a status (at most ~100 ms old):
                     they move to lost or skipped when the next status arrives
      repeated[kind] messages whose seq was not new within their run: two
                     streams with one run id (replay --live of a live run, a
                     forged message), said once per run on stderr; still returned
      undecodable    messages on these channels that did not decode (last_error says why)
      and the transport's: receiver.bad_packets, receiver.dropped_fragmented
    The status channel is always received for this accounting; status messages
    are returned only when "status" is among `kinds`.
    mixed_runs: None, or (run_id, other_run_id) once two runs interleave on these
      channels (two daemons publish on one channel set: a run id comes back after
      another one; a restart, one run after the other, is not a mix). Said once
      on stderr; messages of both are still returned: filter by msg.run_id.
    """

    def __init__(self, url=DEFAULT_URL, prefix="", kinds=DEFAULT_KINDS, recv_buf_size=None):
        self.prefix = prefix
        self.kinds = [names.kind(k) for k in kinds]
        self._by_channel = {prefix + k.base_channel: k for k in self.kinds}
        self._status_channel = prefix + names.kind("status").base_channel
        self._return_status = self._status_channel in self._by_channel
        channels = list(self._by_channel)
        if not self._return_status:
            channels.append(self._status_channel)
        self.receiver = Receiver(url, channels=channels, recv_buf_size=recv_buf_size)
        self.received = collections.Counter()
        self.lost = collections.Counter()
        self.skipped = collections.Counter()
        self.repeated = collections.Counter()
        self.undecodable = 0
        self.last_error = None
        self._last = {}  # kind name -> (run_id, seq)
        self._holes = collections.defaultdict(list)  # kind name -> [[first seq, count]] not yet judged
        self._daemon = {}  # run_id -> (unpublished, failures) of its last status
        self._repeat_said = set()
        self.mixed_runs = None
        self._run = 0
        self._runs_seen = set()

    def close(self):
        self.receiver.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def fileno(self):
        return self.receiver.fileno()

    @property
    def channels(self):
        return list(self._by_channel)

    @property
    def pending(self):
        return collections.Counter({k: sum(n for _, n in h) for k, h in self._holes.items() if h})

    def _count(self, k, msg):
        if k.name != "status" or self._return_status:
            self.received[k.name] += 1
        if k.name == "status":
            self._judge(msg)
            return
        if not k.per_cycle or (msg.utime == 0 and msg.seq == 0):
            return
        last = self._last.get(k.name)
        if last is not None and last[0] != msg.run_id:
            # A new run: the old one's holes no status will cover are lost.
            self.lost[k.name] += sum(n for _, n in self._holes[k.name])
            self._holes[k.name] = []
            last = None
        if last is not None and msg.seq > last[1] + 1:
            self._holes[k.name].append([last[1] + 1, msg.seq - last[1] - 1])
        elif last is not None and msg.seq <= last[1]:
            self.repeated[k.name] += 1
            if msg.run_id not in self._repeat_said:
                self._repeat_said.add(msg.run_id)
                print("exodaq: WARNING: seq %d of run %s on %s after seq %d: interleaved or "
                      "repeated seq of one run id (a second stream with this run id: replay "
                      "--live of a live run?)" % (msg.seq, names.run_id_text(msg.run_id),
                                                  self.prefix + k.base_channel, last[1]),
                      file=sys.stderr)
            return
        self._last[k.name] = (msg.run_id, msg.seq)

    def _judge(self, st):
        """The holes up to a status's seq: the daemon's up to what its counters
        grew by since its previous status, the rest lost."""
        if st.utime == 0:
            return
        unpublished = max(0, st.seq + 1 - st.cycles)
        failures = max(0, st.publish_failures)
        before = self._daemon.get(st.run_id, (0, 0))
        self._daemon[st.run_id] = (max(before[0], unpublished), max(before[1], failures))
        budget = max(0, unpublished - before[0]) + max(0, failures - before[1])
        for name, holes in self._holes.items():
            last = self._last.get(name)
            if not holes or last is None or last[0] != st.run_id:
                continue
            n = 0
            while holes and holes[0][0] <= st.seq:
                take = min(holes[0][1], st.seq - holes[0][0] + 1)
                n += take
                holes[0][0] += take
                holes[0][1] -= take
                if holes[0][1] == 0:
                    holes.pop(0)
            mine = min(n, budget)
            self.skipped[name] += mine
            self.lost[name] += n - mine

    def _watch_runs(self, msg):
        rid = msg.run_id
        if rid == 0 or rid == self._run:  # 0: the daemon's start-up messages
            return
        previous, self._run = self._run, rid
        if rid not in self._runs_seen:
            self._runs_seen.add(rid)
            return
        if self.mixed_runs is None:
            self.mixed_runs = (rid, previous)
            print("exodaq: WARNING: two runs interleaved on prefix %r: run ids %s and %s (two "
                  "daemons publish on one channel set; filter by run_id)"
                  % (self.prefix, names.run_id_text(rid), names.run_id_text(previous)),
                  file=sys.stderr)

    def recv(self, timeout=None):
        """The next Message; None after `timeout` s (None: wait for ever)."""
        while True:
            got = self.receiver.recv(timeout)
            if got is None:
                return None
            channel, data = got
            k = self._by_channel.get(channel) or names.kind("status")
            try:
                msg = decode(data)
                if msg is None or type(msg) is not k.type:
                    raise ValueError("%s: not a %s (%d bytes)" % (channel, k.type.__name__, len(data)))
            except ValueError as e:
                self.undecodable += 1
                self.last_error = str(e)
                continue  # counted; the caller sees it in undecodable
            self._count(k, msg)
            self._watch_runs(msg)
            if k.name == "status" and not self._return_status:
                continue  # received for the accounting only
            return Message(channel, k.name, msg)

    def messages(self, count=None, timeout=None):
        """Yields Messages until `count` of them or `timeout` s in total (None: no limit)."""
        return take(self.recv, count, timeout)


def _summary(channel, msg):
    if msg is None:
        return "%s: (not an exodaq type)" % channel
    t = type(msg).__name__
    if t == "joint_state_t":
        deg = " ".join("%8.3f" % math.degrees(p) for p in msg.position)
        return "%s seq %d deg [%s] homed %s flags %s sample %s" % (
            channel, msg.seq, deg, "".join("1" if h else "0" for h in msg.homed),
            ",".join(names.joint_flag_names(f) for f in msg.flags),
            names.sample_flag_names(msg.sample_flags))
    if t == "palm_pose_t":
        return "%s seq %d valid %d (%s) mm [%s] manip %.3f" % (
            channel, msg.seq, msg.valid, names.invalid_reason_names(msg.invalid_reason),
            " ".join("%8.2f" % (p * 1e3) for p in msg.position), msg.shoulder_manipulability)
    if t == "encoder_raw_t":
        return "%s seq %d present %d position %s" % (channel, msg.seq, msg.present,
                                                     list(msg.position))
    if t == "homing_t":
        return "%s seq %d changed %d homing %s index_count %s" % (
            channel, msg.seq, msg.changed, list(msg.homing), list(msg.index_count))
    if t == "status_t":
        return "%s seq %d rig %r %s %r" % (channel, msg.seq, msg.rig,
                                           names.state_name(msg.state), msg.message)
    # Any other type of the list: its fields as they are.
    fields = " ".join("%s %r" % (n, getattr(msg, n)) for n in msg.__slots__ if n != "seq")
    return "%s %s seq %d %s" % (channel, t, msg.seq, fields)


def main(argv=None):
    ap = argparse.ArgumentParser(prog="python3 -m exodaq",
                                 description="Print exodaq LCM messages (no LCM module needed).")
    ap.add_argument("--url", default=DEFAULT_URL, help="LCM URL (udpm:// only)")
    ap.add_argument("--prefix", default="", help="rig channel prefix (config lcm.prefix)")
    ap.add_argument("--channel", help="regular expression for the channel (default: every "
                    "exodaq channel with --prefix)")
    ap.add_argument("--count", type=int, help="stop after N messages")
    ap.add_argument("--timeout", type=float, help="stop after S seconds")
    ap.add_argument("--fields", action="store_true", help="print every field")
    a = ap.parse_args(argv)
    channels = a.channel or [a.prefix + c for c in names.BASE_CHANNELS]
    n = 0
    with Receiver(a.url, channels=channels) as rx:
        try:
            for channel, data in rx.messages(count=a.count, timeout=a.timeout):
                n += 1
                try:
                    msg = decode(data)
                except ValueError as e:
                    print("%s: %s" % (channel, e))
                    continue
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
        print("exodaq: %d of %d messages" % (n, a.count), file=sys.stderr)
        return 1
    return 0
