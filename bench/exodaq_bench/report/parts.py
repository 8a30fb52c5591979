"""The report's sections on kinematics and replay: the method in the words of the
benchmark's owner (prose/*.md), then this run's figures."""
import re

from .. import targets
from .fmt import fmt, prose, render


def measured_when(res, part):
    """(commit, date) of the run that measured a part (--reuse keeps older parts)."""
    ru = res.get("reused") or {}
    if part in ru.get("parts", []):
        return ru["from_commit"], ru["from_date"][:10]
    return res["machine"]["commit"], res["machine"]["date"][:10]


def kinematics_figures(k):
    """One phrase per exodaq/KDL pair (with its target when targets.py has one), then
    the benchmarks without a KDL counterpart."""
    rows = {r.figure: r for r in targets.ROWS if r.part == "kinematics"}
    out = []
    for key in (k2 for k2 in k if k2.endswith("_ratio")):
        name = key[: -len("_ratio")]
        row = rows.get(key)
        label = row.what if row else f"`{name}`"
        target = f", target {row.target.text()}" if row else ", no target"
        out.append(f"{label} {fmt(k.get(name + '_exodaq_ns'), 1, ' ns')} vs KDL {fmt(k.get(name + '_kdl_ns'), 1, ' ns')}"
                   f" (**{fmt(k[key], 2, '×')}**{target})")
    for key, value in k.items():
        m = re.fullmatch(r"(\w+)_ns", key)
        if m and not key.endswith(("_exodaq_ns", "_kdl_ns")):
            out.append(f"`{m.group(1)}` {fmt(value, 1, ' ns')}")
    return out


def kinematics(res):
    k = res.get("kinematics")
    if not k:
        return []
    commit, date = measured_when(res, "kinematics")
    how = "one short repetition" if res["quick"] else "median of 10 repetitions"
    return [prose("kinematics"),
            f"*This run ({commit}, {date}; `bench/run` part `kinematics`, CPU time, {how}):* "
            + "; ".join(kinematics_figures(k)) + f". Command: `{k['command']}`.\n"]


def peak_rss(rp):
    row = targets.BY_ID["replay_rss"]
    if rp.get("rss_mib") is None:
        return f"peak RSS not measured ({row.pending or rp.get('note')}; target {row.target.text()})"
    return (render("peak RSS {rss_short_mib:.1f} MiB for that recording, {rss_long_mib:.1f} MiB for "
                   "one of {rss_long_min:g} minutes", rp) + f" (target {row.target.text()})")


def replay(res):
    rp = res.get("replay")
    if rp is None:
        return []
    L = [prose("replay")]
    if not rp.get("available"):
        return L + [f"*Not measured in this run:* {rp.get('note')}.\n"]
    commit, date = measured_when(res, "replay")
    speed = targets.BY_ID["replay_speed"]
    L.append(f"*This run ({commit}, {date}; `bench/run` part `replay`, median of {rp['runs']} runs of "
             f"{rp['cycles']} cycles):* whole process {fmt(rp['process_cpu_speed_x'], 0, '×')} real time "
             f"in CPU time ({fmt(rp['process_wall_speed_x'], 0, '×')} wall), cycle loop "
             f"{rp['loop_cpu_speed_x']:.0f}× CPU ({fmt(rp['loop_wall_speed_x'], 0, '×')} wall); "
             f"target {speed.target.text()} ({speed.note}); {peak_rss(rp)}. Command: `{rp['command']}`.\n")
    return L


# Sections measured by hand with their own tools, kept verbatim (prose/NAME.md).
HAND_MEASURED = ["lab_network"]


def hand_measured():
    return [prose(name) for name in HAND_MEASURED]
