#!/bin/sh
# Runs bench_kinematics and prints ns/call (median of the repetitions), the IK
# success counters and the exodaq/KDL ratios. CPU time is the figure to quote: on a shared or loaded
# machine wall time also counts the time the thread was preempted. Usage: bench/kinematics/kdl_ratio.sh [BUILD_DIR] [REPETITIONS]
set -eu
build=${1:-build}
reps=${2:-10}
exe="$build/bench/kinematics/bench_kinematics"
[ -x "$exe" ] || exe="$build/bk/bench_kinematics"
[ -x "$exe" ] || { echo "kdl_ratio.sh: no bench_kinematics under $build" >&2; exit 2; }
"$exe" --benchmark_repetitions="$reps" --benchmark_report_aggregates_only=true \
  --benchmark_format=json 2>/dev/null | python3 -c '
import json, sys
d = json.load(sys.stdin)
agg = [b for b in d["benchmarks"] if b.get("aggregate_name") == "median"]
real = {b["run_name"]: b["real_time"] for b in agg}
cpu = {b["run_name"]: b["cpu_time"] for b in agg}
scale = {"ns": 1.0, "us": 1e3, "ms": 1e6, "s": 1e9}
for b in agg:
    f = scale[b.get("time_unit", "ns")]
    cpu[b["run_name"]] = b["cpu_time"] * f
    real[b["run_name"]] = b["real_time"] * f
for b in agg:
    n = b["run_name"]
    extra = ""
    if "success" in b:
        ok, lim = b["success"], b["in_limits"]
        extra = f"  success {ok:.4f}, within limits {lim:.4f}"
    print(f"{n:30s} {cpu[n]:11.1f} ns/call cpu, {real[n]:11.1f} ns wall{extra}")
for what, target in (("PalmFk", 0.6), ("FkJacManip", 0.35)):
    rc = cpu[f"BM_{what}_Exodaq"] / cpu[f"BM_{what}_Kdl"]
    rr = real[f"BM_{what}_Exodaq"] / real[f"BM_{what}_Kdl"]
    print(f"ratio {what:12s} exodaq/KDL = {rc:.3f} cpu time, {rr:.3f} wall time (target <= {target})")
for ours, theirs in (("BM_Ik_Exodaq_Nearest", "BM_Ik_Kdl_Lma_FineEpsilon"),
                     ("BM_Ik_Exodaq_Nearest", "BM_Ik_Kdl_Lma")):
    if ours in cpu and theirs in cpu:
        print(f"ratio IK {ours[13:]}/{theirs[6:]} = {cpu[ours] / cpu[theirs]:.3f} cpu time, "
              f"{real[ours] / real[theirs]:.3f} wall time")
print("host:", d["context"].get("host_name", "?"), "cpus:", d["context"].get("num_cpus", "?"),
      "mhz:", d["context"].get("mhz_per_cpu", "?"))
'
