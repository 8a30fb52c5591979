"""The exodaq messages, their channels, and names for their flag bits and codes.

The same table and the same names as the C++ messages library; both come from
the one message list (messages/include/exodaq/messages/message_list.def),
which the build writes into _message_list.py, and tests/python checks both
agree bit for bit. A channel is ``<prefix><base>``, e.g. "RIG2_" +
"EXO_JOINT_STATE", where the prefix is the daemon's lcm.prefix
(docs/messages.md).

The flag names come from the constants of the .lcm files, which lcm-gen puts
into the generated classes: joint_state_t.JOINT_STALE is named "STALE".
"""

import collections

from ._message_list import MESSAGES
from .joint_state_t import joint_state_t
from .palm_pose_t import palm_pose_t
from .status_t import status_t

Kind = collections.namedtuple("Kind", "name base_channel type per_cycle")
Kind.__doc__ = """One message type: short name ("joint_state"), channel without
prefix ("EXO_JOINT_STATE"), generated class, and whether it is sent every
cycle (then its seq counts cycles)."""

KINDS = tuple(Kind(name, base, cls, per_cycle) for name, base, cls, per_cycle, _ in MESSAGES)
BASE_CHANNELS = tuple(k.base_channel for k in KINDS)

_by_fingerprint = {k.type._get_packed_fingerprint(): k for k in KINDS}
_aliases = {alias: k for k, (*_, aliases) in zip(KINDS, MESSAGES) for alias in aliases}


def kind(name):
    """The Kind of a short name, base channel or type name, any case
    ("joint_state", "EXO_JOINT_STATE", "joint_state_t", "joints"); ValueError if none."""
    found = parse_kind(name)
    if found is None:
        raise ValueError("not an exodaq message kind: %r (one of %s)" % (
            name, ", ".join(k.name for k in KINDS)))
    return found


def parse_kind(text):
    """As kind(), but None for an unknown name (C++ messages::parse_kind)."""
    if isinstance(text, Kind):
        return text
    u = str(text).upper()
    for k in KINDS:
        if u in (k.name.upper(), k.base_channel, k.type.__name__.upper()):
            return k
    return _aliases.get(u)


def channel_name(prefix, kind_name):
    """prefix + base channel: channel_name("RIG2_", "palm_pose") == "RIG2_EXO_PALM_POSE"."""
    return prefix + kind(kind_name).base_channel


def split_channel(channel):
    """(prefix, Kind) of a channel name ending in a base channel, else None."""
    for k in KINDS:
        if channel.endswith(k.base_channel):
            return channel[:-len(k.base_channel)], k
    return None


def kind_of_payload(data):
    """The Kind of an encoded message from its 8-byte fingerprint; None for a
    foreign type or fewer than 8 bytes."""
    return _by_fingerprint.get(bytes(data[:8]))


def _constants(cls, group):
    """[(value, name without the group)] of cls's constants GROUP_*, by value."""
    start = group + "_"
    return sorted((v, k[len(start):]) for k, v in vars(cls).items()
                  if k.startswith(start) and isinstance(v, int))


JOINT_FLAGS = _constants(joint_state_t, "JOINT")      # [(1, "UNHOMED"), (2, "STALE"), ...]
SAMPLE_FLAGS = _constants(joint_state_t, "SAMPLE")    # [(1, "MISSING"), ...]
INVALID_REASONS = _constants(palm_pose_t, "INVALID")  # [(1, "UNHOMED"), ...]
STATES = dict(_constants(status_t, "STATE"))          # {2: "RUNNING", ...}
BUS_STATES = dict(_constants(status_t, "BUS"))
HOMING_STATES = dict(_constants(status_t, "HOMING"))


def _bit_names(flags, names):
    if flags == 0:
        return "-"
    rest = flags & 0xFFFFFFFF
    out = []
    for bit, name in names:
        if rest & bit:
            out.append(name)
            rest &= ~bit
    if rest:
        out.append("0x%x" % rest)
    return "|".join(out)


def joint_flag_names(flags):
    """joint_state_t.flags[i] for people: "STALE|HELD"; "-" for none; unknown bits as 0x..."""
    return _bit_names(flags, JOINT_FLAGS)


def sample_flag_names(flags):
    """joint_state_t.sample_flags (and encoder_raw_t.source_flags): "SEQ_GAP|LATE", "-"."""
    return _bit_names(flags, SAMPLE_FLAGS)


def invalid_reason_names(reasons):
    """palm_pose_t.invalid_reason: "UNHOMED|JOINT_FAULT", "-" when valid."""
    return _bit_names(reasons, INVALID_REASONS)


def state_name(state):
    """status_t.state: "RUNNING", ...; "UNKNOWN_STATE" for another value."""
    return STATES.get(state, "UNKNOWN_STATE")


def bus_state_name(bus):
    """status_t.bus_state: "ACTIVE", "OFF", ...; "?" for another value."""
    return BUS_STATES.get(bus, "?")


def homing_name(homing):
    """status_t.homing[i]: "UNHOMED", "HOMED", "REJECTED"; "?" for another value."""
    return HOMING_STATES.get(homing, "?")


def run_id_text(run_id):
    """A run id as every exodaq tool spells it: 16 lower-case hex digits."""
    return "%016x" % (run_id & 0xFFFFFFFFFFFFFFFF)
