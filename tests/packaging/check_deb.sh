#!/usr/bin/env bash
# The .deb (issue 9 point 4): built by CPack from this build, installed into a
# fresh root with `dpkg --root=R --force-script-chrootless` (the maintainer
# scripts run on the host's shell with DPKG_ROOT=R and act on R only: the
# exodaq user is created in R/etc/passwd by systemd-sysusers --root), then the
# installed binaries run from R. --force-depends because R holds no other
# packages; that the dependencies resolve is checked against this host with
# `apt-get install --simulate`. Without root, dpkg --root cannot set owners:
# the package is then unpacked with `dpkg-deb -x` and the scripts are skipped.
# Usage: check_deb.sh BUILD_DIR SOURCE_DIR
set -euo pipefail
build=$1
src=$2
fail() { echo "FAIL: $*" >&2; exit 1; }

work=$(mktemp -d "${TMPDIR:-/tmp}/exodaq-deb.XXXXXX")
trap 'rm -rf "$work"' EXIT

# 1. Build the package.
cpack -G DEB --config "$build/CPackConfig.cmake" -B "$work/out" >"$work/cpack.log" 2>&1 ||
  { cat "$work/cpack.log" >&2; fail "cpack"; }
deb=$(ls "$work"/out/exodaq_*.deb)
echo "built $(basename "$deb") ($(stat -c %s "$deb") bytes)"

# 2. Control data: dependencies declared (dpkg-shlibdeps), conffiles, scripts.
depends=$(dpkg-deb -f "$deb" Depends)
echo "Depends: $depends"
names=$(sed -e 's/([^)]*)//g' -e 's/[,|]/\n/g' <<<"$depends" | tr -d ' ')
for p in liblcm1 libyaml-cpp0.7 libsystemd0 libfmt9 libstdc++6 libc6 systemd; do
  grep -qxF "$p" <<<"$names" || fail "Depends lacks $p"
done
grep -q "^libspdlog1\.10" <<<"$names" || fail "Depends lacks libspdlog1.10"
dpkg-deb --ctrl-tarfile "$deb" | tar -x -C "$work" ./conffiles ./postinst ./prerm
for f in /etc/exodaq/exodaqd.yaml /etc/exodaq/models/macaque_exo.yaml \
  /etc/exodaq/calibration/nominal.yaml; do
  grep -qx "$f" "$work/conffiles" || fail "$f is not a conffile"
done
grep -q systemd-sysusers "$work/postinst" || fail "postinst does not create the user"
# The Python package's byte code is compiled on install and removed on removal.
grep -q "py3compile -p exodaq" "$work/postinst" || fail "postinst does not py3compile"
grep -q "py3clean -p exodaq" "$work/prerm" || fail "prerm does not py3clean"
# Every dependency resolves on this Debian host (nothing is installed).
apt-get install --simulate "$deb" >"$work/apt.log" 2>&1 ||
  { cat "$work/apt.log" >&2; fail "apt-get cannot satisfy the package's dependencies"; }
grep -q "^Inst exodaq " "$work/apt.log" || { cat "$work/apt.log" >&2; fail "apt-get simulate"; }

# 3. The layout.
dpkg-deb -c "$deb" | awk '{print $6}' >"$work/files"
for f in ./usr/bin/exodaqd ./usr/bin/exodaq ./etc/exodaq/exodaqd.yaml \
  ./etc/exodaq/models/macaque_exo.yaml ./etc/exodaq/calibration/nominal.yaml \
  ./lib/systemd/system/exodaqd.service ./usr/lib/sysusers.d/exodaq.conf \
  ./usr/share/exodaq/lcmtypes/exodaq/joint_state_t.lcm ./usr/share/doc/exodaq/operations.md \
  ./usr/share/doc/exodaq/examples/80-can0.network; do
  grep -qx "$f" "$work/files" || fail "package lacks $f"
done
# The Python package (tools/python) in Debian python3's dist-packages, sources only.
py=./usr/lib/python3/dist-packages
for f in $py/exodaq/__init__.py $py/exodaq/client.py $py/exodaq/udpm.py $py/exodaq/names.py \
  $py/exodaq/joint_state_t.py $py/exodaq/palm_pose_t.py $py/exodaq/encoder_raw_t.py \
  $py/exodaq/status_t.py $py/exodaq/homing_t.py $py/exodaq/_version.py $py/exodaq_lcm.py; do
  grep -qx "$f" "$work/files" || fail "package lacks $f"
done
grep -qx "$py/exodaq-[0-9.]*\.egg-info/PKG-INFO" "$work/files" || fail "package lacks the egg-info"
! grep -q '\.pyc$' "$work/files" || fail "package ships byte code"
! grep -q '^./usr/share/exodaq/lcmtypes/python' "$work/files" ||
  fail "package still ships the Python types under /usr/share/exodaq/lcmtypes/python"
if [ -x "$build/tools/board-sim/exodaq-board-sim" ]; then
  grep -qx ./usr/bin/exodaq-board-sim "$work/files" || fail "package lacks exodaq-board-sim"
fi

# 4. Install into a fresh root.
root=$work/root
mkdir -p "$root/var/lib/dpkg/info" "$root/var/lib/dpkg/updates" "$root/var/lib/dpkg/triggers" \
  "$root/var/log"
touch "$root/var/lib/dpkg/status" "$root/var/lib/dpkg/available"
dpkg_root() {
  dpkg --root="$root" --log="$root/var/log/dpkg.log" --force-script-chrootless --force-depends \
    --force-confold "$@"
}
if [ "$(id -u)" -eq 0 ]; then
  echo "installing with dpkg --root=$root"
  dpkg_root -i "$deb" >"$work/dpkg.log" 2>&1 || { cat "$work/dpkg.log" >&2; fail "dpkg -i"; }
  [ "$(dpkg --root="$root" -s exodaq | sed -n 's/^Status: //p')" = "install ok installed" ] ||
    fail "package not configured in $root"
  # postinst ran systemd-sysusers on the root, not on the host.
  grep -q '^exodaq:x:[0-9]*:[0-9]*:.*:/usr/sbin/nologin$' "$root/etc/passwd" ||
    fail "postinst did not create the exodaq user in $root"
else
  echo "not root: unpacking with dpkg-deb -x (maintainer scripts not run)"
  dpkg-deb -x "$deb" "$root"
fi

# 5. The installed daemon, from the root.
"$root/usr/bin/exodaqd" --version | grep -q "^exodaqd " || fail "exodaqd --version"
"$root/usr/bin/exodaqd" --version
"$root/usr/bin/exodaqd" --check-config --config "$root/etc/exodaq/exodaqd.yaml" ||
  fail "installed exodaqd --check-config on the installed /etc/exodaq/exodaqd.yaml"
"$root/usr/bin/exodaqd" --check-config --config "$root/etc/exodaq/sim.yaml" >/dev/null ||
  fail "installed sim.yaml"
"$root/usr/bin/exodaq" --help >/dev/null || fail "exodaq --help"
# The binaries are stripped (the package is small) and find their libraries.
file "$root/usr/bin/exodaqd" | grep -q "stripped" && ! file "$root/usr/bin/exodaqd" | grep -q "not stripped" ||
  fail "exodaqd not stripped"

# 5b. The installed Python package, from an unrelated directory with only the
#     root's dist-packages on PYTHONPATH: the subscriber of docs/messages.md
#     against the installed exodaqd (tests/python/run_docs_subscriber.py).
(cd "$work" && PYTHONPATH="$root/usr/lib/python3/dist-packages" PYTHONDONTWRITEBYTECODE=1 \
  /usr/bin/python3 -c 'import exodaq, sys; sys.exit(exodaq.joint_flag_names(66) != "STALE|HELD")') ||
  fail "import exodaq from the installed root"
/usr/bin/python3 "$src/tests/python/run_docs_subscriber.py" --source-dir "$src" \
  --exodaqd "$root/usr/bin/exodaqd" --exodaq "$root/usr/bin/exodaq" --python /usr/bin/python3 \
  --site "$root/usr/lib/python3/dist-packages" || fail "the docs' Python subscriber on the installed package"

# 6. The packaged unit: identical to systemd/exodaqd.service, and it verifies
#    when its paths point into the root (see tests/systemd/check_unit.sh).
cmp -s "$root/lib/systemd/system/exodaqd.service" "$src/systemd/exodaqd.service" ||
  fail "packaged unit differs from systemd/exodaqd.service"
sed -e "s#/usr/bin/exodaqd#$root/usr/bin/exodaqd#g" -e "s#/etc/exodaq/#$root/etc/exodaq/#g" \
  "$root/lib/systemd/system/exodaqd.service" >"$work/exodaqd.service"
out=$(cd "$work" && systemd-analyze verify "$work/exodaqd.service" 2>&1) ||
  fail "verify of the packaged unit: $out"
[ -z "$out" ] || fail "verify of the packaged unit printed: $out"

if [ "$(id -u)" -eq 0 ]; then
  # 7. Upgrade (reinstall) keeps a locally edited config; remove keeps the
  #    conffiles, purge removes them.
  echo "# local edit" >>"$root/etc/exodaq/exodaqd.yaml"
  dpkg_root -i "$deb" >"$work/dpkg2.log" 2>&1 || { cat "$work/dpkg2.log" >&2; fail "reinstall"; }
  tail -n1 "$root/etc/exodaq/exodaqd.yaml" | grep -qx "# local edit" ||
    fail "reinstall overwrote the edited /etc/exodaq/exodaqd.yaml"
  dpkg_root -r exodaq >"$work/dpkg3.log" 2>&1 || { cat "$work/dpkg3.log" >&2; fail "remove"; }
  [ ! -e "$root/usr/bin/exodaqd" ] || fail "remove left /usr/bin/exodaqd"
  [ ! -e "$root/usr/lib/python3/dist-packages/exodaq" ] || fail "remove left the Python package"
  [ -f "$root/etc/exodaq/exodaqd.yaml" ] || fail "remove deleted the config"
  dpkg_root -P exodaq >"$work/dpkg4.log" 2>&1 || { cat "$work/dpkg4.log" >&2; fail "purge"; }
  [ ! -e "$root/etc/exodaq/exodaqd.yaml" ] || fail "purge left the config"
fi
echo "OK"
