#!/usr/bin/python3
"""Frames at a joint bound: how often each limited joint angle of a calibrated model sits at
(within --tolerance-deg of) the end of its range while `fabrik solve` tracks a trial.

Usage: scripts/joint_bounds.py CONFIG.json TRIAL.trc [--fabrik FABRIK (default: this tree's build, else fabrik on PATH)]
                               [--tolerance-deg 0.5] [--json OUT.json]

CONFIG.json is what `fabrik calibrate` writes. The script adds one coordinate per moving,
limited joint angle (ranges narrower than twice the tolerance hold the angle and are left
out; the Cardan angle of the segment relative to its parent, as the joint's
range is written) to a copy of the config, runs `fabrik solve --angles` on it and reads the
.mot back. It prints, per angle with any frame at a bound, the frames at the lower and upper
bound, the longest run of consecutive frames there, and the largest step into the bound (the
change on a frame it arrived there) beside the angle's 95th-percentile step; then the frames with
any angle at a bound. Standard library only.
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile

LETTERS = ("z", "x", "y")
# Which Cardan angles each joint type lets turn (model format, docs/models.md).
MOVES = {"ball": "zxy", "universal": "zx", "hinge": "z", "fixed": "", "free": ""}


def read_mot(path):
    with open(path) as f:
        lines = f.read().splitlines()
    start = lines.index("endheader") + 1
    names = lines[start].split("\t")
    rows = [[float(x) for x in line.split("\t")] for line in lines[start + 1:] if line.strip()]
    return names, rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("config")
    ap.add_argument("trial")
    # The source tree's build beside this script, else `fabrik` on PATH (an install): the
    # default once depended on the folder it was run from.
    built = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "build", "src", "apps",
                         "fabrik")
    ap.add_argument("--fabrik", default=built if os.access(built, os.X_OK)
                    else shutil.which("fabrik") or built)
    ap.add_argument("--tolerance-deg", type=float, default=0.5)
    ap.add_argument("--json")
    a = ap.parse_args()

    with open(a.config) as f:
        config = json.load(f)
    model = config["model"]
    ranges = {}  # coordinate name -> (segment, letter, lo, hi)
    coords = model.setdefault("coordinates", {})
    for seg in model["segments"]:
        joint = seg.get("joint")
        if not joint:
            continue
        for letter in MOVES.get(joint["type"], ""):
            rng = joint.get("range_deg", {}).get(letter)
            # A range narrower than the tolerance holds the angle: always "at" it.
            if rng is None or rng[1] - rng[0] <= 2 * a.tolerance_deg:
                continue
            name = "bound:%s:%s" % (seg["name"], letter)
            coords[name] = {"segment": seg["name"], "axis": letter}
            ranges[name] = (seg["name"], letter, rng[0], rng[1])
    if not ranges:
        sys.exit("%s: no joint has a range" % a.config)

    with tempfile.TemporaryDirectory() as tmp:
        cfg = os.path.join(tmp, "config.json")
        with open(cfg, "w") as f:
            json.dump(config, f)
        mot = os.path.join(tmp, "angles.mot")
        subprocess.run([a.fabrik, "solve", "--config", cfg, "--input", a.trial, "--output",
                        os.path.join(tmp, "joints.trc"), "--angles", mot, "--quiet"],
                       check=True, stdout=subprocess.DEVNULL)
        names, rows = read_mot(mot)

    tol = a.tolerance_deg
    any_frame = set()
    result = {"frames": len(rows), "tolerance_deg": tol, "angles": {}}
    print("%d frames; an angle within %.2f deg of its range's end is at the bound" % (len(rows), tol))
    print("%-22s %-6s %12s %10s %10s %12s %12s %12s" % ("segment", "angle", "range deg", "at lower",
                                                        "at upper", "longest run", "entry step",
                                                        "p95 step"))
    for name, (seg, letter, lo, hi) in ranges.items():
        col = names.index(name)
        at = [row[col] <= lo + tol or row[col] >= hi - tol for row in rows]
        lower = sum(1 for row in rows if row[col] <= lo + tol)
        upper = sum(1 for row in rows if row[col] >= hi - tol)
        # A jump to a bound: the step on the frame an angle arrives there, against
        # the angle's own steps elsewhere (its 95th percentile).
        steps = sorted(abs(rows[f][col] - rows[f - 1][col]) for f in range(1, len(rows)))
        p95 = steps[int(0.95 * (len(steps) - 1))] if steps else 0.0
        entry = max([abs(rows[f][col] - rows[f - 1][col]) for f in range(1, len(rows))
                     if at[f] and not at[f - 1]] or [0.0])
        run = best = 0
        for f, hit in enumerate(at):
            run = run + 1 if hit else 0
            best = max(best, run)
            if hit:
                any_frame.add(f)
        result["angles"]["%s.%s" % (seg, letter)] = {"range_deg": [lo, hi], "at_lower": lower,
                                                     "at_upper": upper, "longest_run": best,
                                                     "largest_entry_step_deg": entry,
                                                     "p95_step_deg": p95}
        if lower or upper:
            print("%-22s %-6s %12s %10d %10d %12d %12.2f %12.2f" % (
                seg, letter, "[%g, %g]" % (lo, hi), lower, upper, best, entry, p95))
    result["frames_with_any_angle_at_a_bound"] = len(any_frame)
    print("frames with any angle at a bound: %d of %d" % (len(any_frame), len(rows)))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
