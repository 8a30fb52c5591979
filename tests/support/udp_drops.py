"""Datagrams the kernel dropped on a process's UDP sockets because their
receive buffers were full: a receiver's own measure of what it lost, read
while it runs (its sockets close when it exits). The Python tests' copy of
tests/support/process.cpp's test::udp_drops.

The process and its descendants count (a receiver started through `timeout`
or `chrt` is a child of the process the test holds); their sockets are looked
up in /proc/PID/net/udp, so in the process's own network namespace.
"""
import os


def _children(pid):
    out = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        # pid (comm) state ppid ...: comm may hold spaces and parentheses.
        fields = stat[stat.rfind(")") + 2:].split()
        if len(fields) > 1 and int(fields[1]) == pid:
            out.append(int(entry))
    return out


def _tree(pid):
    pids, todo = [], [pid]
    while todo:
        p = todo.pop()
        pids.append(p)
        todo.extend(_children(p))
    return pids


def _socket_inodes(pid):
    inodes = set()
    try:
        for fd in os.listdir(f"/proc/{pid}/fd"):
            try:
                target = os.readlink(f"/proc/{pid}/fd/{fd}")
            except OSError:
                continue
            if target.startswith("socket:["):
                inodes.add(target[8:-1])
    except OSError:
        pass
    return inodes


def udp_drops(pid):
    """The sum of the drops column of /proc/PID/net/udp{,6} over the UDP
    sockets of `pid` and its descendants (0 when it holds none)."""
    drops, counted = 0, set()  # a socket inherited by a child counts once
    for p in _tree(pid):
        inodes = _socket_inodes(p) - counted
        for table in ("udp", "udp6"):
            try:
                lines = open(f"/proc/{p}/net/{table}").read().splitlines()[1:]
            except OSError:
                continue
            for line in lines:
                col = line.split()
                if len(col) >= 13 and col[9] in inodes:
                    drops += int(col[-1])
        counted |= inodes
    return drops
