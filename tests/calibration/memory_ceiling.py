#!/usr/bin/env python3
"""Issue 25.4: a large calibration input costs bounded memory.

The calibration readers keep at most 2^20 encoder and 2^20 marker samples
(tools/calibration/include/exodaq/calibration/inputs.hpp: kMaxEncoderSamples,
kMaxMarkerSamples; 64 and 48 bytes a sample), so `exodaq calibrate` on any
input within the 1 GiB file limit must stay under

    ceiling = baseline + 2^20 x (64 + 48 + 4 x 8) bytes + 16 MiB

where baseline is the same command's peak on a small input in this run (the
process's own code, libraries and solver), 4 x 8 bytes a sample the
alignment's index vectors (EncoderIndex, the usable and per-marker indices,
the kept flags), and 16 MiB allocator slack. The figure depends on the cap,
not on the machine or the input's size; before the cap, 300 MB of rows cost
2.7 GB. Each case's peak is the child's own maximum RSS (wait4's rusage).

  1. calibrate on 2.5 x 2^20 encoder rows and 2.5 x 2^20 marker rows
     (about 290 MB): under the ceiling, and the markers kept are between
     2^19 and 2^20 (evenly thinned within the cap), with the count reported;
  2. shoulder-cor on the same marker rows under a wrong header: the header
     error (line 1) comes before the body is read, within baseline + 16 MiB;
  3. calibrate with 256 MiB of NUL bytes as the markers: an error naming the
     file, within baseline + 16 MiB.

  memory_ceiling.py --exodaq EXE [--keep DIR]     prints a table row per case
"""
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile

CAP = 1 << 20
MIB = 1 << 20
ENCODER_SAMPLE_BYTES = 64
MARKER_SAMPLE_BYTES = 48
INDEX_BYTES = 4 * 8
SLACK = 16 * MIB
T0_US = 1700000000000000
ENCODER_STEP_US = 250


def write_inputs(folder, rows_enc, rows_mk):
    enc, mk = os.path.join(folder, "enc.csv"), os.path.join(folder, "mk.csv")
    with open(enc, "w") as f:
        f.write("utime_us,j1_rad,j2_rad,j3_rad,j4_rad,j5_rad,j6_rad\n")
        chunk = []
        for k in range(rows_enc):
            s = math.sin(k * 1e-4)
            chunk.append("%d,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f\n"
                         % (T0_US + k * ENCODER_STEP_US, s, -s, 0.5 * s, 0.2 * s, -0.3 * s, 0.1 * s))
            if len(chunk) == 65536:
                f.write("".join(chunk))
                chunk = []
        f.write("".join(chunk))
    step = rows_enc * ENCODER_STEP_US // (rows_mk + 1)
    with open(mk, "w") as f:
        f.write("utime_us,x_mm,y_mm,z_mm,marker_id\n")
        chunk = []
        for k in range(rows_mk):
            s = math.sin(k * 1e-3)
            chunk.append("%d,%.3f,%.3f,%.3f,3\n"
                         % (T0_US + 1000 + k * step, 100 * s, 700 + 50 * s, 300 - 20 * s))
            if len(chunk) == 65536:
                f.write("".join(chunk))
                chunk = []
        f.write("".join(chunk))
    return enc, mk


# The measuring parent: a fresh `python3 -S` (about 10 MiB), because a forked
# child's maximum RSS includes the parent's pages it ran with before exec
# (this script holds far more after writing the inputs). It writes the
# child's exit code, the child's peak and its own peak RSS since its exec (KiB,
# the most a forked child starts with) to argv[1].
LAUNCHER = """
import os, sys
own = [int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:")][0]
pid = os.fork()
if pid == 0:
    os.execv(sys.argv[2], sys.argv[2:])
_, status, usage = os.wait4(pid, 0)
open(sys.argv[1], "w").write("%d %d %d" % (os.waitstatus_to_exitcode(status), usage.ru_maxrss, own))
"""


def peak(cmd, cwd):
    """(exit code, output, the child's maximum RSS in bytes, the launcher's)."""
    report = os.path.join(cwd, "peak.txt")
    p = subprocess.run([sys.executable, "-S", "-c", LAUNCHER, report] + cmd, cwd=cwd,
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    rc, child_kib, own_kib = (int(v) for v in open(report).read().split())
    return rc, p.stdout.decode("utf-8", "replace"), child_kib * 1024, own_kib * 1024


def main(argv):
    if len(argv) < 3 or argv[1] != "--exodaq":
        print(__doc__)
        return 2
    exodaq = os.path.abspath(argv[2])
    keep = argv[4] if len(argv) > 4 and argv[3] == "--keep" else None
    work = keep or tempfile.mkdtemp(prefix="memory-ceiling-")
    os.makedirs(os.path.join(work, "small"), exist_ok=True)
    source = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    bounds = os.path.join(source, "config", "calibration", "bounds_seed000.yaml")
    failures = []
    try:
        small_enc, small_mk = write_inputs(os.path.join(work, "small"), 20000, 20000)
        rows = CAP * 5 // 2
        enc, mk = write_inputs(work, rows, rows)
        calibrate = [exodaq, "calibrate", "--bounds", bounds, "-o", "out.yaml", "-q"]
        _, _, baseline, launcher = peak(
            calibrate + ["--encoders", small_enc, "--markers", small_mk], work)
        if launcher >= baseline:
            failures.append("the launcher (%.1f MiB) is not smaller than the baseline (%.1f MiB): "
                            "the peaks would be its own" % (launcher / MIB, baseline / MIB))
        ceiling = baseline + CAP * (ENCODER_SAMPLE_BYTES + MARKER_SAMPLE_BYTES + INDEX_BYTES) + SLACK
        small_ceiling = baseline + SLACK
        size = os.path.getsize(enc) + os.path.getsize(mk)
        print("| case | input | peak RSS (MiB) | ceiling (MiB) | outcome |")
        print("|---|---|---|---|---|")
        print("| calibrate, small input (the baseline) | 2 x 20 000 rows | %.1f | | launcher %.1f |"
              % (baseline / MIB, launcher / MIB))

        # 1. The large input: bounded, thinned within the cap, counted.
        rc, out, rss, _ = peak(calibrate + ["--encoders", enc, "--markers", mk], work)
        m = re.search(r"mk\.csv: (\d+) marker samples[^\n]*", out)
        print("| calibrate | %d encoder + %d marker rows, %.0f MB | %.1f | %.1f | exit %d, `%s` |"
              % (rows, rows, size / 1e6, rss / MIB, ceiling / MIB, rc, m.group(0) if m else ""))
        if rc not in (0, 2) or "Traceback" in out or not m:
            failures.append("calibrate: exit %d without the marker count:\n%s" % (rc, out[-2000:]))
        elif not CAP // 2 <= int(m.group(1)) <= CAP:
            failures.append("calibrate kept %s marker samples, not within 2^19..2^20"
                            % m.group(1))
        if rss > ceiling:
            failures.append("calibrate: peak RSS %.1f MiB above the ceiling %.1f MiB"
                            % (rss / MIB, ceiling / MIB))

        # 2. A header error comes before the body.
        bad = os.path.join(work, "bad_header.csv")
        with open(bad, "w") as f, open(mk) as body:
            f.write("utime_us,x_mm,y_mm,zz_mm,marker_id\n")
            body.readline()
            shutil.copyfileobj(body, f, 1 << 20)
        rc, out, rss, _ = peak([exodaq, "shoulder-cor", "--markers", bad, "--torso", "1", "2", "3",
                             "--humerus", "4", "5", "6", "--torso-axis", "1", "2",
                             "--humerus-axis", "4", "5"], work)
        print("| shoulder-cor, wrong header | %.0f MB | %.1f | %.1f | exit %d, `%s` |"
              % (os.path.getsize(bad) / 1e6, rss / MIB, small_ceiling / MIB, rc,
                 out.strip().split("\n")[-1][:120]))
        if rc != 2 or "bad_header.csv:1:" not in out:
            failures.append("shoulder-cor: exit %d, no line-1 error:\n%s" % (rc, out[-1000:]))
        if rss > small_ceiling:
            failures.append("shoulder-cor: peak RSS %.1f MiB above %.1f MiB"
                            % (rss / MIB, small_ceiling / MIB))

        # 3. NUL bytes (a sparse file: nothing on disk, every byte read).
        nul = os.path.join(work, "nul.csv")
        with open(nul, "wb") as f:
            f.truncate(256 * MIB)
        rc, out, rss, _ = peak(calibrate + ["--encoders", small_enc, "--markers", nul], work)
        print("| calibrate, NUL bytes as markers | 256 MiB | %.1f | %.1f | exit %d, `%s` |"
              % (rss / MIB, small_ceiling / MIB, rc, out.strip().split("\n")[-1][:120]))
        if rc != 2 or "nul.csv" not in out:
            failures.append("calibrate on NUL bytes: exit %d:\n%s" % (rc, out[-1000:]))
        if rss > small_ceiling:
            failures.append("calibrate on NUL bytes: peak RSS %.1f MiB above %.1f MiB"
                            % (rss / MIB, small_ceiling / MIB))
    finally:
        if not keep:
            shutil.rmtree(work, ignore_errors=True)
    for f in failures:
        print("FAIL: " + f)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
