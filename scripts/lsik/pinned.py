#!/usr/bin/python3
"""Do our model and the markers admit OpenSim's angles? On a variant, over the 73 frames shared
with OpenSim's IK, pin the chosen coordinates to OpenSim's values (plus the variant's mean offset
from ik_ls.py, a definition matter), re-optimise everything else, and compare the marker
residuals per segment group with the free optimum. Needs ik_ls.py's res_VARIANT.json in --out.
  /usr/bin/python3 scripts/lsik/pinned.py --out /tmp/lsik c ankle_angle_l,ankle_angle_r,hip_rotation_l,hip_rotation_r
"""
import json
import os

import numpy as np

import ik_ls
import inputs


def main():
    ap = inputs.parser(__doc__.split("\n\n")[0])
    ap.add_argument("variant", choices=ik_ls.VARIANTS)
    ap.add_argument("pin", help="comma-separated rotational coordinates to pin")
    args = ap.parse_args()
    v, pin = args.variant, args.pin.split(",")
    # Checked before the study calibrates and solves (a temporary --out never has it).
    res = os.path.join(args.out or "(a new temporary folder)", f"res_{v}.json")
    if not args.out or not os.path.isfile(res):
        ap.error(f"{res} missing: run ik_ls.py --out FOLDER {v} first and give --out FOLDER")
    st = inputs.Study(args)
    cm0 = json.load(open(res))["cmp"]
    M = ik_ls.variant_model(st.M0, v)
    cm = {c["name"]: c for c in M.coords}
    par = {n: (cm[n]["seg"], cm[n]["angle"]) for n in pin}  # coordinate -> (segment, angle index)
    groups = {"foot": ("hindfoot", "forefoot", "toes"), "shank": ("shank",), "thigh": ("thigh",), "pelvis": ("pelvis",)}

    def grp(i):
        sn = M.names[M.marker_seg[i]]
        return next((g for g, ks in groups.items() if any(sn.endswith(k) for k in ks)), "upper")
    gi = np.array([grp(i) for i in range(len(M.marker_names))])
    P = ik_ls.Problem(M)
    x = ik_ls.fabrik_start(st, M, P)
    res_free = {g: [] for g in list(groups) + ["upper", "all"]}
    res_pin = {g: [] for g in list(groups) + ["upper", "all"]}
    out_coords = []
    first = int(round(st.ref[0, 0] * inputs.RATE_HZ))  # the trial frame of OpenSim's first row
    for f in range(0, first + len(st.ref)):
        r, _, _ = P.solve_frame(x, st.MEAS[f])
        if f == 0:
            r, _, _ = P.solve_frame(r.x, st.MEAS[f])
        x = r.x
        if f < first:
            continue
        row = st.ref[f - first]
        assert abs(row[0] - f / inputs.RATE_HZ) < 1e-3
        Mp = ik_ls.variant_model(st.M0, v)
        for n, (s, k) in par.items():
            raw = np.radians(row[st.ref_cols.index(n)] + cm0[n]["off"]) / cm[n]["sign"]
            Mp.lo[s][k] = Mp.hi[s][k] = raw
        Pp = ik_ls.Problem(Mp)
        A, b = P.unpack(x)
        for n, (s, k) in par.items():
            A[s, k] = Mp.lo[s][k]
        rp, _, _ = Pp.solve_frame(Pp.pack(A, b), st.MEAS[f])
        for PP, rr, store in ((P, r, res_free), (Pp, rp, res_pin)):
            A, b = PP.unpack(rr.x)
            R, B = PP.M.fk(A, b)
            d = np.linalg.norm(PP.M.markers_world(R, B) - st.MEAS[f], axis=1)
            for g in store:
                sel = np.ones(len(d), bool) if g == "all" else gi == g
                store[g].append(np.sqrt(np.nanmean(d[sel] ** 2)))
        A, b = Pp.unpack(rp.x)
        R, B = Mp.fk(A, b)
        out_coords.append(Mp.coordinate_values(R, B))
    print(f"variant {v}, pinned to OpenSim (+ mean offset): {', '.join(pin)}; {len(out_coords)} frames")
    print("marker group   free-optimum RMS mm   pinned RMS mm   increase")
    for g in res_free:
        a, bb = np.mean(res_free[g]), np.mean(res_pin[g])
        print(f"{g:8s}       {a:8.2f}            {bb:8.2f}        {bb - a:+.2f}")
    for n in ["hip_flexion_l", "hip_flexion_r", "knee_angle_l", "knee_angle_r", "pelvis_list", "hip_adduction_l",
              "hip_adduction_r"]:
        if n in pin:
            continue
        a = np.array([c[n] for c in out_coords])
        bb = np.radians(st.ref[:len(out_coords), st.ref_cols.index(n)])
        d = a - bb
        print(f"  pinned run {n}: r {np.corrcoef(a, bb)[0, 1]:.3f}, RMS-off {np.degrees(np.std(d)):.2f} deg")


if __name__ == "__main__":
    main()
