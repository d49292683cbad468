"""Slender deformable parts as discrete Cosserat rods (geometrically exact Simo-Reissner beams).

A rod of N centreline nodes has N positions x_i and N orientations R_i (its material frame,
directors d1, d2 across the section and d3 along the centreline at rest). Pliant's solvers see
a body of 2N "nodes" of three DoFs each: rows 0..N-1 of a state's positions are the centreline
points, rows N..2N-1 the orientations as rotation vectors (R_i = exp([theta_i]x)); the matching
velocity rows are the nodes' velocities and their angular velocities in the world frame. An
increment of an orientation row is a spatial spin (R <- exp([dtheta]x) R), so constraints,
fixed and driven nodes, the compliance W and the factorisation policies work on rods as they
do on tetrahedral bodies, and an actuator or effector may act on the orientations too.

Mechanics (:mod:`pliant.fem.rod_kernels`): stretch, two shears, two bendings and torsion, with
linear-elastic resultants (n = C (gamma - gamma0), m = B (kappa - kappa0)) at any rotation;
one-point quadrature per element, free of shear locking. Mass: lumped, the element's
translational mass split over its nodes and its rotary inertia rho I l lumped isotropically
(the bending value: a circular section's torsional inertia is twice that; rotary inertia
only shifts the highest modes, and an isotropic one has no gyroscopic term).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from pliant.errors import MaterialError, ModelError
from pliant.fem import kernels, rod_kernels
from pliant.fem.body import DeformableBody, Linearisation, set_bulk_properties
from pliant.fem.loads import Load, LoadAssembly
from pliant.fem.material import Material
from pliant.fem.rigid import KinematicBody
from pliant.fem.sparsity import StiffnessPattern


@dataclass(frozen=True)
class RodSection:
    """Cross-section of a rod: area, second moments about d1 and d2, torsion constant, shear
    correction factor, and its outline in the (d1, d2) plane for drawing.

    Use :meth:`circle` or :meth:`rectangle`. `thickness` is the distance from the centreline
    to the surface that a contact uses (the radius; half the smaller side of a rectangle).
    """

    area: float
    inertia: tuple[float, float]
    torsion: float
    shear_coefficient: float
    thickness: float
    outline: tuple[tuple[float, float], ...]

    @classmethod
    def circle(cls, radius: float, *, sides: int = 12) -> RodSection:
        """A solid circular section (shear factor 0.9, Timoshenko/Cowper for nu ~ 0.3)."""
        r = _positive("radius", radius)
        i = math.pi * r**4 / 4.0
        angles = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
        outline = tuple((r * math.cos(a), r * math.sin(a)) for a in angles)
        return cls(math.pi * r * r, (i, i), 2.0 * i, 0.9, r, outline)

    @classmethod
    def rectangle(cls, width: float, height: float) -> RodSection:
        """A solid rectangle, `width` along d1 and `height` along d2 (shear factor 5/6;
        torsion constant a b^3 (1/3 - 0.21 (b/a)(1 - b^4 / (12 a^4))), a >= b, Roark)."""
        w, h = _positive("width", width), _positive("height", height)
        a, b = max(w, h), min(w, h)
        torsion = a * b**3 * (1.0 / 3.0 - 0.21 * (b / a) * (1.0 - b**4 / (12.0 * a**4)))
        outline = ((w / 2, h / 2), (-w / 2, h / 2), (-w / 2, -h / 2), (w / 2, -h / 2))
        return cls(w * h, (w * h**3 / 12.0, h * w**3 / 12.0), torsion, 5.0 / 6.0, b / 2, outline)


def _positive(name: str, value: float) -> float:
    if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
        raise ModelError(f"the rod's {name} must be finite and > 0, got {value!r}")
    return float(value)


def parallel_frames(points: np.ndarray, normal: Sequence[float] | None = None) -> np.ndarray:
    """Node frames (N, 3, 3) along a polyline: d3 the mean tangent of the node's edges, d1
    carried from `normal` (default: the axis least aligned with the first tangent, made
    perpendicular) by parallel transport, d2 = d3 x d1. Columns are d1, d2, d3."""
    edges = np.diff(points, axis=0)
    tangents = edges / np.linalg.norm(edges, axis=1, keepdims=True)
    node_t = np.vstack([tangents[:1], tangents[:-1] + tangents[1:], tangents[-1:]])
    node_t /= np.linalg.norm(node_t, axis=1, keepdims=True)
    t0 = node_t[0]
    d1 = np.eye(3)[int(np.argmin(np.abs(t0)))] if normal is None else np.asarray(normal, float)
    d1 = d1 - (d1 @ t0) * t0
    norm = float(np.linalg.norm(d1))
    if not (np.isfinite(norm) and norm > 1e-9):
        raise ModelError(f"the rod's normal must not be parallel to its first tangent {t0}")
    d1 /= norm
    frames = np.empty((len(points), 3, 3))
    for i, t in enumerate(node_t):
        if i:  # parallel transport: the smallest rotation taking the last tangent to this one
            prev = node_t[i - 1]
            axis = np.cross(prev, t)
            s, c = float(np.linalg.norm(axis)), float(prev @ t)
            if s > 1e-12:
                k = axis / s
                d1 = d1 * c + np.cross(k, d1) * s + k * (k @ d1) * (1.0 - c)
            d1 = d1 - (d1 @ t) * t
            d1 /= np.linalg.norm(d1)
        frames[i] = np.column_stack([d1, np.cross(t, d1), t])
    return frames


class RodBody(DeformableBody):
    """A deformable rod: a discrete Cosserat rod along a polyline, or a lattice of them.

    Args:
        points: (N, 3) centreline nodes at rest, N >= 2, in order along the polyline.
        section: the cross-section (:meth:`RodSection.circle`, :meth:`RodSection.rectangle`).
        material: E and nu (any :class:`pliant.fem.material.Material`; G = E / (2 (1 + nu))).
        density: mass per volume; or give `total_mass` instead.
        elements: (E, 2) node pairs of a lattice (beams joined rigidly where they share a
            node: a junction keeps its angles); default: the polyline 0-1-...-(N-1). A
            lattice's elements are straight at rest, each with its own frame (d3 along it,
            d1 from `normal` made perpendicular, or the axis least aligned with it), held to
            its nodes' frames by constant offsets.
        frames: (N, 3, 3) rest frames of the nodes (columns d1, d2, d3); default on a
            polyline :func:`parallel_frames` with `normal` as the first d1, on a lattice the
            world axes.
        clamped: centreline nodes whose position and orientation are held (a clamp).
        pinned: centreline nodes whose position only is held (a ball joint).
        gravity: acceleration vector (robot scenes: (0, 0, -9810) mm/s^2).
        rayleigh_mass, rayleigh_stiffness: alpha and beta of D = alpha M + beta K.
        point_masses: (node, mass, inertia) of solids built into centreline nodes (a cart,
            a ball welded on with its centre there): the mass is added to the node's and the
            inertia, isotropic (kg length^2), to its orientation's; both carry their weight.
        held_dofs: single DoFs held (3 k + axis, k a body node: an orientation row's axis
            is a world axis of its spin), beside the nodes `clamped` and `pinned` hold.
        loads: external loads on body nodes (:mod:`pliant.fem.loads`, e.g. NodalForces):
            on a centreline node a force, on an orientation row a moment (world axes).
        sections: a section number per element: consecutive elements of a polyline in
            the same section keep the same curvature and twist (a stiff penalty,
            :class:`SectionTies`): SOFA's piecewise-constant-strain Cosserat rod, whose
            sections bend only into helices and arcs. Default: every element free.

    Node k of the body is centreline node k for k < N and the orientation of node k - N
    above: `fixed_nodes` lists those held, as for a :class:`pliant.fem.body.TetBody`.
    """

    mass_type = "lumped"
    membranes: tuple = ()
    # A lagged rod tangent is unstable: the axial stiffness EA, (l / r)^2 times the bending
    # one, turned by a small rotation swamps the bending stiffness. A rod's banded system is
    # cheap to factorise, so the "lagged" policy refactorises it at every step.
    lag_tolerance = 0.0

    def __init__(
        self,
        points: np.ndarray,
        section: RodSection,
        material: Material,
        *,
        density: float | None = None,
        total_mass: float | None = None,
        elements: np.ndarray | None = None,
        frames: np.ndarray | None = None,
        normal: Sequence[float] | None = None,
        clamped: Sequence[int] = (),
        pinned: Sequence[int] = (),
        gravity: Sequence[float] = (0.0, 0.0, 0.0),
        rayleigh_mass: float = 0.0,
        rayleigh_stiffness: float = 0.0,
        young_moduli: Sequence[float] | None = None,
        densities: Sequence[float] | None = None,
        point_masses: Sequence[tuple[int, float, float]] = (),
        held_dofs: Sequence[int] = (),
        loads: Sequence[Load] = (),
        sections: Sequence[int] | None = None,
    ) -> None:
        x = np.ascontiguousarray(points, dtype=np.float64)
        if x.ndim != 2 or x.shape[1] != 3 or x.shape[0] < 2 or not np.all(np.isfinite(x)):
            raise ModelError(f"a rod needs (N >= 2, 3) finite points, got shape {x.shape}")
        n = x.shape[0]
        self.is_lattice = elements is not None
        if elements is None:
            pairs = np.column_stack([np.arange(n - 1), np.arange(1, n)]).astype(np.int64)
        else:
            pairs = _check_elements(elements, n)
        lengths = np.linalg.norm(x[pairs[:, 1]] - x[pairs[:, 0]], axis=1)
        if lengths.min() <= 1e-9 * max(float(lengths.max()), 1e-300):
            raise ModelError(f"the rod has a zero-length element ({int(np.argmin(lengths))})")
        if not isinstance(section, RodSection):
            raise ModelError(f"section must be a RodSection, got {section!r}")
        if not isinstance(material, Material):
            raise MaterialError(f"material must be a Material, got {material!r}")
        if frames is None:
            frames = (
                np.tile(np.eye(3), (n, 1, 1)) if self.is_lattice else parallel_frames(x, normal)
            )
        frames = np.asarray(frames, dtype=float)
        if frames.shape != (n, 3, 3):
            raise ModelError(f"frames must have shape ({n}, 3, 3), got {frames.shape}")
        for i, f in enumerate(frames):
            if np.abs(f.T @ f - np.eye(3)).max() > 1e-9 or np.linalg.det(f) < 0:
                raise ModelError(f"frame {i} of the rod is not a proper rotation")
        self.section = section
        self.material = material
        self.n_centreline = n
        self.lengths = lengths
        self.elements = pairs
        vectors = np.array([_log(f) for f in frames])
        rotations = rod_kernels.node_rotations(vectors)
        # The elements' offsets from their nodes' frames: none on a polyline, whose frames are
        # its elements'; on a lattice, each element's own frame seen from each of its nodes.
        offsets = np.tile(np.eye(3), (len(pairs), 2, 1, 1))
        if self.is_lattice:
            own = _element_frames(x, pairs, normal)
            offsets[:, 0] = np.einsum("eji,ejk->eik", rotations[pairs[:, 0]], own)
            offsets[:, 1] = np.einsum("eji,ejk->eik", rotations[pairs[:, 1]], own)
        self.offsets = np.ascontiguousarray(offsets)
        self.rest_positions = np.ascontiguousarray(np.vstack([x, vectors]))
        self.gamma0, self.kappa0 = rod_kernels.rest_strains(
            x, rotations, self.elements, self.offsets, lengths
        )
        self.natural_curvature = self.kappa0.copy()
        self.natural_strain = self.gamma0.copy()
        m = len(pairs)
        e = np.full((m, 1), material.young_modulus)
        if young_moduli is not None:
            e = _per_element("young_moduli", young_moduli, m)[:, None]
        g = e * (material.mu / material.young_modulus)
        i1, i2 = section.inertia
        shear = section.shear_coefficient * section.area * g
        shear_stretch = np.ascontiguousarray(np.hstack([shear, shear, e * section.area]))
        bend_twist = np.ascontiguousarray(np.hstack([e * i1, e * i2, g * section.torsion]))
        # What every element kernel reads: connectivity and offsets, rest lengths and strains,
        # C and B.
        self._elements = (
            self.elements,
            self.offsets,
            lengths,
            self.gamma0,
            self.kappa0,
            shear_stretch,
            bend_twist,
        )

        if densities is not None:
            if density is not None or total_mass is not None:
                raise MaterialError("give densities per element or one density, not both")
            rho_e = _per_element("densities", densities, m)
            total_mass = float(rho_e @ lengths) * section.area
        set_bulk_properties(
            self,
            section.area * float(lengths.sum()),
            density=density,
            total_mass=total_mass,
            rayleigh_mass=rayleigh_mass,
            rayleigh_stiffness=rayleigh_stiffness,
            gravity=gravity,
        )
        if densities is None:
            rho_e = np.full(m, self.density)

        share = np.zeros(n)  # half of each adjacent element's mass per area
        np.add.at(share, pairs[:, 0], 0.5 * rho_e * lengths)
        np.add.at(share, pairs[:, 1], 0.5 * rho_e * lengths)
        self.node_masses = np.concatenate([section.area * share, 0.5 * (i1 + i2) * share])
        for node, mass, inertia in point_masses:
            if not (0 <= int(node) < n and mass >= 0.0 and inertia >= 0.0):
                raise ModelError(f"point mass ({node}, {mass}, {inertia}): node in [0, {n}), >= 0")
            self.node_masses[int(node)] += float(mass)
            self.node_masses[n + int(node)] += float(inertia)

        for label, nodes in (("clamped", clamped), ("pinned", pinned)):
            idx = np.asarray(nodes, dtype=np.int64).reshape(-1)
            if idx.size and (idx.min() < 0 or idx.max() >= n):
                raise ModelError(f"{label} nodes must lie in [0, {n}), got {idx.tolist()}")
        clamped = np.asarray(clamped, dtype=np.int64).reshape(-1)
        pinned = np.asarray(pinned, dtype=np.int64).reshape(-1)
        self.fixed_nodes = np.unique(np.concatenate([clamped, clamped + n, pinned]))
        fixed_mask = np.zeros(6 * n, dtype=bool)
        fixed_mask[(3 * self.fixed_nodes[:, None] + np.arange(3)).ravel()] = True
        held = np.asarray(held_dofs, dtype=np.int64).reshape(-1)
        if held.size and (held.min() < 0 or held.max() >= 6 * n):
            raise ModelError(f"held DoFs must lie in [0, {6 * n}), got {held.tolist()}")
        fixed_mask[held] = True
        self.free_dofs = np.flatnonzero(~fixed_mask)
        self.free_index = np.full(6 * n, -1, dtype=np.int64)
        self.free_index[self.free_dofs] = np.arange(self.free_dofs.size)
        # An element couples its two nodes and their two orientations: a 4-"node" element.
        self._element_nodes = np.column_stack([self.elements, self.elements + n]).astype(np.int64)
        ties = self._ties(sections, bend_twist)
        groups = self._element_nodes
        if ties is not None:  # the ties couple three orientations: in the pattern too
            tied = ties.groups
            groups = np.vstack([groups, np.column_stack([tied, tied[:, 1]])])
            loads = [*loads, ties]
        self.pattern = StiffnessPattern.build(groups, self.free_index)
        self._scatter = self.pattern.scatter[:m]
        self._mass_diagonal = np.repeat(self.node_masses, 3)[self.free_dofs]
        diagonal = self.pattern.matrix(np.arange(self.pattern.nnz, dtype=float)).diagonal()
        self.mass_data = np.zeros(self.pattern.nnz)
        self._mass_slots = diagonal.astype(np.int64)
        self.mass_data[self._mass_slots] = self._mass_diagonal
        self._blocks = np.empty((m, 12, 12))
        self.loads = [
            LoadAssembly(load, self.n_nodes, self.free_index, self.pattern) for load in loads
        ]

    def _ties(self, sections, bend_twist: np.ndarray) -> SectionTies | None:
        """The ties of consecutive elements in one section, or None."""
        if sections is None:
            return None
        label = np.asarray(sections).reshape(-1)
        if self.is_lattice or label.shape != (self.n_elements,):
            raise ModelError(
                f"sections: one section number per element of a polyline ({self.n_elements})"
            )
        first = np.flatnonzero(label[:-1] == label[1:])  # element e tied to e + 1
        if first.size == 0:
            return None
        stiffness = SectionTies.PENALTY * bend_twist[first].max(axis=1) / self.lengths[first]
        triples = np.column_stack([first, first + 1, first + 2])
        return SectionTies(self.n_centreline, triples, stiffness)

    def set_rest_curvature(self, curvature: np.ndarray, elements: np.ndarray | None = None) -> None:
        """Prescribe the rest curvature and twist kappa0 (k, 3) (material frame, rad per
        length) of `elements` (default: all): the elastic energy l/2 (kappa - kappa0)^T B
        (kappa - kappa0) then rests at that curvature, the next step's forces and tangents
        included. :attr:`natural_curvature` holds the geometry's own."""
        idx = np.arange(self.n_elements) if elements is None else np.asarray(elements, np.int64)
        value = np.broadcast_to(np.asarray(curvature, dtype=float), (idx.size, 3))
        if not np.all(np.isfinite(value)):
            raise ModelError("a rest curvature must be finite")
        if not np.array_equal(self.kappa0[idx], value):
            self.kappa0[idx] = value  # in place: the element kernels read this very array
            self.changed()

    def set_rest_stretch(self, stretch, elements: np.ndarray | None = None) -> None:
        """Prescribe the rest stretch gamma_3 (1: the element's own length; 1.1: at rest 10 %
        longer) of `elements` (default: all), as :meth:`set_rest_curvature` the curvature.
        :attr:`natural_strain` holds the geometry's own (shears and stretch)."""
        idx = np.arange(self.n_elements) if elements is None else np.asarray(elements, np.int64)
        value = np.broadcast_to(np.asarray(stretch, dtype=float), (idx.size,))
        if not np.all(np.isfinite(value)) or np.any(value <= 0.0):
            raise ModelError("a rest stretch must be finite and positive")
        if not np.array_equal(self.gamma0[idx, 2], value):
            self.gamma0[idx, 2] = value
            self.changed()

    def set_elements(
        self,
        lengths: np.ndarray,
        shear_stretch: np.ndarray,
        bend_twist: np.ndarray,
        strain: np.ndarray,
        curvature: np.ndarray,
        node_masses: np.ndarray,
    ) -> None:
        """Replace every element's reference length (m,), stiffness C = diag(shear, shear,
        stretch) and B = diag(bend, bend, twist) (m, 3 each, >= 0: 0 leaves the element
        without elasticity), rest strains gamma0 and kappa0 (m, 3), and the nodes' lumped
        masses (2N,: translational, then rotary): a rod whose material slides along its nodes
        (an instrument pushed through an entry, :mod:`pliant.fem.instruments`). In place:
        the kernels and the solvers read these very arrays from the next step."""
        m, n = self.n_elements, self.n_centreline
        values = {
            "lengths": (lengths, (m,)),
            "shear_stretch": (shear_stretch, (m, 3)),
            "bend_twist": (bend_twist, (m, 3)),
            "strain": (strain, (m, 3)),
            "curvature": (curvature, (m, 3)),
            "node_masses": (node_masses, (2 * n,)),
        }
        for name, (value, shape) in values.items():
            array = np.asarray(value, dtype=float)
            if array.shape != shape or not np.all(np.isfinite(array)):
                raise ModelError(f"set_elements: {name} must be finite, shape {shape}")
            if name != "lengths" and name not in ("strain", "curvature") and array.min() < 0:
                raise ModelError(f"set_elements: {name} must be >= 0")
        if np.min(lengths) <= 0.0:
            raise ModelError("set_elements: lengths must be > 0")
        self.lengths[:] = lengths
        self._elements[5][:] = shear_stretch
        self._elements[6][:] = bend_twist
        self.gamma0[:] = strain
        self.kappa0[:] = curvature
        self.node_masses[:] = node_masses
        self._mass_diagonal[:] = np.repeat(self.node_masses, 3)[self.free_dofs]
        self.mass_data[self._mass_slots] = self._mass_diagonal
        self.changed()

    # --- layout -----------------------------------------------------------------------------
    @property
    def n_nodes(self) -> int:
        return 2 * self.n_centreline

    @property
    def n_elements(self) -> int:
        return int(self.elements.shape[0])

    @property
    def extent(self) -> float:
        """Diagonal of the rest centreline's bounding box."""
        return float(np.linalg.norm(np.ptp(self.rest_positions[: self.n_centreline], axis=0)))

    @property
    def label(self) -> str:
        return f"rod of {self.n_centreline - 1} elements"

    def centreline(self, positions: np.ndarray) -> np.ndarray:
        """(N, 3) centreline points of a state's positions."""
        return positions[: self.n_centreline]

    def frames(self, positions: np.ndarray) -> np.ndarray:
        """(N, 3, 3) material frames (columns d1, d2, d3) of a state's positions."""
        return rod_kernels.node_rotations(np.ascontiguousarray(positions[self.n_centreline :]))

    def interpolation(self, arc_lengths: Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """Points of the centreline at rest arc lengths s (from node 0) as (nodes (k, 2),
        weights (k, 2)): linear between the two nodes of the element holding s."""
        if self.is_lattice:
            raise ModelError(
                "arc lengths are measured along a polyline rod; embed points of a lattice at"
                " its nodes (EmbeddedPoints.at_nodes)"
            )
        s = np.atleast_1d(np.asarray(arc_lengths, dtype=float))
        ends = np.concatenate([[0.0], np.cumsum(self.lengths)])
        if not np.all(np.isfinite(s)) or s.min() < 0 or s.max() > ends[-1] * (1 + 1e-12):
            raise ModelError(f"arc lengths must lie in [0, {ends[-1]:.6g}], got {s.tolist()}")
        e = np.clip(np.searchsorted(ends, s, side="right") - 1, 0, len(self.lengths) - 1)
        t = (s - ends[e]) / self.lengths[e]
        return np.column_stack([e, e + 1]), np.column_stack([1.0 - t, t])

    def colliding_nodes(self) -> np.ndarray:
        """Centreline nodes that are not held: the default points of its contacts."""
        return np.setdiff1d(np.arange(self.n_centreline), self.fixed_nodes)

    # --- configuration space ----------------------------------------------------------------
    def advance(self, positions: np.ndarray, increment: np.ndarray) -> np.ndarray:
        """Positions moved by `increment` (2N, 3): translations of the centreline, spatial
        spins of the orientations."""
        n = self.n_centreline
        out = np.empty_like(positions)
        out[:n] = positions[:n] + increment[:n]
        rod_kernels.advance_rotations(
            np.ascontiguousarray(positions[n:]), np.ascontiguousarray(increment[n:]), out[n:]
        )
        return out

    def difference(self, to: np.ndarray, frm: np.ndarray, nodes: np.ndarray) -> np.ndarray:
        """Increments (k, 3) that :meth:`advance` `frm` to `to`, for the body nodes `nodes`."""
        out = np.empty((len(nodes), 3))
        rod_kernels.node_differences(
            np.ascontiguousarray(to, dtype=np.float64),
            np.ascontiguousarray(frm, dtype=np.float64),
            np.asarray(nodes, dtype=np.int64),
            self.n_centreline,
            out,
        )
        return out

    # --- mass -------------------------------------------------------------------------------
    def mass_matvec(self, u: np.ndarray) -> np.ndarray:
        diag = self._mass_diagonal
        return diag[:, None] * u if u.ndim == 2 else diag * u

    def gravity_forces(self) -> np.ndarray:
        """Weight of the centreline nodes, (2N, 3); none on the orientations."""
        out = np.zeros((self.n_nodes, 3))
        out[: self.n_centreline] = self.node_masses[: self.n_centreline, None] * self.gravity
        return out

    # --- elasticity -------------------------------------------------------------------------
    def _split(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        n = self.n_centreline
        x = np.ascontiguousarray(positions[:n], dtype=np.float64)
        return x, rod_kernels.node_rotations(np.ascontiguousarray(positions[n:], dtype=float))

    def linearise(
        self, positions: np.ndarray, velocities: np.ndarray | None = None, *, time: float = 0.0
    ) -> Linearisation:
        """Forces and moments, energy, the elements' middle frames and stretches gamma_3 (the
        inversion check: an element turned against its frame has gamma_3 <= 0), and K v.
        (`time` is the loads' time.)"""
        x, rot = self._split(positions)
        m = self.elements.shape[0]
        v = np.empty((0, 3)) if velocities is None else np.ascontiguousarray(velocities, float)
        forces = np.empty((self.n_nodes, 3))
        kv = np.empty((self.n_nodes, 3))
        frames = np.empty((m, 3, 3))
        stretch = np.empty(m)
        energy = rod_kernels.rod_forces(x, rot, *self._elements, v, forces, kv, frames, stretch)
        kv = kv if velocities is not None else None
        positions = np.array(positions, dtype=float)
        loads = self._add_loads(positions, v, forces, kv, time) if self.loads else ()
        return Linearisation(positions, forces, float(energy), frames, stretch, kv, (), loads)

    def stiffness_data(self, lin: Linearisation, *, exact: bool = False) -> np.ndarray:
        """Tangent stiffness on the free DoFs, as data aligned with `self.pattern`: the
        Gauss-Newton tangent, or the consistent one (`exact`)."""
        x, rot = self._split(lin.positions)
        rod_kernels.rod_stiffness(x, rot, *self._elements, exact, self._blocks)
        data = np.zeros(self.pattern.nnz)
        kernels.scatter_add(self._blocks, 1.0, self._scatter, data)
        if self.loads:
            self._add_surface_data(lin, data)
        return data

    def stiffness_matvec(
        self, lin: Linearisation, u: np.ndarray, *, exact: bool = False
    ) -> np.ndarray:
        """K u on the free DoFs; u is (n_free,) or (n_free, k)."""
        return self.stiffness_matrix(lin, exact=exact) @ u  # with the loads' tangents

    # --- drawing ----------------------------------------------------------------------------
    def skin(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rod's surface for drawing: the section's outline swept along the centreline
        with the material frames, closed at both ends (on a lattice, one tube per element,
        its rings turned with the element's frames at its ends). (points, triangles)."""
        x, rot = self._split(positions)
        outline = np.array(self.section.outline)
        if self.is_lattice:
            return self._lattice_skin(x, rot, outline)
        k, n = len(outline), self.n_centreline
        local = np.column_stack([outline, np.zeros(k)])
        rings = x[:, None, :] + np.einsum("nij,kj->nki", rot, local)
        ring = np.arange(k)
        nxt = (ring + 1) % k
        tris = [
            np.column_stack([i * k + ring, (i + 1) * k + ring, (i + 1) * k + nxt])
            for i in range(n - 1)
        ] + [np.column_stack([i * k + ring, (i + 1) * k + nxt, i * k + nxt]) for i in range(n - 1)]
        centres = n * k + np.arange(2)  # the end caps' centres
        tris.append(np.column_stack([np.full(k, centres[0]), nxt, ring]))
        tris.append(
            np.column_stack([np.full(k, centres[1]), (n - 1) * k + ring, (n - 1) * k + nxt])
        )
        points = np.vstack([rings.reshape(-1, 3), x[[0, -1]]])
        return points, np.vstack(tris).astype(np.int64)

    def _lattice_skin(self, x, rot, outline) -> tuple[np.ndarray, np.ndarray]:
        k, pairs = len(outline), self.elements
        local = np.column_stack([outline, np.zeros(k)])
        ends = [
            np.einsum("eij,ejk->eik", rot[pairs[:, side]], self.offsets[:, side])
            for side in range(2)
        ]
        rings = [
            x[pairs[:, side], None, :] + np.einsum("eij,kj->eki", ends[side], local)
            for side in range(2)
        ]
        points = np.concatenate([rings[0], rings[1]], axis=1).reshape(-1, 3)  # (E * 2k, 3)
        ring = np.arange(k)
        nxt = (ring + 1) % k
        quad = np.vstack(
            [np.column_stack([ring, k + ring, k + nxt]), np.column_stack([ring, k + nxt, nxt])]
        )
        tris = quad[None, :, :] + (2 * k * np.arange(len(pairs)))[:, None, None]
        return points, tris.reshape(-1, 3).astype(np.int64)

    def vtk_cells(self) -> tuple[str, np.ndarray, np.ndarray]:
        """(cell type, cells, point rows) of the body for ParaView: lines on the centreline."""
        return "line", self.elements, np.arange(self.n_centreline)


class SectionTies(Load):
    """Consecutive elements (a, b) and (b, c) of a rod held to the same turn between their
    ends (equal lengths: the same curvature and twist), by a penalty energy k/2 |u|^2, u =
    log((R_a^T R_b)^T (R_b^T R_c)), on the nodes' orientation rows.

    With spatial spins dtheta, du = G_a^T dtheta_a - (G_a + G_c)^T dtheta_b + G_c^T dtheta_c
    to first order in u (G_a = R_a R_b^T R_c, G_c = R_c); the forces are minus k times that
    row's G u, the tangent k J^T J (Gauss-Newton: exact where the ties hold, u = 0).

    Args:
        n_centreline: the rod's centreline nodes (orientation rows follow them).
        triples: (t, 3) centreline nodes a, b, c.
        stiffness: (t,) k, moment per radian.
    """

    # k as a multiple of the elements' bending stiffness E I / l: ten elements of a section
    # then differ in curvature by 2e-5 of it (1.6e-3 at 1e4).
    PENALTY = 1.0e6

    def __init__(self, n_centreline: int, triples, stiffness) -> None:
        triples = np.asarray(triples, dtype=np.int64).reshape(-1, 3)
        self.groups = n_centreline + triples
        self.stiffness = np.broadcast_to(np.asarray(stiffness, float), (len(triples),)).copy()
        if not np.all(np.isfinite(self.stiffness)) or np.any(self.stiffness <= 0):
            raise ModelError("SectionTies: stiffness must be finite and > 0")

    def _terms(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        vectors = np.ascontiguousarray(x[self.groups].reshape(-1, 3), dtype=float)
        r = rod_kernels.node_rotations(vectors).reshape(-1, 3, 3, 3)
        ra, rb, rc = r[:, 0], r[:, 1], r[:, 2]
        ga = np.einsum("tij,tkj,tkl->til", ra, rb, rc)  # R_a R_b^T R_c
        turn = np.einsum("tji,tjk->tik", rb, ga)  # P = R_b^T R_a R_b^T R_c
        u = np.empty((len(turn), 3))
        for i, q in enumerate(turn):
            rod_kernels.so3_log(np.ascontiguousarray(q), u[i])
        return u, ga, rc

    def group_forces(self, x: np.ndarray, time: float) -> np.ndarray:
        u, ga, gc = self._terms(x)
        fa = -self.stiffness[:, None] * np.einsum("tij,tj->ti", ga, u)
        fc = -self.stiffness[:, None] * np.einsum("tij,tj->ti", gc, u)
        return np.stack([fa, -(fa + fc), fc], axis=1)

    def group_tangents(self, x: np.ndarray, time: float) -> np.ndarray:
        _, ga, gc = self._terms(x)
        rows = np.concatenate(
            [ga.transpose(0, 2, 1), -(ga + gc).transpose(0, 2, 1), gc.transpose(0, 2, 1)], axis=2
        )  # (t, 3, 9): du / dtheta
        return self.stiffness[:, None, None] * np.einsum("tki,tkj->tij", rows, rows)


class ClampedEnd:
    """A rod node clamped to a kinematic body (a cart, a motor's shaft): its position and
    orientation follow the carrier's pose rigidly, as they were at t = 0.

    Args:
        rod: the rod; `node` must be one of its clamped nodes.
        node: centreline node index.
        carrier: the kinematic body whose prescribed pose carries the node.
    """

    def __init__(self, rod: RodBody, node: int, carrier: KinematicBody, *, name: str = "clamp"):
        n = rod.n_centreline
        if not 0 <= int(node) < n:
            raise ModelError(
                f"{name}: node {node} is not a centreline node of the rod (0..{n - 1})"
            )
        self.nodes = np.array([int(node), int(node) + n], dtype=np.int64)
        self.carrier = carrier
        self.name = name
        self._local: tuple[np.ndarray, np.ndarray] | None = None

    def attach(self, rest_positions: np.ndarray) -> None:
        """Fix the node's position and frame in the carrier's frame (called by the Model)."""
        self.carrier.forget()  # positions carried before were another body's
        position, rotation = self.carrier.pose(0.0)
        point, vector = rest_positions[self.nodes]
        self._local = (rotation.T @ (point - position), rotation.T @ _exp(vector))

    def positions(self, t: float) -> np.ndarray:
        """(2, 3): the node's position and its orientation (rotation vector) at time t
        (read-only)."""
        if self._local is None:
            raise ModelError(f"{self.name}: not attached to a rod (give it to a Model)")
        return self.carrier.carry(self, t, self._place)

    def _place(self, position: np.ndarray, rotation: np.ndarray) -> np.ndarray:
        point, frame = self._local
        out = np.empty((2, 3))
        out[0] = position + rotation @ point
        rod_kernels.so3_log(np.ascontiguousarray(rotation @ frame), out[1])
        return out


def _per_element(name: str, values, m: int) -> np.ndarray:
    """(m,) finite positive values, one per element."""
    out = np.asarray(values, dtype=float).reshape(-1)
    if out.shape != (m,) or not np.all(np.isfinite(out)) or out.min() <= 0:
        raise MaterialError(f"{name} must be {m} finite values > 0, one per element")
    return out


def _check_elements(elements, n: int) -> np.ndarray:
    """(E, 2) int64 node pairs of a lattice, checked: in range, no element on one node, none
    twice, every node in one at least."""
    pairs = np.asarray(elements)
    if pairs.ndim != 2 or pairs.shape[1] != 2 or len(pairs) == 0:
        raise ModelError(f"a lattice's elements must be (E >= 1, 2) node pairs, got {pairs.shape}")
    if not np.issubdtype(pairs.dtype, np.integer):
        raise ModelError(f"a lattice's elements must be node indices, got dtype {pairs.dtype}")
    pairs = pairs.astype(np.int64)
    if pairs.min() < 0 or pairs.max() >= n:
        raise ModelError(f"a lattice's elements must join nodes of [0, {n})")
    if np.any(pairs[:, 0] == pairs[:, 1]):
        raise ModelError(
            f"element {int(np.argmax(pairs[:, 0] == pairs[:, 1]))} joins a node to itself"
        )
    if len(np.unique(np.sort(pairs, axis=1), axis=0)) != len(pairs):
        raise ModelError("a lattice joins the same two nodes twice")
    lonely = np.setdiff1d(np.arange(n), pairs)
    if lonely.size:
        raise ModelError(f"nodes {lonely.tolist()} belong to no element of the lattice")
    return pairs


def _element_frames(x: np.ndarray, pairs: np.ndarray, normal) -> np.ndarray:
    """(E, 3, 3) frames of straight elements: d3 along the element, d1 from `normal` (or the
    world axis least aligned with d3) made perpendicular, d2 = d3 x d1."""
    d3 = x[pairs[:, 1]] - x[pairs[:, 0]]
    d3 /= np.linalg.norm(d3, axis=1, keepdims=True)
    out = np.empty((len(pairs), 3, 3))
    for e, t in enumerate(d3):
        d1 = None if normal is None else np.asarray(normal, dtype=float)
        if d1 is None or np.linalg.norm(d1 - (d1 @ t) * t) < 1e-6 * np.linalg.norm(d1):
            d1 = np.eye(3)[int(np.argmin(np.abs(t)))]
        d1 = d1 - (d1 @ t) * t
        d1 /= np.linalg.norm(d1)
        out[e] = np.column_stack([d1, np.cross(t, d1), t])
    return out


def _exp(vector: np.ndarray) -> np.ndarray:
    out = np.empty((3, 3))
    rod_kernels.so3_exp(np.asarray(vector, dtype=float), out)
    return out


def _log(rotation: np.ndarray) -> np.ndarray:
    out = np.empty(3)
    rod_kernels.so3_log(np.ascontiguousarray(rotation, dtype=float), out)
    return out
