"""Running exodaqd and LCM subscribers for the parts that measure the daemon."""
import os
import re
import signal
import subprocess

from .common import cmdline

URL = "udpm://239.255.76.67:7667?ttl=0"
_prefix_counter = [0]


def write_config(src, path, prefix, rate_hz=1000, priority=0, lock_memory=False):
    """src's config/sim.yaml with absolute model/calibration paths and these settings."""
    with open(os.path.join(src, "config", "sim.yaml")) as f:
        text = f.read()
    cfg = os.path.join(src, "config") + "/"
    text = text.replace("model: models/", "model: " + cfg + "models/")
    text = text.replace("calibration: calibration/", "calibration: " + cfg + "calibration/")
    text = text.replace("task: tasks/", "task: " + cfg + "tasks/")
    text = re.sub(r'prefix: ""', f'prefix: "{prefix}"', text)
    text = re.sub(r"rate_hz: \d+", f"rate_hz: {rate_hz}", text)
    text = re.sub(r"priority: \d+", f"priority: {priority}", text)
    text = re.sub(r"lock_memory: \w+", f"lock_memory: {'true' if lock_memory else 'false'}", text)
    with open(path, "w") as f:
        f.write(text)
    return path


def unique_prefix(tag):
    """An LCM channel prefix no other run (or engineer) on this host uses."""
    _prefix_counter[0] += 1
    return f"BENCH{os.getpid()}_{tag}{_prefix_counter[0]}_"


def daemon_argv(exodaqd, config, duration, lateness_log=None):
    argv = [exodaqd, "--config", config, "--duration", f"{duration:.1f}"]
    if lateness_log:
        argv += ["--lateness-log", lateness_log]
    return argv


def overruns(err_path):
    """The last overrun count exodaqd logged, or None."""
    with open(err_path) as f:
        found = re.findall(r"\((\d+) overruns", f.read())
    return int(found[-1]) if found else None


class Sub:
    """A bench_lcm_sub process, waited for until it has subscribed."""

    def __init__(self, exe, channel, out, duration, status_channel=None, status_out=None):
        argv = [exe, "--url", URL, "--channel", channel, "--out", out, "--duration", f"{duration:.1f}"]
        if status_channel:
            argv += ["--status-channel", status_channel, "--status-out", status_out]
        self.argv = argv
        self.out = out
        self.status_out = status_out
        self.p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        line = self.p.stdout.readline()
        if "subscribed" not in line:
            raise RuntimeError(f"{cmdline(argv)}: did not subscribe: {self.p.stderr.read()}")

    def wait(self, grace=1.0):
        """After the publishers have stopped: lets the last datagrams in, then stops it."""
        try:
            self.p.wait(grace)
        except subprocess.TimeoutExpired:
            self.p.send_signal(signal.SIGTERM)
            self.p.wait(30)
        return self.p.stderr.read()

    def samples(self):
        """(seq, receive mono_ns, msg.mono_ns, msg.run_id) per message received; the
        reference publisher puts its loop deadline in run_id."""
        return [tuple(int(x) for x in row) for row in self._rows(self.out, 4)]

    def status(self):
        """Per status_t received: seq, work p50/p99/max, lateness p50/p99/max (µs)."""
        if not self.status_out or not os.path.exists(self.status_out):
            return []
        return [[float(x) for x in row] for row in self._rows(self.status_out, 7)]

    @staticmethod
    def _rows(path, width):
        with open(path) as f:
            return [parts for parts in (line.split() for line in f) if len(parts) == width]
