"""What every Pliant environment shares: stepping with ramped commands, exact save and restore,
divergence handling, rendering and seeding.

An environment is a thin layer over a robot builder (:mod:`pliant.robots`): it builds the model
once, steps it with :class:`pliant.solvers.ImplicitEuler`, and defines the task (observation,
action, reward, termination) in a subclass. One environment step is ``substeps`` simulation
steps of ``dt``; the command moves linearly from its previous value to the new one over the
sub-steps (SofaGym ramps the Trunk's and the Diamond's commands the same way), so that a
discrete action is not a jump.

Kinematic inputs of a scene (a cart's position, a base's height, a maze's tilt, servo angles)
are ramped the same way through :class:`Ramp`, a trajectory of time that the builders take as
their ``cart_motion``/``base_motion``/``tilt``/``servo_angles`` argument.

Exact save and restore (:meth:`SoftRobotEnv.get_state`, :meth:`SoftRobotEnv.set_state`): the
snapshot holds the simulation :class:`pliant.model.State` (positions, velocities, actuation,
contact forces for the warm start, rigid bodies), the ramps, the task (goal, counters, previous
distances), and the random generator. The one solver cache that changes a step's result, the
lagged factorisation of the tangent, is rebuilt at the start of every environment step
(``LinearisedSystem.invalidate``): within the step it lags as usual, and the step's result is
a function of the snapshot and the action only, whatever was simulated before. Restoring a
snapshot and replaying the same actions gives bit-identical observations and rewards, in the
same process and, since snapshots pickle, in another.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

import gymnasium as gym
import numpy as np

from pliant.envs.actions import ActionMap, Commands
from pliant.envs.config import (
    ActionType,
    EnvConfigError,
    SimulationConfig,
    check_choice,
    with_keywords,
)
from pliant.errors import (
    ConstraintError,
    DivergenceError,
    PliantError,
    SolverError,
    StateError,
)
from pliant.model import Model, State
from pliant.solvers import ImplicitEuler
from pliant.viz.model_view import RobotCamera


class EnvStateError(PliantError, ValueError):
    """A snapshot given to ``set_state`` belongs to another environment, version or model."""


class ActionError(PliantError, gym.error.InvalidAction):
    """An action of the wrong type, shape or range, or not finite: Gymnasium's InvalidAction,
    and a PliantError like every input Pliant refuses."""


class Ramp:
    """A kinematic input q(t) in R^n moved linearly from its value at ``start`` to a target over
    ``duration`` and held there: the builders' ``cart_motion``, ``tilt`` and the like.

    ``Ramp`` objects are called with the simulation time by the model's drivers; the
    environment retargets them at each step. Their parameters are part of a snapshot.
    """

    def __init__(self, initial: np.ndarray | float) -> None:
        self.initial = np.atleast_1d(np.asarray(initial, dtype=float)).copy()
        self.reset()

    def reset(self) -> None:
        self.start_time = 0.0
        self.duration = 1.0
        self.source = self.initial.copy()
        self.target = self.initial.copy()

    def value(self, t: float) -> np.ndarray:
        s = min(max((t - self.start_time) / self.duration, 0.0), 1.0)
        return self.source + s * (self.target - self.source)

    def retarget(self, t: float, target: np.ndarray, duration: float) -> None:
        """From its value at t, move to `target` over `duration`."""
        self.source = self.value(t)
        self.start_time = float(t)
        self.duration = float(duration)
        self.target = np.asarray(target, dtype=float).reshape(self.initial.shape).copy()

    def scalar(self, t: float) -> float:
        """The first component, for builders that take a scalar trajectory."""
        return float(self.value(t)[0])

    def pair(self, t: float) -> tuple[float, float]:
        v = self.value(t)
        return float(v[0]), float(v[1])

    def snapshot(self) -> tuple:
        return (self.start_time, self.duration, self.source.copy(), self.target.copy())

    def restore(self, snap: tuple) -> None:
        self.start_time, self.duration = float(snap[0]), float(snap[1])
        self.source, self.target = snap[2].copy(), snap[3].copy()


@dataclass
class EnvSnapshot:
    """A whole environment at one instant (picklable). See :meth:`SoftRobotEnv.get_state`."""

    env: str
    version: int
    n_nodes: int
    state: State
    commands: np.ndarray
    ramps: dict[str, tuple]
    task: dict[str, Any]
    rng: dict[str, Any] | None
    elapsed_steps: int
    extra: dict[str, Any] = field(default_factory=dict)


class SoftRobotEnv(gym.Env):
    """Base of Pliant's environments.

    Subclasses set the class attributes (``default_config``, ``robot_defaults``, ...),
    implement :meth:`_build`, :meth:`_observe` and :meth:`_reward`, and choose their action
    maps with :meth:`use_actions` (:mod:`pliant.envs.actions`; or override :meth:`_commands`);
    optionally :meth:`_reset_task`, :meth:`_render_goal` and :meth:`_before_step`.

    Keyword arguments: ``config``, a :class:`pliant.envs.config.SimulationConfig`, or its
    fields (``dt``, ``substeps``, ``action_type``, ``tangent``, ``render_mode``) as keywords
    over the class's ``default_config``; ``reward`` and ``observation``, one of the class's
    ``rewards`` and ``observations``; the subclass's own; the rest go to the robot builder
    (``self.robot_kwargs``, over ``robot_defaults``).
    """

    metadata: ClassVar[dict] = {"render_modes": ["rgb_array", "human"], "render_fps": 10}
    #: registered name (``pliant/<name>-v0``) and snapshot version (raised where a change
    #: makes older snapshots unfit).
    name: ClassVar[str] = "Base"
    version: ClassVar[int] = 1
    #: camera (elevation, azimuth) of renders.
    view: ClassVar[tuple[float, float]] = (20.0, -60.0)

    #: the simulation config of a constructor given none (its keywords override each field).
    default_config: ClassVar[SimulationConfig] = SimulationConfig()
    #: the task's reward and observation variants, the default first (``reward="sofagym"``,
    #: ``observation="sofagym"``: SofaGym's definitions beside the thesis').
    rewards: ClassVar[tuple[str, ...]] = ("thesis",)
    observations: ClassVar[tuple[str, ...]] = ("thesis",)
    #: the robot builder's keywords of this environment where they are not the builder's own
    #: defaults (the constructor's other keywords override them).
    robot_defaults: ClassVar[dict[str, Any]] = {}

    def __init__(
        self,
        *,
        config: SimulationConfig | None = None,
        reward: str | None = None,
        observation: str | None = None,
        **kwargs,
    ) -> None:
        self.config = with_keywords(self.default_config if config is None else config, kwargs)
        self.reward_variant = self.rewards[0] if reward is None else reward
        self.observation_variant = self.observations[0] if observation is None else observation
        check_choice("reward", self.reward_variant, self.rewards)
        check_choice("observation", self.observation_variant, self.observations)
        render_mode = self.config.render_mode
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise EnvConfigError(
                f"render_mode must be one of {self.metadata['render_modes']}, got {render_mode!r}"
            )
        #: the robot builder's keywords: the constructor's keywords that are neither the
        #: config's nor the environment's own, over ``robot_defaults``.
        self.robot_kwargs: dict[str, Any] = {**self.robot_defaults, **kwargs}
        self.ramps: dict[str, Ramp] = {}
        self.model: Model = self._build()
        self.sim = ImplicitEuler(self.model, dt=self.dt, tangent=self.config.tangent)
        self.metadata = {**self.metadata, "render_fps": max(1, round(1.0 / self.step_time))}
        self.n_actuators = len(self.model.actuators)
        self.commands = np.zeros(self.n_actuators)
        self.task: dict[str, Any] = {}
        self._initial = self._initial_state()
        self.state = self._initial.copy()
        self._last_obs: np.ndarray | None = None
        self._elapsed = 0
        self._camera = None
        self._window = None
        self.sim_seconds = 0.0  # wall time spent in the simulation (for speed reports)

    @property
    def dt(self) -> float:
        return self.config.dt

    @property
    def substeps(self) -> int:
        return self.config.substeps

    @property
    def action_type(self) -> ActionType:
        return self.config.action_type

    @property
    def render_mode(self) -> str | None:
        return self.config.render_mode

    def use_actions(self, actions: ActionMap) -> None:
        """Act through `actions` (:mod:`pliant.envs.actions`); the action space is theirs."""
        self.action_map = actions
        self.action_space = actions.space(self.action_type)

    # ----------------------------------------------------------------- subclass interface
    def _build(self) -> Model:
        """Build the model (once); create the ramps its builder needs."""
        raise NotImplementedError

    def _initial_state(self) -> State:
        """The state every episode starts from (before :meth:`_reset_task` edits it)."""
        return self.model.rest_state()

    def _reset_task(self, rng: np.random.Generator, options: dict | None) -> None:
        """Draw the episode's task (goal, ...) into ``self.task``; may edit ``self.state``."""

    def _commands(self, action) -> Commands:
        """The step's commands for a valid action: those of the action maps."""
        return self.action_map(self, action)

    def _before_step(self) -> None:
        """What happens to the state as a step begins, beside the commands (a disturbance)."""

    def _observe(self) -> np.ndarray:
        raise NotImplementedError

    def _reward(self) -> tuple[float, bool, dict[str, float]]:
        """(reward, terminated, reward parts adding up to the reward) after a step."""
        raise NotImplementedError

    def _render_goal(self) -> np.ndarray | None:
        return self.task.get("goal")

    # ------------------------------------------------------------------------- helpers
    @property
    def step_time(self) -> float:
        """Simulated seconds per environment step."""
        return self.config.step_time

    def ramp(self, name: str, initial) -> Ramp:
        """A kinematic input for the builder, part of the snapshot."""
        self.ramps[name] = Ramp(initial)
        return self.ramps[name]

    def _check_action(self, action):
        """A valid action, or a clear error: wrong shape or type raises; a continuous value out
        of bounds is clipped to the box (documented behaviour of every environment)."""
        space = self.action_space
        if isinstance(space, gym.spaces.Discrete):
            a = np.asarray(action)
            if a.shape not in ((), (1,)) or not np.issubdtype(a.dtype, np.integer):
                raise ActionError(
                    f"{self.name}: a discrete action is one integer in [0, {space.n}), got"
                    f" {action!r}"
                )
            a = int(a.reshape(-1)[0])
            if not 0 <= a < space.n:
                raise ActionError(f"{self.name}: action {a} outside [0, {space.n})")
            return a
        a = np.asarray(action)
        if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
            raise ActionError(
                f"{self.name}: a continuous action is a float array of shape {space.shape},"
                f" got dtype {a.dtype}"
            )
        a = a.astype(float)
        if a.shape != space.shape:
            raise ActionError(f"{self.name}: action shape must be {space.shape}, got {a.shape}")
        if not np.all(np.isfinite(a)):
            raise ActionError(f"{self.name}: action must be finite, got {a}")
        return np.clip(a, space.low, space.high)

    def commands_for(self, action) -> Commands:
        """The commands a (valid) action gives from the present state: what :meth:`step`
        applies; nothing is written."""
        return self._commands(self._check_action(action))

    def _clip_observation(self, obs: np.ndarray) -> np.ndarray:
        space = self.observation_space
        return np.clip(np.asarray(obs, dtype=np.float32), space.low, space.high)

    # ---------------------------------------------------------------------- Gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        for r in self.ramps.values():
            r.reset()
        self.model.trajectories_changed()
        self.state = self._initial.copy()
        self.commands = np.zeros(self.n_actuators)
        self.task = {}
        self._elapsed = 0
        self._reset_task(self.np_random, options)
        obs = self._clip_observation(self._observe())
        self._last_obs = obs
        return obs.copy(), {}

    def step(self, action):
        commands = self.commands_for(action)
        for name, target in commands.ramps.items():
            self.ramps[name].retarget(self.state.time, target, self.step_time)
        self.task.update(commands.task)
        self._before_step()
        if self.ramps:  # retargeted in place: the poses the solver memoised are stale
            self.model.trajectories_changed()
        start = self.commands.copy()
        target = np.asarray(commands.actuators, dtype=float)
        # The lagged tangent is rebuilt at each environment step: the step then depends on
        # the snapshot and the action only (module docstring).
        self.sim.system.invalidate()
        clock = time.perf_counter()
        before = self.state
        try:
            for k in range(1, self.substeps + 1):
                cmd = start + (target - start) * (k / self.substeps)
                self.state = self.sim.step(self.state, cmd if self.n_actuators else None)
            self.commands = target
        except (DivergenceError, SolverError, ConstraintError) as exc:
            self.sim_seconds += time.perf_counter() - clock
            return self._diverged(before, f"{type(exc).__name__}: {exc}")
        self.sim_seconds += time.perf_counter() - clock
        obs = self._observe()
        if not np.all(np.isfinite(obs)):
            return self._diverged(before, "non-finite observation")
        self._elapsed += 1
        obs = self._clip_observation(obs)
        self._last_obs = obs
        reward, terminated, parts = self._reward()
        info = {"reward_parts": parts, **self._info()}
        if self.render_mode == "human":
            self.render()
        return obs.copy(), float(reward), bool(terminated), False, info

    def _diverged(self, before: State, cause: str):
        """A step the simulation could not take: the state goes back to where the step began
        (the last finite observation), the episode is truncated with the cause in
        ``info["diverged"]``, and the reward is that state's, as if the robot had stayed
        there. A learner bootstraps from a truncation; a reward of 0 instead would pay an
        agent of negative rewards (distances) for making the simulation fail."""
        self.state = before
        self._elapsed += 1
        reward, _, parts = self._reward()
        info = {"diverged": cause, "reward_parts": parts}
        return self._last_obs.copy(), float(reward), False, True, info

    def _info(self) -> dict[str, Any]:
        return {}

    # ------------------------------------------------------------------ save / restore
    def get_state(self) -> EnvSnapshot:
        """A picklable snapshot of the whole environment (module docstring)."""
        return EnvSnapshot(
            env=self.name,
            version=self.version,
            n_nodes=int(self.state.positions.shape[0]),
            state=self.state.copy(),
            commands=self.commands.copy(),
            ramps={k: r.snapshot() for k, r in self.ramps.items()},
            task=copy.deepcopy(self.task),
            rng=copy.deepcopy(self.np_random.bit_generator.state)
            if self._np_random is not None
            else None,
            elapsed_steps=self._elapsed,
            extra={"last_obs": None if self._last_obs is None else self._last_obs.copy()},
        )

    def set_state(self, snapshot: EnvSnapshot) -> None:
        """Restore a snapshot of :meth:`get_state` (from this environment class and model)."""
        if not isinstance(snapshot, EnvSnapshot):
            raise EnvStateError(f"expected an EnvSnapshot, got {type(snapshot).__name__}")
        if snapshot.env != self.name or snapshot.version != self.version:
            raise EnvStateError(
                f"snapshot of {snapshot.env} v{snapshot.version} given to {self.name}"
                f" v{self.version}"
            )
        if snapshot.n_nodes != self.state.positions.shape[0] or set(snapshot.ramps) != set(
            self.ramps
        ):
            raise EnvStateError(
                f"{self.name}: the snapshot's model ({snapshot.n_nodes} nodes) is not this"
                f" environment's ({self.state.positions.shape[0]} nodes): built with other"
                " arguments?"
            )
        if snapshot.commands.shape != self.commands.shape:
            raise EnvStateError(f"{self.name}: the snapshot's actuators are not this model's")
        try:  # a reduced model's state is its solver's to check, at its step
            if isinstance(snapshot.state, State):
                self.model.check_state(snapshot.state, what=f"{self.name}: the snapshot's state")
        except StateError as exc:
            raise EnvStateError(str(exc)) from exc
        self.state = snapshot.state.copy()
        self.commands = snapshot.commands.copy()
        for k, r in self.ramps.items():
            r.restore(snapshot.ramps[k])
        self.task = copy.deepcopy(snapshot.task)
        if snapshot.rng is not None:
            self.np_random.bit_generator.state = copy.deepcopy(snapshot.rng)
        self._elapsed = snapshot.elapsed_steps
        last = snapshot.extra.get("last_obs")
        self._last_obs = None if last is None else last.copy()
        self.model.trajectories_changed()
        self.sim.system.invalidate()

    # ------------------------------------------------------------------------ rendering
    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; give render_mode='rgb_array'")
            return None
        if self._camera is None:
            self._camera = RobotCamera(self.model, view=self.view, size=(480, 360))
        frame = self._camera.frame(
            self.state,
            title=f"{self.name}  t = {self.state.time:.2f} s",
            goals=self._render_goal(),
        )
        if self.render_mode == "rgb_array":
            return frame
        import matplotlib.pyplot as plt

        if self._window is None:
            plt.ion()
            self._window = plt.imshow(frame)
            plt.axis("off")
        else:
            self._window.set_data(frame)
        plt.pause(1.0 / self.metadata["render_fps"])
        return None

    def close(self) -> None:
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window.figure)
            self._window = None


def floor_goal(rng: np.random.Generator, options: dict | None, start, low, high) -> np.ndarray:
    """``options["goal"]``, or `start` (3,) plus an offset (x, 0, z) with (x, z) drawn
    uniformly in [low, high]: a goal on the floor (the x-z plane) near an object's start."""
    goal = (options or {}).get("goal")
    if goal is None:
        x, z = rng.uniform(low, high)
        goal = start + [x, 0.0, z]
    return np.asarray(goal, dtype=float).reshape(3)


def progress_reward(previous: float, current: float, eps: float = 1e-6) -> float:
    """Eq. 3.2: max(0, (d_{t-1} - d_t) / (d_{t-1} + eps)), in [0, 1]."""
    return max(0.0, (previous - current) / (previous + eps))


Builder = Callable[..., Model]
