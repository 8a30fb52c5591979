"""Part `replay`: bench/replay/replay_throughput.sh BUILD CYCLES RUNS RSS_CYCLES when the
measured tree has it: `exodaq replay --speed max` on a simulated log, full pipeline + log
writing, and its peak RSS (/usr/bin/time's %M) for that recording and a longer one. Its
figures are parsed from its output."""
import os
import re
import subprocess

from ..common import cmdline, log, median, rel

SCRIPT = os.path.join("bench", "replay", "replay_throughput.sh")


def script(src):
    path = os.path.join(src, SCRIPT)
    return path if os.path.exists(path) else None


def build_targets(src):
    return ["exodaq", "bench_replay_gen"] if script(src) else []


def parse(stdout):
    """Per run the script prints the tool's summary ("N cycles (...) in W s (C s CPU):
    R cycles/s (Xx real time), P per CPU second") and "end to end (process): N cycles,
    W s wall = R cycles/s; C s CPU = P cycles per CPU second (Xx real time); peak RSS M MiB";
    then "peak RSS for a recording of N cycles (...): M MiB" per longer recording. The sim
    runs at 1 kHz: cycles/s / 1000 = × real time. Returns the medians over the runs
    (speed_x: the whole process in CPU time, the judged figure), the largest RSS of the
    timed runs and that of the longest recording; rss_mib, the judged figure, is the
    larger of the two."""
    loop_wall, loop_cpu, proc_wall, proc_cpu, rss_runs, rss_long = [], [], [], [], [], []
    for line in stdout.splitlines():
        if "end to end" in line:
            m = re.search(r"= (\d+) cycles/s;.*= (\d+) cycles per CPU second", line)
            if m:
                proc_wall.append(int(m.group(1)) / 1000)
                proc_cpu.append(int(m.group(2)) / 1000)
            m = re.search(r"peak RSS ([\d.]+) MiB", line)
            if m:
                rss_runs.append(float(m.group(1)))
        elif "peak RSS for a recording of" in line:
            m = re.search(r"of (\d+) cycles .*: ([\d.]+) MiB", line)
            if m:
                rss_long.append((int(m.group(1)), float(m.group(2))))
        else:
            m = re.search(r"\(([\d.]+)x real time\), (\d+) per CPU second", line)
            if m:
                loop_wall.append(float(m.group(1)))
                loop_cpu.append(int(m.group(2)) / 1000)
    med = lambda xs: round(median(xs), 1) if xs else None
    rss_short = max(rss_runs) if rss_runs else None
    long_cycles, rss_long_mib = max(rss_long) if rss_long else (None, None)
    known = [x for x in (rss_short, rss_long_mib) if x is not None]
    return {
        "available": bool(loop_cpu),
        "speed_x": med(proc_cpu),
        "loop_cpu_speed_x": med(loop_cpu),
        "loop_wall_speed_x": med(loop_wall),
        "process_cpu_speed_x": med(proc_cpu),
        "process_wall_speed_x": med(proc_wall),
        "runs": len(loop_cpu),
        "rss_mib": max(known) if known else None,
        "rss_short_mib": rss_short,
        "rss_long_mib": rss_long_mib,
        "rss_long_cycles": long_cycles,
        "rss_long_min": round(long_cycles / 60000, 2) if long_cycles else None,
    }


def measure(ctx):
    path = script(ctx.src)
    if path is None:
        return {"available": False, "speed_x": None, "command": None,
                "note": "bench/replay does not exist in the measured tree"}
    # Timed: 10 minutes at 1 kHz; peak RSS also for 60 minutes (quick: 20 s and 2 min).
    cycles, runs, long = ("20000", "1", "120000") if ctx.quick else ("600000", "3", "3600000")
    argv = ["sh", path, ctx.build_dir, cycles, runs, long]
    log("replay: " + cmdline(argv))
    p = subprocess.run(argv, capture_output=True, text=True)
    r = parse(p.stdout)
    r.update({
        "cycles": int(cycles),
        "minutes": round(int(cycles) / 60000, 2),
        "command": cmdline([SCRIPT, rel(ctx.build_dir), cycles, runs, long]),
        "note": None if r["available"] else f"{SCRIPT} gave no figure (exit {p.returncode}): "
                                            + (p.stderr.strip().splitlines() or ["no output"])[-1],
        "output": p.stdout,
    })
    return r
