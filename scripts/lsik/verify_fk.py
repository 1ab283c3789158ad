#!/usr/bin/python3
"""Checks the Python FK (ikmodel.py) against `fabrik solve`: FABRIK's output coordinates (the
.mot) fed through the FK must reproduce solve's hip/knee/ankle/midtarsal joint centres (its
joint-centre .trc) and round-trip to the same coordinates. Prints the worst differences.
  /usr/bin/python3 scripts/lsik/verify_fk.py [--fabrik BIN] [--data DIR] [--out DIR]
"""
import numpy as np

import inputs
from ikmodel import read_mot, read_trc


def main():
    st = inputs.Study(inputs.parser(__doc__.split("\n\n")[0]).parse_args())
    M = st.M0
    cols, mot, deg = read_mot(st.fab_mot)
    col = {c: i for i, c in enumerate(cols)}
    jn, jt, JX = read_trc(st.fab_joints_trc)
    sc = np.pi / 180 if deg else 1.0
    cmap = {c["name"]: c for c in M.coords}
    legsegs = [M.idx[n] for n in ["pelvis", "l_thigh", "r_thigh", "l_shank", "r_shank", "l_hindfoot", "r_hindfoot"]]
    mk = [i for i in range(len(M.marker_names)) if M.marker_seg[i] in legsegs]
    midx = [st.marker_names.index(M.marker_names[i]) for i in mk]
    errs, res = {}, []
    # Rows are paired by time (to half a frame: a TRC may round its times): solve writes no
    # row before the first measured frame, so the .mot can start later than the trial.
    def row_at(t_s, times_s):
        k = int(np.argmin(np.abs(times_s - t_s)))
        if abs(times_s[k] - t_s) > 0.5 * np.median(np.diff(times_s)):
            raise SystemExit(f"no row at time {t_s:.6f} s")
        return k
    for f in range(mot.shape[0]):
        t_s = mot[f, col["time"]]
        fj, fm = row_at(t_s, jt), row_at(t_s, st.t_s)
        A, B0 = inputs.fabrik_angles(M, mot[f], cols, deg)
        R, B = M.fk(A, B0)
        for j in ["l_hip", "r_hip", "r_knee", "l_knee", "r_ankle", "l_ankle", "r_midtarsal", "l_midtarsal"]:
            s = M.base_name.index(j)
            errs.setdefault(j, []).append(np.linalg.norm(B[s] - JX[fj, jn.index(j)]))
        W = M.markers_world(R, B)[mk]
        d = np.linalg.norm(W - st.MEAS_ALL[fm, midx], axis=1)
        res.append(np.sqrt(np.nanmean(d ** 2)))
        cv = M.coordinate_values(R, B)
        if f in (0, 75, 150):
            worst = max(abs(cv[n] - mot[f, col[n]] * (sc if cmap[n]["kind"] == "r" else 1)) for n in
                        ["hip_flexion_l", "hip_adduction_r", "hip_rotation_l", "knee_angle_r", "ankle_angle_l",
                         "subtalar_angle_r", "pelvis_tx"])
            print(f"frame {f}: coordinate round trip worst |diff| {worst:.2e}")
    for j, e in errs.items():
        print(f"{j:12s} joint centre vs solve TRC: max {max(e):.4f} mm")
    print(f"lower-body marker residual RMS (mean over frames): {np.mean(res):.2f} mm")


if __name__ == "__main__":
    main()
