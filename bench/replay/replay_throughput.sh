#!/bin/sh
# Replay throughput at --speed max, full pipeline + LCM log writing, one core.
#   bench/replay/replay_throughput.sh [BUILD_DIR] [CYCLES] [RUNS]
# Prints the tool's own summary per run (the cycle loop: wall and thread CPU
# time) and the whole process (config, loading the log, the loop, writing the
# output) in wall and CPU time. CPU time is the figure that does not depend on
# what else the machine is running.
set -eu
src=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$src/build}
cycles=${2:-600000}
runs=${3:-3}
work=$(mktemp -d "${TMPDIR:-/tmp}/exodaq-replay-bench-XXXXXX")
trap 'rm -rf "$work"' EXIT
"$build/bench/replay/bench_replay_gen" --config "$src/config/sim.yaml" --cycles "$cycles" \
  --out "$work/in.lcm"
pin=""
if command -v taskset >/dev/null 2>&1; then pin="taskset -c 0"; fi
i=0
while [ "$i" -lt "$runs" ]; do
  i=$((i + 1))
  /usr/bin/time -f "%e %U %S" -o "$work/time" $pin "$build/tools/exodaq" replay "$work/in.lcm" \
    -c "$src/config/sim.yaml" -o "$work/out.lcm" --speed max | sed -n '3p'
  awk -v c="$cycles" '{
    cpu = $2 + $3
    printf "  end to end (process): %d cycles, %.3f s wall = %.0f cycles/s; %.3f s CPU = %.0f cycles per CPU second (%.0fx real time)\n",
           c, $1, c / $1, cpu, c / cpu, c / cpu / 1000 }' "$work/time"
done
ls -l "$work/in.lcm" "$work/out.lcm" | awk '{ print "  " $5 " bytes  " $9 }'
