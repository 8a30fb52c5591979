#!/usr/bin/env python3
"""The Python package's channel table and flag names agree with the C++
messages library's, value for value.

  check_names.py NAMES_DUMP

NAMES_DUMP (names_dump.cpp) prints one line per input with the C++ answer;
this script computes the Python answer (exodaq.names, the package on
PYTHONPATH) for the same input and fails on any difference. Also: the kinds
cover every generated type of the package, in the C++ order.
"""
import os
import re
import subprocess
import sys

import exodaq


def fail(msg):
    print("FAIL: " + msg, file=sys.stderr)
    sys.exit(1)


def python_answer(family, arg):
    if family == "kind":
        return None  # compared as a table below
    if family == "parse":
        k = exodaq.parse_kind(arg)
        return k.type.__name__ if k else "-"
    if family == "split":
        parts = exodaq.split_channel(arg)
        return "'%s' %s" % (parts[0], parts[1].type.__name__) if parts else "-"
    v = int(arg)
    fn = {"joint": exodaq.joint_flag_names, "sample": exodaq.sample_flag_names,
          "invalid": exodaq.invalid_reason_names, "state": exodaq.state_name,
          "bus": exodaq.bus_state_name, "homing": exodaq.homing_name}[family]
    return fn(v)


def main(argv):
    out = subprocess.run([argv[1]], check=True, capture_output=True, text=True).stdout
    cpp_kinds = []
    checked = {}
    for line in out.splitlines():
        m = re.fullmatch(r"(\w+) ('[^']*'|-?\d+|\S+) (.*)", line)
        if not m:
            fail("unreadable line from %s: %r" % (argv[1], line))
        family, arg, cpp = m.group(1), m.group(2), m.group(3)
        if family == "kind":
            cpp_kinds.append((arg, cpp))
            continue
        arg = arg[1:-1] if arg.startswith("'") else arg
        py = python_answer(family, arg)
        if py != cpp:
            fail("%s(%r): C++ %r, Python %r" % (family, arg, cpp, py))
        checked[family] = checked.get(family, 0) + 1
    py_kinds = [(k.type.__name__, "%s %s" % (k.base_channel, "per_cycle" if k.per_cycle else "-"))
                for k in exodaq.KINDS]
    if py_kinds != cpp_kinds:
        fail("kinds: C++ %s, Python %s" % (cpp_kinds, py_kinds))
    pkg = os.path.dirname(exodaq.__file__)
    generated = sorted(f[:-3] for f in os.listdir(pkg) if re.fullmatch(r"\w+_t\.py", f))
    if generated != sorted(t for t, _ in py_kinds):
        fail("generated types %s, exodaq.KINDS %s" % (generated, py_kinds))
    for family in ("parse", "split", "joint", "sample", "invalid", "state", "bus", "homing"):
        if not checked.get(family):
            fail("no %s lines from %s" % (family, argv[1]))
    print("kinds %s; %s: Python == C++" % (
        ", ".join(k.base_channel for k in exodaq.KINDS),
        ", ".join("%s %d" % (f, n) for f, n in sorted(checked.items()))))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
