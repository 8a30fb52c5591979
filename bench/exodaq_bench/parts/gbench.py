"""Running a Google Benchmark binary and reading its JSON."""
import json

from ..common import sh


def repetition_flags(quick, repetitions):
    if quick:
        return ["--benchmark_min_time=0.05"]
    return [f"--benchmark_repetitions={repetitions}", "--benchmark_report_aggregates_only=true"]


def run(argv):
    """{run_name: the median aggregate (or the single run)} of argv's JSON output."""
    rows = json.loads(sh(argv, capture_output=True).stdout)["benchmarks"]
    out = {}
    for x in rows:
        agg = x.get("aggregate_name")
        if agg == "median" or (agg is None and x["run_name"] not in out):
            out[x["run_name"]] = x
    return out
