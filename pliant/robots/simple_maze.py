"""SimpleMaze: a rigid maze tilted directly about x and y, with a ball rolling in it (SofaGym
simple_maze-v0); the maze and ball shared with the Tripod scene (:mod:`pliant.robots.tripod`).

The maze is a square floor with border walls and inner walls that leave a serpentine path of
parallel corridors along y (`maze_boxes`): one rigid body whose shape, a
:class:`pliant.geometry.collision.BoxUnion`, meets the ball box by box (a ball against a
floor and a wall gets both contacts). The ball is a rigid sphere with friction.

A Model needs a deformable body, and a Model's moving supports are driven nodes: the maze
therefore rests, held by friction, on four points of a soft gel pad whose underside is carried by
a gimbal plate, tilted by the action (theta_x, theta_y) = Rot(x, theta_x) Rot(y, theta_y) within
+-0.2 rad (SofaGym's range). The pad follows the plate to a few hundredths of a millimetre, so
the maze is tilted directly: theta_x > 0 sends the ball towards -y, theta_y > 0 towards +x.
Four support points rather than the pad's whole top face keep the contact problem well
conditioned (a rigid body on many stiff contacts makes Gauss-Seidel crawl).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.contact import Contacts
from pliant.errors import ConstraintError, ModelError
from pliant.fem.body import TetBody
from pliant.fem.rigid import DrivenNodes, KinematicBody, RigidBody, Trajectory
from pliant.geometry.collision import Box, BoxUnion, Plane, Sphere
from pliant.geometry.rotation import axis_angle
from pliant.mesh import box_beam
from pliant.mesh.shapes import _require_positive, _require_whole
from pliant.model import Model, State
from pliant.robots.common import fixed_by_box, smooth_ramp
from pliant.robots.parameters import ContactSolver, Damping, Density, Gravity, Meshed, Solid
from pliant.robots.scene import builder

# Indices of the rigid bodies in the models of this module and of pliant.robots.tripod.
BALL, MAZE = 0, 1


@dataclass(frozen=True)
class Maze:
    """The maze (`maze_boxes`: its size, corridors, walls and floor), its mass (kg), the ball
    (radius mm, mass kg) and the Coulomb coefficients of the ball on the maze and of the maze
    on its support, which holds it."""

    keyword: ClassVar[str] = "maze"
    maze_size: float = 60.0
    corridors: int = 3
    wall_thickness: float = 2.0
    wall_height: float = 8.0
    floor_thickness: float = 2.0
    maze_mass: float = 0.015
    ball_radius: float = 4.0
    ball_mass: float = 0.002
    ball_friction: float = 0.3
    support_friction: float = 1.0


# The gel both scenes carry the maze on (kPa, kg/mm^3), and its damping.
GEL = (Density(1.07e-6), Gravity.Z, Damping(1.0, 0.01), Maze(), ContactSolver())


def corridor_width(size: float, corridors: int, wall_thickness: float) -> float:
    """Free width of each corridor: the inside of the borders less the inner walls."""
    _require_whole("corridors", corridors)
    width = (size - (corridors + 1) * wall_thickness) / corridors
    if not width > 0.0:
        raise ModelError(
            f"{corridors} corridors and their walls ({wall_thickness} mm) do not fit in a"
            f" {size} mm maze"
        )
    return width


def maze_boxes(
    *,
    size: float = 60.0,
    corridors: int = 3,
    wall_thickness: float = 2.0,
    wall_height: float = 8.0,
    floor_thickness: float = 2.0,
) -> list[Box]:
    """The maze in its own frame: a `size` x `size` floor (the first box; its top face on
    z = 0, centred on the z axis), walls round it, and `corridors - 1` inner walls along y,
    joined alternately to the -y and +y borders and leaving an opening one corridor wide at
    their other end: a path of `corridors` parallel corridors (`maze_path`). The boxes touch
    without overlapping."""
    _require_positive(
        size=size,
        wall_thickness=wall_thickness,
        wall_height=wall_height,
        floor_thickness=floor_thickness,
    )
    width = corridor_width(size, corridors, wall_thickness)
    half, t, z = size / 2, wall_thickness, wall_height / 2
    inner = half - t  # the inner faces of the borders
    boxes = [
        Box([half, half, floor_thickness / 2], [0.0, 0.0, -floor_thickness / 2]),
        Box([half, t / 2, z], [0.0, -half + t / 2, z]),
        Box([half, t / 2, z], [0.0, half - t / 2, z]),
        Box([t / 2, inner, z], [-half + t / 2, 0.0, z]),
        Box([t / 2, inner, z], [half - t / 2, 0.0, z]),
    ]
    length = 2 * inner - width
    for i in range(1, corridors):
        x = -inner + i * (width + t) - t / 2
        side = -1.0 if i % 2 else 1.0  # odd walls leave from -y, even ones from +y
        boxes.append(Box([t / 2, length / 2, z], [x, side * (inner - length / 2), z]))
    return boxes


def maze_path(size: float, corridors: int, wall_thickness: float) -> np.ndarray:
    """(2 corridors, 2) way points (x, y) of the path in the maze's frame: the centres of each
    corridor's two ends, from the start (corridor 0 at -y) to the goal (the far end of the last
    corridor)."""
    width = corridor_width(size, corridors, wall_thickness)
    inner = size / 2 - wall_thickness
    end = inner - width / 2
    points = []
    for i in range(corridors):
        x = -inner + width / 2 + i * (width + wall_thickness)
        ys = (-end, end) if i % 2 == 0 else (end, -end)
        points += [(x, ys[0]), (x, ys[1])]
    return np.array(points)


def maze_and_ball(underside: float, maze: Maze) -> list[RigidBody]:
    """[ball, maze] (`BALL`, `MAZE`): the maze level, the underside of its floor centred at
    (0, 0, `underside`), the ball at rest at the start of the path. A body's point on a rigid
    body takes the rigid body's friction coefficient: the maze's is `support_friction`, what
    holds it on its support; two rigid bodies take sqrt(mu_a mu_b), so the ball's own
    coefficient is the one that gives `ball_friction` on the maze."""
    m = maze
    _require_positive(
        maze_mass=m.maze_mass,
        ball_radius=m.ball_radius,
        ball_mass=m.ball_mass,
        support_friction=m.support_friction,
    )
    width = corridor_width(m.maze_size, m.corridors, m.wall_thickness)
    if not (2 * m.ball_radius < width and m.ball_radius < m.wall_height):
        raise ModelError(
            f"the ball (radius {m.ball_radius}) must fit in a corridor ({width:.3g} mm wide) and"
            f" stay below the walls ({m.wall_height} mm)"
        )
    boxes = maze_boxes(
        size=m.maze_size,
        corridors=m.corridors,
        wall_thickness=m.wall_thickness,
        wall_height=m.wall_height,
        floor_thickness=m.floor_thickness,
    )
    # The rigid body's origin is its centre of mass: the boxes are centred on their centroid.
    centroid = BoxUnion(boxes).centroid
    centred = [Box(b.half_extents, b.position - centroid, b.rotation) for b in boxes]
    level = underside + m.floor_thickness
    frame = np.array([0.0, 0.0, level])
    # Triangles of 5 mm at most, for the drawings (see BoxUnion).
    shape = BoxUnion(centred, frame + centroid, cell=5.0)
    body = RigidBody(shape, m.maze_mass, friction=m.support_friction, name="maze")
    x, y = maze_path(m.maze_size, m.corridors, m.wall_thickness)[0]
    ball = RigidBody(
        Sphere(m.ball_radius, position=[x, y, level + m.ball_radius]),
        m.ball_mass,
        friction=m.ball_friction**2 / m.support_friction,
        name="ball",
    )
    return [ball, body]


def maze_model(
    p,
    body: TetBody,
    drivers: list[DrivenNodes],
    supports: EmbeddedPoints,
    underside: float,
    floor: float,
    name: str,
) -> Model:
    """The model of `body` carrying the maze and the ball (`p.maze`, `maze_and_ball` at
    `underside`) on its `supports`, driven by `drivers`, over a floor at z = `floor` that
    catches a ball leaving the maze."""
    solver = p.contact_solver
    return Model(
        body,
        contacts=Contacts(
            [Plane(point=(0.0, 0.0, floor))],
            friction=p.maze.support_friction,
            margin=solver.contact_margin,
            points=supports,
            tolerance=solver.contact_tolerance,
            max_iterations=solver.contact_iterations,
        ),
        drivers=drivers,
        rigid_bodies=maze_and_ball(underside, p.maze),
        name=name,
    )


def in_maze_frame(model: Model, state: State, points: np.ndarray) -> np.ndarray:
    """World `points` (k, 3) in the frame of `maze_boxes` (the floor's top face on z = 0) of
    the model's maze at `state`."""
    floor = model.rigid_bodies[MAZE].shape.boxes[0]
    origin = floor.position + [0.0, 0.0, floor.half_extents[2]]
    position, rotation = state.rigid_positions[MAZE], state.rigid_rotations[MAZE]
    return (np.atleast_2d(points) - position) @ rotation - origin


def ball_in_maze(model: Model, state: State) -> np.ndarray:
    """The ball's centre in the maze's frame (`maze_boxes`)."""
    return in_maze_frame(model, state, state.rigid_positions[BALL])[0]


def checked_commands(
    commands: Callable[[float], np.ndarray | tuple], n: int, limit: float, what: str
) -> Callable[[float], np.ndarray]:
    """`commands` whose values at t are checked: n angles within +-`limit` (rad), else a
    ConstraintError naming the command, its value and the time."""

    def checked(t: float) -> np.ndarray:
        values = np.asarray(commands(t), dtype=float).reshape(-1)
        if values.size != n:
            raise ConstraintError(f"{what}: expected {n} angles at t={t:.4g} s, got {values.size}")
        outside = ~(np.abs(values) <= limit)
        if np.any(outside):
            i = int(np.argmax(outside))
            raise ConstraintError(
                f"{what} {i}: angle {float(values[i])!r} rad at t={t:.4g} s is outside its range"
                f" [-{limit}, {limit}]"
            )
        return values

    return checked


def tilt_rotation(theta_x: float, theta_y: float) -> np.ndarray:
    """Rot(x, theta_x) Rot(y, theta_y)."""
    return axis_angle([1.0, 0.0, 0.0], theta_x) @ axis_angle([0.0, 1.0, 0.0], theta_y)


def gimbal(pivot, tilt: Callable[[float], np.ndarray], position) -> Trajectory:
    """A plate at `position` tilted about `pivot` by tilt_rotation(*tilt(t))."""
    c = np.asarray(pivot, dtype=float).reshape(3)
    x0 = np.asarray(position, dtype=float).reshape(3)

    def pose(t: float) -> tuple[np.ndarray, np.ndarray]:
        rotation = tilt_rotation(*tilt(t))
        return c + rotation @ (x0 - c), rotation

    return pose


# The demos' schedule: (start (s), duration (s), the downhill direction (x, y) in the maze's
# frame), each move eased from the previous direction by a smooth ramp.
DEMO_MOVES = (
    (0.1, 0.2, (0.0, 1.0)),  # corridor 0, towards +y
    (0.8, 0.2, (1.0, 0.5)),  # through the opening at +y into corridor 1
    (1.4, 0.2, (0.0, -1.0)),  # corridor 1, towards -y
    (2.1, 0.2, (1.0, -0.5)),  # through the opening at -y into corridor 2
    (2.7, 0.2, (0.0, 1.0)),  # corridor 2, towards +y: the goal, reached at about 3.1 s
)


def demo_downhill(t: float) -> np.ndarray:
    """The downhill direction (x, y) that the demos give the maze at t (zero before the first
    move): an open-loop schedule that rolls the ball along the three corridors of the default
    maze."""
    direction = np.zeros(2)
    for start, duration, target in DEMO_MOVES:
        direction += smooth_ramp(t, start, duration) * (np.asarray(target) - direction)
    return direction


def demo_tilt(t: float) -> tuple[float, float]:
    """(theta_x, theta_y) = 0.12 rad (-d_y, d_x) for the demo's downhill direction d."""
    dx, dy = 0.12 * demo_downhill(t)
    return -dy, dx


@builder(Meshed(), Solid(50.0, 0.45), *GEL)
def simple_maze(
    p,
    *,
    pad_size: float = 50.0,
    pad_thickness: float = 4.0,
    support_spread: float = 20.0,
    max_tilt: float = 0.2,
    tilt: Callable[[float], tuple[float, float]] = demo_tilt,
) -> Model:
    """The maze on its pad and gimbal, the ball at the start of the path.

    Args:
        mesh: replaces the pad (its underside on z = -pad_thickness, the plate's; its top on
            z = 0, holding the support points (+-support_spread, +-support_spread, 0)).
        pad_size, pad_thickness: the square gel pad (mm) between the plate and the maze.
        young_modulus, poisson_ratio, density, material: the pad's gel (kPa, kg/mm^3).
        rayleigh_mass, rayleigh_stiffness: damping of the pad.
        support_spread: the maze rests on the pad at (+-support_spread, +-support_spread).
        maze_size, corridors, wall_thickness, wall_height, floor_thickness: the maze
            (`maze_boxes`).
        maze_mass, ball_radius, ball_mass: the rigid maze and ball (kg, mm).
        ball_friction: Coulomb coefficient of the ball on the maze.
        support_friction: of the maze on the pad, which holds it.
        max_tilt: the range of each tilt angle (rad); a tilt outside raises ConstraintError.
        contact_margin, contact_tolerance, contact_iterations: detection distance (mm), the
            contact solver's tolerance (mm) and its sweeps at most (a ball wedged in a corner
            takes a few thousand).
        tilt: (theta_x, theta_y) of the plate (rad) as a function of time (s).
    """
    _require_positive(
        pad_size=pad_size,
        pad_thickness=pad_thickness,
        support_spread=support_spread,
        max_tilt=max_tilt,
    )
    mesh = p.mesh
    if mesh is None:
        half, cells = pad_size / 2, max(1, round(pad_size / 5.0))
        mesh = box_beam(
            pad_size,
            pad_size,
            pad_thickness,
            cells,
            cells,
            1,
            origin=(-half, -half, -pad_thickness),
        )
    bottom, top = float(mesh.points[:, 2].min()), float(mesh.points[:, 2].max())
    underside = fixed_by_box(mesh, [[-np.inf, -np.inf, bottom], [np.inf, np.inf, bottom + 1e-9]])
    body = p.tet_body(mesh, fixed_nodes=underside)
    s = support_spread
    supports = EmbeddedPoints(mesh, [[x, y, top] for x in (-s, s) for y in (-s, s)])
    plate = KinematicBody(
        Box([pad_size / 2, pad_size / 2, 1.0], position=[0.0, 0.0, bottom - 1.0]),
        gimbal([0.0, 0.0, top], checked_commands(tilt, 2, max_tilt, "tilt"), [0.0, 0.0, bottom]),
        name="gimbal",
    )
    # The floor catches a ball that leaves the maze.
    drivers = [DrivenNodes(underside, plate, name="gimbal")]
    return maze_model(p, body, drivers, supports, top, bottom - 40.0, "simple_maze")


def demo_actuation(t: float) -> np.ndarray:
    """No actuator: the plate follows the model's own scripted tilt (`tilt`, by default
    `demo_tilt`)."""
    return np.zeros(0)
