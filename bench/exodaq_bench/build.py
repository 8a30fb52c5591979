"""Builds (or finds) the binaries the parts run; exports a commit to measure."""
import os
import shutil
import subprocess
import sys

from .common import REPO, log, sh
from .parts import replay

BINARIES = {
    "exodaqd": "daemon/exodaqd",
    "bench_cycle": "bench/cycle/bench_cycle",
    "bench_kinematics": "bench/kinematics/bench_kinematics",
    "bench_lcm_sub": "bench/latency/bench_lcm_sub",
    "bench_lcm_pub": "bench/latency/bench_lcm_pub",
    "bench_deadline_probe": "bench/latency/bench_deadline_probe.so",
}


def build(src, build_dir, no_build):
    """Configures build_dir from src when it has no CMakeCache.txt, builds what the parts
    run (unless no_build) and returns {name: path}."""
    targets = list(BINARIES) + replay.build_targets(src)
    if not no_build:
        if not os.path.exists(os.path.join(build_dir, "CMakeCache.txt")):
            log(f"configuring {build_dir}")
            sh(["cmake", "-S", src, "-B", build_dir, "-G", "Ninja",
                "-DCMAKE_BUILD_TYPE=RelWithDebInfo", "-DEXODAQ_TEST_AREAS=support;bench"])
        log("building " + " ".join(targets))
        sh(["cmake", "--build", build_dir, "--target", *targets])
    paths = {k: os.path.join(build_dir, v) for k, v in BINARIES.items()}
    missing = [p for p in paths.values() if not os.path.exists(p)]
    if missing:
        sys.exit("bench/run: missing " + ", ".join(missing) + " (build them, or drop --no-build)")
    return paths


def export_commit(rev, root):
    """`git archive rev` extracted to root/src; returns (short hash, src, build dir)."""
    short = subprocess.run(["git", "-C", REPO, "rev-parse", "--short", rev],
                           capture_output=True, text=True).stdout.strip()
    if not short:
        sys.exit(f"bench/run: no commit {rev}")
    src = os.path.join(root, "src")
    shutil.rmtree(src, ignore_errors=True)
    os.makedirs(src)
    log(f"exporting {short} to {src}")
    archive = subprocess.run(["git", "-C", REPO, "archive", short], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", src], input=archive, check=True)
    return short, src, os.path.join(root, "build")
