#!/usr/bin/python3
"""Checks that bench/run's performance.json is complete: every part with every
expected figure, each a finite number, and a verdict for every target of
bench/exodaq_bench/targets.py (the values themselves are not judged: no timing
asserts; whether a target is met is the report's business, not CI's)."""
import json
import math
import os
import sys

sys.dont_write_bytecode = True
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))), "bench"))
from exodaq_bench import targets  # noqa: E402
from exodaq_bench.parts import PARTS  # noqa: E402

NUM = (int, float)
SCHEMA = 2
# The targets of the performance issue: a row may be added in targets.py without
# touching this list, but none of these may disappear.
REQUIRED_TARGETS = ("cycle_hot_p99", "in_loop_work_p99", "allocations", "palm_fk", "fk_jac_manip",
                    "lateness_p99", "e2e_added_p50", "cpu", "rss", "replay_speed", "replay_rss")


def fail(msg):
    print("check_performance_json: " + msg, file=sys.stderr)
    sys.exit(1)


def get(d, path):
    cur = d
    for part in path.split("."):
        if isinstance(cur, list):
            cur = cur[int(part)]
        elif isinstance(cur, dict) and part in cur:
            cur = cur[part]
        else:
            fail(f"missing key {path}")
    return cur


def number(d, path):
    v = get(d, path)
    if isinstance(v, bool) or not isinstance(v, NUM) or not math.isfinite(v):
        fail(f"{path} is not a finite number: {v!r}")
    return v


def text(d, path):
    v = get(d, path)
    if not isinstance(v, str) or not v:
        fail(f"{path} is not a non-empty string: {v!r}")


def check_verdicts(d):
    """A verdict per targets.py row and block, judged (met true/false on a finite figure),
    or left open with a reason only where the row is pending or its part unavailable."""
    declared = get(d, "targets")
    for rid in REQUIRED_TARGETS:
        if rid not in targets.BY_ID or rid not in declared:
            fail(f"target {rid} is not declared")
    verdicts = {(v["id"], v["policy"]): v for v in get(d, "verdicts")}
    n = 0
    for row in targets.ROWS:
        found = targets.blocks(d, row)
        if not found:
            fail(f"no block of part {row.part} for target {row.id}")
        for policy, block in found:
            v = verdicts.get((row.id, policy))
            if v is None:
                fail(f"no verdict for {row.id} ({policy})")
            if v["met"] is None:
                if not (row.pending or block.get("available") is False) or not v.get("note"):
                    fail(f"verdict {row.id} ({policy}) is open: {v.get('note')!r}")
                continue
            if not isinstance(v["met"], bool):
                fail(f"verdict {row.id} ({policy}): met is {v['met']!r}")
            number({"figure": v["figure"]}, "figure")
            n += 1
    return n


def main():
    d = json.load(open(sys.argv[1]))
    if get(d, "schema") != SCHEMA:
        fail(f"schema {d['schema']}, expected {SCHEMA}")
    for part in PARTS:
        get(d, part)
    for k in ("machine.cpu_model", "machine.kernel", "machine.commit", "machine.date"):
        text(d, k)
    number(d, "machine.nproc")
    for k in ("p50_ns", "p99_ns", "p999_ns", "max_ns", "allocations", "allocations_per_cycle",
              "gbench_cycle_cpu_ns", "paced_p50_ns", "paced_p99_ns", "paced_publisher_thread_p50_ns",
              "paced_publisher_thread_p99_ns", "sim_source_read_p50_ns"):
        number(d, "cycle." + k)
    for k in ("palm_fk_exodaq_ns", "palm_fk_kdl_ns", "palm_fk_ratio", "fk_jac_manip_exodaq_ns",
              "fk_jac_manip_kdl_ns", "fk_jac_manip_ratio"):
        number(d, "kinematics." + k)
    policies = {"SCHED_OTHER": "other", "SCHED_FIFO": "fifo"}
    pols = [policies[p] for p in get(d, "policies")]
    if "other" not in pols:
        fail("no SCHED_OTHER runs")
    q = ("p50_us", "p99_us", "p999_us", "max_us")
    for p in pols:
        for who in ("daemon", "cyclictest", "ratio"):
            for k in q:
                number(d, f"lateness.{p}.{who}.{k}")
        for who in ("daemon_from_deadline", "daemon_from_mono_ns", "reference_from_send",
                    "reference_from_deadline"):
            for k in q + ("loss",):
                number(d, f"e2e.{p}.{who}.{k}")
        for k in ("added_p50_us", "added_p50_vs_reference_deadline_us",
                  "sim_sample_to_deadline_offset_us", "in_loop_work_p50_us", "in_loop_work_p99_us",
                  "daemon_messages_per_cycle", "cpu_us_per_message", "reference_cpu_us_per_message"):
            number(d, f"e2e.{p}.{k}")
        for span in ("cycle", "sendmsg", "sem_post", "work"):
            for k in ("p50_us", "p99_us", "mean_us"):
                number(d, f"e2e.{p}.loop_spans.{span}.{k}")
        for who in ("resources", "reference_resources"):
            for k in ("cpu_percent", "rss_mib", "ctx_per_s", "ctx_voluntary_per_s",
                      "ctx_involuntary_per_s"):
                number(d, f"e2e.{p}.{who}.{k}")
    rates = [number(d, f"scaling.rate.{i}.rate_hz") for i in range(len(get(d, "scaling.rate")))]
    subs = [number(d, f"scaling.subscribers.{i}.subscribers")
            for i in range(len(get(d, "scaling.subscribers")))]
    if rates != [250, 1000, 2000, 4000] or subs != [1, 4, 16]:
        fail(f"scaling points {rates} / {subs}")
    for group, n in (("rate", 4), ("subscribers", 3)):
        for i in range(n):
            for k in ("cpu_percent", "ctx_per_s", "work_p50_us", "work_p99_us", "e2e_from_deadline_p50_us"):
                number(d, f"scaling.{group}.{i}.{k}")
    if not isinstance(get(d, "replay.available"), bool):
        fail("replay.available is not a boolean")
    if get(d, "replay.available"):
        number(d, "replay.speed_x")
    judged = check_verdicts(d)
    print(f"check_performance_json: {sys.argv[1]} complete ({', '.join(pols)}; {judged} verdicts)")


if __name__ == "__main__":
    main()
