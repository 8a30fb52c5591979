"""The report's sections on kinematics and replay: the method in the words of the
benchmark's owner (prose/*.md), with this run's figures."""
import dataclasses
import re

from .. import targets
from .fmt import PLACEHOLDER, fmt, prose, render, verdict

# The line of prose/kinematics.md's table that stands for the figures the table does
# not name: a benchmark added to bench_kinematics.cpp shows up without an edit.
UNLISTED = "{unlisted}"


def measured_when(res, part):
    """(commit, reused): the commit of the run that measured a part, and whether that was
    an earlier run (--reuse keeps older parts; the machine table names it)."""
    ru = res.get("reused") or {}
    if part in ru.get("parts", []):
        return ru["from_commit"], True
    return res["machine"]["commit"], False


def kinematics_unlisted(k, named):
    """Table rows for the figures of k that the prose's table does not name: each
    exodaq/KDL pair (with its target when targets.py has one), then the benchmarks
    without a KDL counterpart."""
    rows = {r.figure: r for r in targets.ROWS if r.part == "kinematics"}
    out = []
    for key in (k2 for k2 in k if k2.endswith("_ratio") and k2 not in named):
        name = key[: -len("_ratio")]
        row = rows.get(key)
        label = row.what if row else f"`{name}`"
        out.append(f"| {label} | — | — | {fmt(k.get(name + '_exodaq_ns'), 1, ' ns')}, KDL "
                   f"{fmt(k.get(name + '_kdl_ns'), 1, ' ns')} | **{fmt(k[key], 2)}** | "
                   f"{row.target.text() if row else '—'} |")
    for key, value in k.items():
        m = re.fullmatch(r"(\w+)_ns", key)
        if m and not key.endswith(("_exodaq_ns", "_kdl_ns")) and key not in named:
            out.append(f"| `{m.group(1)}` | — | — | {fmt(value, 1, ' ns')} | — | — |")
    return out


def kinematics(res):
    """prose/kinematics.md, its table's `bench/run` columns filled from this run."""
    k = res.get("kinematics")
    if not k:
        return []
    commit, reused = measured_when(res, "kinematics")
    run = f"`bench/run` on commit {commit}" + (" (an earlier run)" if reused else "") \
        + (" (quick: one short repetition)" if res["quick"] else "")
    text = prose("kinematics")
    named = {m.group(1).partition("|")[0] for m in PLACEHOLDER.finditer(text)}
    lines = []
    for line in text.split("\n"):
        lines += kinematics_unlisted(k, named) if line == UNLISTED else [line]
    return [render("\n".join(lines), k, run=run)]


def target_head(row):
    """A row's target without what it is relative to: "≥ 1000×"."""
    return dataclasses.replace(row.target, of="").text()


def met_word(met):
    return {True: "met", False: "missed", None: "not judged"}[met]


def replay_table(res, rp):
    speed, rss = targets.BY_ID["replay_speed"], targets.BY_ID["replay_rss"]
    v = verdict(res, "replay_speed")
    L = ["| figure | CPU time | wall | target |", "|---|---|---|---|",
         f"| whole process | **{fmt(rp['process_cpu_speed_x'], 0, '×')}** real time | "
         f"{fmt(rp['process_wall_speed_x'], 0, '×')} | {target_head(speed)} (CPU time): "
         f"{met_word(v['met'] if v else None)} |",
         f"| cycle loop | {fmt(rp['loop_cpu_speed_x'], 0, '×')} | {fmt(rp['loop_wall_speed_x'], 0, '×')} | — |"]
    if rp.get("rss_mib") is None:
        return L + [f"| peak RSS | not measured ({rss.pending or rp.get('note')}) | | {rss.target.text()} |", ""]
    for mib, minutes in ((rp["rss_short_mib"], rp["minutes"]), (rp["rss_long_mib"], rp["rss_long_min"])):
        L.append(f"| peak RSS, {minutes:g}-minute recording | {fmt(mib, 1, ' MiB')} | | "
                 f"{rss.target.text()}: {met_word(rss.target.met(mib))} |")
    return L + [""]


def replay(res):
    """prose/replay.md (the method), this run's table, prose/replay_comparisons.md."""
    rp = res.get("replay")
    if rp is None:
        return []
    L = [prose("replay")]
    if not rp.get("available"):
        return L + [f"*Not measured in this run:* {rp.get('note')}.\n", prose("replay_comparisons")]
    cycles = f"{rp['cycles']:,}".replace(",", " ")
    commit, reused = measured_when(res, "replay")
    where = "an earlier run, see the machine table" if reused else "the machine above"
    L += [f"This run (`bench/run` part `replay` on commit {commit}, {where}; median of {rp['runs']} runs of",
          f"{cycles} cycles; command `{rp['command']}`):\n"]
    return L + replay_table(res, rp) + [prose("replay_comparisons")]


# Sections measured by hand with their own tools, kept verbatim (prose/NAME.md).
HAND_MEASURED = ["lab_network", "ik_and_trajectories"]


def hand_measured():
    return [prose(name) for name in HAND_MEASURED]
