#!/usr/bin/env python3
"""Residual figure of `exodaq calibrate` (seed 000 Figs. 13-14 in spirit).

Usage: plot_residuals.py RESIDUALS.csv OUT.png

The CSV is written by `exodaq calibrate --plot`: one row per calibration point
with the 3-D position error before and after calibration, for the training set
and every --validate file.
"""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    sets = {}
    with open(argv[1], newline="") as f:
        for row in csv.DictReader(f):
            s = sets.setdefault(row["set"], {"before": [], "after": [], "xyz": []})
            s["before"].append(float(row["before_mm"]))
            s["after"].append(float(row["after_mm"]))
            s["xyz"].append((float(row["after_x_mm"]), float(row["after_y_mm"]), float(row["after_z_mm"])))

    fig, axes = plt.subplots(2, 2, figsize=(12, 8))
    ax = axes[0][0]
    train = sets.get("training")
    if train:
        ax.plot(train["before"], ".", ms=3, label="before")
        ax.plot(train["after"], ".", ms=3, label="after")
        ax.set_yscale("log")
    ax.set_xlabel("training point")
    ax.set_ylabel("3-D position error [mm]")
    ax.set_title("Training set: error before / after calibration")
    ax.legend()

    ax = axes[0][1]
    data = [s["after"] for s in sets.values()]
    ax.boxplot(data, labels=list(sets.keys()), showfliers=True)
    ax.set_ylabel("3-D position error after [mm]")
    ax.set_title("Training and cross-validation (seed 000 Fig. 14)")

    ax = axes[1][0]
    if train:
        ax.hist(train["after"], bins=40)
    ax.set_xlabel("3-D position error after [mm]")
    ax.set_ylabel("points")
    ax.set_title("Training residual distribution")

    ax = axes[1][1]
    if train:
        for k, name in enumerate("xyz"):
            ax.plot([v[k] for v in train["xyz"]], ".", ms=2, label=name)
    ax.set_xlabel("training point")
    ax.set_ylabel("residual after [mm] (measured - model)")
    ax.set_title("Residual components (camera frame)")
    ax.legend()

    fig.tight_layout()
    fig.savefig(argv[2], dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
