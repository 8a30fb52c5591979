#!/usr/bin/env python3
"""Figures of an exodaq recording from the CSV of `exodaq export`.

In the spirit of seed 000: Fig. 16 (joint-space trajectories), Fig. 17 (the
palm's path in 3D in the base frame O0-x0y0z0 of Fig. 5) and Fig. 18 (the
normalised shoulder manipulability over time). Cycles whose palm pose is not
valid (unhomed joint, joint fault, missing or partial sample, source or clock
problem) are shaded in the time plots and drawn in grey in the 3D path.

Usually run by `exodaq plot LOG --out DIR`; by hand:
  /usr/bin/python3 exodaq_plot.py --csv cycles.csv --out DIR
Needs numpy and matplotlib (Debian: python3-numpy python3-matplotlib).
"""
import argparse
import csv
import math
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

MAX_POINTS = 200_000  # line plots are decimated beyond this many cycles

FIGURES = ("joint_trajectories.png", "palm_path_3d.png", "shoulder_manipulability.png")


def read_csv(path):
    with open(path, newline="") as f:
        reader = csv.reader(f)
        header = next(reader)
        col = {name: i for i, name in enumerate(header)}
        rows = list(reader)
    if not rows:
        raise SystemExit(f"{path}: no rows")

    def column(name, empty=math.nan):
        i = col[name]
        return np.array([float(r[i]) if r[i] != "" else empty for r in rows])

    data = {name: column(name) for name in header}
    return data, len(rows)


def invalid_spans(t, valid):
    """[(t0, t1)] of consecutive invalid cycles."""
    bad = ~valid
    if not bad.any():
        return []
    edges = np.flatnonzero(np.diff(np.concatenate(([0], bad.astype(np.int8), [0]))))
    spans = []
    for start, stop in zip(edges[0::2], edges[1::2]):
        t0 = t[start]
        t1 = t[stop] if stop < len(t) else t[-1]
        spans.append((t0, t1))
    return spans


def shade(ax, spans, label=True):
    for k, (t0, t1) in enumerate(spans):
        ax.axvspan(t0, t1, color="0.85", lw=0, zorder=0,
                   label="palm pose invalid" if (label and k == 0) else None)


def decimate(n):
    return max(1, n // MAX_POINTS)


def joint_plot(d, t, spans, names, out, title):
    fig, axes = plt.subplots(6, 1, figsize=(9, 11), sharex=True)
    step = decimate(len(t))
    for i, ax in enumerate(axes):
        q = np.degrees(d[f"position_{i}"])
        shade(ax, spans, label=(i == 0))
        ax.plot(t[::step], q[::step], lw=1.0, color=f"C{i}")
        name = names[i] if i < len(names) and names[i] else f"joint {i + 1}"
        ax.set_ylabel(f"θ{i + 1} (deg)")
        ax.set_title(f"joint {i + 1}: {name}", fontsize=9, loc="left")
        ax.grid(True, lw=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(f"Joint-space trajectory\n{title}", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(out, FIGURES[0]), dpi=110)
    plt.close(fig)


def palm_plot(d, valid, out, title):
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    p = np.column_stack((d["palm_x"], d["palm_y"], d["palm_z"])) * 1000.0  # mm
    have = np.isfinite(p).all(axis=1)
    step = decimate(len(p))
    good = valid & have
    bad = (~valid) & have
    if bad.any():
        pb = p[bad][::step]
        ax.scatter(pb[:, 0], pb[:, 1], pb[:, 2], s=1, color="0.7", label="invalid")
    if good.any():
        # Break the line where the pose is invalid so no false segment is drawn.
        pg = np.where(good[:, None], p, np.nan)[::step]
        ax.plot(pg[:, 0], pg[:, 1], pg[:, 2], lw=1.0, color="C0", label="palm path (valid)")
        first = np.flatnonzero(good)[0]
        last = np.flatnonzero(good)[-1]
        ax.scatter(*p[first], color="green", s=30, label="start")
        ax.scatter(*p[last], color="red", s=30, label="end")
    # Base frame O0-x0y0z0 (seed 000 Fig. 5).
    pts = p[have]
    span = float(np.nanmax(np.abs(pts))) if pts.size else 100.0
    axis_len = max(0.25 * span, 20.0)
    for vec, color, name in (((1, 0, 0), "r", "x0"), ((0, 1, 0), "g", "y0"), ((0, 0, 1), "b", "z0")):
        ax.quiver(0, 0, 0, *(axis_len * np.array(vec)), color=color, lw=1.5,
                  arrow_length_ratio=0.15)
        ax.text(*(1.1 * axis_len * np.array(vec)), name, color=color)
    ax.text(0, 0, 0, "O0", color="k")
    if pts.size:
        lo = np.minimum(pts.min(axis=0), 0.0)
        hi = np.maximum(pts.max(axis=0), 0.0)
        centre = (lo + hi) / 2
        half = max(float((hi - lo).max()) / 2, axis_len)
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_xlabel("x0 (mm)")
    ax.set_ylabel("y0 (mm)")
    ax.set_zlabel("z0 (mm)")
    ax.legend(loc="upper left", fontsize=8)
    ax.set_title(f"Palm path in the base frame O0\n{title}", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(out, FIGURES[1]), dpi=110)
    plt.close(fig)


def manipulability_plot(d, t, spans, out, title):
    fig, ax = plt.subplots(figsize=(9, 4))
    m = d["manipulability"]
    step = decimate(len(t))
    shade(ax, spans)
    ax.plot(t[::step], m[::step], lw=1.0, color="C0", label="normalised shoulder manipulability")
    near = d["near_singular"] == 1
    if near.any():
        ax.scatter(t[near][::step], m[near][::step], s=2, color="C3", label="near singular")
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("w / w_max")
    ax.grid(True, lw=0.3)
    ax.legend(loc="lower right", fontsize=8)
    ax.set_title(f"Normalised shoulder manipulability\n{title}", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(out, FIGURES[2]), dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--csv", required=True, help="CSV written by `exodaq export`")
    ap.add_argument("--out", required=True, help="directory for the PNG files")
    ap.add_argument("--title", default="", help="subtitle (e.g. the log file)")
    ap.add_argument("--joint-names", default="", help="comma-separated joint names")
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    d, n = read_csv(a.csv)
    t = (d["utime"] - d["utime"][0]) * 1e-6
    valid = d["valid"] == 1  # empty (no palm message) counts as invalid
    spans = invalid_spans(t, valid)
    names = [s for s in a.joint_names.split(",")] if a.joint_names else []
    title = os.path.basename(a.title) if a.title else os.path.basename(a.csv)
    joint_plot(d, t, spans, names, a.out, title)
    palm_plot(d, valid, a.out, title)
    manipulability_plot(d, t, spans, a.out, title)
    print(f"exodaq_plot: {n} cycles, {int(valid.sum())} valid, {len(spans)} invalid span(s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
