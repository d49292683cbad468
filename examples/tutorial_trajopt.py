"""Tutorial: trajectory optimisation (thesis §5.2). A box-constrained DDP plans the Diamond's
four cable tensions over a horizon so that its top reaches two successive goals: the forward
pass rolls out the full FEM, the backward pass runs on the effector's condensed dynamics
(a 6-dimensional state, however fine the mesh)."""

import numpy as np
from _common import QUICK, out

from pliant.trajopt import BoxDDP
from pliant.trajopt.plots import plot_trajectory
from pliant.trajopt.scenarios import diamond_two_goals

# The Diamond at rest under gravity; each goal is where a constant tension pattern takes the
# top; bounds 0 <= u <= 1500 mN and |u_k - u_{k-1}| <= 40 mN a step (Eq. 5.28).
problem = diamond_two_goals(
    mesh_size=30.0 if QUICK else 20.0,
    dt=0.02,
    horizon=20 if QUICK else 100,
    max_change=150.0 if QUICK else 40.0,  # a short horizon needs faster changes
    settle=1.0 if QUICK else 3.0,
)
ddp = BoxDDP(max_iterations=3 if QUICK else 30)
result = ddp.solve(problem.dynamics, problem.start, problem.cost, problem.bounds)
report = result.report()
print(
    f"{report['iterations']} iterations ({report['reason']}), cost {result.cost:.3g},"
    f" bound violation {result.bound_violation}, {result.wall_time:.1f} s"
)
half = len(problem.goals) // 2
distance = np.linalg.norm(result.xs[:, :3] - problem.goals, axis=1)
print(
    f"first goal: within {distance[: half + 1].min():.3f} mm during the first half;"
    f" second goal: {distance[-1]:.3f} mm away at the end"
)
plot_trajectory(
    problem.dynamics.dt * np.arange(len(result.xs)),
    {"box-DDP": (result.xs, result.us)},
    problem.goals,
    (problem.bounds.lower, problem.bounds.upper),
    out("trajopt_diamond.png"),
    title="Diamond: two goals, box-DDP on the condensed dynamics",
)
