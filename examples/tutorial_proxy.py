"""Tutorial: beam-skeleton proxies (thesis §4.1). The Multigait's proxy, 19 rod nodes whose rest
curvatures are the actuation, walks the hand-defined gait beside the FEM Multigait (2041
nodes, 5 inflated chambers): the same travel at a fraction of the cost."""

import time

import numpy as np
from _common import QUICK, save_figure

from pliant import ImplicitEuler
from pliant.mesh.multigait import CHAMBERS
from pliant.proxy import multigait_proxy
from pliant.proxy.actuation import ProxySolver
from pliant.robots.multigait import demo_actuation, multigait
from pliant.viz.render import offscreen_figure

steps = 60 if QUICK else 1080  # 3 gait cycles of 3.6 s at dt = 0.01 s
centre, leg = 4900.0, 3300.0  # the FEM's volume commands of an inflated chamber (mm^3)
amplitude = np.where(np.array(CHAMBERS) == "centre", centre, leg)

# The proxy takes each chamber's command as a bending in [0, 1]: the FEM's over its amplitude.
proxy = multigait_proxy()  # calibrated defaults
proxy_solver = ProxySolver(proxy, ImplicitEuler(proxy.model, dt=0.01))
fem = multigait()
fem_solver = ImplicitEuler(fem, dt=0.01)

travel, seconds = {}, {}
for name, solver, model, command, where in (
    ("proxy", proxy_solver, proxy.model, lambda v: v / amplitude, proxy.skeleton),
    ("FEM", fem_solver, fem, lambda v: v, lambda x: x),
):
    state = model.rest_state()
    start_x = where(state.positions)[:, 0].mean()
    xs, clock = [], time.perf_counter()
    for _ in range(steps):
        volumes = demo_actuation(state.time, amplitude=(centre, leg))
        state = solver.step(state, command(volumes))
        xs.append(where(state.positions)[:, 0].mean() - start_x)
    seconds[name] = time.perf_counter() - clock
    travel[name] = np.array(xs)
    print(
        f"{name}: travelled {travel[name][-1]:.2f} mm along x in {steps} steps,"
        f" {steps / seconds[name]:.0f} steps/s"
    )

fig = offscreen_figure(6.5, 3.8)
ax = fig.add_subplot(1, 1, 1)
t = 0.01 * np.arange(1, steps + 1)
for name, xs in travel.items():
    ax.plot(t, xs, label=f"{name} ({steps / seconds[name]:.0f} steps/s)")
ax.set_xlabel("time (s)")
ax.set_ylabel("mean x (mm); forward is -x")
ax.set_title("Multigait walking the hand gait: FEM and proxy")
ax.legend()
ax.grid(alpha=0.3)
save_figure(fig, "proxy_multigait.png")
