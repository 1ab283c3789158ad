#!/usr/bin/python3
"""The summary table of docs/least-squares-ik.md (r / RMS-off deg against OpenSim's IK per
coordinate, and mean marker RMS) from the res_*.json files ik_ls.py wrote into a folder.
ik_ls.py prints it at the end; this re-prints it without solving again:
  /usr/bin/python3 scripts/lsik/summary.py /tmp/lsik
"""
import json
import os
import sys

ORDER = ["fab", "a", "b", "c", "d", "dc", "e", "ed", "eq"]
DESC = {"fab": "FABRIK (fabrik solve)", "a": "(a) LS, model as calibrated",
        "b": "(b) LS, rigid foot (forefoot+toes at rest)", "c": "(c) LS, rigid foot + hindfoot hinge z",
        "d": "(d) = (b) + knee ball x/y rest +-5 deg", "dc": "(d') = (c) + knee ball x/y rest +-5 deg",
        "e": "(e) = (c) with ankle hinge about OpenSim's oblique talocrural axis",
        "ed": "(e') = (e) + knee ball x/y +-5 deg", "eq": "(b) with equal marker weights"}


def cell(c):
    return f"{c['r']:.3f}/{c['rms_off']:.2f}"


def summary_table(folder):
    out = ("| variant | ank_l r/RMS | ank_r r/RMS | hadd_l r/RMS | hadd_r r/RMS | hrot_l r/RMS | hrot_r r/RMS "
           "| hflex l/r r, RMS | knee l/r r, RMS | marker RMS mm |\n|---|---|---|---|---|---|---|---|---|---|\n")
    for v in ORDER:
        path = os.path.join(folder, f"res_{v}.json")
        if not os.path.isfile(path):
            continue
        j = json.load(open(path))
        g, rms = j["cmp"].__getitem__, j["rms_mean_mm"]
        out += (f"| {DESC[v]} | {cell(g('ankle_angle_l'))} | {cell(g('ankle_angle_r'))} | {cell(g('hip_adduction_l'))} | "
                f"{cell(g('hip_adduction_r'))} | {cell(g('hip_rotation_l'))} | {cell(g('hip_rotation_r'))} | "
                f"{g('hip_flexion_l')['r']:.3f}/{g('hip_flexion_r')['r']:.3f}, {g('hip_flexion_l')['rms_off']:.2f}/{g('hip_flexion_r')['rms_off']:.2f} | "
                f"{g('knee_angle_l')['r']:.3f}/{g('knee_angle_r')['r']:.3f}, {g('knee_angle_l')['rms_off']:.2f}/{g('knee_angle_r')['rms_off']:.2f} | {rms:.2f} |\n")
    return out


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    folder = sys.argv[1]
    if not any(os.path.isfile(os.path.join(folder, f"res_{v}.json")) for v in ORDER):
        # An empty table with exit 0 read as "nothing to compare" where the path was wrong.
        sys.exit(f"summary.py: no res_*.json in {folder}. Fix: give the folder ik_ls.py --out wrote")
    print(summary_table(folder))
