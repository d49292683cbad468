"""Tutorial 2: inverse control (thesis Eq. 2.15): the Diamond's top point follows goals, the
QP choosing the four cable forces, first without then with a contact-free static check."""

import numpy as np
from _common import QUICK, out

from pliant import ImplicitEuler, robots
from pliant.scenario import track_goals
from pliant.viz import plot_trajectory

model = robots.diamond(mesh_size=20.0 if QUICK else 13.0)
sim = ImplicitEuler(model, dt=0.01)
goals = robots.entry("diamond").trajectories["lifted_circle"](4 if QUICK else 12)
results, state = track_goals(model, sim, model.rest_state(), goals, max_steps=30)
errors = [r.error for r in results]
print(f"{len(goals)} goals, error mean {np.mean(errors):.3f} mm, max {np.max(errors):.3f} mm")
plot_trajectory(
    np.array([r.goal for r in results]),
    np.array([r.reached for r in results]),
    out("inverse_circle.png"),
    title="Diamond: goals and reached effector positions",
)
