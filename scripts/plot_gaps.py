#!/usr/bin/python3
"""Plot for `fabrik eval gaps`: the worst markers' withheld vs live and offline filled traces.

Usage: scripts/plot_gaps.py GAPS.csv OUT.png [--window 1] [--worst 4] [--markers a,b]
GAPS.csv is what `fabrik eval gaps --csv` writes (marker,mode,window_s,start_frame,frame,...).
The markers are those with the largest live RMS at that gap length (or the named ones); each
panel shows the vertical coordinate of the real marker (black), the live prediction (red,
dashed) and the offline two-sided fill (blue, dotted), every window withheld separately.
Debian's python3-matplotlib.
"""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

STYLE = {"live": ("tab:red", "--", "live prediction"),
         "offline": ("tab:blue", ":", "offline two-sided fill")}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("csv")
    p.add_argument("out")
    p.add_argument("--window", type=float, default=1.0)
    p.add_argument("--worst", type=int, default=4)
    p.add_argument("--markers", help="comma-separated names (default: the worst live ones)")
    a = p.parse_args()
    rows = [r for r in csv.DictReader(open(a.csv)) if float(r["window_s"]) == a.window]
    if not rows:
        raise SystemExit(f"{a.csv}: no rows for {a.window:g} s gaps")
    if a.markers:
        markers = a.markers.split(",")
    else:
        sq = {}
        for r in rows:
            if r["mode"] == "live":
                s = sq.setdefault(r["marker"], [0.0, 0])
                s[0] += float(r["error_mm"]) ** 2
                s[1] += 1
        rms = {m: math.sqrt(s / n) for m, (s, n) in sq.items()}
        markers = sorted(rms, key=rms.get, reverse=True)[: a.worst]
    fig, axes = plt.subplots(len(markers), 1, figsize=(8, 2.0 * len(markers)), sharex=True,
                             squeeze=False)
    axes = [ax for (ax,) in axes]
    for ax, marker in zip(axes, markers):
        mine = [r for r in rows if r["marker"] == marker]
        for start in sorted({r["start_frame"] for r in mine}, key=int):
            for mode, (color, ls, _) in STYLE.items():
                w = [r for r in mine if r["start_frame"] == start and r["mode"] == mode]
                if not w:
                    continue
                t = [float(r["time_s"]) for r in w]
                if mode == "live":
                    # The vertical axis (Y up in these files) shows the motion best.
                    ax.plot(t, [float(r["real_y_mm"]) for r in w], color="k", lw=1.2)
                    ax.axvline(t[0], color="grey", lw=0.5)
                ax.plot(t, [float(r["pred_y_mm"]) for r in w], color=color, lw=1.0, ls=ls)
        ax.set_ylabel(marker + "\ny (mm)", fontsize=8)
    axes[0].plot([], [], color="k", label="withheld real marker")
    for color, ls, label in STYLE.values():
        axes[0].plot([], [], color=color, ls=ls, label=label)
    axes[0].legend(fontsize=7, loc="upper right")
    axes[0].set_title(f"{a.window:g} s gaps, worst markers: each window withheld separately")
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(a.out, dpi=90)


if __name__ == "__main__":
    main()
