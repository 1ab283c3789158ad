#!/usr/bin/python3
"""Knee, hip and ankle flexion over a walk from an OpenSim Coordinates file (.mot).

Usage: scripts/plot_gait_angles.py WALK.mot OUT.png [--title T]
WALK.mot is what `fabrik solve --angles` or `fabrik eval imu --angles` writes (Gait2354 names:
hip_flexion_r/l, knee_angle_r/l, negative in flexion and drawn as flexion, ankle_angle_r/l).
Debian's python3-matplotlib.
"""
import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_mot(path):
    text = open(path).read().split("endheader\n", 1)[1].strip().split("\n")
    cols = text[0].split("\t")
    rows = [[float(x) for x in line.split("\t")] for line in text[1:]]
    return {c: [r[i] for r in rows] for i, c in enumerate(cols)}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("mot")
    p.add_argument("out")
    p.add_argument("--title", default="Joint angles")
    a = p.parse_args()
    c = read_mot(a.mot)
    panels = [("hip_flexion", "hip flexion (+) / extension", 1), ("knee_angle", "knee flexion", -1),
              ("ankle_angle", "ankle dorsiflexion (+) / plantarflexion", 1)]
    fig, axes = plt.subplots(len(panels), 1, figsize=(11, 7), sharex=True)
    for ax, (name, label, sign) in zip(axes, panels):
        for side, colour in (("r", "tab:red"), ("l", "tab:blue")):
            ax.plot(c["time"], [sign * v for v in c[f"{name}_{side}"]], colour, lw=0.8,
                    label="right" if side == "r" else "left")
        ax.set_ylabel(label + " (deg)", fontsize=8)
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8)
    axes[0].set_title(a.title)
    axes[-1].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)


if __name__ == "__main__":
    main()
