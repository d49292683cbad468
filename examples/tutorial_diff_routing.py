"""Routing design by gradient: move a Finger's cable so that its tip comes down further for the
same pull.

The Soft Finger's closing cable passes through six points, two in each phalanx, 8 mm below
mid-height. Shortened by 8 mm, it curls the finger down. Where should those points sit, each
within its half-phalanx, for the tip to come down furthest for the same 8 mm? The tip's drop
at equilibrium is a smooth function of the routing points (inside each element), and
pliant.diff gives its exact gradient by the implicit-function theorem: one static solve and
one adjoint per evaluation, for all 12 coordinates at once. L-BFGS-B does the rest.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from _common import QUICK, save_figure  # noqa: E402

from pliant.diff.design import RoutingDesign, optimise_routing  # noqa: E402
from pliant.diff.scenes import routing_finger  # noqa: E402
from pliant.robots.finger import soft_finger  # noqa: E402

# The coarse Finger (1610 tetrahedra), no gravity, its closing cable only, pulled by 8 mm; the
# box of each routing point: (x, z) within the half of its phalanx, 1 mm inside.
finger = soft_finger(resolution="coarse", gravity=(0.0, 0.0, 0.0))
model, commands, free, lower, upper = routing_finger(finger, pull=8.0)
design = RoutingDesign(model, "cable_0", commands, free=free)  # reach: the tip's drop (-z)

# The gradient, and a central difference of the same solver to check it.
theta = design.initial
reach, gradient = design.reach_and_gradient(theta)
step = np.zeros_like(theta)
step[1] = 1e-4  # the first point's height
check = (design.reach(theta + step) - design.reach(theta - step)) / 2e-4
print(f"the Finger's routing: the tip comes down {reach:.2f} mm")
print(f"d reach / d z_0: {gradient[1]:.6f} (central difference {check:.6f})")
assert abs(gradient[1] - check) < 1e-6 * max(1.0, abs(check))

result = optimise_routing(design, lower, upper, max_solves=6 if QUICK else 40)
print(
    f"L-BFGS-B: {result.reach:.2f} mm after {result.solves} equilibria"
    f" ({result.adjoints} with their adjoint, {result.failed} failed)"
)
assert result.reach > reach
before = design.points(theta)[design.rows]
after = design.points(result.theta)[design.rows]
for p, q in zip(before, after, strict=True):
    print(f"  ({p[0]:5.1f}, {p[2]:4.1f}) -> ({q[0]:5.1f}, {q[2]:4.1f})")

fig, axes = plt.subplots(1, 2, figsize=(10, 3.4))
best = np.maximum.accumulate([r for _, r in result.history])
axes[0].step([n for n, _ in result.history], best, where="post")
axes[0].set(xlabel="equilibria solved", ylabel="best tip drop (mm)")
for n in range(3):
    axes[1].add_patch(plt.Rectangle((52 * n, 0), 40, 20, fill=False, color="0.6"))
axes[1].plot(before[:, 0], before[:, 2], "k--o", ms=3, label="the Finger's routing")
axes[1].plot(after[:, 0], after[:, 2], "o-", ms=3, label="L-BFGS-B")
axes[1].set(xlabel="x (mm)", ylabel="z (mm)", aspect="equal")
axes[1].set_ylim(-2.0, 36.0)
axes[1].legend(fontsize=7, loc="upper center", ncols=2)
save_figure(fig, "diff_routing.png")
