#!/usr/bin/python3
"""Is the warm-started per-frame least squares at the global optimum? For frames 20, 30, ...,
120 of a variant (default a), re-solve from 6 starts with all leg angles perturbed uniformly by up
to +-15 deg (seed 1) and count starts that end at a lower or a higher cost.
  /usr/bin/python3 scripts/lsik/multistart.py [--fabrik BIN] [--data DIR] [--out DIR] [VARIANT]
"""
import numpy as np

import ik_ls


def main():
    st, v, M, P = ik_ls.variant_problem(__doc__)
    rng = np.random.default_rng(1)
    x = ik_ls.fabrik_start(st, M, P)
    names = ["hip_rotation_l", "hip_rotation_r", "ankle_angle_l", "ankle_angle_r", "hip_adduction_l"]
    legs = [i for i, (s, k) in enumerate(P.free)
            if M.names[s].split("_")[-1] in ("thigh", "shank", "hindfoot", "forefoot", "toes")]
    legs = [i if i < 3 else i + 3 for i in legs]  # parameter index: root base sits at 3..5
    worse = better = 0
    for f in range(0, 131):
        r, _, _ = P.solve_frame(x, st.MEAS[f])
        if f == 0:
            r, _, _ = P.solve_frame(r.x, st.MEAS[f])
        x = r.x
        if f % 10 or f < 20:
            continue
        base_cost = r.cost
        A, b = P.unpack(r.x)
        R, B = M.fk(A, b)
        c0 = M.coordinate_values(R, B)
        for t in range(6):
            x1 = r.x.copy()
            x1[legs] += np.radians(rng.uniform(-15, 15, len(legs)))
            r1, _, _ = P.solve_frame(x1, st.MEAS[f])
            A, b = P.unpack(r1.x)
            R, B = M.fk(A, b)
            c1 = M.coordinate_values(R, B)
            dmax = max(abs(np.degrees(c1[n] - c0[n])) for n in names)
            if r1.cost < base_cost * (1 - 1e-6):
                better += 1
                print(f"frame {f} start {t}: cost {r1.cost:.1f} < warm {base_cost:.1f}; coord change up to {dmax:.2f} deg")
            elif r1.cost > base_cost * (1 + 1e-6):
                worse += 1
    print(f"{v}: perturbed starts that found a lower cost: {better}, a higher (other local minimum): {worse}, out of {6 * 11}")


if __name__ == "__main__":
    main()
