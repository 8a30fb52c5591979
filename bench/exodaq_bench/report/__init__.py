"""performance.json -> performance.md and performance.png. Measures nothing: every
figure comes from the JSON, every target and verdict from targets.py / the JSON."""
import os

from . import cycle, daemon, parts, summary
from .plot import plot


def markdown(res, png_name):
    L = summary.intro(res) + summary.machine_table(res) + summary.summary(res)
    L += cycle.section(res)
    L += parts.kinematics(res)
    L += daemon.lateness(res) + daemon.e2e(res) + daemon.resources(res) + daemon.scaling(res, png_name)
    L += parts.replay(res)
    L += parts.hand_measured()
    return "\n".join(L).rstrip() + "\n"


def write(res, out_dir):
    """Writes out_dir/performance.md and, when res has the scaling part and matplotlib is
    there, out_dir/performance.png. Returns the paths written."""
    written = []
    png = None
    if "scaling" in res and plot(res, os.path.join(out_dir, "performance.png")):
        png = "performance.png"
        written.append(os.path.join(out_dir, png))
    md = os.path.join(out_dir, "performance.md")
    with open(md, "w", encoding="utf-8") as f:
        f.write(markdown(res, png))
    return [md] + written
