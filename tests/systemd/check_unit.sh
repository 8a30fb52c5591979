#!/usr/bin/env bash
# The unit's figures (issue 9 point 2), on the unit as installed:
#   systemd-analyze verify      prints nothing and exits 0
#   systemd-analyze security --offline=true   overall exposure <= 2.0
# The project is installed into a fresh staging prefix (cmake --install
# --prefix STAGE); the install rules point the staged unit's ExecStart= at
# STAGE/bin/exodaqd and STAGE/etc/exodaq, so verify checks real binaries
# without a --root holding a whole system (which Debian 12's systemd 252 needs
# for sysinit.target and /bin/kill). No running systemd is needed.
# Usage: check_unit.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$(cd "$1" && pwd)
src=$(cd "$2" && pwd)
fail() { echo "FAIL: $*" >&2; exit 1; }

stage=$(mktemp -d "${TMPDIR:-/tmp}/exodaq-unit.XXXXXX")
trap 'rm -rf "$stage"' EXIT
cmake --install "$build" --prefix "$stage" >"$stage.install.log" 2>&1 ||
  { cat "$stage.install.log" >&2; fail "cmake --install into $stage"; }
rm -f "$stage.install.log"
unit=$stage/lib/systemd/system/exodaqd.service
[ -f "$unit" ] || fail "no unit at $unit"
[ -x "$stage/bin/exodaqd" ] || fail "no exodaqd at $stage/bin"
[ -f "$stage/lib/sysusers.d/exodaq.conf" ] || fail "no sysusers file"
# The slice that makes the unit's MemoryMin= effective, installed as written.
cmp -s "$stage/lib/systemd/system/exodaq.slice" "$src/systemd/exodaq.slice" ||
  fail "exodaq.slice not installed as systemd/exodaq.slice"
grep -q '^MemoryMin=' "$stage/lib/systemd/system/exodaq.slice" || fail "exodaq.slice has no MemoryMin="
[ -f "$stage/etc/exodaq/exodaqd.yaml" ] || fail "no /etc/exodaq/exodaqd.yaml"

# The staged unit is the source unit with the install paths moved, nothing else.
expected=$(sed -e "s#/usr/bin/exodaqd#$stage/bin/exodaqd#g" -e "s#/etc/exodaq/#$stage/etc/exodaq/#g" \
  "$src/systemd/exodaqd.service")
[ "$expected" = "$(cat "$unit")" ] || fail "installed unit differs from systemd/exodaqd.service beyond its paths"
grep -q "^ExecStart=$stage/bin/exodaqd --config $stage/etc/exodaq/exodaqd.yaml\$" "$unit" ||
  fail "ExecStart not moved to the stage"

# The unit's configuration passes the daemon's own check (ExecStartPre).
"$stage/bin/exodaqd" --check-config --config "$stage/etc/exodaq/exodaqd.yaml" >/dev/null ||
  fail "exodaqd --check-config on the installed config"

# 1. verify: exit 0 and not a single line of output (warnings such as
#    "Unknown key" do not change the exit status, so the output is checked).
cd "$stage"
out=$(systemd-analyze verify "$unit" 2>&1) && rc=0 || rc=$?
echo "systemd-analyze verify: exit $rc, output: '${out}'"
[ "$rc" -eq 0 ] || fail "verify exit $rc"
[ -z "$out" ] || fail "verify printed: $out"

# verify does look at the binaries: the same unit with a missing ExecStart fails.
sed "s#$stage/bin/exodaqd#$stage/bin/missing-exodaqd#g" "$unit" >"$stage/broken.service"
if systemd-analyze verify "$stage/broken.service" >/dev/null 2>&1; then
  fail "verify accepted a unit whose binary is missing: the check above proves nothing"
fi

# 2. security: the exposure figure, and --threshold=20 (exposure x 10) as the gate.
sec=$(systemd-analyze security --offline=true "$unit" 2>&1) || true
score=$(printf '%s\n' "$sec" | sed -n 's/.*Overall exposure level for exodaqd.service: \([0-9.]*\).*/\1/p')
echo "systemd-analyze security --offline=true: exposure $score"
[ -n "$score" ] || { printf '%s\n' "$sec" >&2; fail "no exposure figure"; }
systemd-analyze security --offline=true --threshold=20 "$unit" >/dev/null 2>&1 ||
  { printf '%s\n' "$sec" | grep '✗' >&2; fail "exposure $score > 2.0"; }
awk -v s="$score" 'BEGIN { exit !(s <= 2.0) }' || fail "exposure $score > 2.0"

# 3. What the issue asks of the unit, and what it must not contain.
for key in "Type=notify" "WatchdogSec=" "Restart=on-failure" "User=exodaq" "LimitRTPRIO=" \
  "LimitMEMLOCK=" "ProtectSystem=strict" "NoNewPrivileges=yes" "PrivateTmp=yes" \
  "PrivateDevices=yes" "ProtectHome=yes" "ProtectKernelTunables=yes" "ProtectKernelModules=yes" \
  "ProtectKernelLogs=yes" "CapabilityBoundingSet=\$" \
  "RestrictAddressFamilies=AF_UNIX AF_INET AF_INET6 AF_CAN AF_NETLINK\$" \
  "SystemCallFilter=@system-service adjtimex" "ExecStartPre=.*--check-config" \
  "After=.*time-sync.target" "Wants=sys-subsystem-net-devices-can0.device" \
  "OOMScoreAdjust=-900\$" "Slice=exodaq.slice\$" "MemoryMin="; do
  grep -q "^$key" "$unit" || fail "unit lacks $key"
done
# IPAddressDeny=/IPAddressAllow= filter received packets by source address:
# "localhost multicast" made the foreign-run listener deaf (issue 25.8).
for key in ProtectClock RestrictRealtime CPUSchedulingPolicy "Requires=.*time-sync" IPAddressDeny \
  IPAddressAllow; do
  if grep -q "^$key" "$unit"; then fail "unit must not set $key"; fi
done
# The seccomp filter keeps the syscalls the daemon needs (glibc 2.36's
# ntp_adjtime is clock_adjtime; SCHED_FIFO and pinning of the loop thread).
for sc in clock_adjtime sched_setscheduler sched_setaffinity; do
  grep -q "^SystemCallFilter=.*\b$sc\b" "$unit" || fail "SystemCallFilter drops $sc"
done

# 3b. The per-rig template exodaqd@.service (docs/operations.md "Several rigs"):
#     the same unit but for its config, /etc/exodaq/%i.yaml, and description;
#     an instance verifies clean and has the same exposure; a rig's config
#     passes the instance's ExecStartPre check.
tpl=$stage/lib/systemd/system/exodaqd@.service
[ -f "$tpl" ] || fail "no template unit at $tpl"
body() { sed -n '/^\[Unit\]/,$p' "$1"; }
expected_tpl=$(sed -e "s#/etc/exodaq/exodaqd.yaml#/etc/exodaq/%i.yaml#g" \
  -e "s#^Description=exodaq encoder acquisition service (#Description=exodaq encoder acquisition service, rig %i (#" \
  "$src/systemd/exodaqd.service" | body /dev/stdin |
  sed -e "s#/usr/bin/exodaqd#$stage/bin/exodaqd#g" -e "s#/etc/exodaq/#$stage/etc/exodaq/#g")
[ "$expected_tpl" = "$(body "$tpl")" ] ||
  fail "template differs from systemd/exodaqd.service beyond its config, description and paths"
grep -q "^ExecStart=$stage/bin/exodaqd --config $stage/etc/exodaq/%i.yaml\$" "$tpl" ||
  fail "template's ExecStart does not read /etc/exodaq/%i.yaml"
grep -q "^Description=.*rig %i" "$tpl" || fail "template's description does not name the rig"
cp "$tpl" "$stage/lib/systemd/system/exodaqd@rig-b.service"
for u in "$tpl" "$stage/lib/systemd/system/exodaqd@rig-b.service"; do
  out=$(systemd-analyze verify "$u" 2>&1) && rc=0 || rc=$?
  echo "systemd-analyze verify $(basename "$u"): exit $rc, output: '${out}'"
  [ "$rc" -eq 0 ] && [ -z "$out" ] || fail "verify $(basename "$u"): exit $rc: $out"
done
sed "s#$stage/bin/exodaqd#$stage/bin/missing-exodaqd#g" "$tpl" >"$stage/broken@.service"
if systemd-analyze verify "$stage/broken@.service" >/dev/null 2>&1; then
  fail "verify accepted a template whose binary is missing"
fi
rm -f "$stage/broken@.service"
sec_b=$(systemd-analyze security --offline=true "$stage/lib/systemd/system/exodaqd@rig-b.service" 2>&1) || true
score_b=$(printf '%s\n' "$sec_b" | sed -n 's/.*Overall exposure level for exodaqd@rig-b.service: \([0-9.]*\).*/\1/p')
echo "systemd-analyze security --offline=true exodaqd@rig-b.service: exposure $score_b"
[ "$score_b" = "$score" ] || fail "instance exposure '$score_b' differs from the unit's $score"
# rig-b's config: the simulated rig under its own name and prefix; the
# instance's ExecStartPre, %i expanded, accepts it.
sed -e "s#model: models/#model: $src/config/models/#" \
  -e "s#calibration: calibration/#calibration: $src/config/calibration/#" \
  -e "s#task: tasks/#task: $src/config/tasks/#" -e 's/^rig: .*/rig: rig-b/' \
  -e 's/prefix: ""/prefix: "RIGB_"/' "$src/config/sim.yaml" >"$stage/etc/exodaq/rig-b.yaml"
pre=$(sed -n 's/^ExecStartPre=//p' "$tpl" | sed 's/%i/rig-b/g')
# shellcheck disable=SC2086  # the unit's command line, split as systemd splits it
check_out=$($pre) || fail "the instance's ExecStartPre on rig-b.yaml: $check_out"
printf '%s\n' "$check_out" | grep -q "rig rig-b" || fail "check-config does not name rig-b: $check_out"

# 4. The daemon's own system calls pass the unit's filter (a missing one would
#    kill it with SIGSYS or fail with EPERM under systemd): the simulated rig
#    with SCHED_FIFO and locked memory, traced for 2 s. Needs strace.
if command -v strace >/dev/null 2>&1; then
  expand() {
    systemd-analyze syscall-filter "$1" 2>/dev/null | grep -v '^#' | awk 'NR > 1 && NF == 1 { print $1 }' |
      while read -r x; do case $x in @*) expand "$x" ;; *) echo "$x" ;; esac; done
  }
  : >"$stage/allowed"
  while read -r line; do
    items=${line#SystemCallFilter=}
    op=add
    case $items in "~"*) op=remove; items=${items#\~} ;; esac
    for it in $items; do
      case $it in @*) expand "$it" ;; *) echo "$it" ;; esac
    done | sort -u >"$stage/items"
    if [ "$op" = add ]; then
      sort -u "$stage/allowed" "$stage/items" -o "$stage/allowed"
    else
      comm -23 "$stage/allowed" "$stage/items" >"$stage/allowed.new" && mv "$stage/allowed.new" "$stage/allowed"
    fi
  done < <(grep '^SystemCallFilter=' "$unit")
  sed -e "s#model: models/#model: $src/config/models/#" \
    -e "s#calibration: calibration/#calibration: $src/config/calibration/#" \
    -e "s#task: tasks/#task: $src/config/tasks/#" \
    -e 's/priority: 0 /priority: 50 /' -e 's/lock_memory: false/lock_memory: true/' \
    -e "s/prefix: \"\"/prefix: \"T$$_strace_\"/" "$src/config/sim.yaml" >"$stage/strace.yaml"
  strace -f -qq -o "$stage/strace.out" "$stage/bin/exodaqd" --config "$stage/strace.yaml" \
    --duration 2 >/dev/null 2>&1 || fail "exodaqd under strace"
  sed -n 's/^[0-9]* *\([a-z_0-9]*\)(.*/\1/p' "$stage/strace.out" | sort -u >"$stage/used"
  [ "$(wc -l <"$stage/used")" -gt 20 ] || fail "strace saw too few system calls"
  missing=$(comm -23 "$stage/used" "$stage/allowed" | tr '\n' ' ')
  echo "system calls used: $(wc -l <"$stage/used"), outside the unit's filter: '${missing}'"
  [ -z "$missing" ] || fail "exodaqd uses system calls the unit's SystemCallFilter= refuses: $missing"
else
  echo "strace missing: the system-call check is skipped"
fi
echo "OK: verify clean, exposure $score"
