"""Control by gradient: the Trunk reaching a goal, open loop and closed loop.

Open loop: the eight cable tensions over the horizon minimise a tracking loss of the full FEM
rollout by L-BFGS-B on its exact gradient (pliant.diff.optimise_controls: one rollout and
its adjoint per evaluation), beside the box-DDP of pliant.trajopt on the same task. Closed loop:
a small torch policy reads the tip and the goal at each control step and sets the tensions;
its parameters follow the exact gradient of an episode's loss (pliant.diff.policy.closed_loop,
back-propagation through time with each step's adjoint), goal after goal.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import torch  # noqa: E402
from _common import QUICK, save_figure  # noqa: E402

from pliant import robots  # noqa: E402
from pliant.diff import ControlPenalty, Losses, PointTracking, optimise_controls, rollout  # noqa: E402
from pliant.diff.policy import closed_loop, embedded_positions  # noqa: E402
from pliant.solvers import ImplicitEuler  # noqa: E402
from pliant.trajopt import ActuationBounds, BoxDDP  # noqa: E402
from pliant.trajopt.scenarios import trunk_reach  # noqa: E402

horizon, iterations = (10, 4) if QUICK else (40, 40)
# The coarse Trunk (712 tetrahedra); its tip to the point where tensions (1000, 0, 0, 600, ...)
# mN hold it, about 30 mm from where it hangs under gravity.
scenario = trunk_reach(mesh_size=8.0, horizon=horizon)
model = robots.trunk(mesh_size=8.0, cable_mode="force")
solver = ImplicitEuler(model, scenario.dynamics.dt, tangent="fresh")  # the exact step
tip = model.effectors[0].points
goal = scenario.goals[-1]
loss = Losses(
    PointTracking(tip, goal[None], n_steps=horizon),  # 1/2 |p_k - goal|^2 at every step
    PointTracking(tip, np.zeros((1, 3)), n_steps=horizon, weight=1e-3, quantity="velocities"),
    ControlPenalty(1e-6),
)
lower, upper = np.zeros(8), np.full(8, 1500.0)  # mN
lbfgs = optimise_controls(
    model,
    solver,
    scenario.start,
    loss,
    np.zeros((horizon, 8)),
    lower=lower,
    upper=upper,
    max_iterations=iterations,
)
ddp = BoxDDP(max_iterations=iterations, tolerance=1e-4).solve(
    scenario.dynamics, scenario.start, scenario.cost, ActuationBounds(lower, upper)
)


def tip_distances(controls):
    states = rollout(model, solver, scenario.start, np.asarray(controls))
    return [float(np.linalg.norm(tip.positions(s.positions)[0] - goal)) for s in states]


print(
    f"L-BFGS-B: {lbfgs.iterations} iterations, {lbfgs.evaluations} rollouts with adjoint,"
    f" {lbfgs.wall_time:.1f} s, loss {lbfgs.loss:.1f}"
)
print(f"box-DDP: {ddp.iterations} iterations, {ddp.rollouts} rollouts, {ddp.wall_time:.1f} s")
lbfgs_path, ddp_path = tip_distances(lbfgs.controls), tip_distances(ddp.us)
assert lbfgs_path[-1] < lbfgs_path[0]

# Closed loop: tensions = 1500 sigmoid(MLP(tip - goal)), trained on random goals around the
# first (within 15 mm), 5 control steps of 2 solver steps each per episode.
torch.manual_seed(0)
policy = torch.nn.Sequential(
    torch.nn.Linear(3, 32), torch.nn.Tanh(), torch.nn.Linear(32, 8)
).double()
optimiser = torch.optim.Adam(policy.parameters(), lr=1e-2)
rng = np.random.default_rng(0)
episode_losses = []
for _ in range(3 if QUICK else 40):
    target = torch.as_tensor(goal + rng.uniform(-15.0, 15.0, 3))

    def tensions(q, v, n, target=target):
        return 1500.0 * torch.sigmoid(policy((embedded_positions(tip, q)[0] - target) / 10.0))

    episode = closed_loop(model, solver, scenario.start, tensions, 5, substeps=2)
    reached = torch.stack([embedded_positions(tip, q)[0] for q, _ in episode[1:]])
    mean_distance = torch.linalg.norm(reached - target, dim=1).mean()
    optimiser.zero_grad()
    mean_distance.backward()  # through 10 solver steps: their adjoints
    optimiser.step()
    episode_losses.append(float(mean_distance.detach()))
print(f"policy: mean tip distance {episode_losses[0]:.1f} mm -> {episode_losses[-1]:.1f} mm")

fig, axes = plt.subplots(1, 2, figsize=(9, 3.2))
t = scenario.dynamics.dt * np.arange(horizon + 1)
axes[0].plot(t, lbfgs_path, label="L-BFGS-B + adjoint")
axes[0].plot(t, ddp_path, "--", label="box-DDP")
axes[0].set(xlabel="time (s)", ylabel="tip to goal (mm)", title="open loop")
axes[0].legend(fontsize=7)
axes[1].plot(np.arange(1, len(episode_losses) + 1), episode_losses, "o-", ms=3)
axes[1].set(xlabel="episode", ylabel="mean tip to goal (mm)", title="policy, closed loop")
save_figure(fig, "diff_control.png")
