#!/bin/sh
# The installed unit under systemd as PID 1 (issue 25.8), run by
# exodaq-vmtest.service inside the VM that tests/vm/systemd/run-systemd-vm
# boots. Every wait is bounded and judged by what happened, never by how long
# it took (the VM may be emulated on a loaded host).
#   0. network: veth0 (10.77.0.1) here, veth1 (10.77.0.2) in netns "foreign"
#      (another host); multicast routed through veth0, as through a NIC
#   1. start: active after READY=1, as user exodaq, in exodaq.slice with its
#      memory protection, oom_score_adj -900, its lock in /run/exodaq
#   2. systemctl reload: SIGHUP applied, same process
#   3. exodaqd@rig-b on the same channels (URL without ?ttl=0): refused
#   4. a foreign status from 10.77.0.2: heard, FOREIGN_RUN, then cleared
#   5. watchdog: the daemon stopped (SIGSTOP) is killed and restarted
#   6. systemctl stop: a clean stop
# Prints VM-STEP / VM-FAIL lines and, last, VM-RESULT: rc=N; then powers off.
export PATH=/usr/bin:/usr/sbin:/exodaq/bin
RC=0
fail() {
  echo "VM-FAIL: $*"
  RC=1
}
step() { echo "VM-STEP: $* (uptime $(cut -d' ' -f1 /proc/uptime)s)"; }
# wait_for SECONDS COMMAND...: until COMMAND succeeds; 1 if it never did.
wait_for() {
  end=$(($(cut -d. -f1 /proc/uptime) + $1))
  shift
  while ! "$@" >/dev/null 2>&1; do
    [ "$(cut -d. -f1 /proc/uptime)" -ge "$end" ] && return 1
    sleep 0.2
  done
}
prop() { systemctl --no-pager show -p "$2" --value "$1"; }
journal_has() { journalctl --no-pager -q -o cat -u "$1" | grep -qF -- "$2"; }
status_json() { exodaq status -c /etc/exodaq/exodaqd.yaml --json -t 30; }
json_field() { sed -n "s/^  \"$1\": \"*\([^\",]*\)\"*,*$/\1/p"; }
finish() {
  for u in exodaqd exodaqd@rig-b; do
    echo "--- journal of $u (last 40 lines) ---"
    journalctl --no-pager -q -o short-monotonic -u "$u" | tail -40
  done
  echo "VM-RESULT: rc=$RC uptime=$(cut -d' ' -f1 /proc/uptime)s"
  sync
  poweroff -f
}
# iproute2's ip by its path: busybox's shell runs its own applets first.
IP=/usr/bin/ip
RATE=$(sed -n 's/.*exodaq\.rate=\([0-9]*\).*/\1/p' /proc/cmdline)

step "0 network"
$IP link add veth0 type veth peer name veth1 || fail "veth pair"
$IP netns add foreign || fail "netns"
$IP link set veth1 netns foreign
$IP addr add 10.77.0.1/24 dev veth0
$IP link set veth0 up
$IP route add 224.0.0.0/4 dev veth0
$IP -n foreign link set lo up
$IP -n foreign addr add 10.77.0.2/24 dev veth1
$IP -n foreign link set veth1 up
$IP -n foreign route add 224.0.0.0/4 dev veth1
[ "$RC" -eq 0 ] || finish

# The simulated rig as the unit's config (installed sim.yaml), memory locked
# as on the rig; the rate the host chose for this VM.
sed -e "s/rate_hz: 1000 /rate_hz: $RATE /" -e 's/lock_memory: false/lock_memory: true/' \
  /etc/exodaq/sim.yaml >/etc/exodaq/exodaqd.yaml
grep -q "rate_hz: $RATE " /etc/exodaq/exodaqd.yaml || fail "rate not set in the config"
# No udev here: can0's device unit never appears, so it is masked (the unit
# only Wants= it) instead of waiting for systemd's 90 s device timeout.
ln -s /dev/null /etc/systemd/system/sys-subsystem-net-devices-can0.device
# Emulated on a loaded host, the whole guest can stall for seconds: with the
# unit's 2 s the watchdog could restart the daemon in the middle of a stage.
# 15 s keeps it for the deliberate stall of stage 5 alone (a drop-in, as an
# administrator would add one; the rest of the unit is as installed).
mkdir -p /etc/systemd/system/exodaqd.service.d
printf '[Service]\nWatchdogSec=15s\n' >/etc/systemd/system/exodaqd.service.d/vm.conf
systemctl daemon-reload

step "1 start"
systemctl start exodaqd || fail "systemctl start exodaqd: exit $?"
PID=$(prop exodaqd MainPID)
[ "$(prop exodaqd ActiveState)" = active ] || fail "exodaqd not active: $(prop exodaqd ActiveState)"
[ "$(stat -c %U /proc/"$PID")" = exodaq ] || fail "runs as $(stat -c %U /proc/"$PID"), not exodaq"
[ "$(cat /proc/"$PID"/oom_score_adj)" = -900 ] || fail "oom_score_adj $(cat /proc/"$PID"/oom_score_adj)"
CG=$(sed -n 's/^0:://p' /proc/"$PID"/cgroup)
[ "$CG" = /exodaq.slice/exodaqd.service ] || fail "cgroup $CG"
[ "$(cat /sys/fs/cgroup/exodaq.slice/memory.min)" = 536870912 ] ||
  fail "exodaq.slice memory.min $(cat /sys/fs/cgroup/exodaq.slice/memory.min)"
[ "$(cat /sys/fs/cgroup"$CG"/memory.min)" = 134217728 ] || fail "memory.min $(cat /sys/fs/cgroup"$CG"/memory.min)"
echo "exodaqd pid $PID: memory.current $(cat /sys/fs/cgroup"$CG"/memory.current) bytes, VmRSS $(sed -n 's/VmRSS:[ \t]*//p' /proc/"$PID"/status)"
LOCKS=$(ls /run/exodaq/exodaqd-*.lock 2>/dev/null)
[ "$(stat -c %U "$LOCKS" 2>/dev/null)" = exodaq ] || fail "lock file(s) '$LOCKS' not exodaq's"
grep -q "^pid=$PID\$" "$LOCKS" 2>/dev/null || fail "the lock does not name pid $PID"
S=$(status_json) || fail "no status heard from the daemon"
RUN=$(echo "$S" | json_field run_id)
echo "status: state $(echo "$S" | json_field state), run id $RUN"

[ "$RC" -eq 0 ] || finish  # the steps build on each other
step "2 reload"
RELOADS=$(echo "$S" | json_field reloads)
systemctl reload exodaqd || fail "systemctl reload: exit $?"
wait_for 120 journal_has exodaqd "new configuration in effect" || fail "no reload applied in the journal"
[ "$(prop exodaqd MainPID)" = "$PID" ] || fail "reload changed the process: $(prop exodaqd MainPID)"
after_reload() { [ "$(status_json | json_field reloads)" = $((RELOADS + 1)) ]; }
wait_for 120 after_reload || fail "status_t.reloads not $((RELOADS + 1))"

[ "$RC" -eq 0 ] || finish  # the steps build on each other
step "3 second unit on the same channels"
sed -e 's#url: "udpm://239.255.76.67:7667?ttl=0"#url: "udpm://239.255.76.67:7667"#' \
  -e 's/^rig: .*/rig: rig-b/' /etc/exodaq/exodaqd.yaml >/etc/exodaq/rig-b.yaml
grep -q 'url: "udpm://239.255.76.67:7667"' /etc/exodaq/rig-b.yaml || fail "rig-b's URL not set"
if systemctl start exodaqd@rig-b; then fail "exodaqd@rig-b started beside exodaqd"; fi
[ "$(prop exodaqd@rig-b Result)" = exit-code ] || fail "exodaqd@rig-b: result $(prop exodaqd@rig-b Result)"
# Found by the daemon's own EXODAQ_RIG field: it logs the refusal natively and
# exits at once, and journald then cannot always tell which unit it came from.
REFUSAL=$(journalctl --no-pager -q -o cat EXODAQ_RIG=rig-b | grep -F "cannot start: another exodaqd already publishes on LCM udpm://239.255.76.67:7667 with prefix ''")
echo "$REFUSAL" | grep -qF ": pid $PID, run id $RUN" || fail "no refusal naming pid $PID and run $RUN: '$REFUSAL'"
echo "$REFUSAL" | grep -qF "(lock $LOCKS)" || fail "the refusal does not name $LOCKS: '$REFUSAL'"
systemctl stop exodaqd@rig-b
[ "$(prop exodaqd MainPID)" = "$PID" ] || fail "exodaqd changed: $(prop exodaqd MainPID)"

[ "$RC" -eq 0 ] || finish  # the steps build on each other
step "4 foreign status from 10.77.0.2"
$IP netns exec foreign exodaq_test_status_publisher 'udpm://239.255.76.67:7667?ttl=1' EXO_STATUS \
  0123456789abcdef 10 600 >/tmp/publisher.out 2>&1 &
PUB=$!
heard() {
  kill -0 "$PUB" || return 0  # the publisher ended: stop waiting
  journal_has exodaqd "another publisher on EXO_STATUS: run id 0123456789abcdef (rig fake-rig)"
}
wait_for 180 heard
if ! kill -0 "$PUB" 2>/dev/null; then
  fail "the foreign publisher ended early: $(cat /tmp/publisher.out)"
elif ! journal_has exodaqd "another publisher on EXO_STATUS: run id 0123456789abcdef (rig fake-rig)"; then
  fail "the foreign status from 10.77.0.2 was not heard under the unit"
else
  flagged() { [ "$(status_json | json_field foreign_run_id)" = 0123456789abcdef ]; }
  wait_for 120 flagged || fail "status_t.foreign_run_id never named the foreign run"
fi
kill "$PUB" 2>/dev/null
wait "$PUB"
echo "foreign publisher: $(cat /tmp/publisher.out) statuses sent from 10.77.0.2"
[ "$RC" -eq 0 ] || finish
wait_for 180 journal_has exodaqd "run id 0123456789abcdef no longer heard" || fail "FOREIGN_RUN never cleared"

[ "$RC" -eq 0 ] || finish  # the steps build on each other
step "5 watchdog"
[ "$(prop exodaqd NRestarts)" = 0 ] || fail "restarted $(prop exodaqd NRestarts) times before the watchdog stage"
kill -STOP "$PID"
restarted() { [ "$(prop exodaqd NRestarts)" = 1 ] && [ "$(prop exodaqd ActiveState)" = active ]; }
wait_for 180 restarted || fail "not restarted after SIGSTOP: $(prop exodaqd NRestarts) restarts, $(prop exodaqd ActiveState)"
journal_has exodaqd "Watchdog timeout" || fail "no watchdog timeout in the journal"
NEW=$(prop exodaqd MainPID)
[ "$NEW" != "$PID" ] || fail "same pid after the restart"
new_run() { R=$(status_json | json_field run_id) && [ -n "$R" ] && [ "$R" != "$RUN" ]; }
wait_for 120 new_run || fail "no status of a new run after the restart"

[ "$RC" -eq 0 ] || finish  # the steps build on each other
step "6 stop"
systemctl stop exodaqd || fail "systemctl stop: exit $?"
[ "$(prop exodaqd ActiveState)" = inactive ] || fail "after stop: $(prop exodaqd ActiveState)"
[ "$(prop exodaqd Result)" = success ] || fail "stop result $(prop exodaqd Result)"

finish
