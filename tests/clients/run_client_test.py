#!/usr/bin/env python3
"""Test driver for the client binding tests (tests/clients/CMakeLists.txt).

Every test uses its own channel prefix (test name + pid + random), so tests can
run in parallel with each other and with a live exodaqd on the same URL.

  run_client_test.py files FIXTURE -- CLIENT... {dir}
      fixture writes the four encoded messages into a temporary {dir}; the
      client decodes them; its sorted output must equal `FIXTURE dump`.
  run_client_test.py subscribe FIXTURE URL [--big N] -- CLIENT... {url} {prefix} {wait_ms}|{wait_s}
      the client runs as its own process and subscribes; once it reports
      "subscribed" on stderr, FIXTURE publishes the messages from a second
      process until the client is done; output compared as above.
  run_client_test.py echo-csv FIXTURE URL -- TOOL
  run_client_test.py echo-literal FIXTURE URL -- TOOL
  run_client_test.py echo-table FIXTURE URL -- TOOL
  run_client_test.py echo-errors FIXTURE URL -- TOOL
  run_client_test.py status FIXTURE URL -- TOOL
  run_client_test.py status-json FIXTURE URL -- TOOL
  run_client_test.py status-timeout FIXTURE URL -- TOOL
      the `exodaq echo` / `exodaq status` commands against the fixture publisher.
"""
import os
import pty
import random
import re
import select
import subprocess
import sys
import tempfile
import threading
import time

WAIT_S = 20  # generous: a loaded CI machine, JVM start-up


def fail(msg):
    print("FAIL: " + msg, file=sys.stderr)
    sys.exit(1)


def unique_prefix(tag):
    return "T%s_%d_%06d_" % (re.sub(r"\W", "", tag), os.getpid(), random.randrange(10 ** 6))


def subst(cmd, **kw):
    return [c.format(**kw) for c in cmd]


def expected_dump(fixture):
    return subprocess.run([fixture, "dump"], check=True, capture_output=True,
                          text=True).stdout.splitlines()


def compare(expected, actual_text, what):
    actual = actual_text.splitlines()
    exp, act = sorted(expected), sorted(actual)
    if exp != act:
        missing = sorted(set(exp) - set(act))
        extra = sorted(set(act) - set(exp))
        fail("%s: %d lines expected, %d got\n  missing: %s\n  unexpected: %s" % (
            what, len(exp), len(act), "\n    ".join(missing[:40]), "\n    ".join(extra[:40])))
    print("%s: all %d values match" % (what, len(exp)))


class Publisher:
    """The fixture publishing from its own process until stopped."""

    def __init__(self, fixture, url, prefix, *extra):
        self.proc = subprocess.Popen(
            [fixture, "publish", url, prefix, "--count", "100000", "--interval-ms", "10"] +
            list(extra), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)

    def stop(self):
        if self.proc.poll() is None:
            self.proc.terminate()
        try:
            _, err = self.proc.communicate(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            _, err = self.proc.communicate()
        if err:
            sys.stderr.write(err)
        if self.proc.returncode == 3:
            fail("the publisher cannot open LCM: no multicast route? see docs/messages.md")

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()


def run_files(fixture, client):
    with tempfile.TemporaryDirectory(prefix="exodaq-clients-") as d:
        subprocess.run([fixture, "write", d], check=True)
        r = subprocess.run(subst(client, dir=d), capture_output=True, text=True, timeout=120)
        sys.stderr.write(r.stderr)
        if r.returncode != 0:
            fail("client exited %d\n%s" % (r.returncode, r.stdout))
        compare(expected_dump(fixture), r.stdout, os.path.basename(client[0]) + " files")


def run_subscribe(fixture, url, client, big):
    prefix = unique_prefix(os.path.basename(client[-1] if client else "sub"))
    cmd = subst(client, url=url, prefix=prefix, wait_ms=str(WAIT_S * 1000), wait_s=str(WAIT_S))
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    subscribed = threading.Event()
    err_lines = []

    def read_err():
        for line in proc.stderr:
            err_lines.append(line)
            if "subscribed" in line:
                subscribed.set()

    t = threading.Thread(target=read_err, daemon=True)
    t.start()
    if not subscribed.wait(WAIT_S):
        proc.kill()
        fail("client never subscribed:\n" + "".join(err_lines))
    extra = ["--big", str(big)] if big else []
    with Publisher(fixture, url, prefix, *extra):
        try:
            out, _ = proc.communicate(timeout=WAIT_S + 10)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, _ = proc.communicate()
    t.join(5)
    sys.stderr.write("".join(err_lines))
    if proc.returncode != 0:
        fail("subscriber exited %d (prefix %s)\n%s" % (proc.returncode, prefix, out))
    compare(expected_dump(fixture), out, "%s subscribe over %s" % (os.path.basename(cmd[0]), url))


def run_tool(tool, args, timeout=WAIT_S + 20):
    return subprocess.run(tool + args, capture_output=True, text=True, timeout=timeout)


def parse_csv(text):
    import csv
    import io
    return list(csv.reader(io.StringIO(text)))


NAMES = ("shoulder_abduction", "shoulder_flexion", "shoulder_rotation", "elbow_flexion",
         "wrist_pronation", "wrist_flexion")  # the fixture's joints


def run_echo_csv(fixture, url, tool):
    prefix = unique_prefix("echo_csv")
    n = 25
    with Publisher(fixture, url, prefix, "--vary-seq"):
        # Not a terminal (captured), so CSV even without --csv.
        r = run_tool(tool, ["echo", "--url", url, "--prefix", prefix, "--count", str(n),
                            "--duration", str(WAIT_S)])
    if r.returncode != 0:
        fail("echo exited %d: %s" % (r.returncode, r.stderr))
    rows = parse_csv(r.stdout)
    header, rows = rows[0], rows[1:]
    if len(rows) != n:
        fail("expected %d rows, got %d" % (n, len(rows)))
    # The schema of docs/messages.md, the same as `exodaq export` up to its
    # palm columns: joints by name, units in the names, no joint names in rows.
    want = ["utime_us", "mono_ns", "seq", "run_id"]
    for suffix in ("_rad", "_vel_rad_s", "_count", "_homed", "_flags"):
        want += [j + suffix for j in NAMES]
    want += ["sample_flags"]
    if header != want:
        fail("header %s, expected %s" % (header, want))
    col = {name: i for i, name in enumerate(header)}
    seqs = [int(row[col["seq"]]) for row in rows]
    if any(b <= a for a, b in zip(seqs, seqs[1:])):
        fail("seq not increasing: %s" % seqs)
    for row in rows:
        if len(row) != len(header):
            fail("row has %d values, header %d" % (len(row), len(header)))
        if any(v == "-0" for v in row):
            fail("a value printed as -0: %s" % row)
        k = int(row[col["seq"]]) - 4242424242
        checks = {
            "utime_us": str(1700000000123456 + 1000 * k),
            "run_id": "fedcba9876543211",  # -0x0123456789abcdef, 16 hex digits
            "elbow_flexion_rad": "-2.75",
            "wrist_pronation_rad": "0.1",  # shortest round-trip text
            "shoulder_rotation_count": "123456789012",
            "shoulder_flexion_homed": "0",
            "shoulder_rotation_flags": str(2 | 64),
            "sample_flags": str(2 | 256),
        }
        for name, want_value in checks.items():
            if row[col[name]] != want_value:
                fail("%s = %r, expected %r (row %s)" % (name, row[col[name]], want_value, row))
    print("echo csv: header of %d named columns, %d rows, seq %d..%d, values match" % (
        len(header), len(rows), seqs[0], seqs[-1]))


def run_echo_literal(fixture, url, tool):
    # A full channel name that is not one of the short names: taken literally,
    # type recognised from the fingerprint, header printed with the first row.
    prefix = unique_prefix("echo_literal")
    with Publisher(fixture, url, prefix):
        r = run_tool(tool, ["echo", "--csv", "--url", url, "--channel", prefix + "EXO_STATUS",
                            "--count", "3", "--duration", str(WAIT_S)])
    if r.returncode != 0:
        fail("echo exited %d: %s" % (r.returncode, r.stderr))
    rows = parse_csv(r.stdout)
    if len(rows) != 4:
        fail("expected header + 3 rows, got %r" % rows)
    col = {name: i for i, name in enumerate(rows[0])}
    for row in rows[1:]:
        if row[col["rig"]] != "sim-rig, bench 2" or \
                row[col["message"]] != 'joint 3 "elbow_flexion" stale' or \
                row[col["state"]] != "3" or row[col["wrist_pronation_homing"]] != "2" or \
                row[col["run_id"]] != "fedcba9876543211":
            fail("status row wrong: %s" % row)
    print("echo literal channel: status_t recognised, CSV quoting round-trips")


def run_echo_errors(fixture, url, tool):
    """Issue 15 point 6: echo checks its writes. A full device, a closed
    stdout and a full filesystem end it with exit 1 and the reason; -o FILE
    appears whole when echo ends."""
    prefix = unique_prefix("echo_errors")
    base = tool + ["echo", "--url", url, "--prefix", prefix, "--duration", str(WAIT_S)]
    with Publisher(fixture, url, prefix, "--vary-seq"):
        for redirect, reason in (("> /dev/full", "No space left on device"),
                                 (">&-", "Bad file descriptor")):
            line = " ".join(base + ["--count", "20"]) + " " + redirect
            r = subprocess.run(["/bin/sh", "-c", line], capture_output=True, text=True,
                               timeout=WAIT_S + 20)
            want = "exodaq echo: standard output: cannot write: %s\n" % reason
            if r.returncode != 1 or r.stderr != want:
                fail("echo %s: exit %d, stderr %r (want %r)" % (redirect, r.returncode,
                                                                 r.stderr, want))
        with tempfile.TemporaryDirectory(prefix="exodaq-echo-") as d:
            out = os.path.join(d, "joints.csv")
            r = run_tool(base, ["--count", "10", "-o", out])
            if r.returncode != 0:
                fail("echo -o: exit %d: %s" % (r.returncode, r.stderr))
            lines = open(out).read().splitlines()
            if len(lines) != 11 or not lines[0].startswith("utime_us,mono_ns,seq,run_id,"):
                fail("echo -o wrote %d lines: %s" % (len(lines), lines[:2]))
            if sorted(os.listdir(d)) != ["joints.csv"]:
                fail("echo -o left %s" % os.listdir(d))
            full = os.path.join(d, "full")
            os.mkdir(full)
            if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", full],
                              capture_output=True).returncode != 0:
                print("echo on a full filesystem: skipped (cannot mount a tmpfs: needs root)")
            else:
                try:
                    # The reproduction: `echo > file` on a full disk exited 0
                    # with part of the lines.
                    line = " ".join(base + ["--count", "2000"]) + " > " + full + "/joints.csv"
                    r = subprocess.run(["/bin/sh", "-c", line], capture_output=True, text=True,
                                       timeout=WAIT_S + 40)
                    want = "exodaq echo: standard output: cannot write: No space left on device\n"
                    if r.returncode != 1 or r.stderr != want:
                        fail("echo > full disk: exit %d, %r" % (r.returncode, r.stderr))
                    os.remove(full + "/joints.csv")
                    r = run_tool(base, ["--count", "2000", "-o", full + "/joints.csv"],
                                 timeout=WAIT_S + 40)
                    want = ("exodaq echo: %s/joints.csv: cannot write: No space left on device\n"
                            % full)
                    if r.returncode != 1 or r.stderr != want or os.listdir(full):
                        fail("echo -o on a full disk: exit %d, %r, left %s"
                             % (r.returncode, r.stderr, os.listdir(full)))
                finally:
                    subprocess.run(["umount", full])
    print("echo: /dev/full, a closed stdout and a full filesystem exit 1 with the reason; "
          "-o writes the whole file at the end")


def run_echo_table(fixture, url, tool):
    prefix = unique_prefix("echo_table")
    with Publisher(fixture, url, prefix):
        pid, fd = pty.fork()
        if pid == 0:
            os.execv(tool[0], tool + ["echo", "--url", url, "--prefix", prefix, "--count", "40",
                                      "--duration", str(WAIT_S)])
        out = b""
        deadline = time.monotonic() + WAIT_S + 10
        while time.monotonic() < deadline:
            if select.select([fd], [], [], 1)[0]:
                try:
                    chunk = os.read(fd, 65536)
                except OSError:  # EIO: the child closed the terminal
                    break
                if not chunk:
                    break
                out += chunk
        _, status = os.waitpid(pid, 0)
        os.close(fd)
    text = out.decode("utf-8", "replace")
    if os.waitstatus_to_exitcode(status) != 0:
        fail("echo (table) exited %d:\n%s" % (os.waitstatus_to_exitcode(status), text))
    for want in ("\x1b[?25l", "angle deg", "elbow_flexion", "-157.563", "STALE|HELD",
                 "DEGRADED", "x   123.40", "valid no (UNHOMED|JOINT_FAULT)", "NEAR-SINGULAR",
                 "seq 4242424242", "\x1b[?25h"):
        if want not in text:
            fail("table output lacks %r:\n%s" % (want, text))
    print("echo table on a pty: %d bytes, all expected cells present" % len(out))


def run_status(fixture, url, tool):
    prefix = unique_prefix("status")
    with Publisher(fixture, url, prefix):
        r = run_tool(tool, ["status", "--url", url, "--prefix", prefix, "--timeout", str(WAIT_S)])
    if r.returncode != 0:
        fail("status exited %d: %s" % (r.returncode, r.stderr))
    print(r.stdout)
    for want in (prefix + "EXO_STATUS", "rig 'sim-rig, bench 2'", "DEGRADED",
                 'joint 3 "elbow_flexion" stale', "2023-11-14 22:13:20.123461 UTC",
                 "overruns 3", "bus WARNING", "board errors 0x40", "synchronised",
                 "offset -3.2 us", "1250.2", "REJECTED", "STALE", "rx overflows 9"):
        if want not in r.stdout:
            fail("status output lacks %r" % want)
    print("status: all expected fields present")


def run_status_json(fixture, url, tool):
    import json
    prefix = unique_prefix("status_json")

    def status_json(*extra):
        with Publisher(fixture, url, prefix, *extra):
            r = run_tool(tool, ["status", "--url", url, "--prefix", prefix, "--timeout",
                                str(WAIT_S), "--json"])
        if r.returncode != 0:
            fail("status --json exited %d: %s" % (r.returncode, r.stderr))
        return json.loads(r.stdout)

    s = status_json()
    # States, homing and flags by name; booleans as booleans; no enum as a number.
    want = {"channel": prefix + "EXO_STATUS", "rig": "sim-rig, bench 2", "state": "DEGRADED",
            "run_id": "fedcba9876543211", "overruns": 3, "clock_synchronised": True,
            "bus_state": "WARNING", "clock_est_error_us": 16, "clock_max_error_us": 500,
            "wrist_pronation_homing": "REJECTED", "shoulder_flexion_homing": "UNHOMED",
            "elbow_flexion_flags": ["STALE"], "shoulder_abduction_flags": [],
            "config_path": "/etc/exodaq/exodaqd.yaml",
            "calibration_sha256":
                "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855",
            "reloads": 3, "foreign_run_id": "0123456789abcdef"}
    for k, v in want.items():
        if s.get(k) != v or type(s.get(k)) is not type(v):
            fail("status --json: %s = %r, expected %r" % (k, s.get(k), v))
    for k, v in s.items():
        if (k in ("state", "bus_state") or k.endswith("_homing")) and not isinstance(v, str):
            fail("status --json: %s = %r is not a name" % (k, v))
    # The kernel's "no estimate" and no foreign run: null, not 16000000 or 0.
    s = status_json("--clock-unknown")
    for k in ("clock_est_error_us", "clock_max_error_us", "foreign_run_id"):
        if k not in s or s[k] is not None:
            fail("status --json with the clock unknown: %s = %r, expected null" % (k, s.get(k)))
    print("status --json: one object in the CSV schema's names, enums by name, unknown null")


def run_status_timeout(fixture, url, tool):
    prefix = unique_prefix("status_none")
    r = run_tool(tool, ["status", "--url", url, "--prefix", prefix, "--timeout", "0.5"])
    if r.returncode != 1 or "no " + prefix + "EXO_STATUS" not in r.stderr:
        fail("expected exit 1 and a message, got %d: %s" % (r.returncode, r.stderr))
    print("status without a publisher: exit 1, %s" % r.stderr.strip())


def main(argv):
    if "--" not in argv:
        print(__doc__, file=sys.stderr)
        return 2
    sep = argv.index("--")
    head, cmd = argv[1:sep], argv[sep + 1:]
    mode, fixture = head[0], head[1]
    big = 0
    if "--big" in head:
        i = head.index("--big")
        big = int(head[i + 1])
        del head[i:i + 2]
    if mode == "files":
        run_files(fixture, cmd)
    elif mode == "subscribe":
        run_subscribe(fixture, head[2], cmd, big)
    else:
        fn = {"echo-csv": run_echo_csv, "echo-literal": run_echo_literal,
              "echo-table": run_echo_table, "echo-errors": run_echo_errors,
              "status": run_status, "status-json": run_status_json,
              "status-timeout": run_status_timeout}[mode]
        fn(fixture, head[2], cmd)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
