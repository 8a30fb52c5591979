"""Part `lateness`: exodaqd --lateness-log and cyclictest side by side, same duration,
1000 µs, same policy and priority, memory locked on both; one run per policy."""
import os
import subprocess

from ..common import cmdline, log, policy_name, priority, ratio, read_ints, summary_us
from ..daemon import daemon_argv, overruns, unique_prefix, write_config


def parse_cyclictest_verbose(path):
    """The samples of `cyclictest -v -N` (ns): lines "thread: loop: value"."""
    vals = []
    with open(path) as f:
        for line in f:
            parts = line.split(":")
            if len(parts) == 3:
                try:
                    vals.append(int(parts[2]))
                except ValueError:
                    pass
    return vals


def run_one(ctx, policy):
    prio = priority(policy)
    d = os.path.join(ctx.tmp, f"lateness_{policy}")
    os.makedirs(d, exist_ok=True)
    config = write_config(ctx.src, os.path.join(d, "exodaqd.yaml"), unique_prefix("L"), 1000, prio, True)
    late = os.path.join(d, "lateness.txt")
    ct = ["cyclictest", "-m", "-i", "1000", "-d", "0", "-l", str(int(ctx.duration * 1000)), "-v", "-N",
          "-p", str(prio), f"--policy={'fifo' if policy == 'fifo' else 'other'}"]
    dm = daemon_argv(ctx.bin["exodaqd"], config, ctx.duration, late)
    log(f"lateness {policy}: {cmdline(dm)}  ||  {cmdline(ct)}")
    ct_out, err = os.path.join(d, "cyclictest.txt"), os.path.join(d, "exodaqd.err")
    with open(ct_out, "w") as f, open(err, "w") as e:
        pc = subprocess.Popen(ct, stdout=f, stderr=subprocess.STDOUT)
        pd = subprocess.Popen(dm, stdout=e, stderr=subprocess.STDOUT)
        pd.wait(ctx.duration + 60)
        pc.wait(ctx.duration + 60)
    ds, cs = summary_us(read_ints(late)), summary_us(parse_cyclictest_verbose(ct_out))
    return {
        "policy": policy_name(policy),
        "priority": prio,
        "duration_s": ctx.duration,
        "daemon": ds,
        "cyclictest": cs,
        "ratio": {k: ratio(ds[k], cs[k]) for k in ("p50_us", "p99_us", "p999_us", "max_us")},
        "daemon_overruns": overruns(err),
        "daemon_exit_code": pd.returncode,
        "cyclictest_exit_code": pc.returncode,
        "commands": [cmdline(["exodaqd"] + dm[1:2] + ["<sim.yaml, priority %d, lock_memory true>" % prio]
                             + dm[3:-1] + ["FILE"]),
                     cmdline(ct)],
    }


def measure(ctx):
    return {p: run_one(ctx, p) for p in ctx.policies}
