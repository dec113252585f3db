"""The pinned elastica with its end shortening prescribed by an integral condition and the load free.

theta'' + P sin(theta) = 0 on [0, 1] (EI = 1, theta the tangent angle), theta'(0) = theta'(1) = 0
(pins), int_0^1 cos(theta) ds = 1 - delta (delta the end shortening, continued), the compressive
load P an unknown (as AUTO's NINT: one integral condition, one freed parameter). Closed form:
P = (2 K(m))^2 with delta = 2 - 2 E(m)/K(m). Starts near Euler's load on the first mode
(theta ~ 2 sqrt(delta) cos(pi s)) at delta = 0.01 and continues to delta = 1.5 (past delta = 1 the
ends have passed through each other), with a point forced at delta = 1, where the ends meet.
Writes elastica.h5 and prints ``load_at_delta_1 VALUE`` and the end angle there.
"""

import numpy as np

import rodcont

elastica = rodcont.BVProblem(
    orders=[2],
    residual=lambda S, z, p: z[2] + p[0] * np.sin(z[0]),             # theta'' + P sin(theta) = 0
    bc=lambda za, zb, p: np.stack([za[1], zb[1]]),                     # theta'(0) = theta'(1) = 0
    integrals=lambda S, z, p: (np.cos(z[0]) - (1.0 - p[1]))[None, :],  # int cos(theta) = 1 - delta
    interval=(0.0, 1.0), params=["P", "delta"], free=[0], names=["theta"])
outputs = {"theta_0": lambda sol: sol.evaluate(0.0, "theta")}

delta0 = 0.01
start = rodcont.bvp.solve(elastica, {"P": np.pi**2, "delta": delta0},
                          guess=lambda s: 2 * np.sqrt(delta0) * np.cos(np.pi * s), max_error=1e-10,
                          outputs=outputs, name="pinned_elastica")
res = rodcont.continue_bvp(elastica, "delta", start, p_range=(delta0, 1.5), ds=0.1, ds_max=0.5, forced=[1.0],
                           max_error=1e-10, out="elastica.h5", overwrite=True)

at1 = res.point("P1")  # the forced point, delta = 1
print("delta", repr(float(at1["delta"])))
print("load_at_delta_1", repr(float(at1["P"])))
print("theta_0_at_delta_1", repr(float(at1["theta_0"])))
print("N", len(at1["breakpoints"]) - 1)
print("points", len(res))
print("status", res.status)
