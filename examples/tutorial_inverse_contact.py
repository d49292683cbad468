"""Tutorial: inverse control with contact (QPCC). The Trunk pushes a cube on an air table to
5, 10 and 15 mm: the cube's position is an effector that the cables move only through the
trunk-cube contact, so the inverse QP must choose cable forces *and* which contacts close."""

import numpy as np
from _common import QUICK, save_figure

from pliant import ImplicitEuler
from pliant.robots.trunk_cube import PushControl, trunk_push
from pliant.viz.model_view import RobotCamera
from pliant.viz.render import offscreen_figure

model = trunk_push()  # the Trunk, its 8 cables, a 50 mm cube 0.3 mm from its side
sim = ImplicitEuler(model, dt=0.01)
state = model.rest_state()
start = state.rigid_positions[0].copy()  # the cube's centre
targets = [5.0] if QUICK else [5.0, 10.0, 15.0]  # mm along x
steps_per_target = 60 if QUICK else 150

times, cube_x, goal_x = [], [], []
for offset in targets:
    # Each step PushControl moves the cube's goal towards the target by at most 10 mm/s and
    # keeps the trunk's point facing the cube pressed 2 mm into its face (the contact the QP
    # must keep closed to push); InverseControl solves Eq. 2.15 with complementarity.
    control = PushControl(start + [offset, 0.0, 0.0], dt=sim.dt)
    for _ in range(steps_per_target):
        state = sim.step(state, control)
        times.append(state.time)
        cube_x.append(state.rigid_positions[0, 0] - start[0])
        goal_x.append(offset)
    print(
        f"target +{offset:.0f} mm: cube at +{cube_x[-1]:.3f} mm, cable forces"
        f" {np.round(state.actuation, 0).tolist()} mN"
    )

fig = offscreen_figure(10.0, 4.5)
ax = fig.add_subplot(1, 2, 1)
ax.imshow(RobotCamera(model, view=(20.0, -60.0), size=(480, 360)).frame(state))
ax.set_axis_off()
ax.set_title(f"t = {state.time:.1f} s")
ax = fig.add_subplot(1, 2, 2)
ax.plot(times, goal_x, "k:", label="target")
ax.plot(times, cube_x, label="cube (pushed through the contact)")
ax.set_xlabel("time (s)")
ax.set_ylabel("cube x (mm)")
ax.legend()
ax.grid(alpha=0.3)
save_figure(fig, "inverse_contact.png")
