"""Tutorial: cables and cavities. The Soft Finger closed by a cable and the PneuNet bent by
its chambers' pressure, each swept slowly through its command range: the tip's motion, the
cable's tension and the cavity's volume growth against the command."""

import numpy as np
from _common import QUICK, save_figure

from pliant import ImplicitEuler, robots
from pliant.viz.model_view import RobotCamera
from pliant.viz.render import offscreen_figure


def sweep(model, command, n_steps: int, settle: int):
    """Let the robot settle under gravity for `settle` steps of 0.01 s, then ramp the commands
    from 0 to `command(1)` over `n_steps` steps (slow enough to be nearly quasi-static);
    record the tip and the actuator during the ramp."""
    sim = ImplicitEuler(model, dt=0.01)
    x0 = model.body.rest_positions
    tip = x0[:, 0] > x0[:, 0].max() - 1.0  # the nodes of the free end
    state, rows = model.rest_state(), []
    for _ in range(settle):
        state = sim.step(state, command(0.0))
    for k in range(n_steps):
        u = command((k + 1) / n_steps)
        state = sim.step(state, u)
        moved = state.positions[tip].mean(axis=0) - x0[tip].mean(axis=0)
        rows.append([u[0], *moved, state.actuation[0], state.displacement[0]])
    return state, np.array(rows)


n_steps, settle = (15, 5) if QUICK else (200, 100)

# A cable in displacement mode: the command is how far the cable is pulled (mm), the solver
# finds the tension (mN) that achieves it. Cable 1 (the upper one) is held at zero.
finger = robots.soft_finger()
finger_state, finger_rows = sweep(finger, lambda s: np.array([15.0 * s, 0.0]), n_steps, settle)

# A cavity in pressure mode: the command is the pressure (kPa), the solver finds the volume
# growth (mm^3). All six chambers share one actuator.
pneunet = robots.pneunet(mesh_size=8.0 if QUICK else 6.0)
pneunet_state, pneunet_rows = sweep(pneunet, lambda s: np.array([30.0 * s]), n_steps, settle)

for name, rows in (("finger", finger_rows), ("pneunet", pneunet_rows)):
    u, dx, _, dz, force, delta = rows[-1]
    print(
        f"{name}: command {u:.1f}, tip moved ({dx:.1f}, {dz:.1f}) mm (x, z),"
        f" lambda {force:.1f}, delta {delta:.1f}"
    )

fig = offscreen_figure(10.0, 7.0)
for col, (model, state, rows, what) in enumerate(
    (
        (finger, finger_state, finger_rows, ("cable pull (mm)", "tension (mN)")),
        (pneunet, pneunet_state, pneunet_rows, ("pressure (kPa)", "volume growth (mm³)")),
    )
):
    image = RobotCamera(model, view=(10.0, -80.0), size=(480, 360)).frame(state)
    ax = fig.add_subplot(2, 2, 1 + col)
    ax.imshow(image)
    ax.set_axis_off()
    ax.set_title(f"{model.name}, {what[0].split(' (')[0]} {rows[-1, 0]:.0f}")
    ax = fig.add_subplot(2, 2, 3 + col)
    ax.plot(rows[:, 0], rows[:, 1], label="tip x (mm)")
    ax.plot(rows[:, 0], rows[:, 3], label="tip z (mm)")
    ax.set_xlabel(what[0])
    ax.legend(loc="upper left")
    ax.grid(alpha=0.3)
    twin = ax.twinx()
    twin.plot(rows[:, 0], rows[:, 5 if col else 4], "k--", label=what[1])
    twin.set_ylabel(what[1])
save_figure(fig, "actuators.png")
