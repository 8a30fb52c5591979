"""Part `cycle`: Acquisition::run_cycle on the sim source (bench/cycle/bench_cycle),
per-cycle percentiles from its harness, Google Benchmark means, heap allocations."""
import json
import os
import subprocess

from ..common import FIFO_PRIORITY, cmdline, log, rel
from . import gbench

# performance.json key -> (harness JSON block, its key)
HARNESS_FIGURES = {
    "without_status_p50_ns": ("cycle_without_status", "p50_ns"),
    "without_status_p99_ns": ("cycle_without_status", "p99_ns"),
    "status_cycle_p50_ns": ("cycle_with_status", "p50_ns"),
    "status_cycle_p99_ns": ("cycle_with_status", "p99_ns"),
    "sim_source_read_p50_ns": ("sim_source_read", "p50_ns"),
    "sim_source_read_p99_ns": ("sim_source_read", "p99_ns"),
    "clock_gettime_pair_ns": ("clock_gettime_pair", "p50_ns"),
    "paced_cycles": ("paced_cycle", "n"),
    "paced_p50_ns": ("paced_cycle", "p50_ns"),
    "paced_p99_ns": ("paced_cycle", "p99_ns"),
    "paced_publisher_thread_p50_ns": ("paced_cycle_publisher_thread", "p50_ns"),
    "paced_publisher_thread_p99_ns": ("paced_cycle_publisher_thread", "p99_ns"),
}


def run_harness(ctx, fifo):
    cycles, paced = (20000, 1000) if ctx.quick else (200000, 10000)
    out = os.path.join(ctx.tmp, "cycle_harness.json")
    argv = [ctx.bin["bench_cycle"], "--harness", "--cycles", str(cycles), "--paced", str(paced), "--json", out]
    if fifo:  # as the loop thread runs: not preempted by the concurrent builds
        argv = ["chrt", "-f", str(FIFO_PRIORITY)] + argv
    log("cycle: " + cmdline(argv))
    rc = subprocess.run(argv).returncode
    with open(out) as f:
        return argv, rc, json.load(f)


def harness_figures(h):
    c = h["cycle"]
    r = {"cycles": h["cycles"], "homed_and_running": h["homed_and_running"]}
    r.update({k: c[k] for k in ("p50_ns", "p90_ns", "p99_ns", "p999_ns", "max_ns", "mean_ns")})
    r.update({key: h[block][k] for key, (block, k) in HARNESS_FIGURES.items()})
    r["status_every_cycles"] = h["status_every_cycles"]
    r["allocations"] = h["allocations_loop_thread"]
    r["allocations_process"] = h["allocations_process"]
    r["allocations_per_cycle"] = h["allocations_per_cycle"]
    return r


def measure(ctx):
    fifo = "fifo" in ctx.policies
    harness, rc, h = run_harness(ctx, fifo)
    gb = [ctx.bin["bench_cycle"], "--benchmark_format=json", "--benchmark_out_format=json"]
    gb += gbench.repetition_flags(ctx.quick, 5)
    log("cycle: " + cmdline(gb))
    g = gbench.run(gb)
    bc, bs = g["BM_Cycle"], g["BM_SimSourceRead"]
    r = harness_figures(h)
    r.update({
        "harness_exit_code": rc,
        "gbench_cycle_cpu_ns": round(bc["cpu_time"], 1),
        "gbench_cycle_real_ns": round(bc["real_time"], 1),
        "gbench_sim_source_read_cpu_ns": round(bs["cpu_time"], 1),
        "gbench_allocs_per_cycle": bc.get("allocs_per_cycle", 0.0),
        "harness_policy": "SCHED_FIFO %d" % FIFO_PRIORITY if fifo else "SCHED_OTHER",
        "commands": [cmdline([rel(x) if "bench_cycle" in x else x for x in harness[:-2]]),
                     cmdline([rel(gb[0])] + gb[1:])],
    })
    return r
