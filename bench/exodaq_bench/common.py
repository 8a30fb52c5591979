"""What every part shares: the checkout, logging, commands as the reader would type
them, statistics over samples, and the run's context."""
import os
import re
import subprocess
import time
from dataclasses import dataclass

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def log(msg):
    print(f"[bench/run {time.strftime('%H:%M:%S')}] {msg}", flush=True)


def sh(cmd, **kw):
    return subprocess.run(cmd, check=True, text=True, **kw)


def out_of(cmd):
    """The command's stdout (stripped), or "" when it cannot run."""
    try:
        return subprocess.run(cmd, capture_output=True, text=True, cwd=REPO).stdout.strip()
    except OSError:
        return ""


def cmdline(argv):
    return " ".join(a if re.fullmatch(r"[\w@%+=:,./-]+", a) else repr(a) for a in argv)


def rel(path):
    """A path as the reader would type it from the repository root."""
    p = os.path.abspath(path)
    return os.path.relpath(p, REPO) if p.startswith(REPO + os.sep) else p


def read_ints(path):
    with open(path) as f:
        return [int(line) for line in (raw.strip() for raw in f) if line]


# ---------------------------------------------------------------- statistics
def pct(sorted_values, q):
    if not sorted_values:
        return float("nan")
    i = min(len(sorted_values) - 1, max(0, int(round(q * (len(sorted_values) - 1)))))
    return sorted_values[i]


def summary_us(values_ns):
    v = sorted(values_ns)
    if not v:
        return {"n": 0, "p50_us": None, "p99_us": None, "p999_us": None, "max_us": None}
    return {
        "n": len(v),
        "p50_us": round(pct(v, 0.5) / 1000, 2),
        "p99_us": round(pct(v, 0.99) / 1000, 2),
        "p999_us": round(pct(v, 0.999) / 1000, 2),
        "max_us": round(v[-1] / 1000, 2),
    }


def median(xs):
    xs = sorted(xs)
    return xs[len(xs) // 2] if xs else float("nan")


def ratio(a, b):
    return round(a / b, 3) if a is not None and b not in (None, 0) else None


# ---------------------------------------------------------------- scheduling
FIFO_PRIORITY = 50


def policy_name(policy):
    return "SCHED_FIFO" if policy == "fifo" else "SCHED_OTHER"


def priority(policy):
    return FIFO_PRIORITY if policy == "fifo" else 0


# ---------------------------------------------------------------- the run
@dataclass
class Context:
    """What a part needs to measure: where things are and how long to run."""
    src: str             # the tree that was built; exodaqd runs with its config/
    build_dir: str
    bin: dict            # binary name -> path (build.BINARIES)
    tmp: str             # scratch directory of this run
    quick: bool
    policies: list       # "other", and "fifo" when SCHED_FIFO is allowed
    duration: float      # seconds per lateness / e2e run
    scale_duration: float  # seconds per scaling point
