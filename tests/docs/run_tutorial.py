#!/usr/bin/env python3
"""Runs the tutorials of docs/calibration.md and docs/shoulder-cor.md exactly
as written (issue 28.4): the docs' commands are the test's commands.

In a page, a fenced block whose info string is `sh tutorial` (or
`sh tutorial exit=N`) is a step: its text runs as one `bash -e` script in a
scratch folder that holds a `config` link to the source tree's config/, with
the exodaq under test first on PATH, and must exit 0 (or N). A following
`text tutorial-output` block lists lines that the step's output (stdout and
stderr) must contain: the same words, and every number within 3 units of its
last shown digit.

After the steps, the results are checked against the truth, independently of
what the pages show:
  - every calibration a step wrote (`-o FILE.yaml`, exit 0) matches the
    example session's truth.yaml (offsets within 0.1 deg, lengths 0.3 mm,
    camera 0.1 mm and 0.05 deg); a step that failed wrote nothing;
  - every shoulder-cor bins CSV (`--csv FILE`) has six valid bins whose
    vertical motion is within 2.5 mm of seed 001 Table II, the first bin's
    vertical flagged.

  run_tutorial.py --exodaq EXE --source DIR PAGE...
  run_tutorial.py --self-test      the line matcher on planted differences

Exit 0: every step ran and matched; 1: findings (one line each); 2: usage.
"""
import csv
import os
import re
import shutil
import subprocess
import sys
import tempfile

NUMBER = re.compile(r"[-+]?\d+(?:\.\d+)?")
STEP = re.compile(r"^```sh tutorial(?:\s+exit=(\d+))?\s*$")
OUTPUT = re.compile(r"^```text tutorial-output\s*$")
TABLE2_MM = [0, 4, 13, 27, 43, 62]  # seed 001 Table II at the 20 deg bins' centres


def steps(page):
    """[(line, script, exit code, [expected lines])] of a page."""
    lines = open(page, encoding="utf-8").read().split("\n")
    out, i = [], 0
    while i < len(lines):
        m, o = STEP.match(lines[i]), OUTPUT.match(lines[i])
        if not m and not o:
            i += 1
            continue
        start, i = i + 1, i + 1
        while i < len(lines) and not lines[i].startswith("```"):
            i += 1
        body = lines[start:i]
        i += 1
        if m:
            out.append((start, "\n".join(body) + "\n", int(m.group(1) or 0), []))
        elif not out:
            raise SystemExit("%s:%d: tutorial output before any step" % (page, start))
        else:
            out[-1][3].extend(b for b in body if b.strip())
    return out


def split(line):
    """The words (whitespace collapsed) and the numbers of a line."""
    words = [" ".join(w.split()) for w in NUMBER.split(line)]
    return words, NUMBER.findall(line)


def matches(expected, actual):
    ew, en = split(expected)
    aw, an = split(actual)
    if ew != aw or len(en) != len(an):
        return False
    for e, a in zip(en, an):
        decimals = len(e.split(".")[1]) if "." in e else 0
        if abs(float(e) - float(a)) > 3 * 10 ** -decimals:
            return False
    return True


def read_calibration(path):
    """The numbers of a calibration file (docs/calibration.md §3.1) by key."""
    text = open(path, encoding="utf-8").read()
    values = {}
    for key in ("encoder_offsets_deg", "marker_offset_mm", "translation_mm", "euler_xyz_deg"):
        m = re.search(r"^\s*%s:\s*\[([^\]]*)\]" % key, text, re.M)
        values[key] = [float(v) for v in m.group(1).split(",")] if m else None
    for key in ("d2", "d3", "d5", "a3", "a5"):
        m = re.search(r"^\s+%s:\s*(\S+)" % key, text, re.M)
        values[key] = [float(m.group(1))] if m else None
    return values


TOLERANCE = {"encoder_offsets_deg": 0.1, "marker_offset_mm": 0.3, "translation_mm": 0.1,
             "euler_xyz_deg": 0.05, "d2": 0.3, "d3": 0.3, "d5": 0.3, "a3": 0.3, "a5": 0.3}


def check_calibration(path, truth, findings):
    got, want = read_calibration(path), read_calibration(truth)
    for key, tol in TOLERANCE.items():
        if got[key] is None or want[key] is None:
            findings.append("%s: no %s" % (path, key))
            continue
        for k, (g, w) in enumerate(zip(got[key], want[key])):
            if abs(g - w) > tol:
                findings.append("%s: %s[%d] = %.4f, truth %.4f (tolerance %g)"
                                % (path, key, k, g, w, tol))


def check_bins(path, findings):
    rows = list(csv.DictReader(open(path, encoding="utf-8")))
    if len(rows) != 6 or not all(r["valid"] == "1" for r in rows):
        findings.append("%s: %d bins, expected 6 valid" % (path, len(rows)))
        return
    for r, table in zip(rows, TABLE2_MM):
        if abs(float(r["vertical_mm"]) - table) > 2.5:
            findings.append("%s: bin %s vertical %s mm, Table II %d mm"
                            % (path, r["bin"], r["vertical_mm"], table))
    if "vertical" not in rows[0]["flags"]:
        findings.append("%s: the first bin's vertical is not flagged (%r)" % (path, rows[0]["flags"]))


def outputs_of(script, flag):
    joined = script.replace("\\\n", " ")
    return re.findall(r"(?:^|\s)%s\s+(\S+)" % re.escape(flag), joined)


def run(exodaq, source, pages):
    findings, checked = [], 0
    work = tempfile.mkdtemp(prefix="tutorial-")
    try:
        os.symlink(os.path.join(os.path.abspath(source), "config"), os.path.join(work, "config"))
        env = dict(os.environ)
        env["PATH"] = os.path.dirname(os.path.abspath(exodaq)) + os.pathsep + env.get("PATH", "")
        for page in pages:
            for line, script, want_rc, expected in steps(os.path.join(source, page)):
                where = "%s:%d" % (page, line)
                p = subprocess.run(["bash", "-e", "-c", script], cwd=work, env=env,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                   text=True, timeout=600)
                print("%s: exit %d, %d lines of output" % (where, p.returncode,
                                                            p.stdout.count("\n")))
                if p.returncode != want_rc:
                    findings.append("%s: exit %d, expected %d; output:\n%s"
                                    % (where, p.returncode, want_rc, p.stdout[-3000:]))
                    continue
                actual = p.stdout.split("\n")
                for e in expected:
                    checked += 1
                    if not any(matches(e, a) for a in actual):
                        findings.append("%s: no output line matches\n  %s" % (where, e))
                is_calibrate = "exodaq calibrate" in script
                for out in outputs_of(script, "-o") if is_calibrate else []:
                    path = os.path.join(work, out)
                    if want_rc != 0 and os.path.exists(path):
                        findings.append("%s: failed, yet wrote %s" % (where, out))
                    elif want_rc == 0:
                        check_calibration(path, os.path.join(os.path.dirname(path), "truth.yaml"),
                                          findings)
                        checked += 1
                for out in outputs_of(script, "--csv") if "shoulder-cor" in script else []:
                    check_bins(os.path.join(work, out), findings)
                    checked += 1
    finally:
        shutil.rmtree(work, ignore_errors=True)
    if checked == 0:
        findings.append("no tutorial step with checked output in %s" % ", ".join(pages))
    for f in findings:
        print(f)
    print("run_tutorial: %d checks, %d finding(s)" % (checked, len(findings)))
    return 1 if findings else 0


def self_test():
    shown = "  Δθ1⁰                 51.000       49.015      0.003  deg   identified"
    cases = [
        (shown, "  Δθ1⁰   51.000   49.016   0.003  deg   identified", True),  # 1 unit, realigned
        (shown, "  Δθ1⁰                 51.000       49.019      0.003  deg   identified", False),
        (shown, "  Δθ1⁰                 51.000       49.015      0.003  deg   HELD", False),
        (shown, "  Δθ1⁰                 51.000       49.015  deg   identified", False),
        ("written 101458 cycles", "written 101459 cycles", True),
        ("written 101458 cycles", "written 101462 cycles", False),
    ]
    bad = [(e, a) for e, a, want in cases if matches(e, a) != want]
    for e, a in bad:
        print("self-test: matches(%r, %r) is wrong" % (e, a))
    print("run_tutorial self-test: %d of %d cases right" % (len(cases) - len(bad), len(cases)))
    return 1 if bad else 0


def main(argv):
    if argv[1:] == ["--self-test"]:
        return self_test()
    if len(argv) < 6 or argv[1] != "--exodaq" or argv[3] != "--source":
        print(__doc__)
        return 2
    return run(argv[2], argv[4], argv[5:])


if __name__ == "__main__":
    sys.exit(main(sys.argv))
