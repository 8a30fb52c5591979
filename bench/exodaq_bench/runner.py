"""bench/run's command line: builds, runs the parts, judges the targets, writes
performance.json and hands it to the report (or only re-renders an existing JSON)."""
import argparse
import datetime
import difflib
import json
import os
import shutil
import sys
import tempfile
import time

from . import report, targets
from .build import build, export_commit
from .common import REPO, Context, log, policy_name, rel
from .environment import fifo_allowed, lcm_version, machine
from .parts import PARTS

SCHEMA = 2  # 2: "targets" as data per summary row, "verdicts"; machine.lcm


def parse_args(argv):
    ap = argparse.ArgumentParser(prog="bench/run", description=sys.modules["__main__"].__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="a few seconds per part: checks the plumbing")
    ap.add_argument("--out", default=os.path.join(REPO, "docs"), help="where performance.md/.json/.png go")
    ap.add_argument("--build-dir", default=None, help="build tree (default build-bench/)")
    ap.add_argument("--no-build", action="store_true", help="use the binaries already in --build-dir")
    ap.add_argument("--duration", type=float, default=None, help="seconds per lateness / e2e run")
    ap.add_argument("--only", default=",".join(PARTS), help="comma-separated subset of " + ",".join(PARTS))
    ap.add_argument("--from-commit", default=None, help="measure a clean export of this commit")
    ap.add_argument("--reuse", default=None, help="a previous performance.json: parts not in --only are taken from it")
    ap.add_argument("--report-only", metavar="JSON", default=None,
                    help="measure nothing: re-judge JSON's figures and re-render the report into --out")
    ap.add_argument("--check", metavar="PAGE", default=None,
                    help="with --report-only: write nothing; exit 1 with a diff unless PAGE is what "
                         "--report-only renders from JSON (with the JSON's own render date)")
    args = ap.parse_args(argv)
    if args.check and not args.report_only:
        sys.exit("bench/run: --check needs --report-only JSON")
    args.parts = [p.strip() for p in args.only.split(",") if p.strip()]
    for p in args.parts:
        if p not in PARTS:
            sys.exit(f"bench/run: unknown part {p} (known: {', '.join(PARTS)})")
    return args


def context(args):
    """Exports --from-commit, builds, and returns (Context, the measured commit or None)."""
    src, from_commit = REPO, None
    build_dir = os.path.abspath(args.build_dir or os.path.join(REPO, "build-bench"))
    if args.from_commit:
        root = build_dir if args.build_dir else os.path.join(REPO, "build-bench-commit")
        from_commit, src, build_dir = export_commit(args.from_commit, root)
    if "lateness" in args.parts and not shutil.which("cyclictest"):
        sys.exit("bench/run: cyclictest not found (apt-get install rt-tests; scripts/setup does)")
    binaries = build(src, build_dir, args.no_build)
    tmp = tempfile.mkdtemp(prefix="exodaq-bench-")
    log(f"scratch files in {tmp}")
    return Context(src=src, build_dir=build_dir, bin=binaries, tmp=tmp, quick=args.quick,
                   policies=["other", "fifo"] if fifo_allowed() else ["other"],
                   duration=args.duration or (3.0 if args.quick else 60.0),
                   scale_duration=2.0 if args.quick else 20.0), from_commit


def reuse(res, path, parts):
    """Takes the parts not measured in this run from the performance.json at path."""
    with open(path, encoding="utf-8") as f:
        old = json.load(f)
    reused = [p for p in PARTS if p not in parts and p in old]
    for p in reused:
        res[p] = old[p]
    om = old["machine"]
    res["reused"] = {"parts": reused, "from_date": om["date"], "from_commit": om["commit"],
                     "from_loadavg": [om["loadavg_start"], om["loadavg_end"]]}
    res["generator"] += f" (re-running {','.join(parts)}; the rest from the run of {om['date']})"


def measure(args):
    ctx, from_commit = context(args)
    res = {"schema": SCHEMA, "quick": args.quick, "machine": machine(from_commit),
           "targets": targets.as_json(), "policies": [policy_name(p) for p in ctx.policies],
           "generator": "bench/run" + (" --quick" if args.quick else "")
           + (f" --from-commit {args.from_commit}" if args.from_commit else "")}
    t_start = time.monotonic()
    for name, part in PARTS.items():
        if name in args.parts:
            res[name] = part(ctx)
    if args.reuse:
        reuse(res, args.reuse, args.parts)
    res["machine"]["loadavg_end"] = list(os.getloadavg())
    res["elapsed_s"] = round(time.monotonic() - t_start, 1)
    return res


def load_for_report(path, keep_date=False):
    """A performance.json to re-render; what schema 1 did not record is filled in. The
    render is stamped with now, or (keep_date) keeps the JSON's own stamp, if any."""
    with open(path, encoding="utf-8") as f:
        res = json.load(f)
    if "lcm" not in res["machine"]:
        res["machine"]["lcm"] = lcm_version()  # schema 1 asked pkg-config when rendering
    res["schema"] = SCHEMA
    if not keep_date:
        res["rendered"] = {"by": f"bench/run --report-only {rel(path)}",
                           "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds")}
    return res


def check(res, page):
    """0 when page is the report rendered from res (the plot linked when page's directory
    has performance.png), else 1 after printing a unified diff."""
    res["targets"] = targets.as_json()
    res["verdicts"] = targets.evaluate(res)
    png = "performance.png" if "scaling" in res and os.path.exists(
        os.path.join(os.path.dirname(os.path.abspath(page)), "performance.png")) else None
    want = report.markdown(res, png)
    with open(page, encoding="utf-8") as f:
        have = f.read()
    if have == want:
        log(f"{rel(page)} is the report rendered from the JSON")
        return 0
    sys.stdout.writelines(difflib.unified_diff(have.splitlines(True), want.splitlines(True),
                                               f"{rel(page)} (as committed)", "rendered from the JSON"))
    log(f"{rel(page)} differs from the report rendered from the JSON (above: what a re-render changes); "
        "re-render it (bench/run --report-only JSON) or port the page's edits to bench/exodaq_bench/report/")
    return 1


def finish(res, out):
    """Judges every target and writes performance.json, .md and .png into out."""
    res["targets"] = targets.as_json()
    res["verdicts"] = targets.evaluate(res)
    path = os.path.join(out, "performance.json")
    with open(path, "w", encoding="utf-8") as f:
        json.dump(res, f, indent=1, ensure_ascii=False)
        f.write("\n")
    written = report.write(res, out)
    if "scaling" in res and not any(p.endswith(".png") for p in written):
        log("no matplotlib for this python: no plot (apt-get install python3-matplotlib)")
    return [path] + written


def main(argv=None):
    args = parse_args(argv)
    if args.check:
        sys.exit(check(load_for_report(args.report_only, keep_date=True), args.check))
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    res = load_for_report(args.report_only) if args.report_only else measure(args)
    written = finish(res, out)
    took = "" if args.report_only else f" in {res['elapsed_s']:.0f} s"
    log("wrote " + ", ".join(written) + took)
