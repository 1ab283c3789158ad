#!/usr/bin/python3
"""Plots for `fabrik eval angles`: fabrik's coordinates beside the reference's, one panel each.

Usage: scripts/plot_angles.py ANGLES.csv OUT.png [--coordinates a,b,c] [--json ANGLES.json]
ANGLES.csv is what `fabrik eval angles --csv` writes (coordinate,unit,frame,time_s,fabrik,
reference). Each panel shows both curves and, dotted, fabrik's curve shifted by the mean
offset, so the shape can be compared apart from the offset; its title gives Pearson r and the
RMS after removing the offset. Debian's python3-matplotlib.
"""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def stats(fab, ref):
    n = len(fab)
    d = [a - b for a, b in zip(fab, ref)]
    off = sum(d) / n
    rms_off = math.sqrt(sum((x - off) ** 2 for x in d) / n)
    ma, mb = sum(fab) / n, sum(ref) / n
    saa = sum((a - ma) ** 2 for a in fab)
    sbb = sum((b - mb) ** 2 for b in ref)
    sab = sum((a - ma) * (b - mb) for a, b in zip(fab, ref))
    r = sab / math.sqrt(saa * sbb) if saa > 1e-12 and sbb > 1e-12 else float("nan")
    return off, rms_off, r


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("csv")
    p.add_argument("out")
    p.add_argument("--coordinates", help="comma-separated names (default: all, file order)")
    p.add_argument("--title", default="fabrik vs reference")
    a = p.parse_args()
    series = {}
    for row in csv.DictReader(open(a.csv)):
        s = series.setdefault(row["coordinate"], {"unit": row["unit"], "t": [], "fab": [], "ref": []})
        s["t"].append(float(row["time_s"]))
        s["fab"].append(float(row["fabrik"]))
        s["ref"].append(float(row["reference"]))
    names = a.coordinates.split(",") if a.coordinates else list(series)
    missing = [n for n in names if n not in series]
    if missing:
        raise SystemExit("not in %s: %s" % (a.csv, ", ".join(missing)))
    cols = 3
    rows = (len(names) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 2.4 * rows), squeeze=False)
    for i, name in enumerate(names):
        ax = axes[i // cols][i % cols]
        s = series[name]
        off, rms_off, r = stats(s["fab"], s["ref"])
        ax.plot(s["t"], s["ref"], color="black", lw=1.4, label="reference")
        ax.plot(s["t"], s["fab"], color="tab:red", lw=1.2, label="fabrik")
        ax.plot(s["t"], [v - off for v in s["fab"]], color="tab:red", lw=0.9, ls=":",
                label="fabrik - mean offset")
        rtext = "-" if math.isnan(r) else "%.3f" % r
        ax.set_title("%s: r %s, RMS-off %.2f %s" % (name, rtext, rms_off, s["unit"]), fontsize=9)
        ax.set_ylabel(s["unit"], fontsize=8)
        ax.tick_params(labelsize=7)
    for j in range(len(names), rows * cols):
        axes[j // cols][j % cols].axis("off")
    axes[0][0].legend(fontsize=7)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)", fontsize=8)
    fig.suptitle(a.title, fontsize=11)
    fig.tight_layout()
    fig.savefig(a.out, dpi=80)


if __name__ == "__main__":
    main()
