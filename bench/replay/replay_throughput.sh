#!/bin/sh
# Replay throughput at --speed max, full pipeline + LCM log writing, one core,
# and the replay's peak RSS for recordings of several lengths.
#   bench/replay/replay_throughput.sh [BUILD_DIR] [CYCLES] [RUNS] [RSS_CYCLES]
# Per run: the tool's own summary (the cycle loop: wall and thread CPU time)
# and the whole process (config, reading the log, the loop, writing the
# output) in wall and CPU time, with its peak RSS. CPU time is the figure that
# does not depend on what else the machine is running. Then, for each length
# in RSS_CYCLES (default 3600000: 60 minutes at 1 kHz; "" for none), one more
# run on a recording that long: its peak RSS. Every run writes a new output
# file (an existing one would be truncated first, at a cost that is the
# kernel's, not the replay's).
set -eu
src=$(cd "$(dirname "$0")/../.." && pwd)
build=${1:-$src/build}
cycles=${2:-600000}
runs=${3:-3}
rss_cycles=${4-3600000}
work=$(mktemp -d "${TMPDIR:-/tmp}/exodaq-replay-bench-XXXXXX")
trap 'rm -rf "$work"' EXIT
pin=""
if command -v taskset >/dev/null 2>&1; then pin="taskset -c 0"; fi

# replay IN N: one run on IN (N cycles); prints the summary line and the process's figures.
replay() {
  rm -f "$work/out.lcm"
  /usr/bin/time -f "%e %U %S %M" -o "$work/time" $pin "$build/tools/exodaq" replay "$1" \
    -c "$src/config/sim.yaml" -o "$work/out.lcm" --speed max | sed -n '3p'
  awk -v c="$2" '{
    cpu = $2 + $3
    printf "  end to end (process): %d cycles, %.3f s wall = %.0f cycles/s; %.3f s CPU = %.0f cycles per CPU second (%.0fx real time); peak RSS %.1f MiB\n",
           c, $1, c / $1, cpu, c / cpu, c / cpu / 1000, $4 / 1024 }' "$work/time"
}

"$build/bench/replay/bench_replay_gen" --config "$src/config/sim.yaml" --cycles "$cycles" \
  --out "$work/in.lcm"
i=0
while [ "$i" -lt "$runs" ]; do
  i=$((i + 1))
  replay "$work/in.lcm" "$cycles"
done
ls -l "$work/in.lcm" "$work/out.lcm" | awk '{ print "  " $5 " bytes  " $9 }'
rm -f "$work/in.lcm" "$work/out.lcm"

for n in $rss_cycles; do
  "$build/bench/replay/bench_replay_gen" --config "$src/config/sim.yaml" --cycles "$n" \
    --out "$work/long.lcm"
  replay "$work/long.lcm" "$n" | awk -v n="$n" '/end to end/ {
    for (i = 1; i <= NF; i++) if ($i == "RSS") rss = $(i + 1)
    printf "  peak RSS for a recording of %d cycles (%.0f min at 1 kHz): %s MiB\n", n, n / 60000, rss }'
  ls -l "$work/long.lcm" "$work/out.lcm" | awk '{ print "  " $5 " bytes  " $9 }'
  rm -f "$work/long.lcm" "$work/out.lcm"
done
