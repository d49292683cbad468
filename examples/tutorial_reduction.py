"""Tutorial: model order reduction. Snapshots of the Diamond under training pulls, a POD basis
with an ECSW-hyper-reduced integration of its forces, and the reduced model stepped beside the
full one on a held-out actuation (the same step interface: controllers run on it unchanged).
Run it with OPENBLAS_NUM_THREADS=1: the reduced step's dense algebra is small."""

import time

import numpy as np
from _common import QUICK, save_figure

from pliant import ImplicitEuler, robots
from pliant.reduction import build
from pliant.viz.render import offscreen_figure

model = robots.diamond(mesh_size=20.0 if QUICK else 13.0)
full = ImplicitEuler(model, dt=0.01)
steps = 50 if QUICK else 100


def training_pull(t: float) -> np.ndarray:
    """Each cable alone, pulled to 20 mm and released over 0.5 s, one after the other."""
    u = np.zeros(4)
    u[int(t // 0.5) % 4] = 20.0 * np.sin(np.pi * (t % 0.5) / 0.5)
    return u


# 1. Snapshots: the full model's positions every other step.
state, snapshots = model.rest_state(), []
for k in range(2 * steps):
    state = full.step(state, training_pull(k * full.dt))
    if k % 2 == 0:
        snapshots.append(state.positions)

# 2. POD modes up to a tail energy of 1e-3, and the elements (with weights) whose forces
# reproduce the reduced force to tau = 3e-3 on the snapshots (ECSW).
reduced = build(model, np.array(snapshots), pod_tolerance=1e-3, tau=3e-3, tau_membrane=3e-3)
meta = reduced.metadata
print(f"{meta['n_modes']} modes, {meta['tets_selected']} of {len(model.body.mesh.tets)} tets")


# 3. A held-out actuation (three cables at once), full and reduced side by side.
def test_pull(t: float) -> np.ndarray:
    return np.array([12.0, 5.0, 0.0, 8.0]) * min(1.0, t / 0.5)


solver = reduced.solver(model, dt=0.01)  # step(state, commands) -> state, as ImplicitEuler
effector = model.effectors[0]
rest = effector.position(model.body.rest_positions)[0]
state, small = model.rest_state(), solver.rest_state()
times, paths, clock = [], {"full": [], "reduced": []}, {"full": 0.0, "reduced": 0.0}
for k in range(steps):
    u = test_pull(k * full.dt)
    for name, sim in (("full", full), ("reduced", solver)):
        start = time.perf_counter()
        if name == "full":
            state = sim.step(state, u)
        else:
            small = sim.step(small, u)
        clock[name] += time.perf_counter() - start
    times.append(state.time)
    paths["full"].append(effector.position(state.positions)[0] - rest)
    paths["reduced"].append(effector.position(small.positions)[0] - rest)
paths = {k: np.array(v) for k, v in paths.items()}
error = np.linalg.norm(paths["full"] - paths["reduced"], axis=1).max()
print(
    f"effector moved {np.linalg.norm(paths['full'][-1]):.2f} mm; reduced within {error:.3f} mm;"
    f" {steps / clock['full']:.0f} vs {steps / clock['reduced']:.0f} steps/s (full vs reduced)"
)

fig = offscreen_figure(6.5, 3.8)
ax = fig.add_subplot(1, 1, 1)
for axis, name in enumerate("xyz"):
    (line,) = ax.plot(times, paths["full"][:, axis], label=f"full, {name}")
    ax.plot(
        times, paths["reduced"][:, axis], "--", color=line.get_color(), label=f"reduced, {name}"
    )
ax.set_xlabel("time (s)")
ax.set_ylabel("effector displacement (mm)")
ax.set_title(f"Diamond, held-out pulls: {meta['n_modes']} modes, {meta['tets_selected']} tets")
ax.legend(ncol=3, fontsize=8)
ax.grid(alpha=0.3)
save_figure(fig, "reduction_diamond.png")
