"""Tutorial: contact and friction. A soft cube on a floor tilted by tan(theta) = 0.4, for
several Coulomb coefficients mu: below tan(theta) it slides at the rigid block's rate
g (sin theta - mu cos theta), above it sticks; the floor's force stays in the friction cone."""

import numpy as np
from _common import QUICK, save_figure

from pliant import Contacts, Corotational, ImplicitEuler, Model, Plane, TetBody
from pliant.mesh import box_beam
from pliant.viz.render import offscreen_figure

G = 9810.0  # mm/s^2
theta = np.arctan(0.4)
dt, steps = 0.01, 15 if QUICK else 30


def slide(mu: float):
    """The cube released on the incline: its distance along the slope each step, and the
    ratio |tangential| / normal of the floor's total force at the end."""
    mesh = box_beam(20.0, 20.0, 20.0, nx=3, ny=3, nz=3)  # mm
    body = TetBody(
        mesh,
        Corotational(100.0, 0.3),  # kPa: a soft silicone
        density=1e-6,  # kg/mm^3
        # Tilting gravity rather than the floor: the slope runs along +x.
        gravity=(G * np.sin(theta), 0.0, -G * np.cos(theta)),
        rayleigh_stiffness=0.01,  # damps the cube's vibrations, not its sliding
    )
    # The floor z = 0; the margin (alarm distance) exceeds what a point travels in a step.
    model = Model(body, contacts=Contacts([Plane()], friction=mu, margin=12.0))
    sim = ImplicitEuler(model, dt)
    state, travel = model.rest_state(), []
    for _ in range(steps):
        state = sim.step(state)
        travel.append(state.positions[:, 0].mean() - mesh.points[:, 0].mean())
    force = state.contact_forces.forces.sum(axis=0)  # (x, y, z) of the floor on the cube
    return np.array(travel), np.linalg.norm(force[:2]) / force[2]


mus = [0.0, 0.2, 0.3, 0.5] if QUICK else [0.0, 0.1, 0.2, 0.3, 0.35, 0.45, 0.6]
t = dt * np.arange(1, steps + 1)
fig = offscreen_figure(10.0, 4.0)
ax, cone = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
ratios = []
for mu in mus:
    travel, ratio = slide(mu)
    ratios.append(ratio)
    a = max(0.0, G * (np.sin(theta) - mu * np.cos(theta)))  # the rigid block's acceleration
    rigid = 0.5 * a * t * (t + dt)  # implicit Euler's distance after N steps: a h^2 N (N+1) / 2
    (line,) = ax.plot(t, travel, label=f"μ = {mu}")
    ax.plot(t, rigid, ":", color=line.get_color())
    print(f"mu {mu:.2f}: slid {travel[-1]:7.2f} mm, rigid {rigid[-1]:7.2f}, |f_t|/f_n {ratio:.3f}")
ax.set_xlabel("time (s)")
ax.set_ylabel("distance down the slope (mm)")
ax.set_title("soft cube (solid) and rigid block (dotted)")
ax.legend()
ax.grid(alpha=0.3)
cone.plot(mus, ratios, "o-", label="|f_t| / f_n of the floor's force")
cone.plot(mus, np.minimum(mus, np.tan(theta)), "k:", label="min(μ, tan θ)")
cone.set_xlabel("friction coefficient μ")
cone.set_title("sliding on the cone's edge, sticking inside it")
cone.legend()
cone.grid(alpha=0.3)
save_figure(fig, "contact_friction.png")
