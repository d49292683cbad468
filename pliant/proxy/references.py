"""The FEM robots' side of a calibration: the trajectory of matched points that a proxy is
fitted to, and each robot's calibration set-up (search box, matched points, commands).

Multigait (thesis L694): the hand-defined gait (:func:`pliant.robots.multigait.demo_actuation`,
every chamber inflated to its volume and deflated in turn) for 10.8 s at dt = 0.01 s, the
matched points on the bottom face (the FEM's underside nodes, skinned on the proxy). A proxy
command is the FEM's volume command over its amplitude, in [0, 1].
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pliant.errors import UnknownRobotError
from pliant.mesh.multigait import CHAMBERS
from pliant.proxy.builders import MULTIGAIT_PARAMETERS, Proxy, multigait_proxy
from pliant.proxy.calibrate import rollout
from pliant.proxy.skinning import Skinning
from pliant.solvers import ImplicitEuler


@dataclass(frozen=True)
class Reference:
    """A FEM trajectory: proxy commands (T, n) of each step, the FEM's matched points (T, K,
    3) after it, their rest positions (K, 3) and the time step."""

    commands: np.ndarray
    points: np.ndarray
    surface: np.ndarray
    dt: float

    def save(self, path) -> None:
        np.savez_compressed(
            path, commands=self.commands, points=self.points, surface=self.surface, dt=self.dt
        )

    @classmethod
    def load(cls, path) -> Reference:
        data = np.load(path)
        return cls(data["commands"], data["points"], data["surface"], float(data["dt"]))


def multigait_reference(
    *, duration: float = 10.8, dt: float = 0.01, mesh_size: float = 6.0, spacing: float = 10.0
) -> Reference:
    """The FEM Multigait walking its gait for `duration` s; matched points: its underside
    nodes, one per `spacing` mm cell and along the outline."""
    from pliant.robots.multigait import _underside_nodes, demo_actuation, multigait

    model = multigait(mesh_size=mesh_size)
    nodes = _underside_nodes(model.body.mesh, spacing)
    centre, leg = 4900.0, 3300.0  # demo_actuation's amplitudes (mm^3 of volume growth)
    amplitude = np.where(np.array(CHAMBERS) == "centre", centre, leg)
    solver, state = ImplicitEuler(model, dt), model.rest_state()
    commands, points = [], []
    for _ in range(int(round(duration / dt))):
        volume = demo_actuation(state.time, amplitude=(centre, leg))
        state = solver.step(state, volume)
        commands.append(volume / amplitude)
        points.append(state.positions[nodes].copy())
    return Reference(
        np.array(commands), np.array(points), model.body.rest_positions[nodes].copy(), dt
    )


@dataclass(frozen=True)
class Setup:
    """How to calibrate one robot's proxy: its builder, the search box, the FEM reference."""

    build: Callable[..., Proxy]
    space: dict[str, tuple[float, float]]
    reference: Callable[..., Reference]

    def simulate(self, reference: Reference) -> Callable[[dict[str, float]], np.ndarray]:
        """parameters -> (T, K, 3) the proxy's skinned matched points along `reference`."""

        def run(parameters: dict[str, float]) -> np.ndarray:
            proxy = self.build(**parameters)
            skin = Skinning(proxy.rod, reference.surface, neighbours=2)
            return rollout(proxy, reference.commands, skin.positions, dt=reference.dt)

        return run


def _around(values: dict[str, float], low: float, high: float) -> dict[str, tuple[float, float]]:
    return {k: (low * v, high * v) for k, v in values.items()}


SETUPS = {
    # Search box of 0.3x to 3x the values found so far (thesis: "restricted around
    # hand-found values"); the first round's centre was hand-set.
    "multigait": Setup(
        multigait_proxy, _around(MULTIGAIT_PARAMETERS, 0.3, 3.0), multigait_reference
    ),
}


def setup(robot: str) -> Setup:
    if robot not in SETUPS:
        raise UnknownRobotError(f"no proxy calibration for {robot!r}; known: {sorted(SETUPS)}")
    return SETUPS[robot]
