"""Calibration by gradient: fit E, nu and Rayleigh damping to a measured trajectory.

A 60 mm silicone-like beam, held at one end and pulled by a cable along its top edge, is
"measured" (a synthetic trajectory of every node, generated with the true parameters). From
a start 50 % to 100 % off, L-BFGS-B on the exact gradient of the trajectory error
(pliant.diff.calibration.calibrate: one rollout and its adjoint per evaluation) finds the
parameters again.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from _common import QUICK, save_figure  # noqa: E402

from pliant import (  # noqa: E402
    CableActuator,
    Corotational,
    EmbeddedPoints,
    ImplicitEuler,
    Model,
    TetBody,
)
from pliant.diff.calibration import calibrate, observe, relative_errors  # noqa: E402
from pliant.mesh import box_beam  # noqa: E402


def pulled_beam(young_modulus, poisson_ratio, rayleigh_mass, rayleigh_stiffness) -> Model:
    mesh = box_beam(60.0, 10.0, 10.0, 5, 1, 1)
    x = mesh.points
    top = np.flatnonzero(np.isclose(x[:, 2], 10.0) & np.isclose(x[:, 1], 0.0) & (x[:, 0] > 0))
    body = TetBody(
        mesh,
        Corotational(young_modulus, poisson_ratio),
        density=1e-6,  # kg/mm^3
        fixed_nodes=np.flatnonzero(np.isclose(x[:, 0], 0.0)),
        gravity=(0.0, 0.0, -9810.0),
        rayleigh_mass=rayleigh_mass,
        rayleigh_stiffness=rayleigh_stiffness,
    )
    cable = CableActuator(
        EmbeddedPoints.at_nodes(top[np.argsort(x[top, 0])]),
        body.rest_positions,
        pull_point=np.array([-10.0, 0.0, 10.0]),
        name="cable",
    )
    return Model(body, actuators=[cable], name="beam")


truth = dict(young_modulus=200.0, poisson_ratio=0.3, rayleigh_mass=0.5, rayleigh_stiffness=0.01)
start = dict(young_modulus=300.0, poisson_ratio=0.4, rayleigh_mass=1.0, rayleigh_stiffness=0.02)
bounds = dict(
    young_modulus=(50.0, 1000.0),
    poisson_ratio=(0.05, 0.49),
    rayleigh_mass=(0.01, 5.0),
    rayleigh_stiffness=(0.001, 0.1),
)
if QUICK:  # CI: two parameters, a short pull
    start = {k: start[k] for k in ("young_modulus", "rayleigh_stiffness")}
n_steps = 10 if QUICK else 30
dt = 0.01
# The cable shortens by 0.5 mm a step up to 2 mm, then holds: a pull and a damped swing.
controls = np.minimum(np.arange(1, n_steps + 1) * 0.5, 2.0)[:, None]

measured = pulled_beam(**truth)
points = EmbeddedPoints.at_nodes(np.flatnonzero(measured.body.free_index[::3] >= 0))
solver = ImplicitEuler(measured, dt, tangent="fresh")  # the gradient needs the exact step
observed = observe(measured, solver, measured.rest_state(), controls, points)

model = pulled_beam(**{**truth, **start})
solver = ImplicitEuler(model, dt, tangent="fresh")
result = calibrate(model, solver, model.rest_state(), controls, points, observed, start, bounds)
errors = relative_errors(result.parameters, truth)
print(f"{result.evaluations} rollouts with their adjoint, {result.iterations} L-BFGS-B iterations")
for name, value in result.parameters.items():
    print(f"  {name}: {value:.6g} (truth {truth[name]}, relative error {errors[name]:.1e})")
assert max(errors.values()) < 1e-4

fig, axes = plt.subplots(1, 2, figsize=(9, 3.2))
losses = [loss for loss, _ in result.history]
axes[0].semilogy(np.arange(1, len(losses) + 1), losses, "o-", ms=3)
axes[0].set(xlabel="rollout + adjoint", ylabel="trajectory error (mm$^2$)")
for name in result.parameters:
    values = [p[name] / truth[name] for _, p in result.history]
    axes[1].plot(np.arange(1, len(values) + 1), values, label=name)
axes[1].axhline(1.0, color="k", lw=0.5)
axes[1].set(xlabel="rollout + adjoint", ylabel="value / truth")
axes[1].legend(fontsize=7)
save_figure(fig, "diff_calibration.png")
