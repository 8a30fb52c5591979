"""A process's CPU time, context switches and RSS, from /proc."""
import os
import time


def tasks(pid):
    try:
        return os.listdir(f"/proc/{pid}/task")
    except OSError:
        return []


def cpu_ns(pid):
    """CPU time of all of the process's threads, ns (schedstat), or None once it is gone."""
    total = 0
    found = False
    for t in tasks(pid):
        try:
            with open(f"/proc/{pid}/task/{t}/schedstat") as f:
                total += int(f.read().split()[0])
                found = True
        except (OSError, ValueError, IndexError):
            pass
    if found:
        return total
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) * 1_000_000_000 // os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


def ctx_switches(pid):
    vol = invol = 0
    for t in tasks(pid):
        try:
            with open(f"/proc/{pid}/task/{t}/status") as f:
                for line in f:
                    if line.startswith("voluntary_ctxt_switches:"):
                        vol += int(line.split()[1])
                    elif line.startswith("nonvoluntary_ctxt_switches:"):
                        invol += int(line.split()[1])
        except OSError:
            pass
    return vol, invol


def status_kib(pid, key):
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith(key + ":"):
                    return int(line.split()[1])
    except OSError:
        pass
    return None


class ResourceProbe:
    """CPU %, context switches/s and RSS of a process between start() and stop()."""

    def __init__(self, pid):
        self.pid = pid
        self.rss_max_kib = 0
        self.t0 = self.c0 = self.v0 = self.i0 = None
        self.result = None

    def start(self):
        self.t0 = time.monotonic()
        self.c0 = cpu_ns(self.pid)
        self.v0, self.i0 = ctx_switches(self.pid)
        self.poll()

    def poll(self):
        rss = status_kib(self.pid, "VmRSS")
        if rss:
            self.rss_max_kib = max(self.rss_max_kib, rss)

    def stop(self):
        t1 = time.monotonic()
        c1 = cpu_ns(self.pid)
        v1, i1 = ctx_switches(self.pid)
        self.poll()
        hwm = status_kib(self.pid, "VmHWM")
        dt = t1 - self.t0
        if c1 is None or self.c0 is None or dt <= 0:
            self.result = None
            return None
        self.result = {
            "window_s": round(dt, 2),
            "cpu_percent": round(100.0 * (c1 - self.c0) / 1e9 / dt, 3),
            "ctx_voluntary_per_s": round((v1 - self.v0) / dt, 1),
            "ctx_involuntary_per_s": round((i1 - self.i0) / dt, 1),
            "ctx_per_s": round((v1 - self.v0 + i1 - self.i0) / dt, 1),
            "rss_mib": round(self.rss_max_kib / 1024, 2),
            "rss_hwm_mib": round((hwm or 0) / 1024, 2),
            "threads": len(tasks(self.pid)),
        }
        return self.result


def sample_resources(proc, probe, start_after, stop_before_end, duration):
    """Polls RSS once a second; starts the probe after start_after s, stops it
    stop_before_end s before the process's duration ends."""
    t0 = time.monotonic()
    started = False
    while proc.poll() is None:
        el = time.monotonic() - t0
        if not started and el >= start_after:
            probe.start()
            started = True
        if started and el >= duration - stop_before_end:
            probe.stop()
            return probe.result
        if started:
            probe.poll()
        time.sleep(min(1.0, max(0.05, duration - stop_before_end - el)) if started else 0.05)
    return None
