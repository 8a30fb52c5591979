#!/usr/bin/env python3
"""The complete subscriber of docs/messages.md, installed like a decoder
author would, against a live exodaqd on the simulated rig.

  run_docs_subscriber.py --source-dir DIR --exodaqd BIN --exodaq BIN
                         (--wheel WHEEL --python PY | --site DIR --python PY) [--after-homed N]

1. The code block after the marker comment in docs/messages.md is written to
   an empty directory outside the source and build trees, so docs and test
   cannot drift apart.
2. The package is installed: --wheel into a new virtual environment of PY with
   `pip install --no-index WHEEL` (the docs' command); --site: already
   installed in DIR (the .deb unpacked into a root, tests/packaging), used
   through PYTHONPATH=DIR alone. Either way PYTHONPATH holds nothing of the
   source or build tree, and `import exodaq` must resolve into the install.
3. exodaqd runs config/sim.yaml on an LCM port of its own and a private
   channel prefix; the simulated rig homes its six joints one after the
   other, all homed about 10.3 s of the rig's time after start. The
   subscriber runs from that directory from the daemon's start until the
   daemon's status (`exodaq status --json`) says every joint is homed and
   --after-homed more cycles have passed (then Ctrl-C, as its docs say), so
   it sees unhomed and homed joints however fast the machine is, and
   `exodaq echo --csv` records the same joint states and palm poses meanwhile.
4. Asserted: the subscriber received both kinds, decoded nothing wrong, its
   printed angles, palm positions, validity and flag names equal what the C++
   tool decoded for the same seq (names from the .lcm constants), it saw
   joints unhomed (named UNHOMED) and then homed, palm poses invalid and then
   valid, and it named the daemon's state.
"""
import argparse
import ast
import csv
import io
import json
import math
import os
import random
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "support"))
from sim_config import write_sim_config  # noqa: E402

MARKER = "<!-- tests/python/run_docs_subscriber.py runs the next code block -->"
EVERY = 50


def fail(msg):
    print("FAIL: " + msg, file=sys.stderr)
    sys.exit(1)


def check(cond, msg):
    if not cond:
        fail(msg)


def docs_block(path):
    """The ```python block right after MARKER."""
    text = open(path, encoding="utf-8").read()
    check(text.count(MARKER) == 1, "%s: the marker %r must appear once" % (path, MARKER))
    m = re.match(r"\s*```python\n(.*?)\n```", text[text.index(MARKER) + len(MARKER):], re.S)
    check(m, "%s: no ```python block right after the marker" % path)
    return m.group(1) + "\n"


def lcm_bits(path, group):
    """{value: NAME} of the `const int32_t GROUP_NAME = value;` lines of an .lcm file."""
    text = open(path, encoding="utf-8").read()
    found = re.findall(r"const\s+int32_t\s+%s_(\w+)\s*=\s*(\d+)\s*;" % group, text)
    check(found, "%s: no %s_* constants" % (path, group))
    return {int(v): n for n, v in found}


def names_of(flags, bits):
    return set(bits[b] for b in bits if flags & b) or {"-"}


def clean_env(pythonpath=None):
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "EXODAQ_LCMTYPES_PYTHONPATH",
                        "VIRTUAL_ENV")}
    env["PYTHONNOUSERSITE"] = "1"
    env["PYTHONDONTWRITEBYTECODE"] = "1"  # leaves an installed root as dpkg put it
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    return env


def install(args, tmp):
    """(python, env, where the package must come from)."""
    if args.wheel:
        venv = os.path.join(tmp, "venv")
        subprocess.run([args.python, "-m", "venv", venv], check=True, env=clean_env())
        py = os.path.join(venv, "bin", "python")
        r = subprocess.run([os.path.join(venv, "bin", "pip"), "install", "--no-index", "--quiet",
                            "--disable-pip-version-check", "--no-cache-dir", args.wheel],
                           capture_output=True, text=True, env=clean_env())
        check(r.returncode == 0, "pip install --no-index %s:\n%s%s" % (args.wheel, r.stdout, r.stderr))
        return py, clean_env(), venv
    return args.python, clean_env(args.site), args.site


JOINTS = []  # the joint column stems of echo's CSV (docs/messages.md "CSV")


def echo_rows(text, what):
    reader = csv.DictReader(io.StringIO(text))
    rows = list(reader)
    check(rows, "exodaq echo recorded no %s" % what)
    if what == "joint_state":
        JOINTS[:] = [n[:-len("_rad")] for n in reader.fieldnames
                     if n.endswith("_rad") and not n.endswith("_vel_rad_s")]
        check(len(JOINTS) == 6, "echo's joint_state header %s" % reader.fieldnames)
    return {int(r["seq"]): r for r in rows}


def parse_output(out):
    joints, palms, states, summary = {}, {}, [], None
    for line in out.splitlines():
        m = re.fullmatch(r"joints seq (\d+) deg (\S+(?: \S+){5}) usable ([01]{6}) "
                         r"flags (\S+(?:,\S+){5}) sample (\S+)", line)
        if m:
            joints[int(m.group(1))] = ([float(x) for x in m.group(2).split()], m.group(3),
                                       m.group(4).split(","), m.group(5))
            continue
        m = re.fullmatch(r"palm seq (\d+) valid ([01]) mm (\S+ \S+ \S+) reason (\S+)", line)
        if m:
            palms[int(m.group(1))] = (m.group(2) == "1", [float(x) for x in m.group(3).split()],
                                      m.group(4))
            continue
        m = re.fullmatch(r"status (\S+) (\w+): (.*)", line)
        if m:
            states.append((m.group(1), m.group(2), m.group(3)))
            continue
        m = re.fullmatch(r"received (\{.*\}), lost on the way (\{.*\}), undecodable (\d+)", line)
        if m:
            summary = (ast.literal_eval(m.group(1)), ast.literal_eval(m.group(2)), int(m.group(3)))
            continue
        fail("the subscriber printed an unexpected line: %r" % line)
    return joints, palms, states, summary


def check_joints(joints, echo, bits, sample_bits):
    """Checks every joints line whose seq echo also has; returns those seqs."""
    matched = []
    for seq, (deg, usable, flag_names, sample_names) in joints.items():
        check(seq % EVERY == 0, "joints line for seq %d, not a multiple of %d" % (seq, EVERY))
        row = echo.get(seq)
        if row is None:
            continue
        matched.append(seq)
        for i in range(6):
            j = JOINTS[i]
            rad = float(row[j + "_rad"])
            check(abs(deg[i] - math.degrees(rad)) <= 0.0005 + 1e-9,
                  "seq %d joint %d: %.3f deg printed, C++ decoded %r rad" % (seq, i, deg[i], rad))
            flags = int(row[j + "_flags"])
            want_usable = row[j + "_homed"] == "1" and flags == 0
            check((usable[i] == "1") == want_usable, "seq %d joint %d: usable %s, C++ homed %s flags %d"
                  % (seq, i, usable[i], row[j + "_homed"], flags))
            check(set(flag_names[i].split("|")) == names_of(flags, bits),
                  "seq %d joint %d: flags named %r, C++ flags %d" % (seq, i, flag_names[i], flags))
        sf = int(row["sample_flags"])
        check(set(sample_names.split("|")) == names_of(sf, sample_bits),
              "seq %d: sample flags named %r, C++ %d" % (seq, sample_names, sf))
    return matched


def check_palms(palms, joints, echo, reason_bits):
    matched = 0
    for seq, (valid, mm, reason) in palms.items():
        check(seq % EVERY == 0, "palm line for seq %d" % seq)
        if valid:
            check(reason == "-", "seq %d: valid palm pose with reason %s" % (seq, reason))
            if seq in joints:
                check(joints[seq][1] == "111111", "seq %d: valid palm pose, joints usable %s"
                      % (seq, joints[seq][1]))
        row = echo.get(seq)
        if row is None:
            continue
        matched += 1
        check(valid == (row["palm_valid"] == "1"), "seq %d: valid %s, C++ %s"
              % (seq, valid, row["palm_valid"]))
        for k, axis in enumerate("xyz"):
            m = 1e3 * float(row["palm_%s_m" % axis])
            check(abs(mm[k] - m) <= 0.0005 + 1e-9, "seq %d palm %d: %.3f mm printed, C++ %r mm"
                  % (seq, k, mm[k], m))
        r = int(row["palm_invalid_reason"])
        check(set(reason.split("|")) == names_of(r, reason_bits),
              "seq %d: reason named %r, C++ %d" % (seq, reason, r))
    return matched


def run(args, tmp):
    work = os.path.join(tmp, "decoder")  # outside the source and build trees
    os.makedirs(work)
    script = os.path.join(work, "exodaq_subscriber.py")
    with open(script, "w") as f:
        f.write(docs_block(os.path.join(args.source_dir, "docs", "messages.md")))
    py, env, home = install(args, tmp)
    check_import(py, env, home, work)
    prefix = "TPY_%d_%06d_" % (os.getpid(), random.randrange(10 ** 6))
    url = "udpm://239.255.76.67:%d?ttl=0" % (20000 + (os.getpid() * 13 + random.randrange(89)) % 20000)
    config = write_sim_config(args.source_dir, tmp, prefix, url=url)
    log = open(os.path.join(tmp, "exodaqd.log"), "w")
    daemon = subprocess.Popen([args.exodaqd, "--config", config], stdout=log, stderr=log)
    procs = [daemon]
    try:
        return run_with_daemon(args, tmp, work, url, prefix, procs, py, env)
    finally:
        for p in procs:
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        log.close()


def check_import(py, env, home, work):
    r = subprocess.run([py, "-c", "import exodaq, exodaq_lcm; print(exodaq.__file__); "
                        "print(exodaq_lcm.__file__); print(exodaq.__version__)"],
                       cwd=work, env=env, capture_output=True, text=True)
    check(r.returncode == 0, "import exodaq from %s failed:\n%s" % (work, r.stderr))
    where = r.stdout.split()
    for path in where[:2]:
        real = os.path.realpath(path)
        check(real.startswith(os.path.realpath(home) + os.sep),
              "exodaq imported from %s, not from the install in %s" % (path, home))
    print("package %s imported from %s" % (where[2], os.path.dirname(where[0])))


def wait_homed(args, url, prefix, after, timeout=300):
    """Until the daemon's status says every joint is homed and `after` more
    cycles (seq) have passed; that status's seq, or None after `timeout` s."""
    end = time.monotonic() + timeout
    homed_at = None
    while time.monotonic() < end:
        r = subprocess.run([args.exodaq, "status", "--json", "--url", url, "--prefix", prefix,
                            "--timeout", "10"], capture_output=True, text=True)
        if r.returncode == 0:
            s = json.loads(r.stdout)
            homed = [v for k, v in s.items() if k.endswith("_homing")]
            if len(homed) == 6 and all(v == "HOMED" for v in homed):  # names, not codes
                homed_at = s["seq"] if homed_at is None else homed_at
                if s["seq"] >= homed_at + after:
                    return s["seq"]
        time.sleep(0.5)
    return None


def run_with_daemon(args, tmp, work, url, prefix, procs, py, env):
    daemon = procs[0]
    check(daemon.poll() is None, "exodaqd exited %s" % daemon.returncode)
    echo, files = {}, {}
    for kind in ("joint_state", "palm_pose"):
        # To files: a pipe nobody reads while the subscriber runs would stall echo.
        # Both stop at SIGINT; --duration only guards against a hang.
        files[kind] = open(os.path.join(tmp, kind + ".csv"), "w+")
        echo[kind] = subprocess.Popen(
            [args.exodaq, "echo", "--csv", "--url", url, "--prefix", prefix, "--channel", kind,
             "--duration", "600"], stdout=files[kind], stderr=subprocess.PIPE, text=True)
        procs.append(echo[kind])
    sub = subprocess.Popen([py, "exodaq_subscriber.py", "--url", url, "--prefix", prefix,
                            "--seconds", "600", "--every", str(EVERY)],
                           cwd=work, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           text=True)
    procs.append(sub)
    until = wait_homed(args, url, prefix, args.after_homed)
    for p in [sub] + list(echo.values()):
        p.send_signal(signal.SIGINT)  # the subscriber's Ctrl-C
    out, err = sub.communicate(timeout=60)
    echo_err = {k: p.communicate(timeout=60)[1] for k, p in echo.items()}
    check(until is not None, "the daemon's status never said every joint homed")
    check(daemon.poll() is None, "exodaqd exited %s during the run" % daemon.returncode)
    print("subscriber ran until seq %d, %d cycles after every joint was homed" % (
        until, args.after_homed))
    check(sub.returncode == 0, "the subscriber exited %d:\n%s%s" % (sub.returncode, out, err))
    check(not err.strip(), "the subscriber wrote to stderr:\n%s" % err)
    rows = {}
    for k, f in files.items():
        check(echo[k].returncode == 0, "exodaq echo %s exited %d: %s" % (
            k, echo[k].returncode, echo_err[k]))
        f.seek(0)
        rows[k] = echo_rows(f.read(), k)
        f.close()
    return out, prefix, rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--source-dir", required=True)
    ap.add_argument("--exodaqd", required=True)
    ap.add_argument("--exodaq", required=True)
    ap.add_argument("--python", required=True, help="the interpreter to install for / run")
    ap.add_argument("--wheel", help="install this wheel into a new virtual environment")
    ap.add_argument("--site", help="the package is installed in this directory")
    ap.add_argument("--after-homed", type=int, default=1500,
                    help="run the subscriber this many cycles past every joint homed")
    args = ap.parse_args()
    check(bool(args.wheel) != bool(args.site), "give one of --wheel, --site")
    lcm_dir = os.path.join(args.source_dir, "lcmtypes", "exodaq")
    joint_bits = lcm_bits(os.path.join(lcm_dir, "joint_state_t.lcm"), "JOINT")
    sample_bits = lcm_bits(os.path.join(lcm_dir, "joint_state_t.lcm"), "SAMPLE")
    reason_bits = lcm_bits(os.path.join(lcm_dir, "palm_pose_t.lcm"), "INVALID")

    tmp = tempfile.mkdtemp(prefix="exodaq-python-")
    try:
        out, prefix, echo = run(args, tmp)
    except SystemExit:
        log = os.path.join(tmp, "exodaqd.log")
        if os.path.exists(log):
            sys.stderr.write("exodaqd log:\n" + open(log).read())
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    shutil.rmtree(tmp, ignore_errors=True)

    joints, palms, states, summary = parse_output(out)
    check(summary, "no summary line:\n" + out)
    received, lost, undecodable = summary
    print("subscriber: %d joints lines, %d palm lines, states %s; received %s, lost %s" % (
        len(joints), len(palms), [s[1] for s in states], received, lost))
    check(undecodable == 0, "%d messages did not decode" % undecodable)
    # Each kind received, and every cycle missing from its seq lost on the way:
    # the subscriber's own count of both (sub.received, sub.lost) covers the run.
    check(received.get("joint_state", 0) > 0 and received.get("palm_pose", 0) > 0,
          "received %s" % received)
    mj = check_joints(joints, echo["joint_state"], joint_bits, sample_bits)
    mp = check_palms(palms, joints, echo["palm_pose"], reason_bits)
    # Both sides (the subscriber prints every 50th cycle, either may lose some)
    # had cycles with an unhomed joint and with every joint usable.
    both_phases = (any("UNHOMED" in joints[q][2] for q in mj) and
                   any(joints[q][1] == "111111" for q in mj))
    check(both_phases and mp > 0, "%d joints lines (unhomed and homed: %s) and %d palm lines had "
          "a seq that exodaq echo also received: subscriber seq %s..%s, echo joint_state %d rows "
          "seq %s..%s, palm_pose %d rows seq %s..%s" % (
              len(mj), both_phases, mp, min(joints, default=None), max(joints, default=None),
                                  len(echo["joint_state"]), min(echo["joint_state"]),
                                  max(echo["joint_state"]), len(echo["palm_pose"]),
                                  min(echo["palm_pose"]), max(echo["palm_pose"])))
    check(any(j[1] == "111111" for j in joints.values()), "no cycle with every joint usable")
    check(any("UNHOMED" in j[2] and "0" in j[1] for j in joints.values()),
          "no cycle with an unhomed joint named UNHOMED")
    check(any(p[0] for p in palms.values()), "no valid palm pose")
    check(any(not p[0] and "UNHOMED" in p[2].split("|") for p in palms.values()),
          "no palm pose invalid for reason UNHOMED")
    check(states and all(s[0] == prefix + "EXO_STATUS" for s in states), "status lines %s" % states)
    check(all(s[1] in ("STARTING", "HOMING", "RUNNING", "DEGRADED", "FAULT", "STOPPING")
              for s in states), "state names %s" % states)
    print("values equal exodaq echo's for %d joint and %d palm cycles; flags named as in the .lcm "
          "files" % (len(mj), mp))
    return 0


if __name__ == "__main__":
    sys.exit(main())
