#!/bin/sh
# Runs bench_kinematics and prints ns/call (median of the repetitions) and the
# exodaq/KDL ratios. Usage: bench/kinematics/kdl_ratio.sh [BUILD_DIR] [REPETITIONS]
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
med = {b["run_name"]: b["real_time"] for b in d["benchmarks"] if b.get("aggregate_name") == "median"}
for name, t in med.items():
    print(f"{name:28s} {t:8.1f} ns/call")
for what, target in (("PalmFk", 0.6), ("FkJacManip", 0.35)):
    r = med[f"BM_{what}_Exodaq"] / med[f"BM_{what}_Kdl"]
    print(f"ratio {what:12s} exodaq/KDL = {r:.3f} (target <= {target})")
print("host:", d["context"].get("host_name", "?"), "cpus:", d["context"].get("num_cpus", "?"),
      "mhz:", d["context"].get("mhz_per_cpu", "?"))
'
