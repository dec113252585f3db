"""Bratu's problem u'' + lam e^u = 0, u(0) = u(1) = 0, continued in lam from 0 through its fold.

The fold is at lam* = 3.513830719125162 (closed form). The mesh adapts until the estimated error of
every stored point is below max_error = 1e-10 and that of the fold below fold_error = 1e-11, so the
printed fold is right to about 1e-11 (on the starting mesh, N = 4, k = 5, held fixed it is 4.8e-9 off).
Writes bratu.h5 (in the current directory) and prints ``fold_lambda VALUE``, the fold's ``u_mid`` and
``slope_at_0`` (4 exactly there), the subintervals there, and why the run ended.
"""

import numpy as np

import rodcont

bratu = rodcont.BVProblem(
    orders=[2],                                               # one field, of second order
    residual=lambda S, z, p: z[2] + p[0] * np.exp(z[0]),      # z = (u, u', u''), p = (lam,)
    bc=lambda za, zb, p: np.stack([za[0], zb[0]]),            # u(0) = 0, u(1) = 0
    interval=(0.0, 1.0), params=["lam"], names=["u"])
outputs = {"u_mid": lambda sol: sol.evaluate(0.5, "u"),      # max u (by symmetry)
           "slope_at_0": lambda sol: sol.evaluate(0.0, "u", 1)}

start = rodcont.bvp.solve(bratu, {"lam": 0.0}, guess=0.0, N=4, max_error=1e-10, outputs=outputs, name="bratu")
upper = rodcont.Event("u(1/2) reached 4 on the upper branch", lambda pt: 4.0 - pt.data["u_mid"], stop=True,
                      label="u_mid")
res = rodcont.continue_bvp(bratu, "lam", start, p_range=(0.0, 4.0), ds=0.1, ds_max=0.5, max_error=1e-10,
                           fold_error=1e-11, events=[upper], out="bratu.h5", overwrite=True)

fold = res.folds[0]                                           # the table's row at F1
print("fold_lambda", repr(float(fold["lam"])))               # 3.51383071912526...
print("fold_u_mid", repr(float(fold["u_mid"])))
print("fold_slope_at_0", repr(float(fold["slope_at_0"])))
print("fold_N", len(res.point("F1")["breakpoints"]) - 1)
print("fold_located", bool(fold["located"]))
print("points", len(res))
print("status", res.status)                                   # event: u(1/2) reached 4
