#!/usr/bin/env python3
"""Figures of an exodaq recording from the CSV of `exodaq export`.

In the spirit of seed 000: Fig. 16 (joint-space trajectories), Fig. 17 (the
palm's path in 3D in the base frame O0-x0y0z0 of Fig. 5) and Fig. 18 (the
normalised shoulder manipulability over time). Cycles whose palm pose is not
valid (unhomed joint, joint fault, missing or partial sample, source or clock
problem) are shaded in the time plots and drawn in grey in the 3D path; the
stretches where a joint is not homed yet (its angle is then relative to
power-up, not to its index) are hatched on that joint's axis. The
manipulability plot draws the near-singularity threshold.

The CSV columns are the schema of docs/messages.md: utime_us, <joint>_rad,
<joint>_homed, palm_x_m .. palm_z_m, manipulability, near_singular,
palm_valid, ...

Usually run by `exodaq plot LOG -o DIR`; by hand:
  /usr/bin/python3 exodaq_plot.py --csv cycles.csv --out DIR
Needs numpy and matplotlib (Debian: python3-numpy python3-matplotlib).
Errors are one line on stderr ("exodaq_plot: ...") and exit status 1.
"""
import argparse
import csv
import math
import os
import sys

MAX_POINTS = 200_000  # line plots are decimated beyond this many cycles

FIGURES = ("joint_trajectories.png", "palm_path_3d.png", "shoulder_manipulability.png")


class PlotError(Exception):
    pass


def read_csv(path, np):
    try:
        with open(path, newline="") as f:
            reader = csv.reader(f)
            header = next(reader, None)
            rows = list(reader)
    except OSError as e:
        raise PlotError(f"{path}: {e.strerror}")
    if not header:
        raise PlotError(f"{path}: empty file")
    if not rows:
        raise PlotError(f"{path}: no rows")
    col = {name: i for i, name in enumerate(header)}
    for need in ("utime_us", "palm_valid", "manipulability", "near_singular", "palm_x_m"):
        if need not in col:
            raise PlotError(f"{path}: no column '{need}' (not a CSV of `exodaq export`?)")
    joints = [n[:-len("_rad")] for n in header
              if n.endswith("_rad") and not n.endswith("_vel_rad_s")][:6]
    if len(joints) != 6:
        raise PlotError(f"{path}: expected six <joint>_rad columns, found {len(joints)}")

    def column(name):
        i = col[name]
        return np.array([float(r[i]) if i < len(r) and r[i] != "" else math.nan for r in rows])

    data = {name: column(name) for name in header if name not in ("run_id",)}
    return data, joints, len(rows)


def spans(t, mask, np):
    """[(t0, t1)] of consecutive cycles where mask is true."""
    if not mask.any():
        return []
    edges = np.flatnonzero(np.diff(np.concatenate(([0], mask.astype(np.int8), [0]))))
    out = []
    for start, stop in zip(edges[0::2], edges[1::2]):
        out.append((t[start], t[stop] if stop < len(t) else t[-1]))
    return out


def shade(ax, spans_, label):
    for k, (t0, t1) in enumerate(spans_):
        ax.axvspan(t0, t1, color="0.85", lw=0, zorder=0, label=label if k == 0 else None)


def hatch(ax, spans_, label):
    for k, (t0, t1) in enumerate(spans_):
        ax.axvspan(t0, t1, facecolor="none", edgecolor="C1", hatch="///", lw=0, zorder=0.5,
                   label=label if k == 0 else None)


def decimate(n):
    return max(1, n // MAX_POINTS)


def joint_plot(plt, np, d, t, invalid, joints, names, path, title):
    fig, axes = plt.subplots(6, 1, figsize=(9, 11.5), sharex=True)
    step = decimate(len(t))
    for i, ax in enumerate(axes):
        stem = joints[i]
        q = np.degrees(d[f"{stem}_rad"])
        homed = d.get(f"{stem}_homed")
        shade(ax, invalid, "palm pose invalid")
        if homed is not None:
            hatch(ax, spans(t, homed != 1, np), "not homed (angle from power-up)")
        ax.plot(t[::step], q[::step], lw=1.0, color=f"C{i}")
        name = names[i] if i < len(names) and names[i] else stem
        ax.set_ylabel(f"θ{i + 1} (deg)")
        ax.set_title(f"joint {i + 1}: {name}", fontsize=9, loc="left")
        ax.grid(True, lw=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(loc="upper right", fontsize=7)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle(f"Joint-space trajectory\n{title}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def palm_plot(plt, np, d, valid, path, title):
    fig = plt.figure(figsize=(8, 7))
    ax = fig.add_subplot(projection="3d")
    p = np.column_stack((d["palm_x_m"], d["palm_y_m"], d["palm_z_m"])) * 1000.0  # mm
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
    fig.savefig(path, dpi=110)
    plt.close(fig)


def manipulability_plot(plt, np, d, t, invalid, threshold, path, title):
    fig, ax = plt.subplots(figsize=(9, 4.2))
    m = d["manipulability"]
    step = decimate(len(t))
    shade(ax, invalid, "palm pose invalid")
    ax.plot(t[::step], m[::step], lw=1.0, color="C0", label="normalised shoulder manipulability")
    near = d["near_singular"] == 1
    if near.any():
        ax.scatter(t[near][::step], m[near][::step], s=2, color="C3", label="near singular")
    if threshold is not None:
        ax.axhline(threshold, color="C3", lw=0.8, ls="--",
                   label=f"near-singular threshold {threshold:g} (config)")
    ax.set_ylim(0, 1.05)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("w / w_max")
    ax.grid(True, lw=0.3)
    ax.legend(loc="lower right", fontsize=8)
    note = "" if threshold is not None else "\n(threshold not shown: give the config, -c)"
    ax.set_title(f"Normalised shoulder manipulability\n{title}{note}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def run(a):
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        import numpy as np
    except ImportError as e:
        raise PlotError(f"needs numpy and matplotlib ({e}; Debian: apt install python3-matplotlib)")
    if not os.path.isdir(a.out):
        raise PlotError(f"{a.out}: not a folder")
    d, joints, n = read_csv(a.csv, np)
    t = (d["utime_us"] - d["utime_us"][0]) * 1e-6
    valid = d["palm_valid"] == 1  # empty (no palm message) counts as invalid
    invalid = spans(t, ~valid, np)
    names = a.joint_names.split(",") if a.joint_names else []
    title = a.title or os.path.basename(a.csv)
    jobs = ((FIGURES[0], lambda p: joint_plot(plt, np, d, t, invalid, joints, names, p, title)),
            (FIGURES[1], lambda p: palm_plot(plt, np, d, valid, p, title)),
            (FIGURES[2], lambda p: manipulability_plot(plt, np, d, t, invalid, a.threshold, p,
                                                       title)))
    for name, draw in jobs:
        path = os.path.join(a.out, name)
        try:
            draw(path)
        except OSError as e:
            raise PlotError(f"{path}: cannot write: {e.strerror or e}")
    if not a.quiet:
        print(f"exodaq_plot: {n} cycles, {int(valid.sum())} valid, {len(invalid)} invalid span(s)")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--csv", required=True, help="CSV written by `exodaq export`")
    ap.add_argument("--out", required=True, help="existing folder for the PNG files")
    ap.add_argument("--title", default="", help="subtitle (log, rig, run, calibration)")
    ap.add_argument("--joint-names", default="", help="comma-separated joint names")
    ap.add_argument("--threshold", type=float, default=None,
                    help="near-singularity threshold of the normalised manipulability")
    ap.add_argument("--quiet", action="store_true", help="no summary line")
    a = ap.parse_args(argv)
    try:
        run(a)
    except PlotError as e:
        print(f"exodaq_plot: {e}", file=sys.stderr)
        return 1
    except Exception as e:  # anything else: one line, not a traceback
        print(f"exodaq_plot: {type(e).__name__}: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
