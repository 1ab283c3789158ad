#!/usr/bin/python3
"""Plots for `fabrik eval`: residual over time (walk) and withheld-vs-predicted traces (gaps).

Usage: scripts/plot_eval.py WALK.csv GAPS.csv OUT_DIR [--markers A,B,C] [--window 1]
Writes OUT_DIR/eval_walk.png and OUT_DIR/eval_gaps.png. Debian's python3-matplotlib.
"""
import argparse
import csv
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def plot_walk(path, out):
    rows = list(csv.DictReader(open(path)))
    t = [float(r["time_s"]) for r in rows]
    fig, ax = plt.subplots(figsize=(8, 3.2))
    ax.plot(t, [float(r["rms_mm"]) for r in rows], label="RMS over markers")
    ax.plot(t, [float(r["max_mm"]) for r in rows], label="max over markers")
    ax.plot(t, [float(r["cluster_max_mm"]) for r in rows], ":",
            label="max, each segment's markers fitted alone")
    worst = max(rows, key=lambda r: float(r["max_mm"]))
    ax.annotate(worst["worst_marker"], (float(worst["time_s"]), float(worst["max_mm"])),
                xytext=(5, -5), textcoords="offset points", fontsize=8)
    ax.axhline(25, color="grey", lw=0.8, ls="--")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("marker residual (mm)")
    ax.set_title("subject01_walk1: measured vs model markers per frame")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=90)


def plot_gaps(path, out, markers, window):
    rows = [r for r in csv.DictReader(open(path))
            if float(r["window_s"]) == window and r.get("mode", "live") == "live"]
    fig, axes = plt.subplots(len(markers), 1, figsize=(8, 2.0 * len(markers)), sharex=True)
    for ax, marker in zip(axes, markers):
        mine = [r for r in rows if r["marker"] == marker]
        for start in sorted({r["start_frame"] for r in mine}, key=int):
            w = [r for r in mine if r["start_frame"] == start]
            t = [float(r["time_s"]) for r in w]
            # The vertical axis (Y up in these files) shows the motion best.
            ax.plot(t, [float(r["real_y_mm"]) for r in w], color="k", lw=1.2)
            ax.plot(t, [float(r["pred_y_mm"]) for r in w], color="tab:red", lw=1.0, ls="--")
            ax.axvline(t[0], color="grey", lw=0.5)
        ax.set_ylabel(marker + "\ny (mm)", fontsize=8)
    axes[0].plot([], [], color="k", label="withheld real marker")
    axes[0].plot([], [], color="tab:red", ls="--", label="model's gap-filled position")
    axes[0].legend(fontsize=8, loc="upper right")
    axes[0].set_title(f"{window:g} s gaps: each window withheld separately")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(out, dpi=90)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("walk_csv")
    p.add_argument("gaps_csv")
    p.add_argument("out_dir")
    p.add_argument("--markers", default="R.Heel,L.Wrist.Lat,R.Thigh.Front,Top.Head")
    p.add_argument("--window", type=float, default=1.0)
    a = p.parse_args()
    os.makedirs(a.out_dir, exist_ok=True)
    plot_walk(a.walk_csv, os.path.join(a.out_dir, "eval_walk.png"))
    plot_gaps(a.gaps_csv, os.path.join(a.out_dir, "eval_gaps.png"), a.markers.split(","), a.window)


if __name__ == "__main__":
    main()
