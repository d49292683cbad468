"""Concentric instruments pushed through an entry (interventional radiology: a catheter, a
guidewire, coils, the tubes of a concentric-tube robot), on one Cosserat rod.

The semantics are those of SOFA's BeamAdapter plugin (``WireRestShape``,
``WireBeamInterpolation``, ``AdaptiveBeamForceFieldAndMass``,
``InterventionalRadiologyController``), re-implemented from its documented behaviour:

* each instrument has a rest shape (:class:`RestShape`): straight along x for
  ``straight_length``, then a spire of diameter D and height h per turn up to its ``length``
  (the frame turned by theta = 2 pi s / sqrt(h^2 + (pi D)^2) about y, tilted by
  atan(h / (pi D)) about z); Young's modulus ``young`` on the straight part,
  ``young_extremity`` beyond (read at each beam's distal end, as BeamAdapter does); the
  key points [0, straight_length, length] sampled by ``density`` beams each;
* the instruments share one rod of N nodes (the combined instrument). Each instrument's tip
  is at the abscissa ``xtip`` from the entry, its proximal end ``xtip - length`` (behind the
  entry while not fully pushed). Each step the nodes are placed at the deployed abscissas: 0,
  the instruments' key points and samplings past the entry, sorted, those closer than the
  ``threshold`` merged (:func:`node_abscissas`); the last ones of the N nodes are deployed,
  the first ones wait at the entry (``start``). The deformed shape of the last step is carried
  onto the new abscissas: when the deployed length changes by dL, the nodes that belong to
  one instrument only take the shape at their abscissa minus dL (the instrument slides
  forward through its own shape; the elasticity then pushes it on), the others keep theirs;
* an element between two deployed nodes gets the beams of every instrument present over it,
  each with its own rest shape (turned by the instrument's ``rotation`` about its axis) and
  stiffness, and all act together (BeamAdapter adds one beam per instrument there): on Pliant's
  element, with quadratic energies, the stiffnesses add and the rest strains are their
  stiffness-weighted mean (the same energy up to a constant). Mass: ``mass_density`` times
  the section, per instrument present, lumped on the nodes.

Departures from BeamAdapter: Pliant's rod is a geometrically exact Cosserat rod (one-point
quadrature, shear and stretch as stiffnesses: its shear deformation adds about (r / L)^2 of
the bending deflection), not BeamAdapter's Euler-Bernoulli beam elements (shear areas 0) on
spline-interpolated frames; the last shape is carried onto new abscissas linearly (positions,
velocities) and by slerp (frames) where BeamAdapter interpolates on its beam spline; the nodes
waiting at the entry are held by stiff springs at points on the entry axis behind it (their
elements have no stiffness, so they hold exactly; they are reported at the entry); a node
whose shape comes from before the entry (a push) is put on the entry's axis at that abscissa,
and the nodes deployed at the start straight along it, where BeamAdapter puts them on the
entry itself, and two nodes BeamAdapter takes from one point of the last shape are taken
half their new spacing apart (Pliant's elements must not shrink to nothing; its elasticity
pushes them out, as BeamAdapter's does); the masses are lumped on the nodes
(translational, and rotary rho I per length), where BeamAdapter's beam has its own mass
matrix; ``rigidCurvAbs`` rigid parts and non-procedural (mesh) rest shapes are not read.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from pliant.errors import ModelError
from pliant.fem import rod_kernels
from pliant.fem.loads import Load, NodalForces, RestShapeSprings, RotationSprings
from pliant.fem.material import Material
from pliant.fem.rod import RodBody, RodSection

# SOFA's beam frame (x along the beam) as Pliant's directors (d1 = y, d2 = z, d3 = x).
AXES = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
EPSILON = float(np.finfo(np.float32).eps)  # BeamAdapter's least deployed length


@dataclass(frozen=True)
class RestShape:
    """An instrument's procedural rest shape and material (BeamAdapter's WireRestShape)."""

    length: float
    straight_length: float = 0.0
    spire_diameter: float = 0.1
    spire_height: float = 0.01
    young: float = 5000.0
    young_extremity: float = 3000.0
    poisson: float = 0.49
    key_points: tuple[float, ...] = ()
    density: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        if not (math.isfinite(self.length) and self.length > 0):
            raise ModelError(f"an instrument's length must be > 0, got {self.length}")
        if not 0.0 <= self.straight_length <= self.length:
            raise ModelError(
                f"straightLength {self.straight_length} must lie in [0, length {self.length}]"
            )
        if self.spire_diameter <= 0 and self.straight_length < self.length:
            raise ModelError(f"spireDiameter must be > 0, got {self.spire_diameter}")
        keys = list(self.key_points)
        if not keys:  # WireRestShape: 0, the end of the straight part (if inside), the tip
            keys = [0.0]
            if 0.001 * self.length <= self.straight_length <= 0.999 * self.length:
                keys.append(self.straight_length)
            keys.append(self.length)
        density = [int(d) for d in self.density]
        if len(density) > len(keys) - 1:
            density = density[: len(keys) - 1]
        elif len(density) < len(keys) - 1:  # WireRestShape's defaults
            density = []
            if self.straight_length >= 0.001 * self.length:
                density.append(math.floor(5.0 * self.straight_length / self.length))
            if self.straight_length <= 0.999 * self.length:
                density.append(math.floor(20.0 * (1.0 - self.straight_length / self.length)))
        if any(d < 0 for d in density) or np.any(np.diff(keys) < 0):
            raise ModelError(f"densityOfBeams {density}, key points {keys}: ordered and >= 0")
        object.__setattr__(self, "key_points", tuple(float(k) for k in keys))
        object.__setattr__(self, "density", tuple(density))

    def transform(self, x: float) -> tuple[np.ndarray, np.ndarray]:
        """The rest frame at the abscissa x from the proximal end: its point and rotation
        (columns: the frame's x along the instrument, y, z)."""
        x = min(max(float(x), 0.0), self.length)
        if x <= self.straight_length:
            return np.array([x, 0.0, 0.0]), np.eye(3)
        projected = self.spire_diameter * math.pi
        turn = math.hypot(self.spire_height, projected)
        phi = math.atan(self.spire_height / projected)
        spires = (x - self.straight_length) / turn
        theta = 2.0 * math.pi * spires
        radius = self.spire_diameter / 2.0
        point = np.array(
            [
                self.straight_length + radius * math.sin(theta),
                spires * self.spire_height,
                radius * (math.cos(theta) - 1.0),
            ]
        )
        rotation = Rotation.from_rotvec([0.0, theta, 0.0]) * Rotation.from_rotvec([0.0, 0.0, phi])
        return point, rotation.as_matrix()

    def young_at(self, x: float) -> float:
        """Young's modulus at the abscissa x (the extremity's beyond the straight part)."""
        if x <= self.straight_length or self.young_extremity == 0.0:
            return self.young
        return self.young_extremity


@dataclass(frozen=True)
class Instrument:
    """One instrument: its rest shape, section radius and mass per volume."""

    shape: RestShape
    radius: float = 1.0
    mass_density: float = 1.0
    name: str = "instrument"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise ModelError(f"{self.name}: the radius must be > 0, got {self.radius}")
        if not (math.isfinite(self.mass_density) and self.mass_density >= 0):
            raise ModelError(f"{self.name}: the mass density must be >= 0")


def node_abscissas(
    instruments: Sequence[Instrument], tips: np.ndarray, threshold: float
) -> np.ndarray:
    """The deployed nodes' abscissas from the entry: 0, each instrument's key points past
    the entry, and the samplings of its parts (``density`` per part, spaced back from the
    part's end, from where the last sampled part ended), sorted, closer ones than
    `threshold` merged (BeamAdapter's computeInstrumentsCurvAbs)."""
    values = [0.0]
    sampled = 0.0
    for instrument, tip in zip(instruments, tips, strict=True):
        begin = float(tip) - instrument.shape.length
        keys, density = instrument.shape.key_points, instrument.shape.density
        for j in range(len(keys) - 1):
            start, end = begin + keys[j], begin + keys[j + 1]
            if start > 0:
                values.append(start)
            interval = end - sampled
            if interval <= 0:
                continue
            part = keys[j + 1] - keys[j]
            if part <= 0 or density[j] == 0:
                sampled = end
                continue
            ratio = density[j] / part
            count = math.floor(interval * ratio)
            values += [end - k / ratio for k in range(count, 0, -1)]
            sampled = end
        if begin + keys[-1] > 0:
            values.append(begin + keys[-1])
    values.sort()
    merged = [values[0]]
    for v in values[1:]:  # std::unique against the last kept value
        if abs(v - merged[-1]) >= threshold:
            merged.append(v)
    return np.array(merged)


def instrument_table(
    abscissas: np.ndarray, begins: np.ndarray, ends: np.ndarray, threshold: float
) -> list[list[int]]:
    """For each node abscissa, the instruments present there."""
    return [
        [i for i in range(len(begins)) if begins[i] - threshold <= s <= ends[i] + threshold]
        for s in abscissas
    ]


def slid_abscissas(
    new: np.ndarray, old_tip: float, table: list[list[int]], threshold: float
) -> np.ndarray:
    """Where each new node takes the last shape from: when the deployed length changed by
    dL, a node of one instrument only at s - dL (not before the previous node), the others
    at s (BeamAdapter's totalLengthIsChanging)."""
    slid = new.copy()
    change = new[-1] - old_tip
    if abs(change) <= threshold:
        return slid
    for i, present in enumerate(table):
        if len(present) == 1:
            slid[i] -= change
            if i > 1 and slid[i] < slid[i - 1]:
                slid[i] = slid[i - 1]
    return slid


class CombinedInstrument:
    """The instruments on one rod of `n_nodes` nodes, deployed from the entry pose `start`
    (a point and a SOFA frame, x along the entry) by :meth:`deploy`.

    Args:
        instruments: the instruments, innermost last or in any order (as the scene lists).
        n_nodes: the rod's nodes (BeamAdapter's combined instrument's degrees of freedom).
        start: (point (3,), rotation (3, 3)) of the entry.
        base_stiffness: springs (force per length, moment per radian) holding the node at
            the entry to the entry's pose (RestShapeSpringsForceField on indexFirstNode).
        gravity, rayleigh_mass, rayleigh_stiffness: as :class:`~pliant.fem.rod.RodBody`.
        threshold: abscissas closer than this are one node.
        loads: more loads on the rod's rows (forces on nodes, moments on orientation rows).
    """

    def __init__(
        self,
        instruments: Sequence[Instrument],
        n_nodes: int,
        start: tuple[np.ndarray, np.ndarray],
        *,
        base_stiffness: tuple[float, float] = (0.0, 0.0),
        gravity: Sequence[float] = (0.0, 0.0, 0.0),
        rayleigh_mass: float = 0.0,
        rayleigh_stiffness: float = 0.0,
        threshold: float = 0.01,
        loads: Sequence[Load] = (),
    ) -> None:
        if not instruments:
            raise ModelError("a combined instrument needs one instrument at least")
        if n_nodes < 2:
            raise ModelError(f"a combined instrument needs 2 nodes at least, got {n_nodes}")
        self.instruments = list(instruments)
        self.n = int(n_nodes)
        self.start = (np.asarray(start[0], float), np.asarray(start[1], float))
        self.base_stiffness = tuple(float(k) for k in base_stiffness)
        self.gravity = np.asarray(gravity, dtype=float)
        self.threshold = float(threshold)
        # Nodes waiting at the entry sit behind it, this far apart (elements need a length).
        self.spacing = max(i.shape.length for i in self.instruments) / self.n
        n = self.n
        axis = self.start[1][:, 0]
        points = self.start[0] - axis * self.spacing * np.arange(n)[::-1, None]
        first = self.instruments[0]
        self.body = RodBody(
            points,
            RodSection.circle(first.radius),
            Material(first.shape.young, first.shape.poisson),
            total_mass=1.0,
            frames=np.repeat((self.start[1] @ AXES)[None], n, axis=0),
            rayleigh_mass=rayleigh_mass,
            rayleigh_stiffness=rayleigh_stiffness,
            loads=[
                RestShapeSprings(np.arange(n), np.zeros((n, 3)), 1.0),
                RotationSprings(np.arange(n, 2 * n), np.zeros((2 * n, 3)), 1.0),
                NodalForces(np.arange(n), np.zeros((n, 3))),
                *loads,
            ],
        )
        self.springs, self.turns, self.weight = (a.load for a in self.body.loads[:3])
        self.abscissas = np.zeros(1)  # of the deployed nodes, the last of the rod's
        self.tips = np.zeros(len(self.instruments))
        self.rotations = np.zeros(len(self.instruments))

    @property
    def first(self) -> int:
        """The first deployed node: the one at the entry."""
        return self.n - len(self.abscissas)

    def waiting_pose(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Where the waiting node k is held: on the entry's axis, behind it."""
        axis = self.start[1][:, 0]
        return self.start[0] - axis * self.spacing * (self.first - k), self.start[1]

    def start_state(self, tips: Sequence[float], rotations: Sequence[float]) -> np.ndarray:
        """(2N, 3) positions: every node at the entry, then deployed twice (BeamAdapter's
        controller at init); the body's rest positions become these."""
        n = self.n
        positions = np.empty((2 * n, 3))
        positions[:n] = self.start[0]
        positions[n:] = Rotation.from_matrix(self.start[1] @ AXES).as_rotvec()
        initial = [0.0] + [float(t) for t in reversed(list(tips)) if t > 0]
        self.abscissas = np.array(initial[:n])
        # straight along the entry (BeamAdapter starts them all at the entry, compressed)
        positions[n - len(self.abscissas) : n] += np.outer(self.abscissas, self.start[1][:, 0])
        for _ in range(2):
            positions, _ = self.deploy(positions, np.zeros_like(positions), tips, rotations)
        self.body.rest_positions[:] = positions
        return positions

    def deploy(
        self,
        positions: np.ndarray,
        velocities: np.ndarray,
        tips: Sequence[float],
        rotations: Sequence[float],
    ) -> tuple[np.ndarray, np.ndarray]:
        """Place the nodes for the instruments' tips `tips` (each clamped to its length) and
        turns `rotations` (radians about their axes): new positions and velocities, the
        elements' lengths, stiffnesses, rest strains and the masses set on the body."""
        tips = np.array(
            [min(float(t), i.shape.length) for t, i in zip(tips, self.instruments, strict=True)]
        )
        if tips.max() < EPSILON:
            tips[0] = EPSILON
        self.tips, self.rotations = tips, np.asarray(rotations, dtype=float).copy()
        lengths = np.array([i.shape.length for i in self.instruments])
        begins = tips - lengths
        new = node_abscissas(self.instruments, tips, self.threshold)[: self.n]
        table = instrument_table(new, begins, tips, self.threshold)
        slid = slid_abscissas(new, self.abscissas[-1], table, self.threshold)
        for k in range(1, len(slid)):  # no two nodes from one point: half their spacing
            slid[k] = max(slid[k], slid[k - 1] + 0.5 * (new[k] - new[k - 1]))
        x, v = self._carried(positions, velocities, slid)
        self.abscissas = new
        self._set_elements(begins, tips)
        n, first = self.n, self.first
        for k in range(first):
            point, frame = self.waiting_pose(k)
            x[k], x[n + k] = point, Rotation.from_matrix(frame @ AXES).as_rotvec()
            v[k] = v[n + k] = 0.0
        return x, v

    def _carried(self, positions, velocities, slid) -> tuple[np.ndarray, np.ndarray]:
        """The last shape (its deployed nodes at self.abscissas) at the abscissas `slid`."""
        n, old = self.n, self.abscissas
        old_first = n - len(old)
        frames = self.body.frames(positions)
        x, v = np.array(positions, dtype=float), np.array(velocities, dtype=float)
        first = n - len(slid)
        entry = Rotation.from_matrix(self.start[1] @ AXES).as_rotvec()
        for k, s in enumerate(slid):
            node = first + k
            j = int(np.searchsorted(old + self.threshold, s, side="right"))
            j = min(j, len(old) - 1)
            at = old_first + j
            if abs(old[j] - s) < self.threshold:
                x[node], x[n + node] = positions[at], positions[n + at]
                v[node], v[n + node] = velocities[at], velocities[n + at]
            elif j == 0:  # before the entry: on its axis (not on it: no zero-length element)
                x[node], x[n + node] = self.start[0] + s * self.start[1][:, 0], entry
                v[node] = v[n + node] = 0.0
            else:
                t = (s - old[j - 1]) / (old[j] - old[j - 1])
                x[node] = (1 - t) * positions[at - 1] + t * positions[at]
                turn = Rotation.from_matrix(frames[at - 1].T @ frames[at]).as_rotvec()
                x[n + node] = Rotation.from_matrix(
                    frames[at - 1] @ Rotation.from_rotvec(t * turn).as_matrix()
                ).as_rotvec()
                v[node] = (1 - t) * velocities[at - 1] + t * velocities[at]
                v[n + node] = (1 - t) * velocities[n + at - 1] + t * velocities[n + at]
        return x, v

    def _set_elements(self, begins: np.ndarray, ends: np.ndarray) -> None:
        n, m, first, th = self.n, self.n - 1, self.first, self.threshold
        lengths = np.full(m, self.spacing)
        shear_stretch, bend_twist = np.zeros((m, 3)), np.zeros((m, 3))
        strain, curvature = np.tile([0.0, 0.0, 1.0], (m, 1)), np.zeros((m, 3))
        mass, rotary = np.zeros(n), np.zeros(n)
        # Every (element, instrument present): its rest frames at both ends.
        pairs, ends_x, ends_r, lens, stiff = [], [], [], [], []
        for e in range(first, m):
            x0, x1 = self.abscissas[e - first], self.abscissas[e - first + 1]
            lengths[e] = x1 - x0
            for i, inst in enumerate(self.instruments):
                if not (begins[i] - th < x0 < ends[i] + th and begins[i] - th < x1 < ends[i] + th):
                    continue
                turn = Rotation.from_rotvec([-self.rotations[i], 0.0, 0.0]).as_matrix()
                for s in (x0 - begins[i], x1 - begins[i]):
                    p, r = inst.shape.transform(s)
                    ends_x.append(p)
                    ends_r.append(r @ turn @ AXES)
                section = RodSection.circle(inst.radius)
                young = inst.shape.young_at(x1 - begins[i])
                shear = young / (2.0 * (1.0 + inst.shape.poisson))
                c = section.shear_coefficient * section.area * shear
                stiff.append(
                    (
                        [c, c, young * section.area],
                        [young * section.inertia[0], young * section.inertia[1]]
                        + [shear * section.torsion],
                    )
                )
                pairs.append(e)
                lens.append(x1 - x0)
                share = 0.5 * inst.mass_density * (x1 - x0)
                mass[[e, e + 1]] += share * section.area
                rotary[[e, e + 1]] += share * section.inertia[0]
        if pairs:
            k = len(pairs)
            vectors = np.array([_rotvec(r) for r in ends_r])
            rot = rod_kernels.node_rotations(np.ascontiguousarray(vectors))
            gamma, kappa = rod_kernels.rest_strains(
                np.ascontiguousarray(ends_x, dtype=float),
                rot,
                np.arange(2 * k, dtype=np.int64).reshape(k, 2),
                np.ascontiguousarray(np.tile(np.eye(3), (k, 2, 1, 1))),
                np.asarray(lens, dtype=float),
            )
            c = np.array([s[0] for s in stiff])
            b = np.array([s[1] for s in stiff])
            at = np.array(pairs)
            weighted_g, weighted_k = np.zeros((m, 3)), np.zeros((m, 3))
            np.add.at(shear_stretch, at, c)
            np.add.at(bend_twist, at, b)
            np.add.at(weighted_g, at, c * gamma)
            np.add.at(weighted_k, at, b * kappa)
            live = np.unique(at)
            strain[live] = weighted_g[live] / np.maximum(shear_stretch[live], 1e-300)
            curvature[live] = weighted_k[live] / np.maximum(bend_twist[live], 1e-300)
        deployed = mass[first:]
        fill = float(deployed.mean()) if deployed.size and deployed.mean() > 0 else 1.0
        fill_rot = float(rotary[first:].mean()) if rotary[first:].mean() > 0 else fill
        mass[:first], rotary[:first] = fill, fill_rot  # held: any positive mass
        mass[mass <= 0], rotary[rotary <= 0] = fill, fill_rot
        self.body.set_elements(
            lengths, shear_stretch, bend_twist, strain, curvature, np.concatenate([mass, rotary])
        )
        self._set_supports(shear_stretch, bend_twist, lengths, mass)

    def _set_supports(self, shear_stretch, bend_twist, lengths, mass) -> None:
        """The springs: stiff on the waiting nodes, the scene's on the node at the entry;
        the weight of the deployed nodes."""
        n, first = self.n, self.first
        live = shear_stretch[:, 2] > 0  # held as stiffly as the stiffest element
        hold, hold_turn = 1.0, 1.0
        if live.any():
            hold = max(float((shear_stretch[live, 2] / lengths[live]).max()), 1.0)
            hold_turn = max(float((bend_twist[live] / lengths[live, None]).max()), 1.0)
        k, k_turn = self.springs.stiffness, self.turns.stiffness
        k[:], k_turn[:] = 0.0, 0.0
        k[:first], k_turn[:first] = hold, hold_turn
        k[first] += self.base_stiffness[0]
        k_turn[first] += self.base_stiffness[1]
        anchors = np.repeat((self.start[1] @ AXES)[None], n, axis=0)
        for node in range(first + 1):
            self.springs.anchors[node] = self.waiting_pose(node)[0]
        self.turns.rest = Rotation.from_matrix(anchors)  # every node's: the entry's frame
        self.weight.values[:] = 0.0
        self.weight.values[first:] = mass[first:, None] * self.gravity
        self.body.changed()

    def poses(self, positions: np.ndarray) -> np.ndarray:
        """(N, 7) SOFA poses (point, quaternion x y z w) of the nodes: the waiting ones at
        the entry."""
        n, first = self.n, self.first
        frames = self.body.frames(positions) @ AXES.T
        quats = Rotation.from_matrix(frames).as_quat()
        points = np.array(positions[:n], dtype=float)
        points[:first] = self.start[0]
        quats[:first] = Rotation.from_matrix(self.start[1]).as_quat()
        quats[quats[:, 3] < 0] *= -1.0
        return np.hstack([points, quats])


def _rotvec(rotation: np.ndarray) -> np.ndarray:
    out = np.empty(3)
    rod_kernels.so3_log(np.ascontiguousarray(rotation, dtype=float), out)
    return out
