"""exodaq: the exodaqd messages for decoders, in pure Python.

The message types generated from lcmtypes/exodaq/*.lcm by lcm-gen
(joint_state_t, palm_pose_t, ... as listed in exodaq.KINDS, with their constants),
a receiver for LCM's udpm:// transport (Debian 12 has no LCM Python module),
decoding by fingerprint, the channel names and names for the flag bits.
docs/messages.md (installed as /usr/share/doc/exodaq/messages.md) has a
complete subscriber.

    import exodaq
    with exodaq.Subscriber("udpm://239.255.76.67:7667?ttl=0", prefix="") as sub:
        for m in sub.messages(timeout=10):
            if m.kind == "palm_pose" and m.msg.valid:
                print(m.msg.seq, m.msg.position)
"""

from ._version import __version__
from ._message_list import *  # noqa: F401,F403  every message class: joint_state_t, ...
from .client import DEFAULT_KINDS, Message, Subscriber, decode, fields, main
from .names import (BASE_CHANNELS, KINDS, Kind, bus_state_name, channel_name, homing_name,
                    invalid_reason_names, joint_flag_names, kind, kind_of_payload, parse_kind,
                    run_id_text, sample_flag_names, split_channel, state_name)
from .udpm import DEFAULT_URL, Receiver, parse_url
