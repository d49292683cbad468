"""RodManipulator's configuration-space graph (thesis §4.2.2, Fig. 4.8 B): its contact
configurations by collision detection on the observation, and the re-contact experts that
take the rod from one configuration to the next.

Pliant's scene is not the authors' (:mod:`pliant.envs.rod_manipulator`): two one-segment
fingers hang side by side at (0, ±spacing/2) over a rod lying along y, so their crossed/on-top
configurations do not exist here. What limits a turn is the geometry: a straight finger reaches
the rod's top only while the rod's axis passes within its bending range, 25|sin θ| mm for a rod
turned by θ, so pressing on the top turns the rod to about 50° and no further (there the
fingertips would have to land 20 mm off their axes and the bend lifts them over the rod), and
around 90° a fingertip can touch the rod only near its centre, where it exerts no torque. The
fingers lowered *beside* the rod and bent inwards in opposite directions pinch it by its sides
and carry it through 90° to about 150°, where the top is in reach again. The contact
configurations are therefore:

- node 0, **free**: neither fingertip touches the rod;
- node 1, **on top**: a fingertip on the rod's top face (pressing, it can drag the rod round);
- node 2, **beside**: a fingertip lower than the rod's top, at its side (a pinch).

Two experts move between them (:func:`rod_experts`): ``stroke`` (lift, place the fingertips
over the rod's axis where it passes nearest to them — a fingertip inverse computed from the
observed rod pose and the fingers' measured bending — press, bend along the turn, lift while
bent: the rod is dragged round) and ``pinch`` (the fingers lowered beside the rod and bent
inwards, a fixed open-loop sequence like the authors' experts). Each runs its fixed number of
steps through the nodes it crosses.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from pliant.errors import ModelError, TrainingError
from pliant.learn.graph.agents import ExpertOption
from pliant.learn.graph.graph import ConfigurationGraph

NODE_NAMES = ("free", "on top", "beside")


@dataclass(frozen=True)
class RodGeometry:
    """What the partition and the experts need of the scene (mm): the fingers' axes in the
    table's plane, the fingertips' radius, the rod's size, the observation's length scale.

    Observation layout (:class:`pliant.envs.rod_manipulator.RodManipulatorEnv`): 3 points at
    each fingertip (its centre 1 mm above the tip, then 3 mm towards +x and +y), the rod's
    centre, all divided by ``length_scale``, then the cumulative angle and the goal divided by
    2π. The rod starts along y, so its heading is the cumulative angle."""

    fingers: np.ndarray  # (2, 2)
    finger_radius: float
    rod_size: tuple[float, float, float]
    length_scale: float
    margin: float = 2.0

    @classmethod
    def of(cls, env: gym.Env) -> RodGeometry:
        """Read from the environment's model: the fingertips' rest centres (the effectors),
        their radius (the tip face's nodes), the rod's box and the contacts' margin."""
        base = env.unwrapped
        model = base.model
        rest = model.body.rest_positions
        tips = np.vstack([e.points.positions(rest) for e in model.effectors])
        half_spacing = 0.5 * float(np.linalg.norm(tips[1, :2] - tips[0, :2]))
        radii = []
        for tip in tips:
            offsets = np.hypot(*(rest[:, :2] - tip[:2]).T)
            face = (np.abs(rest[:, 2] - tip[2]) < 1e-9) & (offsets < half_spacing)
            radii.append(float(offsets[face].max()))
        (rod,) = model.rigid_bodies
        return cls(
            fingers=tips[:, :2].copy(),
            finger_radius=max(radii),
            rod_size=tuple(float(v) for v in 2.0 * rod.shape.half_extents),
            length_scale=base.length_scale,
            margin=float(model.contacts.margin),
        )

    def _checked(self, obs: np.ndarray) -> np.ndarray:
        obs = np.asarray(obs, dtype=float)
        if obs.shape != (23,) or not np.all(np.isfinite(obs)):
            raise TrainingError(
                f"a RodManipulator observation is 23 finite values, got shape {obs.shape}"
                + ("" if obs.shape != (23,) else " with non-finite values")
            )
        return obs

    def tips(self, obs: np.ndarray) -> np.ndarray:
        """The fingertips' centres (2, 3), mm (the observation's points are 1 mm above)."""
        points = self._checked(obs)[:18].reshape(2, 3, 3)[:, 0] * self.length_scale
        return points - [0.0, 0.0, 1.0]

    def rod(self, obs: np.ndarray) -> tuple[np.ndarray, float]:
        """The rod's centre (3,), mm, and heading (rad)."""
        obs = self._checked(obs)
        return obs[18:21] * self.length_scale, float(obs[21]) * 2 * np.pi

    def local(self, obs: np.ndarray) -> np.ndarray:
        """The fingertips in the rod's frame (2, 3): across the rod, along it, up from its
        centre."""
        centre, heading = self.rod(obs)
        c, s = np.cos(heading), np.sin(heading)
        # The rod's long axis is (-sin, cos): rotate world offsets by -heading.
        d = self.tips(obs) - centre
        return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]])


def finger_contacts(geometry: RodGeometry, obs: np.ndarray) -> list[str]:
    """Each fingertip's contact with the rod, by collision detection between the fingertip
    (a disc of the finger's radius) and the rod's box, within the contact margin: 'top' (the
    disc over the top face, at most ``margin`` above it), 'side' (lower than the top face, the
    disc within ``margin`` of a side or end face), or 'free'."""
    width, length, height = geometry.rod_size
    r, m = geometry.finger_radius, geometry.margin
    out = []
    for across, along, up in geometry.local(obs):
        # Horizontal distance from the fingertip's centre to the rod's outline (0 inside it).
        outside = np.hypot(max(abs(across) - width / 2, 0.0), max(abs(along) - length / 2, 0.0))
        if outside < r and height / 2 - m <= up <= height / 2 + m:
            out.append("top")  # the disc overlaps the top face, at most `margin` above it
        elif up < height / 2 - m and outside - r <= m:
            out.append("side")  # lower than the top, the disc within `margin` of a side
        else:
            out.append("free")
    return out


def rod_partition(geometry: RodGeometry):
    """Observation -> node: 2 (beside) if a fingertip is at the rod's side, else 1 (on top) if
    one is on its top, else 0 (free)."""

    def partition(obs: np.ndarray) -> int:
        contacts = finger_contacts(geometry, obs)
        if "side" in contacts:
            return 2
        if "top" in contacts:
            return 1
        return 0

    return partition


def rod_graph(geometry: RodGeometry) -> ConfigurationGraph:
    """Free, on top, beside; every configuration reaches the others (lifting, lowering, or a
    fingertip sliding off the top face); episodes start free."""
    return ConfigurationGraph(
        list(NODE_NAMES), [[1, 2], [0, 2], [0, 1]], partition=rod_partition(geometry), start=0
    )


@dataclass(frozen=True)
class BendTable:
    """A fingertip's measured bending: cable pull (mm) -> horizontal displacement and lift of
    the tip (mm), base raised, nothing touched. Monotone in the pull."""

    pull: np.ndarray
    reach: np.ndarray
    lift: np.ndarray

    @classmethod
    def measure(
        cls, env: gym.Env, pulls: Sequence[float] = (2, 4, 6, 8, 10, 12, 15), steps: int = 4
    ) -> BendTable:
        """Pull finger 0's +x cable to each level with the base at its top, ``steps``
        environment steps a level, on ``env`` (reset first; left mid-episode)."""
        base = env.unwrapped
        env.reset(seed=0)
        rest = base.tip_points.positions(base.state.positions)[0]
        maximum = float(base.max_commands[0])
        reach, lift = [0.0], [0.0]
        for pull in pulls:
            if not 0 < pull <= maximum:
                raise ModelError(f"pull {pull} outside (0, {maximum}] mm")
            action = -np.ones(base.n_actuators + 1)
            action[0] = 2 * pull / maximum - 1
            action[-1] = 1.0
            for _ in range(steps):
                env.step(action)
            d = base.tip_points.positions(base.state.positions)[0] - rest
            reach.append(float(np.hypot(d[0], d[1])))
            lift.append(float(d[2] - base.task["base"]))
        table = cls(np.array([0.0, *pulls]), np.array(reach), np.array(lift))
        if np.any(np.diff(table.reach) <= 0):
            raise ModelError(f"the measured reach is not increasing with the pull: {table.reach}")
        return table

    def cables(self, displacement: np.ndarray) -> np.ndarray:
        """The 4 cable pulls (+x, +y, -x, -y) that move a fingertip by `displacement` (2,),
        mm: the pull for its length from the table, split along its direction (bending is
        linear in the cable shortening's vector for a cylindrical finger)."""
        size = float(np.hypot(*displacement))
        out = np.zeros(4)
        if size < 1e-9:
            return out
        pull = float(np.interp(size, self.reach, self.pull))
        cx, cy = pull * np.asarray(displacement) / size
        out[0 if cx >= 0 else 2] = abs(cx)
        out[1 if cy >= 0 else 3] = abs(cy)
        return out


class _Commands:
    """Cable pulls (mm) and base height (mm) -> the environment's action in [-1, 1]^9."""

    def __init__(self, env: gym.Env) -> None:
        base = env.unwrapped
        self.max = np.asarray(base.max_commands, dtype=float)
        self.low, self.high = base.base_low, base.base_high

    def __call__(self, pulls: np.ndarray, height: float) -> np.ndarray:
        action = np.empty(len(self.max) + 1)
        action[:-1] = 2 * np.asarray(pulls) / self.max - 1
        action[-1] = 2 * (height - self.low) / (self.high - self.low) - 1
        return np.clip(action, -1.0, 1.0)


def stroke_expert(
    geometry: RodGeometry,
    table: BendTable,
    env: gym.Env,
    *,
    press: float = -10.0,
    pull: float = 8.0,
    penalty: float = -1.0,
) -> ExpertOption:
    """Re-contact on the top and drag the rod round, 6 steps: raise the base and bend each
    fingertip over the rod's axis where it passes nearest to the finger (the fingertip inverse
    of `table` on the observed rod pose); lower the base to `press` mm; bend each fingertip a
    further `table`-reach of `pull` mm along the turn (counter-clockwise, the goals' sense)
    with the base held; raise the base in two steps, still bent (the fingertips' grip lets go
    as the pressure drops, dragging the rod); relax."""
    commands = _Commands(env)
    top = commands.high
    plan: dict[str, np.ndarray] = {}

    def policy(obs: np.ndarray, k: int) -> np.ndarray:
        if k == 0:  # plan from the rod's pose as the expert starts
            centre, heading = geometry.rod(obs)
            axis = np.array([-np.sin(heading), np.cos(heading)])
            offsets = geometry.fingers - centre[:2]
            foot = centre[:2] + (offsets @ axis)[:, None] * axis  # nearest points of the axis
            radial = foot - centre[:2]
            tangent = np.column_stack([-radial[:, 1], radial[:, 0]])  # counter-clockwise
            tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-9)
            place = foot - geometry.fingers
            turn = place + tangent * float(np.interp(pull, table.pull, table.reach))
            plan["place"] = np.concatenate([table.cables(d) for d in place])
            plan["turn"] = np.concatenate([table.cables(d) for d in turn])
            return commands(plan["place"], top)
        if k == 1:
            return commands(plan["place"], press)
        if k == 2:
            return commands(plan["turn"], press)
        if k in (3, 4):
            return commands(plan["turn"], press + (top - press) * (k - 2) / 2)
        return commands(np.zeros(8), top)

    return ExpertOption(
        "stroke", policy, start_nodes=(0, 1, 2), penalty=penalty, steps=6, action_dim=9
    )


def pinch_expert(
    env: gym.Env,
    *,
    depth: float = -20.0,
    pulls: Sequence[float] = (3.0, 6.0, 8.0, 10.0, 12.0),
    across: float = 0.7,
    penalty: float = -1.0,
) -> ExpertOption:
    """Pinch the rod by its sides and carry it round, open loop: the base lowered to `depth`
    mm (the fingertips beside the rod, below its top), each finger bent inwards (towards the
    other finger's side: finger 0 by +y, finger 1 by -y) and along opposite x (finger 0 +x,
    finger 1 -x, `across` of the inward pull): the rod is held between them and turned
    counter-clockwise, through 90°, as the pulls rise through `pulls`; then raise the base and
    relax."""
    commands = _Commands(env)
    if depth < commands.low:
        raise ModelError(
            f"the pinch lowers the base to {depth} mm, below the environment's base_low"
            f" {commands.low}: make it with base_low <= {depth}"
        )
    sequence = []
    for pull in pulls:
        cables = np.zeros(8)
        cables[[0, 6]] = across * pull  # finger 0 +x, finger 1 -x
        cables[[1, 7]] = pull  # finger 0 +y, finger 1 -y
        sequence.append(commands(cables, depth))
    sequence.append(commands(cables, commands.high))
    sequence.append(commands(np.zeros(8), commands.high))
    return ExpertOption("pinch", np.array(sequence), start_nodes=(0, 1, 2), penalty=penalty)


def rod_experts(
    env: gym.Env, geometry: RodGeometry, table: BendTable, penalty: float = -1.0
) -> list[ExpertOption]:
    """The stroke and the pinch for `env`, each use charged `penalty`."""
    return [
        stroke_expert(geometry, table, env, penalty=penalty),
        pinch_expert(env, penalty=penalty),
    ]


def angle_rule(band: float = 45.0) -> Callable[[np.ndarray], str]:
    """The experts' hand-written chaining (what the Evaluator has to learn): the stroke while
    the rod's axis lies within `band` degrees of the fingers' line, where the fingertips can
    land on its top, the pinch otherwise."""

    def choose(obs: np.ndarray) -> str:
        heading = np.degrees(float(obs[21]) * 2 * np.pi)
        across = (heading + 90.0) % 180.0 - 90.0  # the rod is symmetric under a half turn
        return "stroke" if across < band else "pinch"

    return choose


def expert_rollout(scene, choose: Callable[[np.ndarray], str], steps: int, seed: int = 0) -> dict:
    """Run `scene`'s experts for `steps` environment steps, ``choose(obs)`` naming the next
    one at each of its starts. Returns the experts used, the rod's angle (deg) and node after
    every step, the largest angle and the wall time."""
    env, graph = scene.env, scene.graph
    experts = {e.name: e for e in scene.experts}
    obs, _ = env.reset(seed=seed)
    angles, nodes, used = [0.0], [graph.node_of(obs)], []
    start = time.perf_counter()
    while len(angles) <= steps:
        expert = experts[choose(obs)]
        used.append(expert.name)
        for k in range(len(expert)):
            obs, _, terminated, truncated, info = env.step(expert.act(obs, k))
            angles.append(float(np.degrees(info["angle"])))
            nodes.append(graph.node_of(obs))
            if len(angles) > steps or terminated:
                break
        if terminated:
            break
    return {
        "experts": used,
        "angle_deg": angles,
        "nodes": nodes,
        "max_angle_deg": max(angles),
        "wall_s": time.perf_counter() - start,
    }
