"""Transfer of a strategy found on a proxy to its FEM robot (thesis §4.1.1, Fig. 4.2; the
authors' ``ControllerWithProxy``): the FEM robot follows the proxy's trajectory by closed-loop
inverse control on matched points, inside two outer loops.

Each proxy step (one step of the proxy environment: ``scale`` sub-steps, its action from a
policy or a fixed sequence), the proxy's matched points after each sub-step are the goals g of
a position effector of the FEM robot on the same points, and for each sub-step:

1. goal correction (proportional): g' = g + Kp (g - p), p the FEM's points now (with
   ``follow_shape``, g first loses the mean gap of g - p along the floor: the Multigait's
   inverse model then follows the proxy's shape, not its place);
2. the inverse model (``inverse_model="qp"``, the thesis'): the QP of Eq. 2.15 (with
   complementarity where the robot touches something) stepped ``inverse_steps`` times towards
   g' from a copy of the FEM's state, a look-ahead that gives the actuation reaching the goal
   rather than the part of it one step affords; its actuator displacements (volume growths,
   cable shortenings) are a_inv. The look-ahead's contacts are frictionless by default
   (`lookahead_friction` keeps them): with the Multigait's friction (0.7) the QPCC once found
   no feasible contact state at any step, even for goals where the points already were
   (ProxQP's loose infeasibility certificates, fixed: the resting walker now solves). From
   the walker's rest state, with no contact forces to seed its states, it still fails (no
   contact states in its 30 rounds, 7.5 s, then no friction states a few steps on), so the
   FEM does not move; frictionless, it solves.
   The FEM's own step (5.) keeps its friction.
   ``inverse_model="twin"`` is the authors' arrangement (their ``ControllerWithProxy`` and
   inverse scene): the look-ahead is not restarted from the FEM at each sub-step but is a
   second FEM simulation, the twin, that the inverse QP drives ``inverse_steps`` steps a
   sub-step towards g' and that goes on from where it is; it is registered on the FEM (set
   to its state) at the realignments, and at once where it fails a step (a departure: the
   authors' twin had no such guard). Its clock runs ``inverse_steps`` times the FEM's, so a
   robot on a moving base refuses it.
   With ``prior_weight`` > 0 (a departure, Pliant's) the QP's regularisation pulls the
   actuators towards the proxy's commands of the sub-step mapped onto them (4.'s a_ff)
   instead of towards zero force: where the matched points do not tell two actuations apart
   (the Multigait's centre on, or off with its legs half inflated), the QP takes the
   proxy's, not the weakest.
   ``inverse_model="sensitivity"`` (a departure) instead linearises the FEM's own step, with
   its frictional contacts: the matched points p(a) after ``inverse_steps`` steps under a
   held actuation a are rolled out from the FEM's state at the applied actuation a_0 and at
   a_0 + h e_j for each actuator j (h a fraction ``sensitivity_step`` of its bound range), and
   a_inv = a_0 + x with x the bounded least-squares solution of
   min ||J x - (g' - p(a_0))||^2 + eps ||x||^2, lower - a_0 <= x <= upper - a_0 (SciPy's
   ``lsq_linear``; eps = 1e-3 ||J||_F^2 / n_a, the QP's relative regularisation). It costs
   (n_a + 1) ``inverse_steps`` FEM steps a sub-step and needs no contact active set: what the
   QPCC with friction could not settle, the FEM's own contact solve does in each roll-out;
3. the actuation correction, a robot's own term added to a_inv (the Multigait's, below);
4. optionally, a feedforward: the proxy's own commands of the sub-step mapped onto the FEM's
   actuators (the Multigait: a chamber's command in [0, 1] times the hand gait's volume),
   a_ff, blended in as a_inv <- w a_ff + (1 - w) a_inv (``feedforward`` w; 0 by default, the
   thesis' loop; 1 replays the proxy's actuation and skips the inverse model, the
   correction 3. still added to it);
5. the filter: a <- clip(a + f (s a_inv - a), lower, upper), and the FEM takes one step under
   a (direct control, its actuators in displacement mode).

Realignment (registration): every ``time_register`` proxy steps the FEM's relevant positions
are imposed on the proxy, which plans its next steps from what really happened: the
Multigait's robot points (the skeleton's nodes take the FEM's matched points, their frames
turned by the best rigid fit of the skeleton onto them), the Trunk's cube (pose and velocity,
moved out of the proxy's trunk where they overlap).

The Multigait's actuation correction (thesis Fig. 4.2.2: the corrector adds the contact
points' incidence angles observed in the proxy, which the inverse model's mean error over all
points ignores) is read here as a proportional term on each leg's chamber:
``angle_gain * (theta_proxy - theta_FEM) * upper``, theta the angle under the floor of the
leg's last segment (its tip's incidence on the floor) in each model. The thesis gives neither
the corrector's form nor its gain; ``angle_gain`` 0 leaves it out.

The transfer drives the proxy environments (:mod:`pliant.envs.multigait_proxy`,
:mod:`pliant.envs.trunk_push_proxy`) through their Gymnasium API, get_state and set_state
(and, inside the package, their solver, to read the sub-steps, and their observation after a
realignment), and steps the FEM robots with the ordinary solvers: a controller above both.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field, replace

import numpy as np
from scipy.optimize import lsq_linear

from pliant._proxsuite import BUILD
from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.control import InverseControl
from pliant.constraints.effector import PositionEffector
from pliant.envs.base import Ramp, SoftRobotEnv
from pliant.envs.multigait_proxy import MultigaitProxyEnv
from pliant.envs.trunk_push_proxy import TrunkPushProxyEnv
from pliant.errors import ContactConvergenceWarning, ModelError, PliantError, SolverError
from pliant.geometry.rotation import exp_map, log_map
from pliant.mesh.multigait import CHAMBERS
from pliant.model import Model, State
from pliant.robots.common import settled
from pliant.robots.multigait import chamber_amplitudes, multigait
from pliant.robots.trunk_cube import trunk_cube
from pliant.solvers import ImplicitEuler
from pliant.viz.model_view import RobotCamera
from pliant.viz.render import offscreen_figure
from pliant.viz.video import save_figure

FORWARD = np.array([-1.0, 0.0, 0.0])  # the Multigait's forward direction (its environments')
INVERSE_MODELS = ("qp", "twin", "sensitivity")


@dataclass(frozen=True)
class TransferGains:
    """The transfer loop's parameters (wave2_facts C.6).

    Args:
        scale: sub-steps of a proxy step (the proxy environment's substeps).
        time_register: proxy steps between realignments (0: never).
        rate: the filter's f in (0, 1].
        kp: the goal correction's proportional gain.
        lower, upper: the FEM actuation's bounds (actuator displacement units).
        inverse_steps: steps of the inverse model's look-ahead.
        gain: s, the scale on the inverse model's actuation.
        angle_gain: the Multigait corrector's gain (fraction of `upper` per radian).
        lookahead_friction: keep the contacts' friction in the inverse look-ahead (the QPCC
            with Coulomb friction); off: frictionless look-ahead, the FEM's step keeps it.
        feedforward: the weight w in [0, 1] of the proxy's commands mapped onto the FEM's
            actuators (:meth:`Transfer.feedforward`) against the inverse model's actuation;
            1: open loop, no inverse model.
        follow_shape: the Multigait's inverse model follows the proxy's deformation, not its
            place on the floor: its goals are translated in the floor plane by the mean gap
            between the proxy's and the FEM's matched points (:meth:`Transfer.goal_shift`);
            how far the FEM walks is then left to its own contacts' friction.
        inverse_model: "qp", the inverse QP's look-ahead from a copy of the FEM's state at
            each sub-step; "twin", the authors' inverse scene: a second FEM simulation under
            the inverse QP, stepped ``inverse_steps`` times a sub-step and registered on the
            FEM at the realignments (and where it fails a step); or "sensitivity", the
            bounded least squares on the FEM step's actuation Jacobian by finite differences
            of roll-outs with the FEM's own (frictional) contacts (module docstring, 2.).
        sensitivity_step: the finite-difference step of "sensitivity", a fraction of each
            actuator's bound range.
        rest_offset: the goals carry the gap between the two models' matched points at the
            transfer's start (each settled in its own way): the FEM follows the proxy's
            displacements from its own starting shape rather than the proxy's places (a
            departure; the Trunk's two models sag differently under gravity). Robots whose
            realignment moves the proxy's points (the Multigait) refuse it.
        fem_substeps: FEM steps per proxy sub-step, for a proxy that steps coarser than the
            FEM (:func:`proxy_timing`): the FEM follows the proxy's matched points
            interpolated linearly between its sub-steps.
        prior_weight: the inverse QP's pull towards the proxy's commands mapped onto the
            FEM's actuators (:meth:`Transfer.feedforward`), a relative weight
            (:func:`pliant.constraints.inverse.prior_terms`); 0, the thesis' loop, pulls its
            forces towards zero where the matched points do not decide (module docstring,
            2.). Needs a robot with a feedforward map and the "qp" or "twin" model.
    """

    scale: int
    time_register: int
    rate: float
    kp: float
    lower: tuple[float, ...]
    upper: tuple[float, ...]
    inverse_steps: int = 3
    gain: float = 1.0
    angle_gain: float = 0.0
    lookahead_friction: bool = False
    feedforward: float = 0.0
    follow_shape: bool = False
    inverse_model: str = "qp"
    sensitivity_step: float = 0.02
    rest_offset: bool = False
    fem_substeps: int = 1
    prior_weight: float = 0.0

    def __post_init__(self) -> None:
        if self.inverse_model not in INVERSE_MODELS:
            raise ModelError(
                f"the inverse model is one of {', '.join(INVERSE_MODELS)},"
                f" got {self.inverse_model!r}"
            )
        if not 0.0 < self.sensitivity_step <= 0.5:
            raise ModelError(
                "the sensitivity step must lie in (0, 0.5] of the bounds,"
                f" got {self.sensitivity_step}"
            )
        if self.scale < 1 or self.inverse_steps < 1 or self.time_register < 0:
            raise ModelError("scale and inverse_steps must be >= 1, time_register >= 0")
        if self.fem_substeps < 1:
            raise ModelError(f"fem_substeps must be >= 1, got {self.fem_substeps}")
        if not (np.isfinite(self.prior_weight) and self.prior_weight >= 0.0):
            raise ModelError(f"the prior's weight must be finite and >= 0, got {self.prior_weight}")
        if self.prior_weight > 0.0 and self.inverse_model == "sensitivity":
            raise ModelError("the prior pulls the inverse QP: use the 'qp' or 'twin' model")
        if not 0.0 <= self.feedforward <= 1.0:
            raise ModelError(f"the feedforward weight must lie in [0, 1], got {self.feedforward}")
        if not (np.isfinite(self.gain) and self.gain > 0.0):
            raise ModelError(f"the inverse actuation's scale s must be > 0, got {self.gain}")
        if not 0.0 < self.rate <= 1.0:
            raise ModelError(f"the filter's rate must lie in (0, 1], got {self.rate}")
        if len(self.lower) != len(self.upper) or np.any(np.greater(self.lower, self.upper)):
            raise ModelError("the actuation bounds need lower <= upper, one pair per actuator")


# The thesis' Multigait bounds (volume growth, SofaGym's mesh): [0, 2050] for the centre and
# [0, 1600] for a leg, 1.025 and 1.067 times its commands 2000 and 1500; the same ratios on
# this mesh's commands (4900 and 3300 mm^3, pliant.robots.multigait.demo_actuation).
MULTIGAIT_GAINS = TransferGains(
    scale=60,
    time_register=7,
    rate=0.3,
    kp=0.5,
    lower=(0.0,) * 5,
    upper=tuple(4900.0 * 2050 / 2000 if c == "centre" else 3300.0 * 1600 / 1500 for c in CHAMBERS),
)
# The thesis' cables lie in [0, 1000] (its unit); Pliant's Trunk cables' courses: 70 mm for
# the long ones, 40 for the short.
TRUNK_GAINS = TransferGains(
    scale=30,
    time_register=10,
    rate=1.0,
    kp=0.0,
    lower=(0.0,) * 8,
    upper=(70.0,) * 4 + (40.0,) * 4,
)
#: the chambers' volumes (mm^3) of the hand gait, pliant.robots.multigait.demo_actuation's
#: amplitudes in CHAMBERS order: the Multigait feedforward's map from the proxy's commands.
MULTIGAIT_VOLUMES = chamber_amplitudes()
#: the thesis' Multigait test sequence (Discrete(6): 2 g inflates group g of centre, front,
#: rear; 2 g + 1 deflates it): rear, centre, centre, front, rear off, centre off, front off, rear.
MULTIGAIT_SEQUENCE = (4, 0, 0, 2, 5, 1, 3, 4)


class ActuationFilter:
    """a <- clip(a + rate (gain a_inv - a), lower, upper), from a = clip(0)."""

    def __init__(self, lower, upper, *, rate: float, gain: float = 1.0) -> None:
        self.lower = np.asarray(lower, dtype=float)
        self.upper = np.asarray(upper, dtype=float)
        self.rate, self.gain = float(rate), float(gain)
        self.value = np.clip(np.zeros_like(self.lower), self.lower, self.upper)

    def update(self, target: np.ndarray) -> np.ndarray:
        a = self.value + self.rate * (self.gain * np.asarray(target, dtype=float) - self.value)
        self.value = np.clip(a, self.lower, self.upper)
        return self.value.copy()


class _Recorder:
    """A solver that keeps the states it steps to and the commands of each step (the proxy's
    sub-steps)."""

    def __init__(self, solver) -> None:
        self.solver = solver
        self.states: list[State] = []
        self.commands: list[np.ndarray] = []

    def step(self, state, controls=None):
        state = self.solver.step(state, controls)
        self.states.append(state)
        self.commands.append(np.asarray(controls, dtype=float))
        return state

    def __getattr__(self, name: str):
        return getattr(self.solver, name)


def with_effector(model: Model, points: EmbeddedPoints, name: str = "matched") -> Model:
    """`model` with one position effector on `points` in place of its effectors."""
    effector = PositionEffector(points, model.body.rest_positions, name=name)
    return Model(
        model.body,
        actuators=model.actuators,
        effectors=[effector],
        contacts=model.contacts,
        drivers=model.drivers,
        rigid_bodies=model.rigid_bodies,
        attachments=model.attachments,
        name=model.name,
    )


def rigid_fit(source: np.ndarray, target: np.ndarray) -> np.ndarray:
    """The rotation R minimising sum |R (s - mean s) - (t - mean t)|^2 (Kabsch)."""
    a, b = source - source.mean(axis=0), target - target.mean(axis=0)
    u, _, vt = np.linalg.svd(b.T @ a)
    d = np.sign(np.linalg.det(u @ vt))
    return u @ np.diag([1.0, 1.0, d]) @ vt


def impose_points(rod, state: State, points: np.ndarray, velocities: np.ndarray) -> State:
    """`state` of a rod whose centreline nodes are moved to `points` (with `velocities`), their
    frames (and spins) turned by the best rigid fit of the old centreline onto `points`."""
    n = rod.n_centreline
    turn = rigid_fit(rod.centreline(state.positions), points)
    positions, speeds = state.positions.copy(), state.velocities.copy()
    positions[:n], speeds[:n] = points, velocities
    positions[n:] = [log_map(turn @ exp_map(v)) for v in state.positions[n:]]
    speeds[n:] = state.velocities[n:] @ turn.T
    return replace(state, positions=positions, velocities=speeds)


@dataclass
class StepRecord:
    """One proxy step of a transfer: rewards and positions of both models after it, the mean
    distance between their matched points, and whether the proxy was realigned before it."""

    action: list
    proxy_reward: float
    fem_reward: float
    proxy_position: list[float]
    fem_position: list[float]
    tracking_error: float
    realigned: bool


@dataclass
class TransferResult:
    """A transfer's steps, the sub-step trajectories (time, proxy and FEM positions, the FEM's
    actuation), the gains and the wall time."""

    robot: str
    gains: TransferGains
    steps: list[StepRecord] = field(default_factory=list)
    times: list[float] = field(default_factory=list)
    proxy_trajectory: list[list[float]] = field(default_factory=list)
    fem_trajectory: list[list[float]] = field(default_factory=list)
    actuation: list[list[float]] = field(default_factory=list)
    failed_inverse_steps: int = 0
    #: times the twin (``inverse_model="twin"``) failed a step (diverged) and was registered
    #: on the FEM again at once
    twin_resets: int = 0
    #: look-ahead steps of the inverse QP whose contact states did not settle, or had no
    #: solution (their actuators kept the previous step's forces): ContactConvergenceWarning
    unsettled_inverse_steps: int = 0
    wall_time: float = 0.0
    start: list[float] = field(default_factory=list)

    @property
    def final_gap(self) -> float:
        """|x_proxy - x_FEM| of the two models' positions after the last step (mm)."""
        last = self.steps[-1]
        return float(np.linalg.norm(np.subtract(last.proxy_position, last.fem_position)))

    @property
    def fem_travel(self) -> float:
        """|x_FEM - x_start|: how far the FEM's position went (mm)."""
        return float(np.linalg.norm(np.subtract(self.steps[-1].fem_position, self.start)))

    @property
    def proxy_return(self) -> float:
        return float(sum(s.proxy_reward for s in self.steps))

    @property
    def fem_return(self) -> float:
        return float(sum(s.fem_reward for s in self.steps))

    @property
    def relative_difference(self) -> float:
        """|R_proxy - R_FEM| / |R_FEM| of the summed rewards."""
        return abs(self.proxy_return - self.fem_return) / max(abs(self.fem_return), 1e-12)

    def to_dict(self) -> dict:
        return {
            "robot": self.robot,
            "gains": asdict(self.gains),
            "proxy_return": self.proxy_return,
            "fem_return": self.fem_return,
            "relative_difference": self.relative_difference,
            "start": self.start,
            "final_gap_mm": self.final_gap,
            "fem_travel_mm": self.fem_travel,
            "final_gap_over_travel": self.final_gap / max(self.fem_travel, 1e-12),
            "failed_inverse_steps": self.failed_inverse_steps,
            "twin_resets": self.twin_resets,
            "unsettled_inverse_steps": self.unsettled_inverse_steps,
            "wall_time_s": self.wall_time,
            # the inverse QP's build (pliant._proxsuite): the baseline one is reproducible
            "proxsuite_build": BUILD,
            "steps": [asdict(s) for s in self.steps],
            "times": self.times,
            "proxy_trajectory": self.proxy_trajectory,
            "fem_trajectory": self.fem_trajectory,
            "actuation": self.actuation,
        }


class Transfer:
    """The transfer loop of one proxy environment to one FEM model (module docstring).

    Args:
        env: the proxy environment (reset by the caller), whose ``proxy`` is the skeleton.
        fem: the FEM robot with a position effector on the matched points
            (:func:`with_effector`).
        state: the FEM's starting state.
        gains: the loop's parameters; ``gains.scale`` must be the environment's substeps.
        proxy_points: proxy positions -> (K, 3) matched points.
        base: the FEM's translating base (its builder's trajectory), set from the proxy's.
    """

    robot = "robot"
    follows_shape = False
    #: the realignment leaves the proxy's matched points alone (``gains.rest_offset`` allowed)
    keeps_points = True

    def __init__(
        self,
        env: SoftRobotEnv,
        fem: Model,
        state: State,
        gains: TransferGains,
        proxy_points: Callable[[np.ndarray], np.ndarray],
        *,
        base: Ramp | None = None,
    ) -> None:
        if env.substeps != gains.scale:
            raise ModelError(f"the proxy takes {env.substeps} sub-steps, the gains {gains.scale}")
        if len(fem.effectors) != 1 or len(gains.upper) != fem.n_actuators:
            raise ModelError("the FEM model needs one effector and a bound pair per actuator")
        if gains.follow_shape and not self.follows_shape:
            raise ModelError(f"the {self.robot} transfer follows places: keep follow_shape off")
        if gains.inverse_model == "twin" and base is not None:
            raise ModelError(
                "the twin runs inverse_steps times the FEM's clock, which moves the base:"
                " keep the 'qp' inverse model for a robot on a moving base"
            )
        if (gains.prior_weight > 0.0 or gains.feedforward > 0.0) and (
            type(self).feedforward is Transfer.feedforward
        ):
            raise ModelError(
                f"the {self.robot} transfer has no feedforward map: keep feedforward and"
                " prior_weight 0"
            )
        if gains.rest_offset and not self.keeps_points:
            raise ModelError(
                f"the {self.robot}'s realignment moves the proxy's points: keep rest_offset off"
            )
        self.env, self.fem, self.state, self.gains = env, fem, state, gains
        self.proxy_points = proxy_points
        self.points = fem.effectors[0].points
        #: (K, 3) what the goals carry with ``gains.rest_offset`` (zero without)
        start = self.points.positions(state.positions)
        self.offset = np.zeros_like(start)
        if gains.rest_offset:
            self.offset = start - proxy_points(env.state.positions)
        self.base = base
        self.solver = ImplicitEuler(fem, dt=env.dt / gains.fem_substeps)
        self.filter = ActuationFilter(gains.lower, gains.upper, rate=gains.rate, gain=gains.gain)
        self.recorder = _Recorder(env.sim)
        env.sim = self.recorder
        self.result = TransferResult(self.robot, gains)
        #: the inverse model's own FEM simulation (``inverse_model="twin"``; None otherwise)
        self.twin: State | None = None
        self._register_twin()

    # ------------------------------------------------------------------ robot-specific parts
    def proxy_position(self, state: State) -> np.ndarray:
        """(3,) the proxy's position that the task measures."""
        raise NotImplementedError

    def fem_position(self, state: State) -> np.ndarray:
        raise NotImplementedError

    def reward(self, before: np.ndarray, after: np.ndarray, points: np.ndarray) -> float:
        """The task's reward from a model's position before and after a step and its matched
        points after it (the same function for both models)."""
        raise NotImplementedError

    def realign(self) -> None:
        """Impose the FEM's relevant positions on the proxy environment."""
        raise NotImplementedError

    def correction(self, goal: np.ndarray, points: np.ndarray) -> np.ndarray:
        """What the actuation corrector adds to the inverse model's actuation."""
        return np.zeros(self.fem.n_actuators)

    def goal_shift(self, goal: np.ndarray, points: np.ndarray) -> np.ndarray:
        """(3,) what is taken off the goals before the inverse model (``gains.follow_shape``;
        a robot whose transfer can follow shapes sets ``follows_shape``)."""
        raise NotImplementedError

    def feedforward(self, commands: np.ndarray) -> np.ndarray:
        """The proxy's commands of a sub-step as the FEM's actuation (``gains.feedforward``)."""
        raise ModelError(f"the {self.robot} transfer has no feedforward map: keep feedforward 0")

    # ------------------------------------------------------------------------- the loop
    def observation(self) -> np.ndarray:
        """The proxy environment's observation of its present state (after a realignment)."""
        return self.env._clip_observation(self.env._observe())

    def follow(self, goal: np.ndarray, commands: np.ndarray | None = None) -> None:
        """One FEM step towards the proxy's matched points `goal` (K, 3), the proxy's
        `commands` of that sub-step fed forward with weight ``gains.feedforward``."""
        g = self.gains
        w = g.feedforward
        now = self.points.positions(self.state.positions)
        if w == 1.0:  # the inverse model's actuation would weigh nothing: not solved
            actuation = self.feedforward(commands) + self.correction(goal, now)
            self.state = self.solver.step(self.state, self.filter.update(actuation))
            return
        if g.follow_shape:
            goal = goal - self.goal_shift(goal, now)
        goal = goal + self.offset
        target = goal + g.kp * (goal - now)
        prior = self.feedforward(commands) if g.prior_weight > 0.0 else None
        try:
            if g.inverse_model == "sensitivity":
                inverse = self.sensitivity_inverse(target)
            elif g.inverse_model == "twin":
                inverse = self.twin_inverse(target, prior)
            else:
                inverse = self.qp_inverse(target, prior)
        except PliantError:  # no inverse step: keep the actuation
            self.result.failed_inverse_steps += 1
            inverse = self.filter.value / g.gain
        inverse = inverse + self.correction(goal, now)
        if w > 0.0:
            inverse = w * self.feedforward(commands) + (1.0 - w) * inverse
        self.state = self.solver.step(self.state, self.filter.update(inverse))

    def qp_inverse(self, target: np.ndarray, prior: np.ndarray | None = None) -> np.ndarray:
        """a_inv of the inverse QP's look-ahead towards `target` (module docstring, 2.),
        pulled towards the actuation `prior` (``gains.prior_weight``)."""
        return self._inverse_steps(self.state.copy(), target, prior).displacement

    def twin_inverse(self, target: np.ndarray, prior: np.ndarray | None = None) -> np.ndarray:
        """a_inv of the twin's ``inverse_steps`` steps towards `target`; the twin goes on
        from where they leave it (module docstring, 2.). A twin that fails a step (its
        elements inverted, say) would fail every step until the next realignment: it is
        registered on the FEM at once (counted in ``twin_resets``) and the error passed on,
        so that this sub-step keeps its actuation."""
        try:
            self.twin = self._inverse_steps(self.twin, target, prior)
        except PliantError:
            self._register_twin()
            self.result.twin_resets += 1
            raise
        return self.twin.displacement

    def _register_twin(self) -> None:
        """Set the twin to the FEM's present state (``inverse_model="twin"`` only)."""
        if self.gains.inverse_model == "twin":
            self.twin = self.state.copy()

    def _inverse_steps(
        self, look: State, target: np.ndarray, prior: np.ndarray | None = None
    ) -> State:
        """`look` after ``inverse_steps`` steps of the inverse QP towards `target`, pulled
        towards the actuation `prior` (None: towards zero force)."""
        control = InverseControl(goals=target, prior=prior, prior_weight=self.gains.prior_weight)
        g = self.gains
        contacts = self.fem.contacts
        friction = None if contacts is None else contacts.friction
        try:
            # A far goal widens the course (expected here): the warnings are counted, not shown.
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                if contacts is not None and not g.lookahead_friction:
                    contacts.friction = np.zeros_like(friction)
                for _ in range(g.inverse_steps):
                    look = self.solver.step(look, control)
        finally:
            if contacts is not None:
                contacts.friction = friction
        self.result.unsettled_inverse_steps += sum(
            issubclass(w.category, ContactConvergenceWarning) for w in caught
        )
        return look

    def roll_out(self, actuation: np.ndarray) -> np.ndarray:
        """(K, 3) the matched points after ``inverse_steps`` FEM steps under `actuation`
        held, from the FEM's present state (the state itself is not touched)."""
        look = self.state.copy()
        for _ in range(self.gains.inverse_steps):
            look = self.solver.step(look, actuation)
        return self.points.positions(look.positions)

    def sensitivity_inverse(self, target: np.ndarray) -> np.ndarray:
        """a_inv of the bounded least squares on the roll-outs' Jacobian (module docstring,
        2.): the actuation, within the bounds, whose linearised roll-out lands nearest
        `target`."""
        g = self.gains
        lower, upper = np.asarray(g.lower, dtype=float), np.asarray(g.upper, dtype=float)
        base = np.clip(self.filter.value, lower, upper)
        free = np.flatnonzero(upper > lower)  # an actuator with lower == upper stays put
        if free.size == 0:
            return base
        reached = self.roll_out(base).ravel()
        jacobian = np.empty((reached.size, free.size))
        for col, j in enumerate(free):
            h = g.sensitivity_step * (upper[j] - lower[j])
            if base[j] + h > upper[j]:  # difference backwards at the upper bound
                h = -h
            moved = base.copy()
            moved[j] += h
            jacobian[:, col] = (self.roll_out(moved).ravel() - reached) / h
        eps = 1e-3 * float(np.sum(jacobian**2)) / free.size
        rows = np.vstack([jacobian, np.sqrt(eps) * np.eye(free.size)])
        rhs = np.concatenate([np.ravel(target) - reached, np.zeros(free.size)])
        if not (np.all(np.isfinite(rows)) and np.all(np.isfinite(rhs))):
            raise SolverError("the roll-outs of the sensitivity inverse are not finite")
        bounds = (lower[free] - base[free], upper[free] - base[free])
        out = base.copy()
        out[free] += lsq_linear(rows, rhs, bounds=bounds).x
        return out

    def step(self, action, *, realigned: bool = False) -> StepRecord:
        """One proxy step under `action`, the FEM following each of its sub-steps
        (`realigned`: the proxy was realigned just before, for the record)."""
        proxy_before = self.proxy_position(self.env.state)
        fem_before = self.fem_position(self.state)
        self.recorder.states.clear()
        self.recorder.commands.clear()
        previous = self.proxy_points(self.env.state.positions)
        _, _, _, truncated, info = self.env.step(action)
        if truncated and "diverged" in info:
            raise ModelError(f"the proxy diverged: {info['diverged']}")
        m = self.gains.fem_substeps
        for sub, commands in zip(self.recorder.states, self.recorder.commands, strict=True):
            if self.base is not None:  # where the proxy's base went in this sub-step
                target = np.clip(commands[-1], *self.env.proxy.base.limits)
                self.base.retarget(self.state.time, target, self.env.dt)
                self.fem.trajectories_changed()
            goal = self.proxy_points(sub.positions)
            for j in range(1, m + 1):  # a coarser proxy's points, interpolated
                self.follow(goal if j == m else previous + (goal - previous) * (j / m), commands)
            previous = goal
            self.result.times.append(float(self.state.time))
            self.result.proxy_trajectory.append(self.proxy_position(sub).tolist())
            self.result.fem_trajectory.append(self.fem_position(self.state).tolist())
            self.result.actuation.append(self.filter.value.tolist())
        proxy_points = self.proxy_points(self.env.state.positions)
        fem_points = self.points.positions(self.state.positions)
        proxy_after = self.proxy_position(self.env.state)
        fem_after = self.fem_position(self.state)
        record = StepRecord(
            np.asarray(action).tolist(),
            self.reward(proxy_before, proxy_after, proxy_points),
            self.reward(fem_before, fem_after, fem_points),
            proxy_after.tolist(),
            fem_after.tolist(),
            float(np.linalg.norm(proxy_points - fem_points, axis=1).mean()),
            realigned,
        )
        self.result.steps.append(record)
        return record

    def run(
        self,
        actions: Sequence | None = None,
        *,
        policy: Callable[[np.ndarray], object] | None = None,
        steps: int | None = None,
        progress: Callable[[int, StepRecord], None] | None = None,
        until: Callable[[], bool] | None = None,
    ) -> TransferResult:
        """Transfer a fixed action sequence, or `steps` actions of `policy` (observation ->
        action) chosen on the proxy after each realignment; `until`: stop after the first step
        at which it holds (an episode its task ends early)."""
        if (actions is None) == (policy is None):
            raise ModelError("give either an action sequence or a policy")
        count = len(actions) if actions is not None else steps
        if count is None or count < 1:
            raise ModelError("a policy needs a number of steps >= 1")
        clock = time.perf_counter()
        self.result.start = self.fem_position(self.state).tolist()
        every = self.gains.time_register
        for k in range(count):
            due = every > 0 and k > 0 and k % every == 0
            if due:  # the policy re-plans from what the FEM did
                self.realign()
                self._register_twin()  # and the twin goes on from the FEM
            action = actions[k] if policy is None else policy(self.observation())
            record = self.step(action, realigned=due)
            if progress is not None:
                progress(k, record)
            if until is not None and until():
                break
        self.result.wall_time = time.perf_counter() - clock
        return self.result


class MultigaitTransfer(Transfer):
    """The Multigait: matched points the 19 skeleton nodes (embedded in the FEM body where
    the proxy's rest skeleton lies, at mid-thickness); position: the centre of mass; reward:
    its forward displacement over the step; realignment: the robot's points; corrector: the
    legs' tip angles."""

    robot = "multigait"
    follows_shape = True
    keeps_points = False

    def __init__(self, *args, skeleton_points: EmbeddedPoints | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        #: the FEM's points where the skeleton's nodes lie (mid-thickness), which the
        #: realignment imposes on the proxy: the matched points unless they are elsewhere
        self.skeleton_points = self.points if skeleton_points is None else skeleton_points

    # The skeleton's nodes of each leg, root to tip (pliant.proxy.builders.multigait_proxy).
    LEGS = {name: np.arange(3 + 4 * k, 7 + 4 * k) for k, name in enumerate(CHAMBERS[1:])}

    def proxy_position(self, state: State) -> np.ndarray:
        rod = self.env.proxy.rod
        masses = rod.node_masses[: rod.n_centreline]
        return masses @ rod.centreline(state.positions) / masses.sum()

    def fem_position(self, state: State) -> np.ndarray:
        masses = self.fem.body.node_masses
        return masses @ state.positions / masses.sum()

    def reward(self, before, after, points) -> float:
        return float((after - before) @ FORWARD)

    def realign(self) -> None:
        snapshot = self.env.get_state()
        snapshot.state = impose_points(
            self.env.proxy.rod,
            snapshot.state,
            self.skeleton_points.positions(self.state.positions),
            self.skeleton_points.positions(self.state.velocities),
        )
        self.env.set_state(snapshot)

    @classmethod
    def tip_angles(cls, points: np.ndarray) -> np.ndarray:
        """(4,) each leg's last segment's angle under the horizontal (rad)."""
        angles = []
        for nodes in cls.LEGS.values():
            segment = points[nodes[-1]] - points[nodes[-2]]
            angles.append(np.arctan2(-segment[2], np.linalg.norm(segment[:2])))
        return np.array(angles)

    def goal_shift(self, goal, points) -> np.ndarray:
        """The mean gap between the proxy's and the FEM's points along the floor (x, y)."""
        shift = (goal - points).mean(axis=0)
        shift[2] = 0.0
        return shift

    def feedforward(self, commands: np.ndarray) -> np.ndarray:
        """A chamber's command in [0, 1] times its volume in the hand gait
        (:func:`pliant.robots.multigait.demo_actuation`: 4900 mm^3 the centre, 3300 a leg),
        the volumes whose gait the proxy was calibrated on."""
        return np.asarray(commands, dtype=float)[: len(CHAMBERS)] * MULTIGAIT_VOLUMES

    def correction(self, goal, points) -> np.ndarray:
        out = np.zeros(self.fem.n_actuators)
        gap = self.tip_angles(goal) - self.tip_angles(points)
        out[1:] = self.gains.angle_gain * gap * np.asarray(self.gains.upper[1:])
        return out


class TrunkTransfer(Transfer):
    """The Trunk on its base pushing the cube: matched points the skeleton's 30 nodes (on the
    FEM Trunk's axis); position: the cube's centre; reward: the environment's,
    -d / L - w d_c / L; realignment: the cube's pose and velocity."""

    robot = "trunk"

    def proxy_position(self, state: State) -> np.ndarray:
        return state.rigid_positions[0].copy()

    def fem_position(self, state: State) -> np.ndarray:
        return state.rigid_positions[0].copy()

    def reward(self, before, after, points) -> float:
        env = self.env
        goal = env.task["goal"]
        d = float(np.hypot(after[0] - goal[0], after[2] - goal[2]))
        contact = float(np.linalg.norm(points[env.nodes] - after, axis=1).min())
        return -(d + env.contact_weight * contact) / env.length

    def realign(self) -> None:
        """The FEM's cube imposed on the proxy, moved out of the proxy's trunk where they
        overlap: the proxy touches with balls of its radius (10 mm) all along, where the FEM
        Trunk tapers to 2 mm at its tip, so the FEM's cube may sit inside the proxy, whose
        contact would throw it out (measured: 40 mm in one step)."""
        snapshot = self.env.get_state()
        s = self.state
        centre = s.rigid_positions[0].copy()
        rotation = s.rigid_rotations[0]
        half = np.asarray(self.env.model.rigid_bodies[0].shape.half_extents, dtype=float)
        radius = self.env.model.contacts.thickness
        nodes = self.env.proxy.skeleton(snapshot.state.positions)
        for _ in range(3):  # the overlap along the floor, from the nearest node outwards
            local = (nodes - centre) @ rotation
            outside = np.linalg.norm(np.maximum(np.abs(local) - half, 0.0), axis=1)
            inside = np.minimum(np.max(np.abs(local) - half, axis=1), 0.0)
            clearance = outside + inside - radius
            k = int(np.argmin(clearance))
            if clearance[k] >= 0.0:
                break
            away = centre - nodes[k]
            away[1] = 0.0
            centre += -clearance[k] * away / max(float(np.linalg.norm(away)), 1e-12)
        snapshot.state = replace(
            snapshot.state,
            rigid_positions=centre[None, :],
            rigid_rotations=s.rigid_rotations.copy(),
            rigid_velocities=s.rigid_velocities.copy(),
            rigid_angular_velocities=s.rigid_angular_velocities.copy(),
        )
        self.env.set_state(snapshot)


def proxy_timing(
    env_kwargs: dict | None, gains: TransferGains, dt: float
) -> tuple[dict, TransferGains]:
    """The proxy environment's arguments and the loop's gains for a FEM stepping `dt`: the
    proxy steps as its `env_kwargs` say (a policy's training: its ``dt`` and ``substeps``;
    by default the FEM's `dt` and the gains' `scale`), the gains' `scale` becomes its
    sub-steps and `fem_substeps` the FEM steps in one of them. ModelError if the proxy's step
    is not a whole number of the FEM's."""
    kwargs = dict(env_kwargs or {})
    proxy_dt = float(kwargs.get("dt", dt))
    scale = int(kwargs.get("substeps", gains.scale))
    if not (np.isfinite(proxy_dt) and proxy_dt > 0.0 and np.isfinite(dt) and dt > 0.0):
        raise ModelError(f"time steps must be finite and > 0: proxy {proxy_dt} s, FEM {dt} s")
    ratio = proxy_dt / dt
    substeps = int(round(ratio))
    if substeps < 1 or abs(ratio - substeps) > 1e-6 * ratio:
        raise ModelError(
            f"the proxy's step ({proxy_dt} s) is not a whole number of the FEM's ({dt} s)"
        )
    gains = replace(gains, scale=scale, fem_substeps=substeps)
    return {**kwargs, "dt": proxy_dt, "substeps": scale}, gains


def underside_points(rod) -> Callable[[np.ndarray], np.ndarray]:
    """Positions of a flat skeleton -> (N, 3) the points under its nodes on the underside:
    each node moved by its rest height above the floor along its frame's axis that stood
    vertical at rest (the points ride on the nodes' frames, as the skinned surface does)."""
    rest = rod.rest_positions
    frames = rod.frames(rest)
    axis = int(np.argmax(np.abs(frames[0, 2, :])))
    lever = rod.centreline(rest)[:, 2] * np.sign(frames[:, 2, axis])

    def points(positions: np.ndarray) -> np.ndarray:
        return rod.centreline(positions) - lever[:, None] * rod.frames(positions)[:, :, axis]

    return points


def multigait_transfer(
    *,
    gains: TransferGains = MULTIGAIT_GAINS,
    mesh_size: float = 6.0,
    dt: float = 0.01,
    seed: int = 0,
    env_kwargs: dict | None = None,
    matched: str = "axis",
) -> MultigaitTransfer:
    """The Multigait proxy environment (calibrated proxy; `env_kwargs` those of the policy's
    training, its time step with them: :func:`proxy_timing`) and the FEM Multigait (default
    mesh, volume-controlled chambers, steps of `dt`), both from rest. `matched`: the matched
    points are the skeleton's nodes at mid-thickness ("axis") or under them on the underside
    ("underside", where the authors' effectors sit: :func:`underside_points`); either way the
    realignment imposes the FEM's mid-thickness points on the nodes."""
    if matched not in ("axis", "underside"):
        raise ModelError(f"the matched points are 'axis' or 'underside', got {matched!r}")
    kwargs, gains = proxy_timing(env_kwargs, gains, dt)
    env = MultigaitProxyEnv(**kwargs)
    env.reset(seed=seed)
    rod = env.proxy.rod
    robot = multigait(mesh_size=mesh_size)

    def embedded(points: np.ndarray) -> EmbeddedPoints:
        # Points that fall in a chamber's slot follow the nearest element (SOFA's mapping).
        return EmbeddedPoints(robot.body.mesh, points, tolerance=5.0, outside="keep")

    skeleton = embedded(rod.centreline(rod.rest_positions))
    proxy_points = rod.centreline if matched == "axis" else underside_points(rod)
    points = skeleton if matched == "axis" else embedded(proxy_points(rod.rest_positions))
    fem = with_effector(robot, points)
    return MultigaitTransfer(
        env, fem, fem.rest_state(), gains, proxy_points, skeleton_points=skeleton
    )


#: the Trunk's push along x: both beams bent towards +x (the cube's side; +d2) by 0.02 more
#: at each step up to 0.1, then held, the base still (continuous actions of
#: TrunkPushProxy-v0). On the proxy the cube goes 23 mm along x (and 11 mm back along z, as
#: the curling trunk sweeps it), then stays.
TRUNK_SEQUENCE = tuple((0.0, u, 0.0, u, 0.0) for u in (0.02, 0.04, 0.06, 0.08) + (0.1,) * 8)


def trunk_transfer(
    *,
    gains: TransferGains = TRUNK_GAINS,
    mesh_size: float = 8.0,
    dt: float = 0.01,
    goal_offset: tuple[float, float] = (25.0, -10.0),
    seed: int = 0,
    env_kwargs: dict | None = None,
) -> TrunkTransfer:
    """The Trunk-and-cube proxy environment (calibrated proxy, goal the cube's start plus
    `goal_offset` in (x, z); `env_kwargs` those of the policy's training, its time step with
    them: :func:`proxy_timing`) and the FEM Trunk on its base (mesh 8 mm, steps of `dt`), both
    settled under gravity."""
    kwargs, gains = proxy_timing(env_kwargs, gains, dt)
    env = TrunkPushProxyEnv(**kwargs)
    start = env.state.rigid_positions[0]
    goal = start + np.array([goal_offset[0], 0.0, goal_offset[1]])
    env.reset(seed=seed, options={"goal": goal})
    rod = env.proxy.rod
    base = Ramp(0.0)
    robot = trunk_cube(mesh_size=mesh_size, base_motion=base.scalar)
    fem = with_effector(robot, EmbeddedPoints(robot.body.mesh, rod.centreline(rod.rest_positions)))
    # the FEM settles as long as the proxy did, in its own steps
    state = settled(fem, ImplicitEuler(fem, dt=dt), env.settle_steps * gains.fem_substeps)
    return TrunkTransfer(env, fem, state, gains, rod.centreline, base=base)


TRANSFERS = {"multigait": multigait_transfer, "trunk": trunk_transfer}
GAINS = {"multigait": MULTIGAIT_GAINS, "trunk": TRUNK_GAINS}
SEQUENCES = {"multigait": MULTIGAIT_SEQUENCE, "trunk": TRUNK_SEQUENCE}


def plot_transfer(result: TransferResult, path) -> None:
    """PNG of both trajectories: the Multigait's forward position of its centre of mass, the
    Trunk's cube (x and z), against time; and both models' summed rewards per proxy step."""
    fig = offscreen_figure(10.0, 4.0)
    left, right = fig.subplots(1, 2)
    t = np.asarray(result.times)
    proxy, fem = np.asarray(result.proxy_trajectory), np.asarray(result.fem_trajectory)
    if result.robot == "multigait":
        series = {"forward (mm)": (proxy - proxy[0]) @ FORWARD}
        femseries = {"forward (mm)": (fem - fem[0]) @ FORWARD}
    else:
        series = {"cube x (mm)": proxy[:, 0], "cube z (mm)": proxy[:, 2]}
        femseries = {"cube x (mm)": fem[:, 0], "cube z (mm)": fem[:, 2]}
    for (name, values), style in zip(femseries.items(), ("-", "--"), strict=False):
        left.plot(t, series[name], "C0" + style, label=f"proxy {name}")
        left.plot(t, values, "C1" + style, label=f"FEM {name}")
    for k, s in enumerate(result.steps):
        if s.realigned:
            left.axvline(t[k * result.gains.scale], color="0.7", lw=0.8)
    left.set_xlabel("time (s)")
    left.set_title(f"{result.robot}: trajectories (grey: realignment)")
    left.legend(fontsize=8)
    steps = np.arange(1, len(result.steps) + 1)
    right.plot(steps, np.cumsum([s.proxy_reward for s in result.steps]), "C0o-", label="proxy")
    right.plot(steps, np.cumsum([s.fem_reward for s in result.steps]), "C1s-", label="FEM")
    right.set_xlabel("proxy step")
    right.set_title(f"summed reward (relative difference {100 * result.relative_difference:.1f} %)")
    right.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, path, dpi=120)


def frame(transfer: Transfer, cameras: dict) -> np.ndarray:
    """The FEM robot and the proxy side by side (one frame of a GIF)."""
    env = transfer.env
    if not cameras:
        cameras["fem"] = RobotCamera(transfer.fem, view=env.view, size=(400, 300))
        cameras["proxy"] = RobotCamera(env.model, view=env.view, size=(400, 300))
    t = transfer.state.time
    return np.hstack(
        [
            cameras["fem"].frame(transfer.state, title=f"FEM  t = {t:.2f} s"),
            cameras["proxy"].frame(env.state, title="proxy"),
        ]
    )
