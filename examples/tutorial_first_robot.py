"""Tutorial 1: build a robot from a mesh, add cables, simulate it, save a GIF.

A soft beam clamped at one end, pulled by a cable along its top: the same pieces the Diamond
and the Trunk are made of (mesh -> body -> constraints -> model -> solver -> states).
"""

import numpy as np
from _common import QUICK, out

from pliant import CableActuator, Corotational, EmbeddedPoints, ImplicitEuler, Model, TetBody
from pliant.fem import nodes_in_box
from pliant.mesh import box_beam
from pliant.viz import save_gif
from pliant.viz.model_view import RobotCamera

mesh = box_beam(100.0, 20.0, 20.0, nx=20, ny=4, nz=4)  # mm, 6 tetrahedra per cell
body = TetBody(
    mesh,
    Corotational(young_modulus=300.0, poisson_ratio=0.45),  # kPa
    total_mass=0.04,  # kg
    fixed_nodes=nodes_in_box(mesh.points, [[-1, -1, -1], [0.1, 21, 21]]),
    gravity=(0.0, 0.0, -9810.0),  # mm/s^2
    rayleigh_mass=0.1,
    rayleigh_stiffness=0.1,
)
path = np.column_stack([np.linspace(10, 95, 9), np.full(9, 10.0), np.full(9, 17.0)])
cable = CableActuator(
    EmbeddedPoints(mesh, path),
    body.rest_positions,
    pull_point=[-5.0, 10.0, 17.0],
    max_displacement=15.0,
)
model = Model(body, actuators=[cable], name="beam")
sim = ImplicitEuler(model, dt=0.01)
camera = RobotCamera(model, view=(15.0, -70.0))

state, frames = model.rest_state(), []
steps = 20 if QUICK else 150
for k in range(steps):
    pull = min(10.0, 10.0 * k / (0.5 * steps))  # mm, ramped
    state = sim.step(state, [pull])
    if k % max(1, steps // 15) == 0:
        frames.append(camera.frame(state, title=f"t = {state.time:.2f} s"))
tip_face = mesh.points[:, 0] > 99.9
tip = state.positions[tip_face].mean(axis=0) - mesh.points[tip_face].mean(axis=0)
print(f"cable force {state.actuation[0]:.1f} mN, tip face moved by {np.round(tip, 1)} mm")
save_gif(frames, out("first_robot.gif"), fps=8)
