"""Every target the benchmarks hold exodaq to, written once, as data, each with the row
of performance.md's summary table that shows it. The runner judges the rows into
performance.json ("targets", "verdicts"); the report, the plot and the CI check
(tests/bench/check_performance_json.py) read them from here and nowhere else.

Sources: the design notes' Budgets and the performance issue (issue 10).

Adding a judged figure is one Row in ROWS: the part (performance.json's top-level
key) must produce the figure; the row names it by a dotted path into the part's
dict (per policy when policies="each"), and says how the summary shows it.
Templates: "{path:spec}" formats the value at the path ("—" when it is missing),
"{path|us:spec}" through a FILTERS entry first, "{figure:spec}" the judged figure,
"{policy}" the policy of a per-policy block."""
import math
from dataclasses import dataclass

SYMBOLS = {"<=": "≤", ">=": "≥", "<": "<", "==": "="}


@dataclass(frozen=True)
class Target:
    op: str            # "<=", ">=", "<", "=="
    limit: float
    unit: str = ""     # printed right after the number: "×", " µs", " MiB"
    sign: str = ""     # "+" for a difference from the reference
    of: str = ""       # what a relative target is relative to

    def text(self):
        number = f"{self.sign}{self.limit:g}{self.unit}"
        head = number if self.op == "==" else f"{SYMBOLS[self.op]} {number}"
        return f"{head} {self.of}".rstrip()

    def met(self, value):
        if value is None or isinstance(value, bool) or not math.isfinite(value):
            return None
        return {"<=": value <= self.limit, ">=": value >= self.limit,
                "<": value < self.limit, "==": value == self.limit}[self.op]


@dataclass(frozen=True)
class Ratio:
    """A figure that is the ratio of two paths of the same block."""
    numerator: str
    denominator: str


@dataclass(frozen=True)
class Row:
    id: str
    part: str                # performance.json's key: cycle, kinematics, lateness, e2e, ...
    what: str                # the summary's "figure" column
    figure: object           # the judged figure: a dotted path (optionally |filter) or a Ratio
    target: Target
    exodaq: str              # template of the "exodaq" column
    reference: str = "—"     # template of the "reference (same run)" column
    compared: str = "—"      # template of the "ratio / difference" column
    policies: str = ""       # "": the part is one block; "each": one row per policy;
                             # "rt": the SCHED_FIFO block, else SCHED_OTHER
    note: str = ""           # added to the verdict, e.g. which of two figures is judged
    pending: str = ""        # why the figure is not measured yet (its verdict may be empty)


FILTERS = {
    "us": lambda ns: ns / 1000,                # ns -> µs
    "pct_of_1ms": lambda ns: ns / 1e4,         # ns -> % of the 1 kHz period
}

# The design notes: "a few microseconds" per cycle; issue 10: in-loop work p99 <= 5 µs.
IN_LOOP_P99 = Target("<=", 5, " µs")

ROWS = [
    Row("cycle_hot_p99", "cycle", "whole cycle back to back, p50 / p99 (harness, sim source)",
        "p99_ns|us", IN_LOOP_P99,
        exodaq="{p50_ns|us:.2f} / {p99_ns|us:.2f} µs", reference="— (1000 µs period)",
        compared="{p99_ns|pct_of_1ms:.2f} % of the period at p99"),
    Row("cycle_paced_p99", "cycle",
        "whole cycle paced at 1 kHz with the publisher thread, p50 / p99 (harness)",
        "paced_publisher_thread_p99_ns|us", IN_LOOP_P99,
        exodaq="{paced_publisher_thread_p50_ns|us:.2f} / {paced_publisher_thread_p99_ns|us:.2f} µs",
        reference="same, ring drained inline: {paced_p50_ns|us:.2f} / {paced_p99_ns|us:.2f} µs"),
    Row("in_loop_work_p99", "e2e", "whole cycle inside exodaqd, p50 / p99 ({policy}, status_t)",
        "in_loop_work_p99_us", IN_LOOP_P99, policies="rt",
        exodaq="{in_loop_work_p50_us:.2f} / {in_loop_work_p99_us:.2f} µs"),
    Row("allocations", "cycle", "heap allocations per cycle (loop thread, harness)",
        "allocations", Target("==", 0),
        exodaq="{allocations} in {cycles} cycles"),
    Row("palm_fk", "kinematics", "palm FK", "palm_fk_ratio", Target("<=", 0.4, "×", of="KDL"),
        exodaq="{palm_fk_exodaq_ns:.1f} ns", reference="KDL {palm_fk_kdl_ns:.1f} ns",
        compared="{figure:.2f}×"),
    Row("fk_jac_manip", "kinematics", "FK + Jacobian + manipulability", "fk_jac_manip_ratio",
        Target("<=", 0.35, "×", of="KDL"),
        exodaq="{fk_jac_manip_exodaq_ns:.1f} ns", reference="KDL {fk_jac_manip_kdl_ns:.1f} ns",
        compared="{figure:.2f}×"),
    Row("lateness_p99", "lateness", "wake-up lateness p99, {policy}", "ratio.p99_us",
        Target("<=", 1.2, "×", of="cyclictest"), policies="each",
        exodaq="{daemon.p99_us:.1f} µs", reference="cyclictest {cyclictest.p99_us:.1f} µs",
        compared="{figure:.2f}×"),
    # Issue 17: both from their own loop deadline (each then includes its wake-up).
    Row("e2e_added_p50", "e2e", "end-to-end p50, {policy} (loop deadline → subscriber)",
        "added_p50_vs_reference_deadline_us",
        Target("<=", 10, " µs", sign="+", of="over the bare publisher"), policies="each",
        exodaq="{daemon_from_deadline.p50_us:.1f} µs",
        reference="bare LCM publisher (its deadline → subscriber) {reference_from_deadline.p50_us:.1f} µs",
        compared="{figure:+.1f} µs"),
    Row("cpu", "e2e", "CPU at 1 kHz, {policy}",
        Ratio("resources.cpu_percent", "reference_resources.cpu_percent"),
        Target("<=", 1.5, "×", of="the bare publisher"), policies="each",
        exodaq="{resources.cpu_percent:.2f} % of one core",
        reference="bare publisher {reference_resources.cpu_percent:.2f} %", compared="{figure:.2f}×"),
    # Issue 17: exodaqd sends three messages per cycle (+ status at 10 Hz), the reference one.
    Row("cpu_per_message", "e2e", "CPU per message published at 1 kHz, {policy}",
        Ratio("cpu_us_per_message", "reference_cpu_us_per_message"),
        Target("<=", 1.5, "×", of="the bare publisher"), policies="each",
        exodaq="{cpu_us_per_message:.1f} µs ({daemon_messages_per_cycle:.2f} messages per cycle)",
        reference="bare publisher {reference_cpu_us_per_message:.1f} µs (1 per cycle)",
        compared="{figure:.2f}×"),
    Row("rss", "e2e", "RSS at 1 kHz, {policy}", "resources.rss_mib", Target("<=", 16, " MiB"),
        policies="each", exodaq="{resources.rss_mib:.1f} MiB",
        reference="bare publisher {reference_resources.rss_mib:.1f} MiB"),
    # Issue 17: whole process, CPU time, one core; RSS bounded whatever the length.
    Row("replay_speed", "replay",
        "replay at `--speed max` (full pipeline + log writing), whole process, CPU time / wall",
        "process_cpu_speed_x", Target(">=", 1000, "×", of="real time"),
        note="whole process, CPU time",
        exodaq="{process_cpu_speed_x:.0f}× / {process_wall_speed_x:.0f}× real time",
        reference="real time (1×); cycle loop CPU / wall {loop_cpu_speed_x:.0f}× / "
                  "{loop_wall_speed_x:.0f}×"),
    Row("replay_rss", "replay",
        "replay at `--speed max`, peak RSS of the process, 10- and 60-minute recordings",
        "rss_mib", Target("<", 64, " MiB"), note="the larger of the two",
        exodaq="{rss_short_mib:.1f} MiB ({minutes:g} min) / {rss_long_mib:.1f} MiB "
               "({rss_long_min:g} min)"),
]

BY_ID = {row.id: row for row in ROWS}


def text(row_id):
    """The target of a row as prose writes it: "≤ 1.2× cyclictest"."""
    return BY_ID[row_id].target.text()


def lookup(block, path):
    """The value at a dotted path of block, through a "|filter"; None when missing."""
    path, _, flt = path.partition("|")
    cur = block
    for key in path.split("."):
        if not isinstance(cur, dict) or cur.get(key) is None:
            return None
        cur = cur[key]
    return FILTERS[flt](cur) if flt else cur


def figure(row, block):
    if isinstance(row.figure, Ratio):
        a, b = lookup(block, row.figure.numerator), lookup(block, row.figure.denominator)
        return round(a / b, 3) if a is not None and b else None
    return lookup(block, row.figure)


def blocks(res, row):
    """[(policy name or None, block)] the row is judged on; [] when the part did not run."""
    part = res.get(row.part)
    if not part:
        return []
    if row.policies == "each":
        return [(b.get("policy"), b) for b in part.values()]
    if row.policies == "rt":
        b = part.get("fifo") or part.get("other")
        return [(b.get("policy"), b)] if b else []
    return [(None, part)]


def evaluate(res):
    """performance.json's "verdicts": one per row and block."""
    out = []
    for row in ROWS:
        for policy, block in blocks(res, row):
            value = figure(row, block)
            met = row.target.met(value)
            note = row.note if met is not None else (block.get("note") or row.pending or "not measured")
            out.append({"id": row.id, "policy": policy, "what": row.what.replace("{policy}", policy or ""),
                        "figure": value, "target": row.target.text(), "met": met, "note": note or None})
    return out


def as_json():
    """performance.json's "targets": {row id: the target as data and as text}."""
    return {row.id: {"part": row.part, "what": row.what, "op": row.target.op, "limit": row.target.limit,
                     "unit": row.target.unit.strip(), "text": row.target.text(),
                     **({"pending": row.pending} if row.pending else {})}
            for row in ROWS}
