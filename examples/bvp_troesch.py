"""Troesch's problem u'' = lam sinh(lam u), u(0) = 0, u(1) = 1, continued in lam from 0 to 10.

A boundary layer forms at x = 1 (at lam = 10, u'(1) = 148, and the solution's logarithmic singularity
lies 1.3e-3 beyond x = 1). The mesh adapts under max_error = 1e-8; the slope u'(0) (3.58e-4 at
lam = 10) is an output whose error is held relative to its own size (its floor in ``scales``, 1e-6,
is below it). Writes troesch.h5 and prints ``slope_at_0 VALUE`` (u'(0) at lam = 10), ``N VALUE``
(subintervals at the end), the smallest and largest subinterval there, and why the run ended.
"""

import numpy as np

import rodcont

troesch = rodcont.BVProblem(
    orders=[2],
    residual=lambda S, z, p: z[2] - p[0] * np.sinh(p[0] * z[0]),   # u'' - lam sinh(lam u) = 0
    bc=lambda za, zb, p: np.stack([za[0], zb[0] - 1.0]),            # u(0) = 0, u(1) = 1
    interval=(0.0, 1.0), params=["lam"], names=["u"])
outputs = {"slope_at_0": lambda sol: sol.evaluate(0.0, "u", 1)}
scales = {"slope_at_0": 1e-6}  # its error relative to |u'(0)| while that is above 1e-6

start = rodcont.bvp.solve(troesch, {"lam": 0.0}, guess=lambda x: x, N=4, max_error=1e-8, outputs=outputs,
                          scales=scales, name="troesch")
res = rodcont.continue_bvp(troesch, "lam", start, p_range=(0.0, 10.0), ds=0.1, ds_max=1.0, max_error=1e-8,
                           out="troesch.h5", overwrite=True)

end = res.point(-1)
h = np.diff(end["breakpoints"])
print("lam", repr(float(end["lam"])))
print("slope_at_0", repr(float(end["slope_at_0"])))
print("N", h.size)
print("h_min", f"{h.min():.3g}")
print("h_max", f"{h.max():.3g}")
print("points", len(res))
print("status", res.status)
