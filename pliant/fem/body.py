"""Tetrahedral deformable body: mesh + material + mass + boundary conditions.

The body is part of the model (built once). Everything that changes while simulating lives in
:class:`pliant.model.State`; the body only evaluates forces and tangent operators at given
positions.
"""

from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numba
import numpy as np
import scipy.sparse as sp

from pliant.errors import MaterialError, ModelError
from pliant.fem import kernels, soa_kernels
from pliant.fem.loads import Load, LoadAssembly
from pliant.fem.material import (
    COROTATIONAL,
    COROTATIONAL_LARGE,
    COROTATIONAL_LARGE_INVERTIBLE,
    Material,
)
from pliant.fem.membrane import Membrane, MembraneAssembly
from pliant.fem.sparsity import StiffnessPattern
from pliant.fem.supports import Projection
from pliant.mesh.quality import validate_mesh
from pliant.mesh.tetmesh import TetMesh

MassType = Literal["lumped", "uniform", "consistent", "none"]


def nodes_in_box(points: np.ndarray, box: np.ndarray | tuple) -> np.ndarray:
    """Indices of the nodes inside the axis-aligned box [[xmin, ymin, zmin], [xmax, ymax, zmax]]."""
    box = np.asarray(box, dtype=float)
    if box.shape != (2, 3) or np.any(box[0] > box[1]):
        raise ModelError(f"a box is [[xmin, ymin, zmin], [xmax, ymax, zmax]], got {box.tolist()}")
    inside = np.all((points >= box[0]) & (points <= box[1]), axis=1)
    return np.flatnonzero(inside)


def fixed_components(nodes: np.ndarray, axes: tuple[bool, bool, bool]) -> np.ndarray:
    """DoF indices 3 * node + axis holding the chosen components of `nodes` (SOFA's
    PartialFixedConstraint fixedDirections), for TetBody's `fixed_dofs`."""
    picked = np.flatnonzero(np.asarray(axes, dtype=bool))
    if len(axes) != 3:
        raise ModelError(f"axes are three flags (x, y, z), got {axes!r}")
    return (3 * np.asarray(nodes, dtype=np.int64).reshape(-1, 1) + picked).ravel()


def set_bulk_properties(
    body,
    volume: float,
    *,
    density: float | None,
    total_mass: float | None,
    rayleigh_mass: float,
    rayleigh_stiffness: float,
    gravity,
    massless: bool = False,
) -> None:
    """Check and set a body's density and total mass (from exactly one of them; neither for a
    `massless` body, whose density and total mass are 0), Rayleigh coefficients and gravity:
    MaterialError or ModelError on a missing, non-finite or negative value."""
    damping = (("rayleigh_mass", rayleigh_mass), ("rayleigh_stiffness", rayleigh_stiffness))
    if massless:
        if density is not None or total_mass is not None:
            raise MaterialError("a massless body (mass='none') takes no density or total_mass")
        given = ()
    elif (density is None) == (total_mass is None):
        raise MaterialError("give exactly one of density or total_mass")
    else:
        given = (("density", density) if density is not None else ("total_mass", total_mass),)
    for name, val in (*given, *damping):
        if isinstance(val, bool) or not isinstance(val, numbers.Real):
            raise MaterialError(f"{name} must be a real number, got {val!r}")
    if massless:
        rho = 0.0
    else:
        rho = float(density) if density is not None else float(total_mass) / volume
        if not math.isfinite(rho) or rho <= 0:
            raise MaterialError(f"density must be finite and > 0, got {rho!r}")
    body.density = rho
    body.total_mass = rho * volume
    for name, val in damping:
        if not math.isfinite(val) or val < 0:
            raise MaterialError(f"{name} must be finite and >= 0, got {val!r}")
    body.rayleigh_mass = float(rayleigh_mass)
    body.rayleigh_stiffness = float(rayleigh_stiffness)
    try:
        body.gravity = np.asarray(gravity, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"gravity must be a finite 3-vector, got {gravity!r}") from None
    if body.gravity.shape != (3,) or not np.all(np.isfinite(body.gravity)):
        raise ModelError(f"gravity must be a finite 3-vector, got {gravity!r}")


def _solid_part(mesh: TetMesh, membranes: Sequence[Membrane]) -> tuple[np.ndarray, np.ndarray]:
    """The mesh's points and tetrahedra, less the nodes that only membranes hold (renumbered):
    a node on no tetrahedron and no membrane stays, for validate_mesh to refuse."""
    tets = np.asarray(mesh.tets)
    if not membranes:
        return mesh.points, tets
    on_tets = np.zeros(len(mesh.points), dtype=bool)
    on_tets[tets.ravel()] = True
    shell = np.zeros_like(on_tets)
    for membrane in membranes:
        shell[np.asarray(membrane.triangles).ravel()] = True
    keep = on_tets | ~shell
    if keep.all():
        return mesh.points, tets
    number = np.cumsum(keep) - 1
    return np.asarray(mesh.points)[keep], number[tets]


class Revised:
    """What a body's forces read besides its state (positions, velocities, time) is counted:
    :attr:`revision` goes up at every change made in place between steps (a rod's rest
    curvature or stretch: a proxy's actuation), so that a solver never reuses a linearisation
    computed before it (:class:`pliant.solvers.implicit_euler.ImplicitEuler` linearises the
    next step at the end of this one)."""

    revision: int = 0

    def changed(self) -> None:
        """Say that what the forces read changed in place (the body's own setters say it;
        call it after editing a load's or a material's arrays between steps)."""
        self.revision += 1


@dataclass
class Linearisation:
    """Forces and per-element frames of the body at one configuration."""

    positions: np.ndarray
    forces: np.ndarray
    energy: float
    frames: np.ndarray
    dets: np.ndarray
    stiffness_velocity: np.ndarray | None = None  # K_s v (n, 3) when linearised with v
    membrane_tangents: tuple[np.ndarray, ...] = ()  # (t, 9, 9) per membrane of the body
    load_tangents: tuple[np.ndarray | None, ...] = ()  # per load, its symmetric blocks or None
    tolerates_inversion: bool = False  # inverted elements keep their force (see Corotational)

    @property
    def n_inverted(self) -> int:
        return int(np.count_nonzero(~(self.dets > 0.0)))


class DeformableBody(Revised):
    """What every deformable body (:class:`TetBody`, its hexahedra, a rod) shares: three
    DoFs a node (`n_nodes`), of which `free_dofs` are free, and its tangent stiffness as data
    on its sparsity `pattern` (`stiffness_data`)."""

    @property
    def n_free(self) -> int:
        return int(self.free_dofs.size)

    def gather(self, full: np.ndarray) -> np.ndarray:
        """Free-DoF part of nodal arrays (n, 3) or (n, 3, k) -> (n_free,) or (n_free, k)."""
        flat = full.reshape(3 * self.n_nodes, *full.shape[2:])
        return flat[self.free_dofs]

    def scatter(self, free: np.ndarray) -> np.ndarray:
        """Nodal array (n, 3[, k]) with zeros on fixed DoFs from a free-DoF vector."""
        out = np.zeros((3 * self.n_nodes, *free.shape[1:]))
        out[self.free_dofs] = free
        return out.reshape(self.n_nodes, 3, *free.shape[1:])

    def stiffness_matrix(self, lin: Linearisation, *, exact: bool = False) -> sp.csr_matrix:
        return self.pattern.matrix(self.stiffness_data(lin, exact=exact))

    # Rayleigh damping per body (TetBody.set_rayleigh_per_body): alpha and beta of each free
    # DoF, or None where the scalars rayleigh_mass and rayleigh_stiffness hold for the body.
    _rayleigh_dofs: tuple[np.ndarray, np.ndarray] | None = None

    def rayleigh_dofs(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Per free DoF (alpha, beta) where the body joins bodies of different Rayleigh
        damping (D = sum_i alpha_i M_i + beta_i K_i); None where one pair holds for all."""
        return self._rayleigh_dofs

    def uniform_rayleigh(self, where: str) -> tuple[float, float]:
        """(rayleigh_mass, rayleigh_stiffness) for `where`, which takes one pair for the whole
        body: ModelError where the body holds bodies of different Rayleigh damping."""
        if self._rayleigh_dofs is not None:
            raise ModelError(
                f"{where} takes one Rayleigh damping for the whole body; this body joins bodies"
                " of different Rayleigh damping (per-body damping: use ImplicitEuler)"
            )
        return self.rayleigh_mass, self.rayleigh_stiffness

    def _add_loads(self, x, v, forces, kv, time: float) -> tuple:
        """Add the loads' forces at `time` to `forces` (and, when `kv` is given, their K v);
        return their tangents."""
        tangents = []
        for assembly in self.loads:
            forces += assembly.load.forces(x, time)
            tangent = assembly.tangents(x, time)
            tangents.append(tangent)
            if kv is not None and tangent is not None:
                kv += self.scatter(assembly.matvec(tangent, self.gather(v)[:, None])[:, 0])
        return tuple(tangents)

    def _add_surface_matvec(self, lin: Linearisation, cols: np.ndarray, out: np.ndarray) -> None:
        """out += the membranes' and loads' tangents times `cols`."""
        for assembly, tangent in zip(self.membranes, lin.membrane_tangents, strict=True):
            out += assembly.matvec(tangent, cols)
        for assembly, tangent in zip(self.loads, lin.load_tangents, strict=True):
            if tangent is not None:
                out += assembly.matvec(tangent, cols)

    def _add_surface_data(self, lin: Linearisation, data: np.ndarray) -> None:
        """data += the membranes' and loads' tangents, on the stiffness pattern."""
        for assembly, tangent in zip(self.membranes, lin.membrane_tangents, strict=True):
            assembly.add_to_data(tangent, data)
        for assembly, tangent in zip(self.loads, lin.load_tangents, strict=True):
            if tangent is not None:
                assembly.add_to_data(tangent, data)


# Below this many elements the compiled kernels run on the calling thread alone: waking the
# other threads costs more than they save. Linearisation (forces and K v), microseconds, 1 / 2
# threads: 240 tets 51 / 88, 1972 (Trunk) 345 / 386, 4147 (Diamond) 736 / 785, 15360 3003 /
# 2863 (2-core machine, OpenMP threads sleeping between regions).
PARALLEL_MIN_TETS = 8000


def _sized_threads(method):
    """Run a kernel-calling method on one thread for a body below PARALLEL_MIN_TETS."""

    @functools.wraps(method)
    def wrapper(self, *args, **kwargs):
        saved = numba.get_num_threads()
        if self.n_elements >= PARALLEL_MIN_TETS or saved == 1:
            return method(self, *args, **kwargs)
        numba.set_num_threads(1)
        try:
            return method(self, *args, **kwargs)
        finally:
            numba.set_num_threads(saved)

    return wrapper


@dataclass(frozen=True, eq=False)
class BodyOptions:
    """The keywords that every body of elements (:class:`TetBody`, its hexahedral
    :class:`pliant.fem.hexbody.HexBody`) takes besides its mesh, material and own keywords:
    its mass, supports, gravity, damping and loads, declared once with their defaults (see
    :class:`TetBody` for their meaning). The bodies take them as keywords; an unknown one is
    a TypeError."""

    density: float | None = None
    total_mass: float | None = None
    mass: MassType = "lumped"
    fixed_nodes: np.ndarray | None = None
    gravity: tuple[float, float, float] | np.ndarray = (0.0, 0.0, 0.0)
    rayleigh_mass: float = 0.0
    rayleigh_stiffness: float = 0.0
    fixed_dofs: np.ndarray | None = None
    loads: Sequence[Load] = ()
    projections: Sequence[Projection] = ()


class TetBody(DeformableBody):
    """A deformable body of linear tetrahedra.

    Its own keywords are `membranes`, `frame_nodes` and `separate`; the others (density or
    total mass, mass, held nodes and DoFs, gravity, damping, loads, projections) are those of
    :class:`BodyOptions`, which every body of elements shares.

    Args:
        mesh: the tetrahedral mesh (validated).
        material: constitutive law, e.g. ``Corotational(180.0, 0.45)``.
        density: mass per volume; or give ``total_mass`` instead.
        total_mass: total mass of the body (SOFA scenes give this).
        mass: "lumped" (tet masses split over their nodes), "uniform" (total mass / nodes,
            SOFA's UniformMass), "consistent" (full element mass matrices) or "none": a
            massless body (no density or total mass; SOFA's body with no mass component),
            which gravity does not pull and whose implicit step is a damped Newton step
            towards its static equilibrium (:mod:`pliant.solvers.implicit_euler`); it must
            be held against every rigid motion.
        fixed_nodes: indices of nodes held at their rest position.
        gravity: acceleration vector (robot scenes: (0, 0, -9810) mm/s^2).
        rayleigh_mass, rayleigh_stiffness: alpha and beta of D = alpha M + beta K.
        membranes: membranes of triangles on the body's nodes (faces of its tetrahedra) whose
            stretch adds to the elastic forces (a strain-limiting layer).
        fixed_dofs: single components held at rest, as indices 3 * node + axis (SOFA's
            PartialFixedConstraint; see :func:`fixed_components`): a node on a plane or a line
            through it along the axes.
        loads: external loads and elastic supports (:mod:`pliant.fem.loads`): their forces
            add to the internal ones and their tangents to the stiffness, at the time the
            solver passes.
        frame_nodes: (m, 3) the nodes whose edges give each element's frame under
            ``Corotational(rotation="large")`` (default: its first three; a SOFA mesh whose
            element was reoriented keeps its file order here, see :mod:`pliant.sofa`).
        projections: nodes held on a plane or a line of any direction through their rest
            positions (:class:`pliant.fem.supports.OnPlane`, :class:`~pliant.fem.supports.OnLine`;
            SOFA's ProjectToPlaneConstraint and ProjectToLineConstraint): the solvers project
            their increments (:mod:`pliant.fem.supports`).
        separate: the mesh may hold several separate pieces (bodies that share nothing but
            the solver, as :mod:`pliant.sofa` joins a scene's bodies); otherwise a mesh in
            pieces is refused (DisconnectedMeshError).
    """

    # Largest change of an element frame entry before the "lagged" policy refactorises: on
    # the Diamond pulled by its cables it stays within 8e-3 mm of refactorising every step
    # (see pliant.solvers.system).
    lag_tolerance = 0.02
    # The polar corotational law's forces (and K_s v) by blocks of elements vectorised across
    # them (pliant.fem.soa_kernels, equal to round-off); False: one element at a time.
    vectorised_element_pass = True

    def __init__(
        self,
        mesh: TetMesh,
        material: Material,
        *,
        membranes: Sequence[Membrane] = (),
        frame_nodes: np.ndarray | None = None,
        separate: bool = False,
        **options: Any,
    ) -> None:
        # Inverted, degenerate, disconnected or malformed meshes raise their MeshError here;
        # nodes on membranes only (a shell of triangles joined beside the tetrahedra) are
        # left out of the check.
        validate_mesh(*_solid_part(mesh, membranes), allow_disconnected=separate)
        self.mesh = mesh
        self.material = material
        self.rest_positions = np.ascontiguousarray(mesh.points, dtype=np.float64)
        self.tets = np.ascontiguousarray(mesh.tets, dtype=np.int64)
        self.volumes, self.grads = kernels.rest_gradients(self.rest_positions, self.tets)
        # The elements' nodes and gradients by component, for the vectorised polar pass.
        self._soa_nodes, self._soa_grads = soa_kernels.soa_layout(self.tets, self.grads)
        # SOFA's "large" rotation compares each element's edge frame with its rest one.
        large = material.kernel_tag in (COROTATIONAL_LARGE, COROTATIONAL_LARGE_INVERTIBLE)
        nodes = self.tets[:, :3] if frame_nodes is None else np.asarray(frame_nodes, np.int64)
        if large and frame_nodes is not None:
            ordered = np.sort(nodes, axis=1) if nodes.ndim == 2 else nodes
            if (
                nodes.shape != (self.tets.shape[0], 3)
                or not (nodes[:, :, None] == self.tets[:, None, :]).any(axis=2).all()
                or np.any(ordered[:, 1:] == ordered[:, :-1])
            ):
                raise ModelError("frame_nodes must give three distinct nodes of each element")
        self.frame_nodes = np.ascontiguousarray(nodes) if large else np.empty((0, 3), np.int64)
        self.rest_frames = (
            kernels.edge_frames(self.rest_positions, self.frame_nodes)
            if large
            else np.empty((0, 3, 3))
        )
        n_elem = self.tets.shape[0]
        self.mu = np.full(n_elem, material.mu)
        self.lam = np.full(n_elem, material.lam)

        self._hold_and_weigh(self.tets, BodyOptions(**options), membranes)
        self._element_blocks = np.empty((n_elem, 12, 12))

    def _hold_and_weigh(
        self, elements: np.ndarray, options: BodyOptions, membranes: Sequence[Membrane]
    ) -> None:
        """What every body of elements does once its volumes are known: its bulk properties
        (mass, damping, gravity), held DoFs, layout and masses from `options`."""
        set_bulk_properties(
            self,
            float(self.volumes.sum()),
            density=options.density,
            total_mass=options.total_mass,
            rayleigh_mass=options.rayleigh_mass,
            rayleigh_stiffness=options.rayleigh_stiffness,
            gravity=options.gravity,
            massless=options.mass == "none",
        )
        self._layout(
            elements,
            options.fixed_nodes,
            options.fixed_dofs,
            membranes,
            options.loads,
            options.projections,
        )
        self.mass_type: MassType = options.mass
        massless = options.mass == "none"
        self.node_masses = np.zeros(self.n_nodes) if massless else self._node_masses(options.mass)
        self.mass_data = np.zeros(self.pattern.nnz) if massless else self._mass_data(options.mass)
        self._mass_diagonal = np.repeat(self.node_masses, 3)[self.free_dofs]

    def _layout(self, elements, fixed_nodes, fixed_dofs, membranes, loads, projections) -> None:
        """Held and free DoFs, the stiffness pattern of `elements` (m, k nodes), the membranes,
        loads and projections on it, and the node -> element incidence."""
        n = self.n_nodes
        fixed = np.unique(np.asarray([] if fixed_nodes is None else fixed_nodes, dtype=np.int64))
        if fixed.size and (fixed.min() < 0 or fixed.max() >= n):
            raise ModelError(
                f"fixed node indices must lie in [0, {n}), got {fixed.min()}..{fixed.max()}"
            )
        fixed_mask = np.zeros(3 * n, dtype=bool)
        fixed_mask[(3 * fixed[:, None] + np.arange(3)).ravel()] = True
        if fixed_dofs is not None:
            dofs = np.asarray(fixed_dofs, dtype=np.int64).reshape(-1)
            if dofs.size and (dofs.min() < 0 or dofs.max() >= 3 * n):
                raise ModelError(f"fixed DoF indices must lie in [0, {3 * n})")
            fixed_mask[dofs] = True
        # Nodes held in all three components (a partly held node still collides, say).
        self.fixed_nodes = np.flatnonzero(fixed_mask.reshape(n, 3).all(axis=1))
        self.free_dofs = np.flatnonzero(~fixed_mask)
        self.free_index = np.full(3 * n, -1, dtype=np.int64)
        self.free_index[self.free_dofs] = np.arange(self.free_dofs.size)
        spanning = tuple(load.groups for load in loads if load.spans_elements)
        # A shell's triangles (pliant.fem.shell) may join nodes that share no tetrahedron.
        spanning += tuple(m.triangles for m in membranes if m.spans_elements)
        self.pattern = StiffnessPattern.build(elements, self.free_index, spanning)
        self.membranes = [MembraneAssembly(m, n, self.free_index, self.pattern) for m in membranes]
        self.loads = [LoadAssembly(load, n, self.free_index, self.pattern) for load in loads]
        self.projections = list(projections)
        self.projection = self._projection_matrix()
        # Node -> (element, local vertex) incidence, to gather element contributions in parallel.
        order = np.argsort(elements.ravel(), kind="stable")
        self._incidence = order.astype(np.int64)
        self._incidence_ptr = np.zeros(n + 1, dtype=np.int64)
        np.cumsum(np.bincount(elements.ravel(), minlength=n), out=self._incidence_ptr[1:])
        size = 3 * elements.shape[1]
        self._elem_dofs = self.free_index[
            (3 * elements[:, :, None] + np.arange(3)).reshape(-1, size)
        ].copy()

    # --- layout -----------------------------------------------------------------------------
    @property
    def n_nodes(self) -> int:
        return int(self.rest_positions.shape[0])

    @property
    def element_nodes(self) -> np.ndarray:
        """The elements' nodes (m, 4): what the kernels gather onto the nodes."""
        return self.tets

    @property
    def n_elements(self) -> int:
        return int(self.element_nodes.shape[0])

    @property
    def extent(self) -> float:
        """Diagonal of the rest shape's bounding box (the scale of divergence checks)."""
        return float(np.linalg.norm(np.ptp(self.rest_positions, axis=0)))

    @property
    def label(self) -> str:
        return f"{self.tets.shape[0]} tetrahedra"

    def advance(self, positions: np.ndarray, increment: np.ndarray) -> np.ndarray:
        """Positions moved by a displacement (the configuration space is a vector space here;
        a rod's orientations are not, see :class:`pliant.fem.rod.RodBody`)."""
        return positions + increment

    def difference(self, to: np.ndarray, frm: np.ndarray, nodes: np.ndarray) -> np.ndarray:
        """Displacements (k, 3) that :meth:`advance` `frm` to `to` (rows of the nodes `nodes`)."""
        return to - frm

    @functools.cached_property
    def boundary_triangles(self) -> np.ndarray:
        """The mesh's boundary faces (k, 3), outward (found once)."""
        return self.mesh.boundary_triangles()

    def colliding_nodes(self) -> np.ndarray:
        """Surface nodes that are not held: the default points of its contacts."""
        return np.setdiff1d(np.unique(self.boundary_triangles), self.fixed_nodes)

    def skin(self, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The surface to draw: (points, boundary triangles)."""
        return positions, self.boundary_triangles

    def vtk_cells(self) -> tuple[str, np.ndarray, np.ndarray]:
        """(cell type, cells, point rows) of the body for ParaView."""
        return "tetra", self.tets, np.arange(self.n_nodes)

    def free_rigid_motions(self) -> list[str]:
        """The rigid motions that nothing holds (neither held DoFs, lines and planes, nor
        rest-shape springs): along them the elastic stiffness is singular and a static
        equilibrium is not unique. Empty when the body is held."""
        from pliant.fem.loads import RestShapeSprings

        x = self.rest_positions
        centre = x.mean(axis=0)
        scale = max(self.extent, 1e-300)
        # u = t + w x (X - c): columns translations x, y, z, then rotations about x, y, z.
        modes = np.zeros((self.n_nodes, 3, 6))
        modes[:, :, :3] = np.eye(3)
        arm = (x - centre) / scale
        for i in range(3):
            modes[:, :, 3 + i] = np.cross(np.eye(3)[i], arm)
        held = self.free_index < 0
        for assembly in self.loads:
            if isinstance(assembly.load, RestShapeSprings):
                held[(3 * assembly.load.groups[:, :1] + np.arange(3)).ravel()] = True
        rows = modes.reshape(-1, 6)[held]
        for projection in self.projections:
            # A node held on a plane or a line: its motion along each held direction h.
            directions = projection.held_directions()
            held_rows = np.einsum("kmi,kij->kmj", directions, modes[projection.nodes])
            rows = np.vstack([rows, held_rows.reshape(-1, 6)])
        if rows.shape[0] == 0:
            return ["every rigid motion (translations along x, y, z, rotations about x, y, z)"]
        _, sing, vt = np.linalg.svd(rows, full_matrices=True)
        rank = int(np.count_nonzero(sing > 1e-9 * sing.max())) if sing.size else 0
        null = vt[rank:]
        if null.shape[0] == 0:
            return []
        # Reduced row echelon form of the null space: canonical motions where they are free.
        basis = null.copy()
        lead = 0
        for r in range(basis.shape[0]):
            while lead < 6 and np.all(np.abs(basis[r:, lead]) < 1e-9):
                lead += 1
            if lead == 6:
                break
            pivot = r + int(np.argmax(np.abs(basis[r:, lead])))
            basis[[r, pivot]] = basis[[pivot, r]]
            basis[r] /= basis[r, lead]
            for o in range(basis.shape[0]):
                if o != r:
                    basis[o] -= basis[o, lead] * basis[r]
            lead += 1
        names = []
        for t, w in zip(basis[:, :3], basis[:, 3:] / scale, strict=True):
            if np.linalg.norm(w) * scale < 1e-9 * max(np.linalg.norm(t), 1e-300):
                d = np.round(t / np.linalg.norm(t), 3) + 0.0
                names.append(f"translation along ({d[0]:g}, {d[1]:g}, {d[2]:g})")
            else:
                axis = np.round(w / np.linalg.norm(w), 3) + 0.0
                point = np.round(centre + np.cross(w, t) / (w @ w), 3) + 0.0
                names.append(
                    f"rotation about the axis ({axis[0]:g}, {axis[1]:g}, {axis[2]:g}) through"
                    f" ({point[0]:g}, {point[1]:g}, {point[2]:g})"
                )
        return names

    def _projection_matrix(self) -> sp.csr_matrix | None:
        """P on the free DoFs: each projected node's block, the identity elsewhere."""
        if not self.projections:
            return None
        nodes = np.concatenate([p.nodes for p in self.projections])
        if nodes.max() >= self.n_nodes:
            raise ModelError(f"projected node indices must lie in [0, {self.n_nodes})")
        if np.unique(nodes).size != nodes.size:
            raise ModelError("a node is held on two lines or planes: give it one projection")
        dofs = self.free_index[3 * nodes[:, None] + np.arange(3)]
        if np.any(dofs < 0):
            raise ModelError(
                "a node held on a line or a plane has a fixed component: hold it one way"
            )
        blocks = np.concatenate([p.matrices for p in self.projections])
        rest = np.setdiff1d(np.arange(self.n_free), dofs.ravel())
        rows = np.concatenate([np.repeat(dofs, 3, axis=1).ravel(), rest])
        cols = np.concatenate([np.tile(dofs, (1, 3)).ravel(), rest])
        values = np.concatenate([blocks.reshape(-1), np.ones(rest.size)])
        return sp.csr_matrix((values, (rows, cols)), shape=(self.n_free, self.n_free))

    # --- mass -------------------------------------------------------------------------------
    def _node_masses(self, mass: str) -> np.ndarray:
        n = self.n_nodes
        if mass == "uniform":
            return np.full(n, self.total_mass / n)
        if mass in ("lumped", "consistent"):
            nm = np.zeros(n)
            np.add.at(nm, self.tets.ravel(), np.repeat(self.density * self.volumes / 4.0, 4))
            return nm
        raise ModelError(f"mass must be 'lumped', 'uniform', 'consistent' or 'none', got {mass!r}")

    def _mass_data(self, mass: str) -> np.ndarray:
        """Mass matrix on the free DoFs, as data aligned with the stiffness pattern."""
        if mass == "consistent":
            # Element mass rho V / 20 (1 + delta_ab) I3 (linear tetrahedron, exact integration).
            blocks = np.zeros((self.tets.shape[0], 12, 12))
            local = (np.ones((4, 4)) + np.eye(4)) / 20.0
            pattern = np.kron(local, np.eye(3))
            blocks[:] = pattern[None] * (self.density * self.volumes)[:, None, None]
            data = np.zeros(self.pattern.nnz)
            kernels.scatter_add(blocks, 1.0, self.pattern.scatter, data)
            return data
        diag = np.repeat(self.node_masses, 3)[self.free_dofs]
        mat = sp.csr_matrix(
            (diag, (np.arange(self.n_free), np.arange(self.n_free))),
            shape=(self.n_free, self.n_free),
        )
        data = np.zeros(self.pattern.nnz)
        # Every diagonal entry exists in the stiffness pattern; locate it row by row.
        k = (
            self.pattern.matrix(np.arange(self.pattern.nnz, dtype=float))
            .diagonal()
            .astype(np.int64)
        )
        data[k] = mat.diagonal()
        return data

    def set_rayleigh_per_body(self, node_alpha, element_beta) -> None:
        """Rayleigh damping by part of the body: `node_alpha` (n_nodes,) the mass-proportional
        coefficient of each node, `element_beta` (n_elements,) the stiffness-proportional one
        of each element, so that D = sum_i alpha_i M_i + beta_i K_i over the body's parts
        (bodies joined over disjoint meshes, each damped as under its own solver). Where
        all values agree the body keeps the scalar coefficients (the same arithmetic as a body
        made with them). ModelError on a wrong shape, a negative or non-finite value, or a node
        whose elements have different beta (the parts must not share nodes)."""
        alpha = np.asarray(node_alpha, dtype=float)
        beta = np.asarray(element_beta, dtype=float)
        if alpha.shape != (self.n_nodes,) or beta.shape != (self.n_elements,):
            raise ModelError(
                f"per-body Rayleigh damping needs alpha per node ({self.n_nodes},) and beta per"
                f" element ({self.n_elements},), got {alpha.shape} and {beta.shape}"
            )
        for name, val in (("alpha", alpha), ("beta", beta)):
            if not np.all(np.isfinite(val)) or np.any(val < 0):
                raise ModelError(f"per-body Rayleigh {name} must be finite and >= 0")
        if np.all(alpha == alpha[0]) and np.all(beta == beta[0]):
            self.rayleigh_mass, self.rayleigh_stiffness = float(alpha[0]), float(beta[0])
            self._rayleigh_dofs = None
            return
        nodes = self.tets.ravel()
        per = np.repeat(beta, self.tets.shape[1])
        high = np.zeros(self.n_nodes)
        low = np.full(self.n_nodes, np.inf)
        np.maximum.at(high, nodes, per)
        np.minimum.at(low, nodes, per)
        shared = np.flatnonzero(np.isfinite(low) & (low != high))
        if shared.size:
            raise ModelError(
                f"per-body Rayleigh damping: node {int(shared[0])} joins elements of different"
                " stiffness-proportional damping (the damped parts must not share nodes)"
            )
        alpha_dofs, beta_dofs = (
            self.gather(np.repeat(v[:, None], 3, axis=1)) for v in (alpha, high)
        )
        self._rayleigh_dofs = (alpha_dofs, beta_dofs)

    def set_node_masses(self, masses: np.ndarray) -> None:
        """Give each node its own mass (a diagonal mass matrix), in place of those the density
        or total mass spread: separate pieces of one body that weigh differently (a SOFA scene's
        bodies, each with its UniformMass). ModelError for a consistent mass matrix, or masses
        that are not (n,), finite and > 0."""
        masses = np.asarray(masses, dtype=float)
        if self.massless:
            raise ModelError("a massless body (mass='none') has no node masses to set")
        if self.mass_type == "consistent":
            raise ModelError("node masses make a diagonal mass matrix: not a consistent one")
        if masses.shape != (self.n_nodes,) or not np.all(np.isfinite(masses) & (masses > 0)):
            raise ModelError(f"node masses must be {self.n_nodes} finite values > 0")
        self.node_masses = masses.copy()
        self.total_mass = float(masses.sum())
        self.density = self.total_mass / float(self.volumes.sum())
        self.mass_data = self._mass_data(self.mass_type)
        self._mass_diagonal = np.repeat(self.node_masses, 3)[self.free_dofs]
        self.changed()

    @property
    def massless(self) -> bool:
        """The body has no mass (``mass="none"``): M = 0, no weight."""
        return self.mass_type == "none"

    def mass_matvec(self, u: np.ndarray) -> np.ndarray:
        """M u on the free DoFs; u is (n_free,) or (n_free, k)."""
        if self.mass_type == "consistent":
            return self.pattern.matrix(self.mass_data) @ u
        diag = self._mass_diagonal
        return diag[:, None] * u if u.ndim == 2 else diag * u

    def gravity_forces(self) -> np.ndarray:
        """Weight of the nodes, (n, 3): M g with the lumped masses (rows of M sum to them)."""
        return self.node_masses[:, None] * self.gravity[None, :]

    # --- elasticity -------------------------------------------------------------------------
    @_sized_threads
    def linearise(
        self, positions: np.ndarray, velocities: np.ndarray | None = None, *, time: float = 0.0
    ) -> Linearisation:
        """Internal forces, energy and element frames at `positions` (n, 3), and K_s v when
        `velocities` (n, 3, zero on fixed nodes) are given; the loads' forces (and tangents)
        at `time` are added (the energy is the elastic one)."""
        x = np.ascontiguousarray(positions, dtype=np.float64)
        v = (
            np.empty((0, 3))
            if velocities is None
            else np.ascontiguousarray(velocities, dtype=np.float64)
        )
        elem, energy, frames, dets = self._element_forces(x, v)
        nodal = np.empty((x.shape[0], elem.shape[2]))
        kernels.gather_nodal(elem, self.element_nodes, self._incidence_ptr, self._incidence, nodal)
        forces = np.ascontiguousarray(nodal[:, :3])
        kv = np.ascontiguousarray(nodal[:, 3:]) if v.shape[0] else None
        tangents = []
        for assembly in self.membranes:
            membrane_forces, membrane_energy = assembly.membrane.element_forces(x)
            forces += assembly.nodal(membrane_forces)
            energy += membrane_energy
            tangent = assembly.membrane.element_stiffness(x)
            tangents.append(tangent)
            if kv is not None:
                local = v.reshape(-1)[assembly.membrane.dofs]
                kv += assembly.nodal(np.einsum("trc,tc->tr", tangent, local))
        return Linearisation(
            x,
            forces,
            float(energy),
            frames,
            dets,
            kv,
            tuple(tangents),
            self._add_loads(x, v, forces, kv, time),
            self.material.tolerates_inversion,
        )

    def _element_forces(self, x: np.ndarray, v: np.ndarray) -> tuple:
        """Per-element forces (and K_s v when `v` has rows) side by side, (m, k, 3 or 6), the
        elastic energy, the element frames and their determinants at `x`."""
        m = self.tets.shape[0]
        # Forces and K_s v side by side per element node: one gather (one parallel region)
        # assembles both.
        elem = np.empty((m, 4, 6 if v.shape[0] else 3))
        elem_forces = elem[:, :, :3]
        elem_kv = elem[:, :, 3:] if v.shape[0] else np.empty((0, 4, 3))
        frames = np.empty((m, 3, 3))
        dets = np.empty(m)
        if self.vectorised_element_pass and self.material.kernel_tag == COROTATIONAL:
            energy = soa_kernels.corotational_forces(
                x,
                v,
                self.tets,
                self.grads,
                self.volumes,
                self.mu,
                self.lam,
                self._soa_nodes,
                self._soa_grads,
                elem_forces,
                elem_kv,
                frames,
                dets,
            )
            return elem, energy, frames, dets
        energy = kernels.internal_forces(
            x,
            v,
            *self._element_args(),
            self.frame_nodes,
            self.rest_frames,
            elem_forces,
            elem_kv,
            frames,
            dets,
        )
        return elem, energy, frames, dets

    def _tangent_args(self, lin: Linearisation, exact: bool) -> tuple:
        """The arguments the tangent kernels share: configuration, elements, material, frames."""
        return (lin.positions, *self._element_args(), lin.frames, lin.dets, exact)

    def _element_args(self) -> tuple:
        """The elements and their material, as the kernels take them."""
        return (self.tets, self.grads, self.volumes, self.mu, self.lam, self.material.kernel_tag)

    @_sized_threads
    def stiffness_matvec(
        self, lin: Linearisation, u: np.ndarray, *, exact: bool = False
    ) -> np.ndarray:
        """K_s u on the free DoFs (K_s = -df/dx); u is (n_free,) or (n_free, k)."""
        cols = np.ascontiguousarray(u[:, None] if u.ndim == 1 else u, dtype=np.float64)
        elem_out = np.empty((self.tets.shape[0], 4, 3, cols.shape[1]))
        kernels.stiffness_matvec(cols, self._elem_dofs, *self._tangent_args(lin, exact), elem_out)
        out = np.empty_like(cols)
        kernels.gather_free(elem_out, self._incidence_ptr, self._incidence, self.free_index, out)
        self._add_surface_matvec(lin, cols, out)
        return out[:, 0] if u.ndim == 1 else out

    def node_rotations(
        self, frames: np.ndarray, reference: np.ndarray, nodes: np.ndarray
    ) -> tuple[np.ndarray, float]:
        """Each node's best-fit turn (n, 3, 3) from the corotational element frames
        `reference` to `frames` (the polar rotation of the sum of its elements' R R0^T), and
        how far those explain the elements' turns: max |R R0^T - Q_n| over the elements and
        their nodes n with `nodes[n]` (boolean; NaN where a frame holds one)."""
        turns = np.empty_like(frames)
        kernels.element_turns(frames, reference, turns)
        out = np.empty((self.n_nodes, 3, 3))
        kernels.node_rotations(turns, self._incidence_ptr, self._incidence, out)
        return out, float(kernels.warp_drift(turns, out, self.tets, nodes))

    @_sized_threads
    def stiffness_data(self, lin: Linearisation, *, exact: bool = False) -> np.ndarray:
        """Tangent stiffness on the free DoFs, as data aligned with `self.pattern`."""
        data = np.zeros(self.pattern.nnz)
        tag = self.material.kernel_tag
        large = tag in (COROTATIONAL_LARGE, COROTATIONAL_LARGE_INVERTIBLE)
        if (large or (tag == COROTATIONAL and not exact)) and self.tets.shape[
            0
        ] < PARALLEL_MIN_TETS:
            # SOFA's tangent in closed form, scattered as it is computed, on one thread: on the
            # Trunk's 1972 tetrahedra 0.22 ms, against 0.25 ms through stored blocks. Above
            # PARALLEL_MIN_TETS the blocks are computed on every thread (Multigait, 59296
            # tetrahedra: 8.8 ms against 10.1 ms).
            kernels.corotational_assembly(
                self.grads,
                self.volumes,
                self.mu,
                self.lam,
                tag,
                lin.frames,
                lin.dets,
                self.pattern.scatter,
                data,
            )
        else:
            kernels.element_stiffness(*self._tangent_args(lin, exact), self._element_blocks)
            kernels.scatter_add(self._element_blocks, 1.0, self.pattern.scatter, data)
        self._add_surface_data(lin, data)
        return data
