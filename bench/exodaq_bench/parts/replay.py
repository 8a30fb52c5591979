"""Part `replay`: bench/replay/replay_throughput.sh BUILD CYCLES RUNS when the measured
tree has it: `exodaq replay --speed max` on a simulated log, full pipeline + log
writing. Its figures are parsed from its output."""
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
    W s wall = R cycles/s; C s CPU = P cycles per CPU second (Xx real time)". The sim
    runs at 1 kHz: cycles/s / 1000 = × real time. Returns the medians over the runs."""
    loop_wall, loop_cpu, proc_wall, proc_cpu = [], [], [], []
    for line in stdout.splitlines():
        if "end to end" in line:
            m = re.search(r"= (\d+) cycles/s;.*= (\d+) cycles per CPU second", line)
            if m:
                proc_wall.append(int(m.group(1)) / 1000)
                proc_cpu.append(int(m.group(2)) / 1000)
        else:
            m = re.search(r"\(([\d.]+)x real time\), (\d+) per CPU second", line)
            if m:
                loop_wall.append(float(m.group(1)))
                loop_cpu.append(int(m.group(2)) / 1000)
    med = lambda xs: round(median(xs), 1) if xs else None
    return {
        "available": bool(loop_cpu),
        "speed_x": med(loop_cpu),
        "loop_cpu_speed_x": med(loop_cpu),
        "loop_wall_speed_x": med(loop_wall),
        "process_cpu_speed_x": med(proc_cpu),
        "process_wall_speed_x": med(proc_wall),
        "runs": len(loop_cpu),
    }


def measure(ctx):
    path = script(ctx.src)
    if path is None:
        return {"available": False, "speed_x": None, "command": None,
                "note": "bench/replay does not exist in the measured tree"}
    cycles, runs = ("20000", "1") if ctx.quick else ("600000", "3")
    argv = ["sh", path, ctx.build_dir, cycles, runs]
    log("replay: " + cmdline(argv))
    p = subprocess.run(argv, capture_output=True, text=True)
    r = parse(p.stdout)
    r.update({
        "cycles": int(cycles),
        "command": cmdline([SCRIPT, rel(ctx.build_dir), cycles, runs]),
        "note": None if r["available"] else f"{SCRIPT} gave no figure (exit {p.returncode}): "
                                            + (p.stderr.strip().splitlines() or ["no output"])[-1],
        "output": p.stdout,
    })
    return r
