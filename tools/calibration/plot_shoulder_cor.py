#!/usr/bin/env python3
"""Shoulder centre-of-rotation figure of `exodaq shoulder-cor` (seed 001 Table II, Fig. 5).

Usage: plot_shoulder_cor.py BINS.csv OUT.png

The CSV is written by `exodaq shoulder-cor --csv/--plot`: one row per
humerus-elevation bin with the centre of rotation in the torso frame and its
vertical and horizontal motion relative to the first bin, each with its 95 %
confidence half-width (drawn as error bars; a flagged bin is drawn hollow).
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# Seed 001 Table II (macaque): humerus elevation bin (deg) -> CoR vertical motion (mm).
TABLE_II = [((0, 20), 0), ((20, 40), 4), ((40, 60), 13), ((60, 80), 27), ((80, 100), 43), ((100, 120), 62)]


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    bins = []
    with open(argv[1], newline="") as f:
        for row in csv.DictReader(f):
            if row["valid"] == "1":
                bins.append(row)
    if not bins:
        print("plot_shoulder_cor.py: no valid bin in " + argv[1], file=sys.stderr)
        return 1
    # The centre of each bin is at its mean elevation (the moving-centre model).
    mid = [float(b["mean_elevation_deg"]) for b in bins]
    vertical = [float(b["vertical_mm"]) for b in bins]
    horizontal = [float(b["horizontal_mm"]) for b in bins]
    vertical_ci = [float(b.get("vertical_ci95_mm") or 0) for b in bins]
    horizontal_ci = [float(b.get("horizontal_ci95_mm") or 0) for b in bins]
    flagged = [bool(b.get("flags")) for b in bins]

    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    ax = axes[0]
    ax.errorbar(mid, vertical, yerr=vertical_ci, fmt="o-", capsize=4,
                label="this recording (95 % confidence)")
    for x, v, bad in zip(mid, vertical, flagged):
        if bad:
            ax.plot(x, v, "o", markerfacecolor="white", color="tab:red")
    ax.plot([(lo + hi) / 2 for (lo, hi), _ in TABLE_II], [v for _, v in TABLE_II], "s--",
            color="gray", label="seed 001 Table II (macaque)")
    ax.set_xlabel("humerus elevation, the bin's mean [deg]")
    ax.set_ylabel("CoR vertical motion [mm]")
    ax.set_title("Elevation of the shoulder centre")
    ax.grid(True, alpha=0.3)
    ax.legend()

    ax = axes[1]
    ax.plot(horizontal, vertical, "-", color="tab:blue", alpha=0.5)
    for k, (h, v) in enumerate(zip(horizontal, vertical)):
        ax.errorbar(h, v, xerr=horizontal_ci[k], yerr=vertical_ci[k], fmt="o", capsize=3,
                    color="tab:red" if flagged[k] else "tab:blue",
                    markerfacecolor="white" if flagged[k] else "tab:blue")
        ax.annotate(str(int(bins[k]["bin"]) + 1), (h, v), textcoords="offset points", xytext=(6, 4))
    ax.set_xlabel("horizontal motion [mm] (direction of largest spread)")
    ax.set_ylabel("vertical motion [mm]")
    ax.set_title("CoR path by elevation bin (seed 001 Fig. 5)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)

    fig.tight_layout()
    fig.savefig(argv[2], dpi=120)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
