#!/usr/bin/env python3
"""A Python client of the exodaq messages: the exodaq package (build/python:
the lcm-gen types, the udpm:// receiver, the Subscriber, flag names).

  python_client.py files DIR                   decode DIR/<type>.bin of each type
  python_client.py receive URL PREFIX WAIT_S [--big N]
      receive with exodaq.Receiver from a real LCM publisher: the first
      message of each type on PREFIX + EXO_*, and with --big also the N-byte
      blob on PREFIX + BIG (LCM sends it as fragmented LC03 datagrams)
  python_client.py subscriber URL PREFIX WAIT_S
      the same four messages through exodaq.Subscriber, with the flag bits and
      codes named (the fixture sets every flag family)
  python_client.py compat DIR
      the former exodaq_lcm API (the compatibility module) on DIR/<type>.bin

Prints the canonical text of tests/clients/lcm_fixture.cpp (generically, from
__slots__) and checks a few values itself. Exit 0 when all decoded.
Needs build/python on PYTHONPATH (set by CTest).
"""
import struct
import sys

import exodaq

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
    for name, v in exodaq.fields(msg):
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
        check([exodaq.joint_flag_names(f) for f in msg.flags] ==
              ["-", "UNHOMED", "STALE|HELD", "GLITCH|OUT_OF_RANGE", "UNHOMED|LOST_COUNTS",
               "HOMING_REJECTED|BOARD_ERROR"], "joint flag names %s" % msg.flags)
        check(exodaq.sample_flag_names(msg.sample_flags) == "SEQ_GAP|LATE", "sample flag names")
    elif t == "palm_pose_t":
        check(not msg.valid, "valid")
        check(msg.position[0] == 0.1234, "position[0]")
        check(exodaq.invalid_reason_names(msg.invalid_reason) == "UNHOMED|JOINT_FAULT",
              "invalid reason names")
    elif t == "encoder_raw_t":
        check(msg.position[3] == -9007199254740992, "position[3]")
        check(msg.wall_ns == 1700000000123456789, "wall_ns")
        check(exodaq.sample_flag_names(msg.source_flags) == "PARTIAL", "source flag names")
    elif t == "status_t":
        check(msg.state == msg.STATE_DEGRADED, "state")
        check(msg.rig == "sim-rig, bench 2", "rig")
        check(exodaq.state_name(msg.state) == "DEGRADED", "state name")


def files(directory):
    for t in TYPES:
        with open("%s/%s.bin" % (directory, t), "rb") as f:
            data = f.read()
        msg = exodaq.decode(data)
        check(type(msg) is getattr(exodaq, t), "%s recognised by fingerprint" % t)
        check(msg.encode() == data, "%s re-encodes to the same bytes" % t)
        check_values(msg)
        dump(msg)
    return 0


def receive(url, prefix, wait_s, big):
    channels = {exodaq.channel_name(prefix, t): t for t in TYPES}
    wanted = set(channels)
    if big:
        wanted.add(prefix + "BIG")
    rx = exodaq.Receiver(url, channels=list(wanted))
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
                msg = exodaq.decode(data)
                check(type(msg).__name__ == channels[channel], "%s type" % channel)
                check_values(msg)
                dump(msg)
            if seen == wanted:
                break
    if seen != wanted:
        print("python_client: missing %s" % sorted(wanted - seen), file=sys.stderr)
        return 1
    return 0


def subscriber(url, prefix, wait_s):
    # The four the fixture publishes (homing_t, the replay's record, it does not).
    kinds = [k.name for k in exodaq.KINDS if k.name in [t[:-2] for t in TYPES]]
    seen = {}
    with exodaq.Subscriber(url, prefix=prefix, kinds=kinds) as sub:
        check(sorted(sub.channels) == sorted(prefix + exodaq.kind(k).base_channel for k in kinds),
              "channels")
        print("python_client: subscribed", file=sys.stderr)
        sys.stderr.flush()
        for m in sub.messages(timeout=wait_s):
            if m.kind in seen:
                continue
            seen[m.kind] = m
            check(exodaq.split_channel(m.channel) == (prefix, exodaq.kind(m.kind)), "split_channel")
            check(type(m.msg).__name__ == m.kind + "_t", "%s type" % m.channel)
            check_values(m.msg)
            if m.kind == "status":
                check([exodaq.homing_name(h) for h in m.msg.homing] ==
                      ["HOMED", "UNHOMED", "HOMED", "HOMED", "REJECTED", "HOMED"], "homing names")
                check(exodaq.bus_state_name(m.msg.bus_state) == "WARNING", "bus state name")
            dump(m.msg)
            if len(seen) == len(kinds):
                break
        check(sub.undecodable == 0, "undecodable %d: %s" % (sub.undecodable, sub.last_error))
        check(sum(sub.lost.values()) == 0, "lost %s (the fixture repeats one seq)" % sub.lost)
    if len(seen) != len(kinds):
        print("python_client: missing %s" % sorted(set(kinds) - set(seen)), file=sys.stderr)
        return 1
    return 0


def compat(directory):
    import exodaq_lcm
    types = exodaq_lcm.import_types()
    check(types is exodaq, "import_types returns the package")
    check(exodaq_lcm.BASE_CHANNELS == exodaq.BASE_CHANNELS, "BASE_CHANNELS")
    check(exodaq_lcm.DEFAULT_URL == exodaq.DEFAULT_URL, "DEFAULT_URL")
    for t in TYPES:
        with open("%s/%s.bin" % (directory, t), "rb") as f:
            data = f.read()
        msg = exodaq_lcm.decode(data, types)
        check(type(msg) is getattr(exodaq, t), "%s by the compatibility decode" % t)
        check(exodaq_lcm.fields(msg) == exodaq.fields(msg), "fields")
        check_values(msg)
        dump(msg)
    return 0


def main(argv):
    if len(argv) == 3 and argv[1] == "files":
        rc = files(argv[2])
    elif len(argv) in (5, 7) and argv[1] == "receive":
        big = int(argv[6]) if len(argv) == 7 and argv[5] == "--big" else 0
        rc = receive(argv[2], argv[3], float(argv[4]), big)
    elif len(argv) == 5 and argv[1] == "subscriber":
        rc = subscriber(argv[2], argv[3], float(argv[4]))
    elif len(argv) == 3 and argv[1] == "compat":
        rc = compat(argv[2])
    else:
        print(__doc__, file=sys.stderr)
        return 2
    return 1 if rc or failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
