#!/usr/bin/env python3
"""scripts/run, the README's first command (issue 16 point 8), as a user runs
it: piped with --duration it prints only CSV on stdout and exits 0; Ctrl-C
(SIGINT to its process group, as a terminal sends it) exits 0; both print
where the daemon's log is; setup and build print nothing unless they fail.

  test_scripts_run.py --source DIR --build DIR
"""
import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "support"))
from sim_config import write_sim_config  # noqa: E402


def fail(msg):
    print("FAIL: " + msg, file=sys.stderr)
    sys.exit(1)


def check_log_line(err):
    lines = [l for l in err.splitlines() if l.startswith("scripts/run: daemon log: ")]
    if len(lines) != 1:
        fail("'daemon log:' printed %d times:\n%s" % (len(lines), err))
    path = lines[0].split(": ", 2)[2]
    if not os.path.isfile(path) or "started" not in open(path).read():
        fail("the daemon log %s does not hold the daemon's start" % path)
    for noise in ("ninja", "[1/", "Re-checking", "setup: all"):
        if noise in err:
            fail("setup/build output shown although they succeeded (%r):\n%s" % (noise, err))
    return path


def main(argv):
    ap = argparse.ArgumentParser()
    ap.add_argument("--source", required=True)
    ap.add_argument("--build", required=True)
    a = ap.parse_args(argv)
    a.source, a.build = os.path.abspath(a.source), os.path.abspath(a.build)
    work = tempfile.mkdtemp(prefix="exodaq-scripts-run-")
    env = dict(os.environ, EXODAQ_BUILD_DIR=a.build, EXODAQ_CONFIG=write_sim_config(a.source, work, "RUNTEST%d_" % os.getpid()),
               EXODAQ_VIEW_PORT="0")
    run = os.path.join(a.source, "scripts", "run")

    # 1. Piped, --duration: exit 0, only CSV on stdout.
    r = subprocess.run([run, "--duration", "3"], capture_output=True, text=True, env=env,
                       timeout=240)
    if r.returncode != 0:
        fail("scripts/run --duration 3 exited %d:\n%s" % (r.returncode, r.stderr))
    # The header and rows (how many is the machine's speed: echo starts half
    # a second after the daemon and both stop at --duration).
    lines = r.stdout.splitlines()
    if len(lines) < 2 or not lines[0].startswith("utime_us,mono_ns,seq,run_id,palm_x_m,"):
        fail("stdout is not the palm pose CSV (%d lines): %s" % (len(lines), lines[:3]))
    width = lines[0].count(",")
    bad = [l for l in lines if l.count(",") != width]
    if bad:
        fail("stdout holds lines that are not CSV rows: %s" % bad[:3])
    log = check_log_line(r.stderr)
    print("--duration 3, piped: exit 0, %d CSV lines only, log %s" % (len(lines), log))

    # 2. Ctrl-C: SIGINT to the whole process group.
    p = subprocess.Popen([run], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                         start_new_session=True)
    t0 = time.monotonic()
    err = ""
    while "exodaqd running" not in err:
        if p.poll() is not None or time.monotonic() - t0 > 180:
            p.kill()
            fail("scripts/run did not start the daemon:\n" + err + (p.stderr.read() or ""))
        line = p.stderr.readline()
        err += line
    time.sleep(2)
    os.killpg(p.pid, signal.SIGINT)
    try:
        out, rest = p.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        fail("scripts/run did not stop on Ctrl-C")
    err += rest
    if p.returncode != 0:
        fail("scripts/run exited %d after Ctrl-C:\n%s" % (p.returncode, err))
    check_log_line(err)
    print("Ctrl-C: exit 0, %d CSV lines, the log's place printed" % len(out.splitlines()))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
