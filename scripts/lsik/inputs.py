"""Inputs of the least-squares IK study (docs/least-squares-ik.md), shared by its scripts:
the command-line arguments (--fabrik, --data, --out), the check that ../shared/data is there
(exit 0 with a SKIP message when it is not), and the FABRIK run the study starts from:
`fabrik calibrate` of config/templates/gait2354.json on subject01_static.trc, then
`fabrik solve --angles` on subject01_walk1.trc, all written into --out.
"""
import argparse
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

from ikmodel import Model, read_mot, read_trc

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
STATIC, TRIAL, REFERENCE = "subject01_static.trc", "subject01_walk1.trc", "subject01_walk1_ik.mot"
RATE_HZ = 60.0  # subject01_walk1.trc's frame rate; compare() matches OpenSim's rows on it


def parser(description):
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("--fabrik", default=os.path.join(REPO, "build/src/apps/fabrik"),
                    help="fabrik binary (default: build/src/apps/fabrik in the repository)")
    ap.add_argument("--data", default=os.path.join(REPO, "../shared/data"),
                    help="folder with the subject01 files (default: ../shared/data from the repository root)")
    ap.add_argument("--out", default=None,
                    help="folder for the config, FABRIK's output and results (default: a new temp folder)")
    return ap


class Study:
    """The calibrated model, the measured markers, OpenSim's reference angles and FABRIK's run."""

    def __init__(self, args):
        need = [os.path.join(args.data, f) for f in (STATIC, TRIAL, REFERENCE)]
        missing = [p for p in need if not os.path.isfile(p)]
        if missing:
            print(f"SKIP: shared data absent ({', '.join(missing)}); pass --data DIR", flush=True)
            sys.exit(0)
        if not os.access(args.fabrik, os.X_OK):
            sys.exit(f"fabrik binary not found at {args.fabrik}; build it or pass --fabrik")
        self.out = args.out or tempfile.mkdtemp(prefix="lsik-")
        os.makedirs(self.out, exist_ok=True)
        self.cfg = os.path.join(self.out, "cfg.json")
        self.fab_joints_trc = os.path.join(self.out, "fabrik_joints.trc")
        self.fab_mot = os.path.join(self.out, "fabrik_angles.mot")
        run([args.fabrik, "calibrate", "--template", os.path.join(REPO, "config/templates/gait2354.json"),
             "--static", need[0], "--output", self.cfg])
        solve_out = run([args.fabrik, "solve", "--config", self.cfg, "--input", need[1],
                         "--output", self.fab_joints_trc, "--angles", self.fab_mot])
        m = re.search(r"marker residual\s+RMS ([0-9.]+) mm", solve_out)
        self.fab_marker_rms_mm = float(m.group(1))  # as fabrik solve prints it
        self.M0 = Model(self.cfg)
        self.marker_names, self.t_s, X = read_trc(need[1])
        self.MEAS = X[:, [self.marker_names.index(n) for n in self.M0.marker_names]]  # frames x markers x 3, mm
        self.MEAS_ALL = X
        self.ref_cols, self.ref, self.ref_deg = read_mot(need[2])
        print(f"study folder: {self.out}", flush=True)


def run(cmd):
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({p.returncode}):\n{p.stdout}{p.stderr}")
    return p.stdout + p.stderr


def fabrik_angles(M, row, cols, deg, A_base=None):
    """Joint angles (S x 3, rad) and root base (mm, lab) from one row of FABRIK's .mot
    (pelvis and legs; other joints from A_base, default the rest angles)."""
    col = {c: i for i, c in enumerate(cols)}
    cm = {c["name"]: c for c in M.coords}
    v = lambda n: row[col[n]] * (np.pi / 180 if cm[n]["kind"] == "r" and deg else 1.0)
    s = lambda n: cm[n]["sign"]
    A = np.array(M.rest if A_base is None else A_base, float)
    A[0] = [v("pelvis_tilt"), v("pelvis_list"), v("pelvis_rotation")]
    for side in "lr":
        A[M.idx[side + "_thigh"]] = [v("hip_flexion_" + side), s("hip_adduction_" + side) * v("hip_adduction_" + side),
                                     s("hip_rotation_" + side) * v("hip_rotation_" + side)]
        A[M.idx[side + "_shank"], 0] = v("knee_angle_" + side)
        A[M.idx[side + "_hindfoot"], 0] = v("ankle_angle_" + side)
        if M.hi[M.idx[side + "_hindfoot"]][1] > M.lo[M.idx[side + "_hindfoot"]][1]:
            A[M.idx[side + "_hindfoot"], 1] = s("subtalar_angle_" + side) * v("subtalar_angle_" + side)
    R, _ = M.fk(A, np.zeros(3))
    asis = np.array([v("pelvis_tx"), v("pelvis_ty"), v("pelvis_tz")]) * 1e3
    return A, M.lab.T @ asis - R[0] @ M.points[0]["asis_mid"]
