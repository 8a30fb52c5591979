#!/usr/bin/env python3
"""A small lab network out of Linux network namespaces, for LCM across a network.

One namespace per host, each with one veth interface (`eth0`) whose peer is a
port of a Linux bridge (`br0`) in a namespace of its own (the switch): nothing
is created in the caller's namespace, so the lab cannot disturb the machine's
own network or the loopback tests running beside it, and deleting the
namespaces removes every interface. Each host gets lo up, an address on
10.77.0.0/24 and a route for 224.0.0.0/4 on eth0 (LCM needs a multicast route;
there is no default route in the lab). The bridge does IGMP snooping and,
optionally, acts as the IGMP querier, like a managed lab switch.

A Linux bridge that has just become querier floods all multicast for one query
response interval (10 s by default) before it forwards by membership, and
floods the hosts' IGMP reports too: IGMPv2 hosts that hear another member's
report suppress their own, the bridge never learns them, and at the end of
that interval they are cut off until they answer the next general query
(31 s, then every 125 s). A lab switch that has been up for a while has no
such phase, so the lab shortens the interval to 1 s and waits it out before it
returns (settle=False skips the wait, to show the failure).

Names: exolab<pid>-<host>, where <pid> is the process that made the lab; a lab
whose process is gone (killed with SIGKILL, a CTest timeout) is removed by the
next NetLab() or by `netlab.py sweep`. Needs root (CAP_SYS_ADMIN, CAP_NET_ADMIN)
and iproute2.

As a library (tests/lab/run_lab.py):

    with NetLab(["rig", "h1", "h2"]) as lab:
        p = lab.popen("h1", ["exodaq", "echo"], stdout=...)   # runs inside h1
        lab.mdb()                                              # bridge mdb show

From the shell (a lab to try things in by hand; `down` removes it):

    tests/lab/netlab.py up rig bmi rec     # prints the namespace names and addresses
    ip netns exec exolab<pid>-bmi exodaq echo
    tests/lab/netlab.py down <pid>
    tests/lab/netlab.py sweep              # every lab whose process is gone
"""

import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

NAME_RE = re.compile(r"^exolab(\d+)x*-")
SUBNET = "10.77.0"
SWITCH = "sw"
QUERY_RESPONSE_CS = 100  # the bridge's IGMP query response interval, centiseconds


class LabUnavailable(RuntimeError):
    """Network namespaces cannot be created here (not root, no CAP_SYS_ADMIN, no netns)."""


def _ip(*args, check=True):
    r = subprocess.run(["ip", *args], capture_output=True, text=True)
    if check and r.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {r.stderr.strip() or 'exit ' + str(r.returncode)}")
    return r


def list_namespaces():
    r = _ip("netns", "list", check=False)
    return [line.split()[0] for line in r.stdout.splitlines() if line.strip()]


def _pid_alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_namespace(ns):
    """Kills whatever still runs in `ns` (our lab's processes only: nothing else
    can be in it), then deletes it; its veth and bridge go with it."""
    r = _ip("netns", "pids", ns, check=False)
    for pid in r.stdout.split():
        try:
            os.kill(int(pid), signal.SIGKILL)
        except (ProcessLookupError, ValueError):
            pass
    _ip("netns", "del", ns, check=False)


def sweep(owner=None):
    """Removes the labs of processes that are gone (or of `owner`). Returns the names."""
    removed = []
    for ns in list_namespaces():
        m = NAME_RE.match(ns)
        if not m:
            continue
        pid = int(m.group(1))
        if (owner is not None and pid == owner) or (owner is None and not _pid_alive(pid)):
            remove_namespace(ns)
            removed.append(ns)
    return removed


class NetLab:
    """Namespaces `hosts` joined by a bridge; see the module docstring."""

    def __init__(self, hosts, snooping=True, querier=True, owner=None, settle=True):
        if os.geteuid() != 0:
            raise LabUnavailable("network namespaces need root (CAP_SYS_ADMIN and CAP_NET_ADMIN)")
        if len(set(hosts)) != len(hosts) or SWITCH in hosts or len(hosts) > 200:
            raise ValueError(f"host names must be unique, not '{SWITCH}', at most 200: {hosts}")
        sweep()
        self.tag = f"exolab{owner or os.getpid()}"
        while any(ns.startswith(self.tag + "-") for ns in list_namespaces()):
            self.tag += "x"  # a second lab in this process
        self.hosts = list(hosts)
        self.address = {h: f"{SUBNET}.{i + 1}" for i, h in enumerate(hosts)}
        self.port = {h: f"p{i + 1}" for i, h in enumerate(hosts)}  # bridge port of each host
        self.snooping = snooping
        self.querier = querier
        self.settle = settle
        self._made = []
        self._procs = []
        self._run_dirs = {}
        try:
            self._build()
        except BaseException:
            self.close()
            raise

    def ns(self, host):
        return f"{self.tag}-{host}"

    @property
    def switch(self):
        return self.ns(SWITCH)

    def _add_ns(self, name):
        r = _ip("netns", "add", name, check=False)
        if r.returncode != 0:
            # The first one tells whether namespaces can be made here at all.
            kind = RuntimeError if self._made else LabUnavailable
            raise kind(f"ip netns add {name}: {r.stderr.strip()}")
        self._made.append(name)

    def _build(self):
        sw = self.switch
        self._add_ns(sw)
        _ip("-n", sw, "link", "set", "lo", "up")
        _ip("-n", sw, "link", "add", "br0", "type", "bridge",
            "mcast_snooping", "1" if self.snooping else "0",
            "mcast_query_response_interval", str(QUERY_RESPONSE_CS))
        _ip("-n", sw, "link", "set", "br0", "up")
        if self.snooping and self.querier:
            # After the response interval is set: enabling the querier starts
            # the flooding phase with the interval in force at that moment.
            _ip("-n", sw, "link", "set", "br0", "type", "bridge", "mcast_querier", "1")
        querier_on = time.monotonic()
        for h in self.hosts:
            ns = self.ns(h)
            self._add_ns(ns)
            _ip("link", "add", "eth0", "netns", ns, "type", "veth",
                "peer", "name", self.port[h], "netns", sw)
            _ip("-n", sw, "link", "set", self.port[h], "master", "br0")
            _ip("-n", sw, "link", "set", self.port[h], "up")
            _ip("-n", ns, "link", "set", "lo", "up")
            _ip("-n", ns, "addr", "add", f"{self.address[h]}/24", "dev", "eth0")
            _ip("-n", ns, "link", "set", "eth0", "up")
            _ip("-n", ns, "route", "add", "224.0.0.0/4", "dev", "eth0")
        if self.snooping and self.querier and self.settle:
            time.sleep(max(0.0, querier_on + QUERY_RESPONSE_CS / 100 + 0.3 - time.monotonic()))

    # ---- processes inside a host
    def command(self, host, argv):
        return ["ip", "netns", "exec", self.ns(host), *argv]

    def run_dir(self, host):
        """The host's own runtime directory (its /run): a network namespace
        shares the file system, and exodaqd's instance lock lives there, so two
        labs' rigs on the same channels must not meet in /run/exodaq."""
        if host not in self._run_dirs:
            self._run_dirs[host] = tempfile.mkdtemp(prefix=self.ns(host) + "-run-")
        return self._run_dirs[host]

    def host_env(self, host, env=None):
        out = dict(os.environ if env is None else env)
        out["RUNTIME_DIRECTORY"] = self.run_dir(host)
        return out

    def popen(self, host, argv, **kw):
        """Starts argv inside `host` (its own session, so close() can signal its
        group), with RUNTIME_DIRECTORY set to the host's own."""
        kw["env"] = self.host_env(host, kw.get("env"))
        p = subprocess.Popen(self.command(host, argv), start_new_session=True, **kw)
        self._procs.append(p)
        return p

    def run(self, host, argv, **kw):
        kw.setdefault("capture_output", True)
        kw.setdefault("text", True)
        kw["env"] = self.host_env(host, kw.get("env"))
        return subprocess.run(self.command(host, argv), **kw)

    # ---- the switch
    def mdb(self):
        """`bridge mdb show` of the switch: which ports joined which groups."""
        return subprocess.run(["ip", "netns", "exec", self.switch, "bridge", "mdb", "show"],
                              capture_output=True, text=True).stdout

    def ports_in_group(self, group):
        """Bridge ports with an IGMP membership for `group`, as host names."""
        by_port = {p: h for h, p in self.port.items()}
        ports = set()
        for line in self.mdb().splitlines():
            m = re.search(r"port (\S+) grp (\S+)", line)
            if m and m.group(2) == group and m.group(1) in by_port:
                ports.add(by_port[m.group(1)])
        return ports

    def port_stats(self):
        """Per host: the bridge port's rx/tx packets and drops (ip -s -j link)."""
        import json

        r = _ip("-n", self.switch, "-s", "-j", "link", "show", check=False)
        out = {}
        by_port = {p: h for h, p in self.port.items()}
        for link in json.loads(r.stdout or "[]"):
            h = by_port.get(link.get("ifname"))
            if h is None:
                continue
            s = link.get("stats64", {})
            out[h] = {"to_host_packets": s.get("tx", {}).get("packets"),
                      "to_host_dropped": s.get("tx", {}).get("dropped"),
                      "from_host_packets": s.get("rx", {}).get("packets"),
                      "from_host_dropped": s.get("rx", {}).get("dropped")}
        return out

    # ---- teardown
    def close(self):
        for p in self._procs:
            if p.poll() is None:
                try:
                    os.killpg(p.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        for p in self._procs:
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                pass
        self._procs = []
        for ns in reversed(self._made):
            remove_namespace(ns)
        self._made = []
        for d in self._run_dirs.values():
            shutil.rmtree(d, ignore_errors=True)
        self._run_dirs = {}

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False


def _main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    up = sub.add_parser("up", help="create a lab and leave it (remove it with `down PID`)")
    up.add_argument("hosts", nargs="+")
    up.add_argument("--no-snooping", action="store_true")
    up.add_argument("--no-querier", action="store_true")
    down = sub.add_parser("down", help="remove the lab made by `up` (its PID)")
    down.add_argument("pid", type=int)
    sub.add_parser("sweep", help="remove every lab whose process is gone")
    sub.add_parser("list", help="list lab namespaces")
    a = ap.parse_args()
    if a.cmd == "up":
        # The lab outlives this command: name it after a process that stays, a
        # `sleep infinity` started here; `down` ends that sleep and the lab.
        keeper = subprocess.Popen(["sleep", "infinity"], start_new_session=True,
                                  stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        try:
            lab = NetLab(a.hosts, snooping=not a.no_snooping, querier=not a.no_querier,
                         owner=keeper.pid)
        except BaseException:
            keeper.kill()
            raise
        lab._made = []  # keep it
        for h in lab.hosts:
            print(f"{h}\t{lab.ns(h)}\t{lab.address[h]}\tbridge port {lab.port[h]}")
        print(f"switch\t{lab.switch}\tbr0")
        print(f"remove with: {sys.argv[0]} down {keeper.pid}")
    elif a.cmd == "down":
        removed = sweep(owner=a.pid)
        try:
            os.kill(a.pid, signal.SIGTERM)
        except ProcessLookupError:
            pass
        print("\n".join(removed) or "nothing to remove")
    elif a.cmd == "sweep":
        print("\n".join(sweep()) or "nothing to remove")
    elif a.cmd == "list":
        print("\n".join(ns for ns in list_namespaces() if NAME_RE.match(ns)))


if __name__ == "__main__":
    try:
        _main()
    except LabUnavailable as e:
        print(f"netlab: {e}", file=sys.stderr)
        sys.exit(77)
