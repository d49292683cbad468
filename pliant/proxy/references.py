"""The FEM robots' side of a calibration: the trajectory of matched points that a proxy is
fitted to, and each robot's calibration set-up (search box, matched points, commands).

Trunk (thesis L694: a 0.6 s trajectory of 2 actions, the points of the external mesh, no
cube): the FEM Trunk (base fixed) pulls its cables in four 0.3 s phases (towards +x, then +y
at the tip, then -x with the base half towards -y, then release); the matched points are its
surface nodes. The proxy's commands follow from the cables by a linear correspondence, the
assumption that this calibration's error measures: a beam bends towards a side by the pull of
the cables on that side less the opposite ones, each over its longest course (70 mm long
cables, 40 mm short ones); the long cables, which run the whole length, bend both beams, the
short ones (to mid-length) the lower one: u_upper = dl / 70, u_lower = (dl / 70 + ds / 40) / 2.

Multigait (thesis L694): the hand-defined gait (:func:`pliant.robots.multigait.demo_actuation`,
every chamber inflated to its volume and deflated in turn) for 10.8 s at dt = 0.01 s, the
matched points on the bottom face (the FEM's underside nodes, skinned on the proxy). A proxy
command is the FEM's volume command over its amplitude, in [0, 1].
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pliant.errors import ModelError, UnknownRobotError
from pliant.files import load_npz, save_npz
from pliant.mesh.multigait import CHAMBERS
from pliant.proxy.builders import MULTIGAIT_PARAMETERS, Proxy, multigait_proxy, trunk_proxy
from pliant.proxy.calibrate import rollout
from pliant.proxy.skinning import Skinning
from pliant.robots.common import settled
from pliant.robots.multigait import _face_nodes, chamber_amplitudes, demo_actuation, multigait
from pliant.robots.trunk import trunk
from pliant.robots.trunk_cube import trunk_cube
from pliant.solvers import ImplicitEuler


@dataclass(frozen=True)
class Reference:
    """A FEM trajectory: proxy commands (T, n) of each step, the FEM's matched points (T, K,
    3) after it, their rest positions (K, 3), the time step, and the FEM robot's mass (kg;
    NaN where unknown: files saved before it was kept)."""

    commands: np.ndarray
    points: np.ndarray
    surface: np.ndarray
    dt: float
    mass: float = float("nan")

    def save(self, path) -> None:
        save_npz(
            path, compressed=True, commands=self.commands, points=self.points,
            surface=self.surface, dt=self.dt, mass=self.mass,
        )  # fmt: skip

    @classmethod
    def load(cls, path) -> Reference:
        """Raises CorruptFileError for a damaged file, FileNotFoundError for none."""
        data = load_npz(path, "a proxy calibration reference")
        mass = float(data["mass"]) if "mass" in data else float("nan")
        return cls(data["commands"], data["points"], data["surface"], float(data["dt"]), mass)


#: The Multigait's 16-action calibration sequence (the thesis': "16 actions of 5-cavity
#: patterns", not listed): the proxy environment's actions (Discrete(6): 2 g inflates group g
#: of centre, front, rear legs; 2 g + 1 deflates it), two Gray-code cycles through the 8
#: on/off states of the three groups, each action changing one group as the environment's do.
#: The first flips rear, front, rear, centre, ...; the second front, rear, front, centre, ...:
#: every state is visited twice and entered from two sides, and both alternations of the legs
#: with the centre off are in it.
MULTIGAIT_PATTERNS = (4, 2, 5, 0, 4, 3, 5, 1) + (2, 4, 3, 0, 2, 5, 3, 1)


#: duration (s) of one Multigait action: the proxy environment's step, the hand gait's phase
MULTIGAIT_ACTION = 0.6


def pattern_levels(actions, t: float, *, phase: float = MULTIGAIT_ACTION) -> np.ndarray:
    """(5,) chamber commands in [0, 1] at time `t` of a sequence of Multigait actions, each
    ramped over its `phase` s as the hand gait's are; after the sequence, its last state."""
    groups = {0: ("centre",), 1: ("front_left", "front_right"), 2: ("rear_left", "rear_right")}
    if not all(isinstance(a, int | np.integer) and 0 <= a < 6 for a in actions):
        raise ModelError(f"Multigait actions are integers in [0, 6), got {list(actions)}")
    level = np.zeros(len(CHAMBERS))
    k, frac = divmod(t / phase, 1.0)
    for i, action in enumerate(actions):
        if i > k:
            break
        group, off = divmod(int(action), 2)
        target = 0.0 if off else 1.0
        for name in groups[group]:
            j = CHAMBERS.index(name)
            level[j] = target if i < k else level[j] + frac * (target - level[j])
    return level


def multigait_reference(
    *,
    duration: float = 10.8,
    dt: float = 0.01,
    mesh_size: float = 6.0,
    spacing: float = 10.0,
    actions=None,
) -> Reference:
    """The FEM Multigait walking its hand gait for `duration` s, or (`actions`) a sequence of
    the proxy environment's actions of 0.6 s each (:data:`MULTIGAIT_PATTERNS`); matched
    points: its underside nodes, one per `spacing` mm cell and along the outline."""
    model = multigait(mesh_size=mesh_size)
    nodes = _face_nodes(model.body.mesh, spacing)
    amplitude = chamber_amplitudes()  # demo_actuation's (mm^3 of volume growth)
    if actions is not None:
        duration = MULTIGAIT_ACTION * len(actions)
    solver, state = ImplicitEuler(model, dt), model.rest_state()
    commands, points = [], []
    for _ in range(int(round(duration / dt))):
        if actions is None:
            volume = demo_actuation(state.time)
        else:
            volume = pattern_levels(actions, state.time) * amplitude
        state = solver.step(state, volume)
        commands.append(volume / amplitude)
        points.append(state.positions[nodes].copy())
    return Reference(
        np.array(commands), np.array(points), model.body.rest_positions[nodes].copy(), dt,
        model.body.total_mass,
    )  # fmt: skip


def multigait_patterns_reference(**kwargs) -> Reference:
    """:func:`multigait_reference` under :data:`MULTIGAIT_PATTERNS` (9.6 s)."""
    return multigait_reference(actions=MULTIGAIT_PATTERNS, **kwargs)


#: The hand gait as the environment's actions: rear, centre, front inflated, then deflated in
#: that order, three cycles (10.8 s; :func:`pliant.robots.multigait.demo_actuation`).
MULTIGAIT_HAND_GAIT = (4, 0, 2, 5, 1, 3) * 3


def multigait_joint_reference(**kwargs) -> Reference:
    """:func:`multigait_reference` under the hand gait then the 16 patterns, one trajectory
    (20.4 s): a proxy fitted on both."""
    return multigait_reference(actions=MULTIGAIT_HAND_GAIT + MULTIGAIT_PATTERNS, **kwargs)


#: the Trunk's calibration phases: cable shortenings (mm; cables 0-3 long, on +y, -x, -y,
#: +x; 4-7 short, same sides), each reached at 1 mm a step and held to the phase's end.
TRUNK_PHASES = (
    (0.0, 0.0, 0.0, 20.0, 0.0, 0.0, 0.0, 15.0),
    (20.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 15.0),
    (0.0, 20.0, 0.0, 0.0, 0.0, 0.0, 15.0, 0.0),
    (0.0,) * 8,
)


#: Other cable phases, to validate a Trunk proxy on actions it was not fitted on: towards -y
#: (long and short), then -x and -y long with +y short (an S-bend), then +x long alone, further
#: than any fitted phase (30 mm), then release.
TRUNK_OTHER_PHASES = (
    (0.0, 0.0, 20.0, 0.0, 0.0, 0.0, 15.0, 0.0),
    (0.0, 10.0, 10.0, 0.0, 15.0, 0.0, 0.0, 0.0),
    (0.0, 0.0, 0.0, 30.0, 0.0, 0.0, 0.0, 0.0),
    (0.0,) * 8,
)


#: Cable phases that pull opposite cables together, to fit the proxy's axial commands
#: (``trunk_proxy(lower_cocontraction=, upper_cocontraction=)``): all eight cables to half and
#: to all of the Trunk environment's courses (14 / 8 mm), the long ones alone, the short ones
#: alone, a +x bend over a common pull, then release.
TRUNK_COCONTRACTION_PHASES = (
    (7.0,) * 4 + (4.0,) * 4,
    (14.0,) * 4 + (8.0,) * 4,
    (14.0,) * 4 + (0.0,) * 4,
    (0.0,) * 4 + (8.0,) * 4,
    (4.0, 4.0, 4.0, 14.0, 2.0, 2.0, 2.0, 8.0),
    (0.0,) * 8,
)


def trunk_commands(cables: np.ndarray, axial: bool = False) -> np.ndarray:
    """(5,) the Trunk proxy's commands (lower_d1, lower_d2, upper_d1, upper_d2, base) for
    cable shortenings (8,) (module docstring). Bending towards +x is +d2, towards +y -d1.
    `axial`: (7,), the beams' axial commands (lower, upper) before the base: what opposite
    cables pull in common (the lesser of each pair), over the course, mapped as the bendings
    are (the long cables shorten both beams, the short ones the lower)."""
    c = np.asarray(cables, dtype=float)
    long_x, long_y = (c[3] - c[1]) / 70.0, (c[0] - c[2]) / 70.0
    short_x, short_y = (c[7] - c[5]) / 40.0, (c[4] - c[6]) / 40.0
    lower_x, lower_y = 0.5 * (long_x + short_x), 0.5 * (long_y + short_y)
    bend = [-lower_y, lower_x, -long_y, long_x]
    if axial:
        long_c = 0.5 * (min(c[1], c[3]) + min(c[0], c[2])) / 70.0
        short_c = 0.5 * (min(c[5], c[7]) + min(c[4], c[6])) / 40.0
        bend += [0.5 * (long_c + short_c), long_c]
    return np.clip([*bend, 0.0], -1.0, 1.0)


def trunk_reference(
    *,
    phase: float = 0.3,
    dt: float = 0.01,
    mesh_size: float = 8.0,
    phases=TRUNK_PHASES,
    axial: bool = False,
) -> Reference:
    """The FEM Trunk through `phases` (:data:`TRUNK_PHASES`); matched points: its surface
    nodes; `axial`: the commands of a proxy with axial commands (:func:`trunk_commands`)."""
    model = trunk(mesh_size=mesh_size)
    nodes = np.unique(model.body.mesh.boundary_triangles())
    solver, state = ImplicitEuler(model, dt), model.rest_state()
    steps = int(round(phase / dt))
    commands, points = [], []
    for target in phases:
        for _ in range(steps):
            state = solver.step(state, np.array(target))
            # What the cables reached (1 mm a step at most), not what was asked.
            commands.append(trunk_commands(state.displacement, axial))
            points.append(state.positions[nodes].copy())
    return Reference(
        np.array(commands), np.array(points), model.body.rest_positions[nodes].copy(), dt,
        model.body.total_mass,
    )  # fmt: skip


#: Steps both models settle under gravity before the cube's calibration trajectory.
SETTLE_STEPS = 50


def trunk_cube_reference(*, dt: float = 0.01, mesh_size: float = 8.0) -> Reference:
    """The cube's a-posteriori calibration (thesis L694: the proxy calibrated without the
    cube, its weight fitted afterwards): the FEM Trunk, base fixed, settled with the cube,
    bends towards it (+x cables: the long one to 7 mm, the short one to 4 mm, both beams'
    bending 0.1, reached in five 0.3 s ramps and held 2.1 s) and pushes it; the points are
    the cube's centre (T, 1, 3), the commands the bendings the cables reach
    (:func:`trunk_commands`)."""
    model = trunk_cube(mesh_size=mesh_size, base_motion=lambda t: 0.0)
    solver = ImplicitEuler(model, dt)
    state = settled(model, solver, SETTLE_STEPS)
    start = state.rigid_positions[:1].copy()
    steps = int(round(0.3 / dt))
    levels = np.minimum(np.arange(1, 13), 5) * 0.02  # 0.02 more a phase up to 0.1, held
    commands, points = [], []
    for k, level in enumerate(levels):
        previous = levels[k - 1] if k else 0.0
        for j in range(steps):
            u = previous + (level - previous) * (j + 1) / steps
            cables = np.zeros(8)
            cables[3], cables[7] = 70.0 * u, 40.0 * u
            state = solver.step(state, cables)
            commands.append(trunk_commands(state.displacement))
            points.append(state.rigid_positions[:1].copy())
    return Reference(np.array(commands), np.array(points), start, dt)


def _trunk_alone(**parameters) -> Proxy:
    """The Trunk proxy as calibrated: base fixed, neither cube nor floor in reach."""
    return trunk_proxy(cube_position=None, floor_height=-1000.0, **parameters)


@dataclass(frozen=True)
class Setup:
    """How to calibrate one robot's proxy: its builder, the search box, the FEM reference."""

    build: Callable[..., Proxy]
    space: dict[str, tuple[float, float]]
    reference: Callable[..., Reference]
    #: a trajectory under other actions than the fitted ones, to validate on (and its name)
    other: tuple[str, Callable[..., Reference]] | None = None
    #: duration (s) of one action along the reference, the interval a travel term is
    #: measured over (None: the reference is not a sequence of actions)
    action_duration: float | None = None

    def simulate(self, reference: Reference) -> Callable[[dict[str, float]], np.ndarray]:
        """parameters -> (T, K, 3) the proxy's skinned matched points along `reference`."""

        def run(parameters: dict[str, float]) -> np.ndarray:
            proxy = self.build(**parameters)
            skin = Skinning(proxy.rod, reference.surface, neighbours=2)
            return rollout(
                proxy, reference.commands, lambda s: skin.positions(s.positions), dt=reference.dt
            )

        return run

    def mass(self, parameters: dict[str, float]) -> float:
        """The proxy's mass (kg) with these parameters."""
        return float(self.build(**parameters).rod.total_mass)


class CubeSetup(Setup):
    """The Trunk proxy's cube fitted a posteriori: the matched point is the cube's centre."""

    def simulate(self, reference: Reference) -> Callable[[dict[str, float]], np.ndarray]:
        def run(parameters: dict[str, float]) -> np.ndarray:
            return rollout(
                self.build(**parameters),
                reference.commands,
                lambda s: s.rigid_positions[:1].copy(),
                dt=reference.dt,
                settle=SETTLE_STEPS,
            )

        return run


def _around(values: dict[str, float], low: float, high: float) -> dict[str, tuple[float, float]]:
    return {k: (low * v, high * v) for k, v in values.items()}


SETUPS = {
    # Search box of 0.3x to 3x the values found so far (thesis: "restricted around
    # hand-found values"); the first round's centre was hand-set.
    "multigait": Setup(
        multigait_proxy,
        _around(MULTIGAIT_PARAMETERS, 0.3, 3.0),
        multigait_reference,
        action_duration=MULTIGAIT_ACTION,
    ),
    # The thesis' 16-action calibration (MULTIGAIT_PATTERNS), the same box; its validation on
    # other actions is the hand gait (`pliant proxy calibrate multigait-patterns`).
    "multigait-patterns": Setup(
        multigait_proxy,
        _around(MULTIGAIT_PARAMETERS, 0.3, 3.0),
        multigait_patterns_reference,
        other=("multigait", multigait_reference),
        action_duration=MULTIGAIT_ACTION,
    ),
    # Hand-set: from a third of the FEM's E (450 kPa) to the thesis' 14332 kPa (round 1 stopped
    # at 4500, its best at the edge), its 42 g, and curvatures
    # from a cable's pull over its distance to the axis.
    "trunk": Setup(
        _trunk_alone,
        {
            "lower_stiffness": (150.0, 15000.0),
            "upper_stiffness": (150.0, 15000.0),
            "lower_density": (2e-7, 2e-6),
            "upper_density": (2e-7, 2e-6),
            "lower_curvature": (0.005, 0.1),
            "upper_curvature": (0.01, 0.15),
        },
        trunk_reference,
        other=("trunk-other", lambda: trunk_reference(phases=TRUNK_OTHER_PHASES)),
    ),
    "multigait-joint": Setup(
        multigait_proxy,
        _around(MULTIGAIT_PARAMETERS, 0.3, 3.0),
        multigait_joint_reference,
        action_duration=MULTIGAIT_ACTION,
    ),
    # The cube's mass, a posteriori (the calibrated Trunk proxy; the FEM's cube is 10 g).
    "trunk-cube": CubeSetup(trunk_proxy, {"cube_mass": (0.002, 0.05)}, trunk_cube_reference),
}


def setup(robot: str) -> Setup:
    if robot not in SETUPS:
        raise UnknownRobotError(f"no proxy calibration for {robot!r}; known: {sorted(SETUPS)}")
    return SETUPS[robot]
