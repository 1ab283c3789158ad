#!/usr/bin/python3
"""Per-frame whole-body least-squares IK over joint coordinates on our calibrated gait2354 model
(OpenSim-style: minimise the weighted sum of squared marker distances, joint ranges as bounds,
root 6 DOF free), warm-started from the previous frame (frame 0 from our FABRIK solve), compared
with OpenSim's IK (subject01_walk1_ik.mot) exactly as `fabrik eval angles` does.
It calibrates the model and runs `fabrik solve` itself (inputs.py), then solves each variant.
Writes into --out: res_VARIANT.json, coords_VARIANT.npy, tables_full.md; prints the per-variant
tables and the summary table of docs/least-squares-ik.md.

Variants: a (model as calibrated), b (rigid foot), c (b + hindfoot hinge z), d (b + knee ball
x/y +-5 deg), dc (c + knee ball), e (c with OpenSim's oblique ankle axis), ed (e + knee ball),
eq (b with equal marker weights).

Command (from the repository root; about 15-30 s per variant):
  /usr/bin/python3 scripts/lsik/ik_ls.py --out /tmp/lsik a b c d dc e ed eq
"""
import copy
import json
import os
import time

import numpy as np
from scipy.optimize import least_squares

import inputs
from ikmodel import read_mot, rz, rx
from summary import summary_table

VARIANTS = ["a", "b", "c", "d", "dc", "e", "ed", "eq"]


def variant_model(M0, v):
    """Copy of the model's joint set-up for a variant."""
    M = copy.deepcopy(M0)
    def hold(seg, ks):
        s = M.idx[seg]
        for k in ks:
            M.lo[s][k] = M.hi[s][k] = M.rest[s][k]
    if v in ("b", "c", "d", "dc", "e", "ed"):  # rigid foot: forefoot and toes at rest
        for side in "lr":
            hold(side + "_forefoot", [0, 1, 2])
            hold(side + "_toes", [0, 1, 2])
    if v in ("c", "dc", "e", "ed"):  # hindfoot a hinge about z (subtalar held)
        for side in "lr":
            hold(side + "_hindfoot", [1])
    if v in ("e", "ed"):  # ankle hinge about OpenSim gait2354's talocrural axis (in the shank frame)
        M.hinge_axes = {M.idx["r_hindfoot"]: np.array([-0.10501355, -0.17402245, 0.97912632]),
                        M.idx["l_hindfoot"]: np.array([0.10501355, 0.17402245, 0.97912632])}
    if v in ("d", "dc", "ed"):  # knee a ball with small x/y ranges around rest
        for side in "lr":
            s = M.idx[side + "_shank"]
            for k, r in ((1, 5.0), (2, 5.0)):
                M.lo[s][k] = M.rest[s][k] - np.radians(r)
                M.hi[s][k] = M.rest[s][k] + np.radians(r)
    if v == "eq":  # as (b) with equal marker weights
        for side in "lr":
            hold(side + "_forefoot", [0, 1, 2])
            hold(side + "_toes", [0, 1, 2])
        M.marker_w = np.ones_like(M.marker_w)
    return M


class Problem:
    def __init__(self, M):
        self.M = M
        S = len(M.names)
        self.free = [(0, k) for k in range(3)] + [(s, k) for s in range(1, S) for k in range(3)
                                                  if M.hi[s][k] - M.lo[s][k] > 1e-12]
        self.lo = np.array([-np.inf] * 6 + [M.lo[s][k] for s, k in self.free[3:]])
        self.hi = np.array([np.inf] * 6 + [M.hi[s][k] for s, k in self.free[3:]])
        self.A0 = np.array(M.rest, float)
        for s in range(1, S):  # held angles: rest (or the middle of a degenerate range)
            self.A0[s] = np.clip(self.A0[s], M.lo[s], M.hi[s])
        self.sw = np.sqrt(M.marker_w)
        self.pseg = np.array([s for s, k in self.free])

    def unpack(self, x):
        A = self.A0.copy()
        for i, (s, k) in enumerate(self.free):
            A[s, k] = x[i if i < 3 else i + 3]
        return A, x[3:6]

    def pack(self, A, root_base):
        x = [A[s, k] for s, k in self.free]
        return np.array(x[:3] + list(root_base) + x[3:])

    def solve_frame(self, x0, meas):
        ok = ~np.isnan(meas[:, 0])
        sw = self.sw[ok][:, None]
        M = self.M
        anc = M.ancestor[self.pseg][:, M.marker_seg[ok]]  # params x markers
        cache = {}
        def fk(x):
            key = x.tobytes()
            if key not in cache:
                cache.clear()
                A, b = self.unpack(x)
                R, B = M.fk(A, b)
                cache[key] = (A, R, B, M.markers_world(R, B)[ok])
            return cache[key]
        def fun(x):
            return (sw * (fk(x)[3] - meas[ok])).ravel()
        def jac(x):
            A, R, B, P = fk(x)
            axes, piv = [], []
            for s, k in self.free:
                F = M.lab.T if s == 0 else R[M.parent[s]] @ M.J[M.parent[s]]
                if s in getattr(M, "hinge_axes", {}):
                    a = F @ (M.hinge_axes[s] / np.linalg.norm(M.hinge_axes[s]))
                else:
                    a = [F[:, 2], F @ rz(A[s, 0])[:, 0], F @ (rz(A[s, 0]) @ rx(A[s, 1]))[:, 1]][k]
                axes.append(a)
                piv.append(B[s])
            axes, piv = np.array(axes), np.array(piv)
            D = np.cross(axes[:, None, :], P[None, :, :] - piv[:, None, :]) * anc[:, :, None]
            D = D * sw[None]
            Jr = D.reshape(len(self.free), -1).T  # rotation columns
            nm = P.shape[0]
            Jt = np.tile(np.eye(3), (nm, 1)) * np.repeat(sw[:, 0], 3)[:, None]
            return np.hstack([Jr[:, :3], Jt, Jr[:, 3:]])
        eps = 1e-9
        x0 = np.clip(x0, self.lo + eps, self.hi - eps)
        r = least_squares(fun, x0, jac=jac, bounds=(self.lo, self.hi), method="trf",
                          x_scale="jac", ftol=1e-10, xtol=1e-10, gtol=1e-10, max_nfev=500)
        A, R, B, P = fk(r.x)
        d = np.linalg.norm(P - meas[ok], axis=1)
        return r, np.sqrt(np.mean(d ** 2)), d.max()


def fabrik_start(st, M, P):
    """Frame-0 start from our FABRIK coordinates (pelvis and legs; the rest at rest)."""
    cols, mot, deg = read_mot(st.fab_mot)
    A, b = inputs.fabrik_angles(M, mot[0], cols, deg, A_base=P.A0)
    return P.pack(A, b)


def run(st, v):
    M = variant_model(st.M0, v)
    P = Problem(M)
    x = fabrik_start(st, M, P)
    MEAS = st.MEAS
    nF = MEAS.shape[0]
    coords, rms, mx, ms, nfev, stat = [], [], [], [], [], []
    for f in range(nF):
        t0 = time.perf_counter()
        r, rr, dm = P.solve_frame(x, MEAS[f])
        if f == 0:  # frame 0 starts far from the upper body's pose: polish once more
            r, rr, dm = P.solve_frame(r.x, MEAS[f])
        ms.append((time.perf_counter() - t0) * 1e3)
        nfev.append(r.nfev)
        stat.append(r.status)
        x = r.x
        A, b = P.unpack(x)
        R, B = M.fk(A, b)
        coords.append(M.coordinate_values(R, B))
        rms.append(rr)
        mx.append(dm)
    print(v, "least_squares status counts", {s: stat.count(s) for s in set(stat)}, flush=True)
    return M, coords, np.array(rms), np.array(mx), np.array(ms[1:]), np.array(nfev[1:]), len(P.free)


def fabrik_coords(st):
    cols, mot, deg = read_mot(st.fab_mot)
    cm = {c["name"]: c for c in st.M0.coords}
    out = []
    for row in mot:
        out.append({n: row[i] * (np.pi / 180 if deg and cm[n]["kind"] == "r" else 1.0)
                    for i, n in enumerate(cols) if n in cm})
    return out


def compare(st, M, coords):
    """As src/eval/angles.cpp: reference rows matched to frames on time; unwrap; whole turns;
    offset = mean(fab - ref); RMS, RMS-off, Pearson r (NaN when either series is flat)."""
    ref, ref_cols, ref_deg, RATE = st.ref, st.ref_cols, st.ref_deg, inputs.RATE_HZ
    frames, rows = [], []
    for i, t in enumerate(ref[:, 0]):
        f = int(round(t * RATE))
        if 0 <= f < len(coords) and abs(f / RATE - t) <= 0.25 / RATE:
            frames.append(f)
            rows.append(i)
    out = {}
    for c in M.coords:
        if c["name"] not in ref_cols:
            continue
        j = ref_cols.index(c["name"])
        a = np.array([coords[f][c["name"]] for f in frames])
        b = ref[rows, j] * (np.pi / 180 if ref_deg and c["kind"] == "r" else 1.0)
        if c["kind"] == "r":
            a = np.concatenate([[a[0]], a[0] + np.cumsum(np.remainder(np.diff(a) + np.pi, 2 * np.pi) - np.pi)])
            b = np.concatenate([[b[0]], b[0] + np.cumsum(np.remainder(np.diff(b) + np.pi, 2 * np.pi) - np.pi)])
            a = a - 2 * np.pi * np.round((a.mean() - b.mean()) / (2 * np.pi))
        d = a - b
        off = d.mean()
        flat = np.ptp(a) < 1e-6 or np.ptp(b) < 1e-6
        r = np.nan if flat else np.corrcoef(a, b)[0, 1]
        k = 180 / np.pi if c["kind"] == "r" else 1e3
        out[c["name"]] = dict(rms=k * np.sqrt(np.mean(d ** 2)), off=k * off,
                              rms_off=k * np.sqrt(np.mean((d - off) ** 2)), r=r,
                              rom=k * np.ptp(a), rom_ref=k * np.ptp(b))
    return out, len(frames)


KEYS = ["ankle_angle_l", "ankle_angle_r", "hip_adduction_l", "hip_adduction_r", "hip_rotation_l",
        "hip_rotation_r", "hip_flexion_l", "hip_flexion_r", "knee_angle_l", "knee_angle_r",
        "subtalar_angle_l", "subtalar_angle_r", "pelvis_list", "pelvis_tilt", "pelvis_rotation"]


def table(name, cmp, extra):
    s = f"\n### {name}\n{extra}\n\n| coordinate | r | RMS-off deg | offset deg | ROM ours | ROM ref |\n|---|---|---|---|---|---|\n"
    for k in KEYS:
        c = cmp[k]
        rs = "-" if np.isnan(c["r"]) else f"{c['r']:.3f}"
        s += f"| {k} | {rs} | {c['rms_off']:.2f} | {c['off']:.2f} | {c['rom']:.1f} | {c['rom_ref']:.1f} |\n"
    return s


def variant_problem(doc):
    """Set-up shared by the check scripts: their arguments (the inputs' plus an optional VARIANT,
    default a), the study inputs, and the variant's model and least-squares problem."""
    ap = inputs.parser(doc.split("\n\n")[0])
    ap.add_argument("variant", nargs="?", default="a", choices=VARIANTS)
    args = ap.parse_args()
    st = inputs.Study(args)
    M = variant_model(st.M0, args.variant)
    return st, args.variant, M, Problem(M)


def save(st, name, cmp, rms_mean_mm):
    res = dict(cmp={k: {kk: (None if isinstance(vv, float) and np.isnan(vv) else vv) for kk, vv in c.items()}
                    for k, c in cmp.items()}, rms_mean_mm=rms_mean_mm)
    json.dump(res, open(os.path.join(st.out, f"res_{name}.json"), "w"), indent=1)


def main():
    ap = inputs.parser(__doc__.split("\n\n")[0])
    ap.add_argument("variants", nargs="*", help=f"variants to solve, of {' '.join(VARIANTS)} (default: all)")
    args = ap.parse_args()
    args.variants = args.variants or VARIANTS
    bad = [v for v in args.variants if v not in VARIANTS]
    if bad:
        ap.error(f"unknown variant(s) {' '.join(bad)}; known: {' '.join(VARIANTS)}")
    st = inputs.Study(args)
    cmp, n = compare(st, st.M0, fabrik_coords(st))
    save(st, "fab", cmp, st.fab_marker_rms_mm)
    out = table("FABRIK (fabrik solve, reproduces `fabrik eval angles`)", cmp, f"{n} shared frames")
    for v in args.variants:
        t0 = time.time()
        M, coords, rms, mx, ms, nfev, npar = run(st, v)
        cmp, n = compare(st, M, coords)
        extra = (f"{npar + 3} parameters; marker residual RMS mean over 151 frames {rms.mean():.2f} mm "
                 f"(worst frame {rms.max():.2f} mm, max {mx.max():.1f} mm); per-frame least squares "
                 f"p50 {np.median(ms):.0f} ms, p99 {np.percentile(ms, 99):.0f} ms, {nfev.mean():.1f} evaluations on average "
                 f"(Python, analytic Jacobian); total {time.time() - t0:.0f} s")
        out += table(f"variant {v}", cmp, extra)
        save(st, v, cmp, rms.mean())
        np.save(os.path.join(st.out, f"coords_{v}.npy"), np.array([[c[k["name"]] for k in M.coords] for c in coords]))
        print(table(f"variant {v}", cmp, extra), flush=True)
    open(os.path.join(st.out, "tables_full.md"), "w").write(out)
    print(summary_table(st.out))


if __name__ == "__main__":
    main()
