#!/usr/bin/env python3
"""A Python client of the exodaq messages: the generated modules (lcm-gen
--python) plus tools/python/exodaq_lcm.py for the transport.

  python_client.py files DIR                   decode DIR/<type>.bin of each type
  python_client.py receive URL PREFIX WAIT_S [--big N]
      receive with exodaq_lcm.Receiver from a real LCM publisher: the first
      message of each type on PREFIX + EXO_*, and with --big also the N-byte
      blob on PREFIX + BIG (LCM sends it as fragmented LC03 datagrams)

Prints the canonical text of tests/clients/lcm_fixture.cpp (generically, from
__slots__) and checks a few values itself. Exit 0 when all decoded.
Needs EXODAQ_LCMTYPES_PYTHONPATH and tools/python on PYTHONPATH (set by CTest).
"""
import struct
import sys

import exodaq_lcm

TYPES = ("joint_state_t", "palm_pose_t", "encoder_raw_t", "status_t")
failures = 0


def scalar(v):
    if isinstance(v, bool):
        return "1" if v else "0"
    if isinstance(v, float):
        return "0x" + struct.pack(">d", v).hex()
    return str(v)


def dump(msg):
    t = type(msg).__name__
    lines = []
    for name, v in exodaq_lcm.fields(msg):
        if isinstance(v, (list, tuple)):
            lines += ["%s.%s[%d]=%s" % (t, name, i, scalar(x)) for i, x in enumerate(v)]
        else:
            lines.append("%s.%s=%s" % (t, name, scalar(v)))
    print("\n".join(lines))
    sys.stdout.flush()


def check(cond, what):
    global failures
    if not cond:
        print("python_client: check failed: " + what, file=sys.stderr)
        failures += 1


def check_values(msg):
    t = type(msg).__name__
    if t == "joint_state_t":
        check(msg.seq == 4242424242, "seq")
        check(msg.name[3] == "elbow_flexion", "name[3]")
        check(msg.position[3] == -2.75, "position[3]")
        check(msg.homed == [True, False, True, True, False, True], "homed")
        check(msg.flags[2] == msg.JOINT_STALE | msg.JOINT_HELD, "flags[2]")
    elif t == "palm_pose_t":
        check(not msg.valid, "valid")
        check(msg.position[0] == 0.1234, "position[0]")
    elif t == "encoder_raw_t":
        check(msg.count16[3] == -32768, "count16[3]")
        check(msg.wall_ns == 1700000000123456789, "wall_ns")
    elif t == "status_t":
        check(msg.state == msg.STATE_DEGRADED, "state")
        check(msg.rig == "sim-rig, bench 2", "rig")


def files(directory):
    exodaq = exodaq_lcm.import_types()
    for t in TYPES:
        with open("%s/%s.bin" % (directory, t), "rb") as f:
            data = f.read()
        msg = exodaq_lcm.decode(data, exodaq)
        check(type(msg) is getattr(exodaq, t), "%s recognised by fingerprint" % t)
        check(msg.encode() == data, "%s re-encodes to the same bytes" % t)
        check_values(msg)
        dump(msg)
    return 0


def receive(url, prefix, wait_s, big):
    channels = {prefix + c: t for c, t in zip(exodaq_lcm.BASE_CHANNELS, TYPES)}
    wanted = set(channels)
    if big:
        wanted.add(prefix + "BIG")
    rx = exodaq_lcm.Receiver(url, channels=list(wanted))
    print("python_client: subscribed", file=sys.stderr)
    sys.stderr.flush()
    seen = set()
    with rx:
        for channel, data in rx.messages(timeout=wait_s):
            if channel in seen:
                continue
            seen.add(channel)
            if channel == prefix + "BIG":
                expect = bytes((i * 7 + 3) & 0xFF for i in range(big))
                check(data == expect, "BIG blob of %d bytes reassembled (got %d)" % (big, len(data)))
            else:
                msg = exodaq_lcm.decode(data)
                check(type(msg).__name__ == channels[channel], "%s type" % channel)
                check_values(msg)
                dump(msg)
            if seen == wanted:
                break
    if seen != wanted:
        print("python_client: missing %s" % sorted(wanted - seen), file=sys.stderr)
        return 1
    return 0


def main(argv):
    if len(argv) == 3 and argv[1] == "files":
        rc = files(argv[2])
    elif len(argv) in (5, 7) and argv[1] == "receive":
        big = int(argv[6]) if len(argv) == 7 and argv[5] == "--big" else 0
        rc = receive(argv[2], argv[3], float(argv[4]), big)
    else:
        print(__doc__, file=sys.stderr)
        return 2
    return 1 if rc or failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
