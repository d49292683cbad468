"""Proxies of the Multigait and of the Trunk on a translating base (thesis §4.1.2), in the
FEM robots' units (mm, kg, s; stresses in kPa) and placed as they are
(:func:`pliant.robots.multigait.multigait`, :func:`pliant.robots.trunk_cube.trunk_cube`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from pliant.constraints.contact import Contacts
from pliant.errors import ModelError
from pliant.fem.material import Material
from pliant.fem.rigid import KinematicBody, RigidBody, rail
from pliant.fem.rod import ClampedEnd, RodBody, RodSection
from pliant.geometry.collision import Box, Plane
from pliant.model import Model
from pliant.proxy.actuation import Bending, CurvatureActuation
from pliant.proxy.skinning import Skinning
from pliant.robots.multigait import face_points
from pliant.robots.parameters import Cube, Damping, Gravity
from pliant.robots.scene import builder
from pliant.robots.trunk_cube import surface_points as trunk_surface_points

# A leg's or the centre's inflation lengthens its roof over a floor the paper keeps: the beam
# curls with its ends down. With d1 = +z and d3 along the beam, that is a curvature about -d2.
_CURL = (0.0, -1.0, 0.0)


class BaseTranslation:
    """A base moved along a rail by command: the displacement (mm) the carrier holds until
    the next command (a rail's displacement law, read at any time)."""

    def __init__(self, limits: tuple[float, float]) -> None:
        self.limits = (float(limits[0]), float(limits[1]))
        self.value = 0.0

    def set(self, displacement: float) -> None:
        lo, hi = self.limits
        self.value = float(np.clip(displacement, lo, hi))

    def __call__(self, t: float) -> float:
        return self.value


@dataclass
class Proxy:
    """A beam-skeleton proxy: its model, the bendings that actuate it, the rod elements of
    each calibrated beam group, and the base's translation where it has a moving base.

    `apply(controls)` sets the bendings from the first len(actuation) commands and the base
    (mm) from the next one, if any; call it before each solver step."""

    model: Model
    actuation: CurvatureActuation
    groups: dict[str, np.ndarray]
    base: BaseTranslation | None = None
    parameters: dict[str, float] = field(default_factory=dict)

    @property
    def rod(self) -> RodBody:
        return self.model.body

    @property
    def n_controls(self) -> int:
        return len(self.actuation) + (self.base is not None)

    def apply(self, controls) -> None:
        u = np.asarray(controls, dtype=float).reshape(-1)
        if u.shape != (self.n_controls,):
            raise ModelError(f"the proxy takes {self.n_controls} commands, got {u.shape}")
        self.actuation.apply(u[: len(self.actuation)])
        if self.base is not None:
            self.base.set(u[-1])
            # The carriage memoises its last pose by time: the look-ahead of the last step
            # asked for this step's end with the old command (the base would lag a step).
            self.model.trajectories_changed()

    def skeleton(self, positions: np.ndarray) -> np.ndarray:
        """(N, 3) the skeleton's nodes at a state's positions."""
        return self.rod.centreline(positions)


# --- Multigait ------------------------------------------------------------------------------


MULTIGAIT_PARAMETERS = {
    # Stiffness E (kPa), density (kg/mm^3) and curvature at command 1 (rad/mm) of the legs
    # and the centre: the first calibration round on the FEM gait (40 TPE trials in a box of
    # 0.3x to 3x hand-set values, experiments/proxy/round1), the centre of the next box.
    "leg_stiffness": 253.0,
    "centre_stiffness": 672.0,
    "leg_density": 1.9e-6,
    "centre_density": 8.7e-7,
    "leg_curvature": 0.0577,
    "centre_curvature": 0.0224,
}


@builder(Gravity.Z, Damping(0.1, 0.01))
def multigait_proxy(
    p,
    *,
    length: float = 136.0,
    width: float = 58.0,
    thickness: float = 6.3,
    leg_width: float = 16.0,
    centre_length: float = 46.0,
    leg_stiffness: float = MULTIGAIT_PARAMETERS["leg_stiffness"],
    centre_stiffness: float = MULTIGAIT_PARAMETERS["centre_stiffness"],
    leg_density: float = MULTIGAIT_PARAMETERS["leg_density"],
    centre_density: float = MULTIGAIT_PARAMETERS["centre_density"],
    leg_curvature: float = MULTIGAIT_PARAMETERS["leg_curvature"],
    centre_curvature: float = MULTIGAIT_PARAMETERS["centre_curvature"],
    cross_stiffness: float | None = None,
    neutral: Literal["axis", "underside"] = "axis",
    poisson_ratio: float = 0.3,
    friction: float = 0.7,
    contact: Literal["nodes", "surface"] = "nodes",
) -> Proxy:
    """The Multigait proxy: 19 nodes, 4 a leg and 3 in the centre (thesis §4.1.2), at the
    FEM body's mid-thickness (front legs at x = 0, left +y, underside on the floor z = 0).

    The centre beam (3 nodes along x) and each leg (4 nodes along x, from its root beside a
    centre end to its tip) carry one actuated bending each, in the order of
    :data:`pliant.mesh.multigait.CHAMBERS`; four passive cross beams join the legs' roots to
    the centre's ends, of the centre's stiffness unless `cross_stiffness` (kPa) is given
    (``pliant proxy calibrate multigait --cross-stiffness``: stiffer corners hold the centre
    up when every chamber is on, as the FEM's is; docs/proxy.md). Section: the legs'
    (`leg_width` x `thickness`) for every beam, the centre's difference folded into its
    calibrated stiffness. `neutral`: the layer a chamber
    bends its beam about, the beam's axis (the thesis' inextensible beams) or its underside,
    the strain-limiting layer of a pneumatic network, which keeps its length as the chambers
    curl it (the FEM Multigait's underside: within 1 % at full inflation, where a beam bent
    about its axis shortens its underside by kappa h, 13 % at the calibrated curvature): each
    bending then also stretches its beam by kappa h, h = thickness / 2
    (:class:`pliant.proxy.actuation.Bending`). Floor contact, Coulomb
    friction `friction`: with `contact` "nodes", at the nodes, balls of radius thickness / 2;
    with "surface", through the FEM robot's colliding points (its underside and outline) and
    their counterparts on its top face (:func:`pliant.robots.multigait.face_points`),
    skinned onto the skeleton (two nearest nodes each, :class:`pliant.proxy.Skinning`), so
    that a curled leg touches the floor at the edge of its tip as the FEM's does, and one
    curled over rests on its top.
    """
    if contact not in ("nodes", "surface"):
        raise ModelError(f"contact must be 'nodes' or 'surface', got {contact!r}")
    if neutral not in ("axis", "underside"):
        raise ModelError(f"neutral must be 'axis' or 'underside', got {neutral!r}")
    z = 0.5 * thickness
    # An underside that keeps its length: d(stretch) = kappa h, h the skeleton's height on it.
    lever = z if neutral == "underside" else 0.0
    y = 0.5 * (width - leg_width)
    leg_length = 0.5 * (length - centre_length)
    front, back = leg_length, length - leg_length
    centre = [[x, 0.0, z] for x in np.linspace(front, back, 3)]
    legs = {
        "front_left": (front, 0.0, y),
        "front_right": (front, 0.0, -y),
        "rear_left": (back, length, y),
        "rear_right": (back, length, -y),
    }
    points = list(centre)
    elements = [[0, 1], [1, 2]]
    groups: dict[str, list[int]] = {"centre": [0, 1], "legs": [], "cross": []}
    bendings_by_name = {"centre": [0, 1]}
    for name, (root, tip, side) in legs.items():
        first = len(points)
        points += [[x, side, z] for x in np.linspace(root, tip, 4)]
        hub = 0 if root == front else 2
        groups["cross"].append(len(elements))
        elements.append([hub, first])
        own = []
        for k in range(3):
            own.append(len(elements))
            elements.append([first + k, first + k + 1])
        groups["legs"] += own
        bendings_by_name[name] = own
    m = len(elements)
    stiffness, density = np.full(m, float(centre_stiffness)), np.full(m, float(centre_density))
    stiffness[groups["legs"]] = leg_stiffness
    density[groups["legs"]] = leg_density
    if cross_stiffness is not None:
        stiffness[groups["cross"]] = cross_stiffness
    rod = RodBody(
        np.array(points),
        RodSection.rectangle(thickness, leg_width),
        Material(float(centre_stiffness), poisson_ratio),
        elements=np.array(elements),
        normal=(0.0, 0.0, 1.0),
        young_moduli=stiffness,
        densities=density,
        **p.loads(),
    )
    curvatures = {name: leg_curvature for name in bendings_by_name} | {"centre": centre_curvature}
    bendings = [
        Bending(
            name, tuple(bendings_by_name[name]), _CURL, curvatures[name], curvatures[name] * lever
        )
        for name in ("centre", "front_left", "front_right", "rear_left", "rear_right")
    ]
    floor = Plane(point=(0.0, 0.0, 0.0))
    if contact == "nodes":
        contacts = Contacts([floor], friction=friction, margin=3.0, thickness=z)
    else:
        # A leg's tip edge swings up to 6 mm in a 0.01 s step when its bending switches.
        skin = Skinning(rod, face_points(top=True), neighbours=2)
        contacts = Contacts([floor], friction=friction, margin=6.0, points=skin)
    model = Model(rod, contacts=contacts, name="multigait_proxy")
    return Proxy(
        model,
        CurvatureActuation(rod, bendings),
        {k: np.array(v, dtype=np.int64) for k, v in groups.items()},
        parameters=dict(
            leg_stiffness=leg_stiffness,
            centre_stiffness=centre_stiffness,
            leg_density=leg_density,
            centre_density=centre_density,
            leg_curvature=leg_curvature,
            centre_curvature=centre_curvature,
        )
        | ({} if cross_stiffness is None else {"cross_stiffness": cross_stiffness}),
    )


# --- Trunk on a translating base ------------------------------------------------------------


TRUNK_PARAMETERS = {
    # Calibrated on the FEM Trunk (pliant proxy calibrate trunk: round 2, 40 TPE trials,
    # experiments/proxy; 6.34 mm on the optimisation positions). The thesis' values, for a
    # SOFA Cosserat rod of the same radius: E 14332 and 62718 kPa, max curvature 0.01147 and
    # 0.04999 rad/mm.
    "lower_stiffness": 12336.0,
    "upper_stiffness": 2706.0,
    "lower_density": 1.04e-6,
    "upper_density": 7.0e-7,
    "lower_curvature": 0.0193,
    "upper_curvature": 0.0604,
}


@builder(Gravity((0.0, -9810.0, 0.0)), Damping(0.1, 0.01), Cube(30.0, 0.01))
def trunk_proxy(
    p,
    *,
    length: float = 195.0,
    radius: float = 10.0,
    nodes: int = 30,
    lower_stiffness: float = TRUNK_PARAMETERS["lower_stiffness"],
    upper_stiffness: float = TRUNK_PARAMETERS["upper_stiffness"],
    lower_density: float = TRUNK_PARAMETERS["lower_density"],
    upper_density: float = TRUNK_PARAMETERS["upper_density"],
    lower_curvature: float = TRUNK_PARAMETERS["lower_curvature"],
    upper_curvature: float = TRUNK_PARAMETERS["upper_curvature"],
    lower_contraction: float = 0.0,
    upper_contraction: float = 0.0,
    lower_cocontraction: float = 0.0,
    upper_cocontraction: float = 0.0,
    poisson_ratio: float = 0.45,
    base_limits: tuple[float, float] = (-200.0, 0.0),
    cube_position: tuple[float, float] | None = (30.0, 150.0),
    floor_height: float = -30.0,
    friction: float = 0.3,
    contact: Literal["nodes", "surface"] = "nodes",
    cube_friction: float | None = None,
    cube_damping: float = 0.0,
    contact_radius: float | None = None,
) -> Proxy:
    """The Trunk proxy: two beams end to end along +z from the base at the origin (`nodes`
    nodes, 30 as the thesis'), each with two actuated bendings (about d1 = x and d2 = y;
    commands lower_d1, lower_d2, upper_d1, upper_d2), the clamped base translating along z
    by the fifth command (mm, within `base_limits`). Mass per length falls linearly from the
    lower density at the base to the upper one at the tip (thesis: two end values), stiffness
    per beam; gravity -y; the floor y = `floor_height` and, unless `cube_position` is None,
    the rigid cube of :func:`pliant.robots.trunk_cube.trunk_cube` at (x, z). `contact`:
    "nodes", the trunk touches the floor and the cube with balls of `radius` at its nodes;
    "surface", through the FEM Trunk's colliding points (its surface nodes,
    :func:`pliant.robots.trunk_cube.surface_points`) skinned onto the skeleton, tapering as
    the FEM Trunk does. `lower_contraction`, `upper_contraction`: each beam's axial
    shortening per unit bending command (:class:`Bending`'s max_contraction; 0, inextensible
    as the thesis' beams, by default): the FEM Trunk's cables shorten it as they bend it.
    `lower_cocontraction`, `upper_cocontraction` > 0 add an axial command to each beam (in
    [0, 1], after the four bendings and before the base: seven commands): its rest length
    shortened by that fraction at command 1, the FEM Trunk's cables pulled together, which
    shorten it without bending it (all eight to 14 / 8 mm: its tip 12 mm nearer the base;
    :func:`pliant.proxy.references.trunk_commands` with ``axial=True`` gives the commands)."""
    if nodes < 5:
        raise ModelError(f"the Trunk proxy needs at least 5 nodes, got {nodes}")
    if contact not in ("nodes", "surface"):
        raise ModelError(f"contact must be 'nodes' or 'surface', got {contact!r}")
    cube_friction = friction if cube_friction is None else cube_friction
    contact_radius = radius if contact_radius is None else contact_radius
    for key, value in (
        ("lower_cocontraction", lower_cocontraction),
        ("upper_cocontraction", upper_cocontraction),
        ("cube_friction", cube_friction),
        ("cube_damping", cube_damping),
        ("contact_radius", contact_radius),
    ):
        if not (math.isfinite(value) and value >= 0.0):
            raise ModelError(f"{key} must be finite and >= 0, got {value!r}")
    points = np.column_stack([np.zeros(nodes), np.zeros(nodes), np.linspace(0.0, length, nodes)])
    m = nodes - 1
    lower = np.arange(m // 2)
    upper = np.arange(m // 2, m)
    stiffness = np.where(np.arange(m) < m // 2, lower_stiffness, upper_stiffness).astype(float)
    middle = (np.arange(m) + 0.5) / m
    density = lower_density + (upper_density - lower_density) * middle
    rod = RodBody(
        points,
        RodSection.circle(radius),
        Material(float(lower_stiffness), poisson_ratio),
        normal=(1.0, 0.0, 0.0),
        clamped=[0],
        young_moduli=stiffness,
        densities=density,
        **p.loads(),
    )
    bendings = [
        Bending(
            f"{beam}_{axis}",
            tuple(int(e) for e in elements),
            direction,
            curvature,
            max_contraction=contraction,
        )
        for beam, elements, curvature, contraction in (
            ("lower", lower, lower_curvature, lower_contraction),
            ("upper", upper, upper_curvature, upper_contraction),
        )
        for axis, direction in (("d1", (1.0, 0.0, 0.0)), ("d2", (0.0, 1.0, 0.0)))
    ]
    if lower_cocontraction > 0.0 or upper_cocontraction > 0.0:  # pure shortenings
        bendings += [
            Bending(f"{beam}_axial", tuple(int(e) for e in elements), (0.0, 0.0, 1.0), 0.0,
                    max_stretch=-float(c))
            for beam, elements, c in (
                ("lower", lower, lower_cocontraction),
                ("upper", upper, upper_cocontraction),
            )
        ]  # fmt: skip
    base = BaseTranslation(base_limits)
    carriage = KinematicBody(
        Box([radius, radius, 2.5], position=[0.0, 0.0, -2.5]),
        rail([0.0, 0.0, -2.5], [0.0, 0.0, 1.0], base),
        name="carriage",
    )
    floor = Plane(normal=(0.0, 1.0, 0.0), point=(0.0, floor_height, 0.0))
    rigid = []
    if cube_position is not None:
        half, (x, z) = 0.5 * p.cube.cube_size, cube_position
        rigid.append(
            RigidBody(
                Box([half, half, half], position=[x, floor_height + half, z]),
                p.cube.cube_mass,
                friction=cube_friction,
                linear_damping=cube_damping,
                name="cube",
            )
        )
    if contact == "nodes":
        contacts = Contacts([floor], friction=friction, margin=10.0, thickness=contact_radius)
    else:
        skin = Skinning(rod, trunk_surface_points(), neighbours=2)
        contacts = Contacts([floor], friction=friction, margin=10.0, points=skin)
    model = Model(
        rod,
        contacts=contacts,
        drivers=[ClampedEnd(rod, 0, carriage, name="carriage")],
        rigid_bodies=rigid,
        name="trunk_proxy",
    )
    return Proxy(
        model,
        CurvatureActuation(rod, bendings),
        {"lower": lower, "upper": upper},
        base=base,
        parameters=dict(
            lower_stiffness=lower_stiffness,
            upper_stiffness=upper_stiffness,
            lower_density=lower_density,
            upper_density=upper_density,
            lower_curvature=lower_curvature,
            upper_curvature=upper_curvature,
        ),
    )
