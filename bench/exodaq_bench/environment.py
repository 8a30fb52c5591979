"""The machine and checkout a run measured on (performance.json's "machine")."""
import datetime
import os
import platform
import shutil
import subprocess

from .common import FIFO_PRIORITY, out_of


def cpuinfo(key):
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith(key):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return None


def cpu_mhz():
    try:
        return float(cpuinfo("cpu MHz"))
    except (TypeError, ValueError):
        return None


def first_line(cmd):
    text = out_of(cmd)
    return text.splitlines()[0] if text else None


def clocksource():
    path = "/sys/devices/system/clocksource/clocksource0/current_clocksource"
    try:
        with open(path) as f:
            return f.read().strip()
    except OSError:
        return "?"


def lcm_version():
    return out_of(["pkg-config", "--modversion", "lcm"]) or "?"


def machine(from_commit):
    """from_commit: the commit measured from a clean export, or None for the working tree."""
    dirty = from_commit is None and out_of(["git", "status", "--porcelain", "--untracked-files=no"]) != ""
    return {
        "nproc": os.cpu_count(),
        "cpu_model": cpuinfo("model name") or "?",
        "cpu_mhz": cpu_mhz(),
        "kernel": platform.release(),
        "commit": out_of(["git", "rev-parse", "--short", from_commit or "HEAD"]),
        "measured": f"git archive {from_commit} (clean export)" if from_commit else "working tree",
        "tree_dirty": dirty,
        "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
        "hostname": platform.node(),
        "compiler": first_line(["c++", "--version"]) or "?",
        "cyclictest": first_line(["cyclictest", "--help"]) if shutil.which("cyclictest") else None,
        "lcm": lcm_version(),
        "loadavg_start": list(os.getloadavg()),
        "clocksource": clocksource(),
    }


def fifo_allowed():
    try:
        return subprocess.run(["chrt", "-f", str(FIFO_PRIORITY), "true"]).returncode == 0
    except OSError:
        return False
