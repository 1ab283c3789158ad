#!/usr/bin/python3
"""Draws the final postures of `fabrik bench paper --json` side by side, like
Figure 2 of Moya & Colloud (2013), in 3D: one row for the free joints and, if
the run has one, a second row with range-of-motion limits. Titles carry the
run's own times and ratios.

usage: plot_paper_figure.py PAPER.json OUT.png
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

PANELS = [
    ("fabrik", "FABRIK, no priorities"),
    ("fabrik_prioritized", "FABRIK with priorities"),
    ("jacobian_transpose", "Jacobian transpose"),
]
# With limits, JT's own stopping rule does not stop it: show it at FABRIK's accuracy.
LIMIT_PANELS = [
    ("fabrik", "FABRIK, no priorities"),
    ("fabrik_prioritized", "FABRIK with priorities"),
    ("jacobian_transpose_to_fabrik_accuracy", "Jacobian transpose to FABRIK's accuracy"),
]


def xyz(p):
    # Y is up in the model: plot (x, z, y) so the figure stands upright.
    return p[0], p[2], p[1]


def draw_panel(ax, result, algo, title):
    posture = algo["posture"]
    pts = posture["points_m"]
    for seg in posture["segments"]:
        names = seg["points"]
        base = pts[names[0]]
        for other in names[1:]:
            if other in pts:
                xs, ys, zs = zip(xyz(base), xyz(pts[other]))
                ax.plot(xs, ys, zs, "-o", color="tab:blue", lw=3, ms=4)
    targets = result["targets"]
    for t in targets:
        style = "tab:red" if t["level"] == max(x["level"] for x in targets) else "tab:orange"
        x, y, z = xyz(t["position_m"])
        ax.scatter([x], [y], [z], marker="x", s=80, color=style)
        ax.text(x, y, z, f" {t['point']} (level {t['level']})", fontsize=8)
    x, y, z = xyz(result["root_m"])
    ax.scatter([x], [y], [z], marker="s", s=40, color="black")
    err = algo["error_mm"]
    ax.set_title(
        f"{title}\n{algo['median_us']:.1f} us, {algo['iterations']} iterations ({algo['status']})\n"
        + ", ".join(f"{k} {v:.0f} mm" for k, v in err.items()),
        fontsize=9,
    )
    ax.set_xlim(-1.1, 1.1)
    ax.set_ylim(-0.4, 0.8)
    ax.set_zlim(-0.4, 1.1)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("z (m)")
    ax.set_zlabel("y, up (m)")
    ax.view_init(elev=18, azim=-70)


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    with open(argv[1]) as f:
        result = json.load(f)
    rows = [("", result["algorithms"], result["ratios"], PANELS)]
    if "with_limits" in result:
        limits = result["with_limits"]
        rows.append((" (limits)", limits["algorithms"], limits["ratios"], LIMIT_PANELS))
    fig = plt.figure(figsize=(15, 5.6 * len(rows)))
    for r, (suffix, algorithms, ratios, panels) in enumerate(rows):
        for i, (key, title) in enumerate(panels):
            ax = fig.add_subplot(len(rows), 3, 3 * r + i + 1, projection="3d")
            draw_panel(ax, result, algorithms[key], title + suffix)
    ratios = result["ratios"]
    title = (
        "Moya & Colloud (2013) Figure 2 in 3D: both wrists aim at unreachable targets "
        f"(JT/FABRIK {ratios['jt_over_fabrik']:.0f}x, JT/prioritized "
        f"{ratios['jt_over_prioritized']:.0f}x; paper: 25x, 7x)"
    )
    if "with_limits" in result:
        lr = result["with_limits"]["ratios"]
        title += (
            "\nwith elbow hinges and limited shoulders, JT to FABRIK's accuracy: "
            f"{lr['jt_to_fabrik_accuracy_over_fabrik']:.1f}x FABRIK, "
            f"{lr['jt_to_fabrik_accuracy_over_prioritized']:.1f}x prioritized FABRIK"
        )
    fig.suptitle(title, fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 0.93 if len(rows) > 1 else 0.9))
    fig.savefig(argv[2], dpi=80)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
