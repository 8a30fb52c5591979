"""Formatting shared by the report's sections."""
import os
import re

from .. import targets

PLACEHOLDER = re.compile(r"\{([\w.|]+)(?::([^}]*))?\}")
PROSE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "prose")


def fmt(x, nd=1, unit=""):
    if x is None:
        return "—"
    if isinstance(x, float):
        return f"{x:.{nd}f}{unit}"
    return f"{x}{unit}"


def render(template, block, **extra):
    """A targets.Row template filled from block (see targets' docstring)."""
    def one(m):
        name, spec = m.group(1), m.group(2) or ""
        value = extra[name] if name in extra else targets.lookup(block, name)
        return "—" if value is None else format(value, spec)
    return PLACEHOLDER.sub(one, template)


def verdict_word(v):
    """'met', '**missed**' or '—' (not measured), with the verdict's note."""
    if v is None or v["met"] is None:
        return "—"
    word = "met" if v["met"] else "**missed**"
    return f"{word} ({v['note']})" if v.get("note") else word


def verdict(res, row_id, policy=None):
    """The verdict of res for a row (and policy), or None."""
    for v in res.get("verdicts", []):
        if v["id"] == row_id and v["policy"] == policy:
            return v
    return None


def prose(name):
    """report/prose/NAME.md with every {target:ID} replaced by that target's text (a
    caller may fill the rest with render())."""
    with open(os.path.join(PROSE, name + ".md"), encoding="utf-8") as f:
        text = f.read()
    return re.sub(r"\{target:(\w+)\}", lambda m: targets.text(m.group(1)), text).rstrip() + "\n"


def rt_e2e(res):
    """The e2e block of the loop's production policy: SCHED_FIFO, else SCHED_OTHER."""
    e2e = res.get("e2e") or {}
    return e2e.get("fifo") or e2e.get("other")
