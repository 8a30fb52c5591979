#!/bin/bash
# The recorders side by side through one stall (docs/robustness.md,
# "Recorders"): exodaqd following the sim's free-running board for 7 s,
# stress-ng --cpu 2 from 1 s, the daemon held 1 s by SIGSTOP at 3 s; six
# recorders at once on a private port:
#   A exodaq record --priority 10            (the documented way)
#   B exodaq record                          (no real-time priority)
#   C exodaq record --priority 10 --rcvbuf 425984   (the kernel's default-sized buffer)
#   D exodaq record --rcvbuf 425984
#   E lcm-logger                             (the README's former line)
#   F chrt -f 10 lcm-logger recv_buf_size=2097152   (docs/operations.md's former advice)
# Prints each one's cycles (export rows) against the daemon's.
#   tests/record/compare_recorders.sh BUILD_DIR OUT_DIR   (as root)
set -eu
B=$(cd "$1" && pwd)
SRC=$(cd "$(dirname "$0")/../.." && pwd)
O=$2
mkdir -p "$O"
cd "$O"
rm -f ./*.lcm ./*.json ./*.err
PORT=$((9900 + $$ % 90))
URL="udpm://239.255.76.67:$PORT?ttl=0"
sed -e "s#^model: #model: $SRC/config/#; s#^calibration: #calibration: $SRC/config/#" \
    -e "s#task: tasks/#task: $SRC/config/tasks/#; s#7667?ttl=0#$PORT?ttl=0#" \
    -e 's#^  sim:$#  sim:\n    board_clock: {free_running: true, drift_ppm: 50, phase: 0.3}#' \
    "$SRC/config/sim.yaml" > exodaqd.yaml
X="$B/tools/exodaq"
$X record -o A.lcm -u "$URL" --priority 10 2> A.err & RA=$!
$X record -o B.lcm -u "$URL" 2> B.err & RB=$!
$X record -o C.lcm -u "$URL" --priority 10 --rcvbuf 425984 2> C.err & RC=$!
$X record -o D.lcm -u "$URL" --rcvbuf 425984 2> D.err & RD=$!
lcm-logger --lcm-url="$URL" -f E.lcm -q & RE=$!
chrt -f 10 lcm-logger --lcm-url="$URL&recv_buf_size=2097152" -f F.lcm -q & RF=$!
sleep 0.5
"$B/daemon/exodaqd" --config exodaqd.yaml --duration 7 > exodaqd.log 2>&1 & DP=$!
sleep 1
stress-ng --cpu 2 --timeout 8s --quiet & SP=$!
sleep 2
kill -STOP $DP
sleep 1
kill -CONT $DP
wait $DP
wait $SP
sleep 0.3
kill -INT $RA $RB $RC $RD $RE $RF
wait $RA $RB $RC $RD $RE $RF || true
grep -h "the daemon:" A.err | sed 's/.*the daemon: /daemon: /'
for f in A B C D E F; do
  echo "$f: $($X export $f.lcm -q -o - 2> /dev/null | tail -n +2 | wc -l) cycles"
done
for f in A B C D; do grep -h "peak\|INCOMPLETE" $f.err | sed "s/^/$f: /"; done
