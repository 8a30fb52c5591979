#!/bin/sh
# bench_smoke SOURCE_DIR BUILD_DIR OUT_DIR: runs the benchmark suite quickly on
# the binaries of BUILD_DIR (built by the normal build) and checks its JSON;
# then re-renders the report from that JSON alone (--report-only), which must
# give the same page but for the line that says it was re-rendered.
set -eu
src=$1
build=$2
out=$3
rm -rf "$out"
mkdir -p "$out"
"$src/bench/run" --quick --no-build --build-dir "$build" --out "$out"
/usr/bin/python3 "$src/tests/bench/check_performance_json.py" "$out/performance.json"
test -s "$out/performance.md"
"$src/bench/run" --report-only "$out/performance.json" --out "$out/report-only"
/usr/bin/python3 "$src/tests/bench/check_performance_json.py" "$out/report-only/performance.json"
grep -v '^| page and verdicts re-rendered' "$out/report-only/performance.md" >"$out/rerendered.md"
diff -u "$out/performance.md" "$out/rerendered.md"
