#!/bin/sh
# bench_smoke SOURCE_DIR BUILD_DIR OUT_DIR: runs the benchmark suite quickly on
# the binaries of BUILD_DIR (built by the normal build) and checks its JSON.
set -eu
src=$1
build=$2
out=$3
rm -rf "$out"
mkdir -p "$out"
"$src/bench/run" --quick --no-build --build-dir "$build" --out "$out"
/usr/bin/python3 "$src/tests/bench/check_performance_json.py" "$out/performance.json"
test -s "$out/performance.md"
