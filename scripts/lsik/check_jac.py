#!/usr/bin/python3
"""Checks ik_ls.py's analytic Jacobian against central finite differences (step 1e-6) at a
perturbed FABRIK start on frame 10, for one variant (default a). Prints the largest difference.
  /usr/bin/python3 scripts/lsik/check_jac.py [--fabrik BIN] [--data DIR] [--out DIR] [VARIANT]
"""
import numpy as np

import ik_ls


def main():
    st, v, M, P = ik_ls.variant_problem(__doc__)
    x = ik_ls.fabrik_start(st, M, P) + np.random.default_rng(0).normal(0, 0.05, len(P.free) + 3)
    meas = st.MEAS[10]
    ok = ~np.isnan(meas[:, 0])

    def fun(x):
        A, b = P.unpack(x)
        R, B = M.fk(A, b)
        return (np.sqrt(M.marker_w)[ok][:, None] * (M.markers_world(R, B)[ok] - meas[ok])).ravel()
    # solve_frame builds its Jacobian as a closure: capture it from the least_squares call.
    captured = {}
    orig = ik_ls.least_squares

    def capture(fun_, x0, jac, **kw):
        captured["J"], captured["x0"] = jac(x0), x0
        return orig(fun_, x0, jac=jac, max_nfev=1, bounds=kw["bounds"])
    ik_ls.least_squares = capture
    P.solve_frame(x, meas)
    ik_ls.least_squares = orig
    x0 = captured["x0"]
    Jn = np.array([(fun(x0 + h) - fun(x0 - h)) / 2e-6 for h in np.eye(len(x0)) * 1e-6]).T
    print(f"variant {v}: max |J_analytic - J_numeric| {np.abs(captured['J'] - Jn).max():.1e}, "
          f"max |J| {np.abs(Jn).max():.1e}")


if __name__ == "__main__":
    main()
