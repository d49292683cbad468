"""The Trunk pushing a rigid cube on a plane (thesis §4.1.2: "a rigid cube that can glide on a
rigid planar surface, and the base of the trunk can translate in one direction").

The Trunk of :mod:`pliant.robots.trunk` lies along +z under gravity -y, above a floor; its
base is held by a carriage that translates along the trunk's axis (driven nodes). The cables
start from their pull points on the base plane, which are embedded in the held base (carried
with it, as the motors are) rather than fixed in space. A rigid cube rests on the floor beside
the trunk's distal half, on the +x side: pulling the +x cable bends the trunk onto it and pushes
it along the floor.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.control import InverseControl
from pliant.constraints.effector import PositionEffector, RigidEffector
from pliant.errors import ModelError
from pliant.fem.body import TetBody
from pliant.fem.rigid import DrivenNodes, KinematicBody, RigidBody, rail
from pliant.geometry.collision import Box, Plane
from pliant.model import Model
from pliant.robots.common import cables, landmark, smooth_ramp
from pliant.robots.parameters import Contact, Cube, Meshing
from pliant.robots.scene import builder
from pliant.robots.trunk import TRUNK, reference_cable_paths, trunk


def demo_base_motion(t: float) -> float:
    """Advance the base by 20 mm along the trunk's axis between 1 s and 2 s."""
    return 20.0 * smooth_ramp(t, 1.0, 1.0)


def trunk_scene(
    p,
    *,
    base_motion: Callable[[float], float] | None,
    obstacle: Plane,
    objects: Callable[[TetBody], tuple[list[RigidBody], list | None]],
    name: str,
) -> Model:
    """The Trunk of `p`'s groups with the rigid bodies that `objects(body)` makes (and its
    effectors, None: the Trunk's), touching them and the plane `obstacle` (`p.contact`).

    With `base_motion`, the base is held by a carriage that translates along the trunk's axis
    by `base_motion(t)` (mm), and each cable starts from its pull point on the base plane,
    embedded in the held base (carried with it, as the motors are); without, the base is
    fixed, and so are the pull points."""
    shared = ("meshing", "solid", "inertia", "gravity", "damping", "cables", "reach")
    arm = trunk(**{k: p.groups[k] for k in shared})
    body = arm.body
    actuators, drivers = arm.actuators, []
    if base_motion is not None:
        mesh = body.mesh
        paths, pulls = reference_cable_paths()
        carried = [
            np.vstack(
                [
                    landmark(mesh, f"pull_points_{i}", pulls[i]),
                    landmark(mesh, f"cable_points_{i}", paths[i]),
                ]
            )
            for i in range(8)
        ]
        actuators = cables(mesh, body, carried, [None] * 8, p.cables, p.reach.limits())
        carriage = KinematicBody(
            Box([20.0, 20.0, 5.0], position=[0.0, 0.0, -5.0]),
            rail([0.0, 0.0, -5.0], [0.0, 0.0, 1.0], base_motion),
            name="carriage",
        )
        drivers = [DrivenNodes(body.fixed_nodes, carriage, name="carriage")]
    rigid, effectors = objects(body)
    return Model(
        body,
        actuators=actuators,
        effectors=arm.effectors if effectors is None else effectors,
        contacts=p.contacts([obstacle]),
        drivers=drivers,
        rigid_bodies=rigid,
        name=name,
    )


def floor(height: float) -> Plane:
    """The floor y = `height` under the Trunk."""
    return Plane(normal=(0.0, 1.0, 0.0), point=(0.0, height, 0.0))


@builder(Meshing(8.0), *TRUNK, Contact(0.3, 5.0), Cube(30.0, 0.01))
def trunk_cube(
    p,
    *,
    cube_position: tuple[float, float] = (30.0, 150.0),
    floor_height: float = -30.0,
    base_motion: Callable[[float], float] = demo_base_motion,
) -> Model:
    """The Trunk (SoftRobots parameters, coarser mesh by default) over a floor y = floor_height,
    a rigid cube of `cube_size` mm and `cube_mass` kg on it at (x, z) = `cube_position`, the
    base moving along z by `base_motion(t)` (mm)."""

    def cube(body: TetBody) -> tuple[list[RigidBody], None]:
        half = p.cube.cube_size / 2
        x, z = cube_position
        box = Box([half, half, half], position=[x, floor_height + half, z])
        return [RigidBody(box, p.cube.cube_mass, friction=p.contact.friction, name="cube")], None

    return trunk_scene(
        p,
        base_motion=base_motion,
        obstacle=floor(floor_height),
        objects=cube,
        name="trunk_cube",
    )


@cache
def surface_points(mesh_size: float = 8.0) -> np.ndarray:
    """(k, 3) the colliding points of :func:`trunk_cube`'s Trunk at rest (its surface nodes
    but the held base's), what a proxy skins to touch the cube and the floor through the same
    surface (:func:`pliant.proxy.trunk_proxy`). Read-only."""
    body = trunk(mesh_size=mesh_size).body
    points = body.rest_positions[body.colliding_nodes()].copy()
    points.flags.writeable = False
    return points


def demo_actuation(t: float) -> np.ndarray:
    """Pull the long +x cable (cable 3) to 25 mm over 1 s: the trunk bends onto the cube."""
    values = np.zeros(8)
    values[3] = 25.0 * min(t, 1.0)
    return values


# --- Pushing a cube to a goal with inverse control and contacts (QPCC) -----------------------


@builder(Meshing(8.0), *TRUNK, Contact(0.0, 3.0), Cube(50.0, 0.01))
def trunk_push(
    p,
    *,
    cube_gap: float = 0.3,
    cube_z: float = 150.0,
    cube_friction: float = 0.0,
    drag: float = 20.0,
    floor_height: float = -45.0,
    pusher_weight: float = 0.3,
    cube_axes: tuple[bool, bool, bool] = (True, False, False),
) -> Model:
    """The Trunk, base fixed, beside a cube on an air table: the scene of the QPCC push.

    The cube (`cube_size` mm, `cube_mass` kg) stands on a frictionless floor at y =
    floor_height with its -x face `cube_gap` mm from the trunk's side at z = cube_z, and feels
    a viscous drag -drag m v (1/s), so that it moves only while pushed. Its friction with the
    trunk is `cube_friction`. Two effectors: the cube's centre on `cube_axes` (x by default:
    a pusher cannot pull the cube back sideways; a `RigidEffector`, which the actuators move
    only through the contacts), and the trunk's point facing the
    cube on x (weight `pusher_weight`), whose goal :class:`PushControl` keeps on the cube's
    face to hold the contact, as the thesis' Trunk-and-cube reward favours contact (§4.1.2).
    """

    def cube_and_pusher(body: TetBody) -> tuple[list[RigidBody], list]:
        rest = body.rest_positions.reshape(-1, 3)
        near = rest[np.abs(rest[:, 2] - cube_z) <= 0.5 * p.mesh_size]
        if near.size == 0:
            raise ModelError(f"trunk_push: the trunk has no node near z = {cube_z}")
        side = near[np.argmax(near[:, 0])]
        half = 0.5 * p.cube.cube_size
        centre = [side[0] + cube_gap + half, floor_height + half, cube_z]
        cube = RigidBody(
            Box([half, half, half], position=centre),
            p.cube.cube_mass,
            friction=cube_friction,
            linear_damping=drag,
            angular_damping=drag,
            name="cube",
        )
        pusher = PositionEffector(
            EmbeddedPoints(body.mesh, [[side[0], 0.0, cube_z]]),
            body.rest_positions,
            axes=(True, False, False),
            weight=pusher_weight,
            name="pusher",
        )
        return [cube], [RigidEffector(cube, axes=cube_axes, name="cube"), pusher]

    return trunk_scene(
        p,
        base_motion=lambda t: 0.0,
        obstacle=floor(floor_height),
        objects=cube_and_pusher,
        name="trunk_push",
    )


@dataclass
class PushControl:
    """Inverse control with contacts (QPCC) that pushes a model's first rigid body to `target`.

    Each step, in `begin`, the goals of the two effectors of :func:`trunk_push` are set from
    the state: the cube's goal moves from its centre towards `target` by at most
    speed * dt (a goal the step can reach without a jolt: the one-step QP would otherwise
    throw the light trunk at a goal millimetres away), and near the target by at most
    drag * dt * distance, so that the cube does not coast past it once released; the pusher's
    goal is the cube's face pressed in by `depth`, so that the QP keeps the contact closed and
    pushes through it (`dt` is the solver's time step). The
    forces come from :class:`InverseControl` (Eq. 2.15 with complementarity), the contacts
    within `seed_gap` starting closed (default speed * dt: a gap the trunk may close in one
    step at the pushing speed; closing a wider one in a step throws the trunk at the cube).
    """

    target: np.ndarray
    speed: float = 10.0
    depth: float = 2.0
    dt: float = 0.01
    seed_gap: float | None = None
    regularisation: float = 1e-3
    roles = ("actuator", "effector")

    def __post_init__(self) -> None:
        self.target = np.asarray(self.target, dtype=float).reshape(3)
        for label, v in (("speed", self.speed), ("depth", self.depth), ("dt", self.dt)):
            if not (math.isfinite(v) and v > 0):
                raise ModelError(f"PushControl: {label} must be finite and > 0, got {v!r}")
        seed = self.speed * self.dt if self.seed_gap is None else self.seed_gap
        self._inverse = InverseControl(regularisation=self.regularisation, seed_gap=seed)

    def prepare(self, model) -> None:
        if len(model.effectors) != 2 or not model.rigid_bodies:
            raise ModelError(
                f"PushControl drives a cube effector and a pusher effector (trunk_push); "
                f"{model.name} has {len(model.effectors)} effectors"
            )
        self._inverse.prepare(model)

    def begin(self, model, state) -> None:
        cube, pusher = model.effectors
        centre = state.rigid_positions[0]
        step = self.speed * self.dt
        # Slow down near the target: a cube left at speed v coasts v / drag under its drag.
        ahead = self.target - centre
        drag = cube.body.linear_damping
        reach = np.minimum(step, drag * self.dt * np.abs(ahead)) if drag > 0 else step
        cube.goals = centre + np.clip(ahead, -reach, reach)
        half = float(cube.body.shape.half_extents[0])
        face = centre[0] - half + self.depth
        point = pusher.position(state.positions)[0]
        goal = point.copy()
        goal[0] += float(np.clip(face - point[0], -step, step))
        pusher.goals = goal[None, :]

    def actuation_with_contacts(self, problem, model, state, contact):
        return self._inverse.actuation_with_contacts(problem, model, state, contact)

    def actuation(self, problem, model, state):
        return self._inverse.actuation(problem, model, state)


PUSH_TARGETS = (5.0, 10.0, 15.0)


def push_demo(t: float) -> PushControl:
    """Push the cube of the default :func:`trunk_push` by 5, 10 then 15 mm along x, one target
    every 1.5 s."""
    start = _default_push_cube()
    offset = PUSH_TARGETS[min(int(t / 1.5), len(PUSH_TARGETS) - 1)]
    return PushControl(start + np.array([offset, 0.0, 0.0]))


@cache
def _default_push_cube() -> np.ndarray:
    return trunk_push().rigid_bodies[0].position.copy()
