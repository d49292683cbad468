"""A SOFA + SoftRobots scene turned into a Pliant model.

Component semantics follow SOFA's and SoftRobots' documentation. With ``sofa_compatible=True``
(the default) the three choices in which Pliant's own defaults differ from SOFA's are SOFA's:

* element rotation: the FEM's ``method`` ("large", SOFA's default: the edge frame; "polar"
  and "svd": the polar decomposition), see :class:`pliant.fem.material.Corotational`;
* points outside the mesh (cable and effector points of a BarycentricMapping): kept where they
  are, with barycentric coordinates in the element whose centre is nearest
  (:class:`pliant.constraints.base.EmbeddedPoints`, ``outside="keep"``);
* the cables' ``maxDispVariation``: measured from the displacement of the step before
  (``change_reference="lagged"``, see :class:`pliant.constraints.base.Actuator`);
* inverted elements under the "large" frame: kept in the step with their restoring force, as
  SOFA has no inversion check (``inversion="tolerate"``; Pliant stops with a
  DivergenceError).

``sofa_compatible=False`` keeps Pliant's choices (polar rotation, points projected onto the
mesh, change measured from the last step, inversion refused). See docs/sofa-reference.md for
the list of components.
"""

from __future__ import annotations

import dataclasses
import math
import os
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import meshio
import numpy as np
from scipy.spatial.transform import Rotation

from pliant.constraints.attachment import Attachment
from pliant.constraints.base import EmbeddedPoints
from pliant.constraints.cable import CableActuator
from pliant.constraints.cavity import CavityActuator, enclosed_volume
from pliant.constraints.contact import Contacts, PointPlanes
from pliant.constraints.effector import PositionEffector
from pliant.constraints.point import PointActuator
from pliant.constraints.surface import RigidSurfaceContact, SurfaceContact
from pliant.errors import ContactError, ModelError
from pliant.fem.body import TetBody, fixed_components, nodes_in_box
from pliant.fem.loads import EmbeddedSprings, Load, NodalForces, RestShapeSprings
from pliant.fem.material import Corotational, Material, NeoHookean, StVenantKirchhoff
from pliant.fem.rigid import DrivenNodes, RigidBody, box_inertia
from pliant.fem.supports import OnLine, OnPlane, Projection
from pliant.geometry.collision import Box, Plane, TriangleMesh
from pliant.mesh.io import read_meshio
from pliant.mesh.quality import signed_volumes
from pliant.mesh.tetmesh import TetMesh
from pliant.model import Model, State
from pliant.sofa import beams, instruments, reduced, rigid_scene, rods
from pliant.sofa.bodies import (
    Part,
    _groups,
    check_held_if_massless,
    contact_problem,
    join,
    surface_pairs,
)
from pliant.sofa.components import FIELDS, is_visual
from pliant.sofa.grids import GRIDS, HEXAHEDRA, grid_tetrahedra, hex_body
from pliant.sofa.prefabs.stlib import SHARED_MESHES
from pliant.sofa.rigids import (
    MASS_GENERATOR,
    SPHERE_MODEL,
    generate_rigid_mass,
    is_particle_sphere,
    particle_moves,
    rigid_body,
    static_sphere,
)
from pliant.sofa.servos import ARTICULATED, Servo, linked_dofs, read_servos, rigid_pose
from pliant.sofa.shells import TRIANGLE_FEM, is_membrane, membrane, shell_body
from pliant.sofa.states import RecordedStates, read_records
from pliant.sofa.tree import (
    INITIALISERS,
    SceneError,
    SceneNode,
    SceneObject,
    close_match,
    flatten,
    read_scene,
)

# SOFA's BarycentricMapping carries a point wherever it lies; Pliant still refuses one farther
# from the mesh than this share of the body's extent (a typo in a coordinate).
SOFA_REACH = 1.0
# Components that change nothing Pliant computes: plugins, loops, visual and output
# components, linear solvers (Pliant factorises exactly, as SparseLDLSolver does), constraint
# solvers and corrections (Pliant solves the constraint problem exactly; SOFA's Gauss-Seidel
# stops at its tolerance), topology containers (the mesh comes from the loader).
IGNORED = frozenset(
    {
        "RequiredPlugin",
        "DefaultAnimationLoop",
        "FreeMotionAnimationLoop",
        "SparseLDLSolver",
        "AsyncSparseLDLSolver",
        "SparseCholeskySolver",
        "EigenSimplicialLDLT",
        "EigenSparseLU",
        "SparseLUSolver",
        "CGLinearSolver",
        "ShewchukPCGLinearSolver",
        "BlockGaussSeidelConstraintSolver",
        "GenericConstraintSolver",
        "ProjectedGaussSeidelConstraintSolver",
        "LCPConstraintSolver",
        # SoftRobots' inverse solver: `pliant inverse` solves the inverse problem (Eq. 2.15).
        "QPInverseProblemSolver",
        "LinearSolverConstraintCorrection",
        "GenericConstraintCorrection",
        "UncoupledConstraintCorrection",
        "MeshTopology",
        "TetrahedronSetTopologyContainer",
        "TetrahedronSetTopologyModifier",
        "TetrahedronSetGeometryAlgorithms",
        "TetrahedronSetTopologyAlgorithms",
        "TriangleSetTopologyContainer",
        "TriangleSetTopologyModifier",
        "TriangleSetGeometryAlgorithms",
        "TriangleSetTopologyAlgorithms",
        "EdgeSetTopologyContainer",
        "EdgeSetTopologyModifier",
        "EdgeSetGeometryAlgorithms",
        "PointSetTopologyContainer",
        "PointSetTopologyModifier",
        "Tetra2TriangleTopologicalMapping",
        # SoftRobots' volume engines: outputs (the cavity's volume), computed by Pliant's cavity
        "VolumeFromTetrahedrons",
        "VolumeFromTriangles",
        # a reduced-order model's mode amplitudes, read as the full model (pliant.sofa.reduced)
        reduced.AMPLITUDES,
    }
)
MESH_LOADERS = frozenset(
    {"MeshVTKLoader", "MeshGmshLoader", "MeshSTLLoader", "MeshOBJLoader", "GIDMeshLoader"}
)
HYPERELASTIC = "TetrahedronHyperelasticityFEMForceField"
FAST_COROTATIONAL = "FastTetrahedralCorotationalForceField"
FEM = frozenset(
    {"TetrahedronFEMForceField", FAST_COROTATIONAL, HYPERELASTIC, HEXAHEDRA, TRIANGLE_FEM}
)
# The element rotation of each FEM method: TetrahedronFEMForceField's "large" and
# FastTetrahedralCorotationalForceField's "qr" (also called "large" there) both take the frame
# of the element's first edge and first face (Gram-Schmidt on its first two edges), "polar"
# the polar decomposition of F. FastTetrahedralCorotational's "polar2" (the polar factor of
# the edge matrix) and "none" (linear elasticity) have no Pliant rotation.
ROTATIONS = {"large": "large", "qr": "large", "polar": "polar", "svd": "polar"}
# SOFA's hyperelastic materials that Pliant has a law for: the same strain energy, and the
# meaning of each ParameterSet entry (SOFA's material headers).
HYPERELASTIC_MATERIALS = {
    "NeoHookean": (NeoHookean, ("mu", "lambda")),
    "StVenantKirchhoff": (StVenantKirchhoff, ("mu", "lambda")),
}
# SOFA's projective constraints onto a plane (origin, normal) and a line (origin,
# direction), under their old and new names.
PROJECTIONS = {
    "ProjectToPlaneConstraint": ("normal", OnPlane),
    "ProjectToPlaneProjectiveConstraint": ("normal", OnPlane),
    "ProjectToLineConstraint": ("direction", OnLine),
    "ProjectToLineProjectiveConstraint": ("direction", OnLine),
}
HANDLED = frozenset(
    {
        *MESH_LOADERS,
        *FEM,
        "MechanicalObject",
        "UniformMass",
        "MeshMatrixMass",
        "BoxROI",
        "SphereROI",
        "FixedConstraint",
        "FixedProjectiveConstraint",
        "PartialFixedConstraint",
        "PartialFixedProjectiveConstraint",
        *PROJECTIONS,
        "ConstantForceField",
        "RestShapeSpringsForceField",
        "EulerImplicitSolver",
        "StaticSolver",
        "BarycentricMapping",
        "IdentityMapping",
        "CableConstraint",
        "CableActuator",
        "PositionEffector",
        "PositionConstraint",
        "SurfacePressureConstraint",
        "SurfacePressureActuator",
    }
)
# The collision pipeline: what it detects (points of the body, static triangle obstacles,
# rigid bodies) and with which distances and friction becomes Pliant's Contacts; how it
# searches (broad and narrow phases) changes nothing Pliant computes.
PIPELINE = frozenset(
    {
        "CollisionPipeline",
        "DefaultPipeline",
        "BruteForceBroadPhase",
        "BruteForceDetection",
        "BVHNarrowPhase",
        "CollisionResponse",
        "DefaultContactManager",
        "RuleBasedContactManager",
    }
)
RESPONSES = frozenset({"CollisionResponse", "DefaultContactManager", "RuleBasedContactManager"})
MAPPINGS = frozenset({"BarycentricMapping", "IdentityMapping"})
INTERSECTIONS = frozenset(
    {"LocalMinDistance", "MinProximityIntersection", "NewProximityIntersection"}
)
COLLISION_MODELS = frozenset(
    {"PointCollisionModel", "TriangleCollisionModel", "LineCollisionModel", SPHERE_MODEL}
)
HANDLED = HANDLED | PIPELINE | INTERSECTIONS | COLLISION_MODELS | {"RigidMapping"}
# Rigid bodies' masses from a mesh and a density (pliant.sofa.rigids).
HANDLED = HANDLED | {MASS_GENERATOR}
HANDLED = HANDLED | GRIDS  # hexahedral bodies: pliant.sofa.grids
# SoftRobots' self-contact of the body: a point kept on one side of the plane of three others.
PLANE_CONSTRAINT = "UnilateralPlaneConstraint"
HANDLED = HANDLED | {PLANE_CONSTRAINT}
# STLIB's Rigidify: the body's node gathered from its free nodes and from nodes carried by
# rigid frames (a RigidMapping with rigidIndexPerPoint).
HANDLED = HANDLED | {"SubsetMultiMapping"}
# SoftRobots' servo motors (ArticulatedSystemPlugin): kinematic servos, pliant.sofa.servos.
HANDLED = HANDLED | ARTICULATED
# A body's state read from a file (pliant.sofa.states); springs between points the body
# carries (pliant.fem.loads.EmbeddedSprings).
HANDLED = HANDLED | {"ReadState", "MeshSpringForceField"}
# Joints between rigid bodies, in scenes of rigid bodies alone (pliant.sofa.rigid_scene).
HANDLED = HANDLED | rigid_scene.JOINTS
# Components Pliant knows but cannot map, and why (their data are still checked).
UNSUPPORTED = {
    # SoftRobots registers it on Vec1 only: an articulation's angle or course, which an
    # ArticulatedSystemMapping turns into rigid frames. Pliant reads a servo's angle as the
    # rest_position its RestShapeSpringsForceField pulls it to (pliant.sofa.servos), not as a
    # constraint's value.
    "JointConstraint": "an articulation's degree of freedom (Vec1 of an"
    " ArticulatedSystemMapping); Pliant reads a servo's angle from its"
    " RestShapeSpringsForceField's rest_position only",
    # BeamAdapter's beams are read (pliant.sofa.beams) where a BeamInterpolation holds them.
    "AdaptiveBeamForceFieldAndMass": "BeamAdapter's beam element, read with a"
    " BeamInterpolation (pliant.sofa.beams)",
}
# A rigidified group's frame is a Pliant rigid body with this share of its nodes' mass (SOFA's
# frames have none of their own: the nodes carry it; Pliant's rigid bodies need a mass).
FRAME_MASS_SHARE = 1e-6
CAVITIES = frozenset({"SurfacePressureConstraint", "SurfacePressureActuator"})
ROIS = frozenset({"BoxROI", "SphereROI"})
TOPOLOGIES = frozenset({"MeshTopology", "TetrahedronSetTopologyContainer"})
POINT_CONSTRAINTS = frozenset(
    {"CableConstraint", "CableActuator", "PositionEffector", "PositionConstraint", *CAVITIES}
)


@dataclass
class SofaScene:
    """A scene read into Pliant: the model, SOFA's time step and solver kind, and the scene
    tree a script's controllers read and write between steps.

    Attributes:
        model: the Pliant model (actuators hold the scene's commands).
        dt: the root node's time step.
        solver_kind: "dynamic" (EulerImplicitSolver), "first-order" (the same with
            firstOrder: no inertia, see :class:`~pliant.solvers.ImplicitEuler`) or "static"
            (StaticSolver).
        path: the scene file.
        root: the scene's root node (its data hold the last state, see :meth:`write_outputs`).
        bindings: which components hold the model's inputs and outputs.
    """

    model: Model
    dt: float
    solver_kind: str
    path: Path
    root: SceneNode | None = None
    bindings: Bindings | None = None

    @property
    def name(self) -> str:
        return self.path.stem

    def solver(self, *, tangent: str = "fresh"):
        """The solver the scene asks for. The dynamic one refactorises every step by default,
        as SOFA's direct solvers do (the "lagged" tangent is faster, and within 1e-2 mm of
        it on the robot scenes, but not SOFA's step)."""
        from pliant.solvers import ImplicitEuler, StaticSolver

        if self.solver_kind == "static":
            solver = StaticSolver(self.model)
        else:
            first_order = self.solver_kind == "first-order"
            solver = ImplicitEuler(self.model, self.dt, tangent=tangent, first_order=first_order)
        hooks = self.bindings is not None and self.bindings.hooks
        return ControlledSolver(self, solver) if self.controllers() or hooks else solver

    def controllers(self) -> list:
        """The scene's Python controllers, in scene order."""
        if self.root is None:
            return []
        return [c for node in self.root.walk() for c in node.controllers]

    def begin_step(self, state: State) -> State:
        """SOFA's AnimateBeginEvent: each controller's ``onAnimateBeginEvent``, then the data
        they set (actuator values, effector goals, the body's positions) into the model;
        returns the state the step starts from."""
        self._fire("onAnimateBeginEvent", state)
        return self.read_inputs(state)

    def end_step(self, state: State) -> None:
        """After a step: the state into the scene's data, then ``onAnimateEndEvent``."""
        self.write_outputs(state)
        self._fire("onAnimateEndEvent", state)

    def _fire(self, method: str, state: State) -> None:
        from pliant.sofa.script import scene_error

        event = {"type": method[2:-5], "dt": self.dt, "time": state.time}
        for controller in self.controllers():
            handler = getattr(controller, method, None)
            if handler is None:
                continue
            try:
                handler(event)
            except Exception as exc:
                raise scene_error(self.path, exc, f"{type(controller).__name__}.{method}") from exc

    def read_inputs(self, state: State) -> State:
        """Actuator values, effector goals and the body's positions as the data hold them."""
        bindings = self.bindings
        for obj, actuator in zip(bindings.actuators, self.model.actuators, strict=True):
            values = _floats(obj.attrs.get("value", "0"), f"{obj.path}.value")
            actuator.value = float(values[int(_float(obj, "valueIndex", 0.0))])
        for obj, effector in zip(bindings.effectors, self.model.effectors, strict=True):
            goal = obj.attrs.get("effectorGoal")
            if goal is None:
                continue
            if _is_link(goal):
                source = _Builder(self.root, self.path, SOFA_CHOICES, []).link(obj.node, goal)
                goal = None if source is None else source.attrs.get("position")
            if goal is not None:
                goals = _floats(goal, f"{obj.path}.effectorGoal").reshape(-1, 3)
                if goals.shape[0] == 1:
                    goals = np.repeat(goals, len(effector.points), axis=0)
                effector.goals = goals
        for servo in bindings.servos:  # a command reached at the end of this step
            servo.set_command(state.time)
        positions = None  # each body's MechanicalObject holds its rows of the positions
        for (dofs, rows), written in zip(bindings.bodies, bindings.written, strict=True):
            if dofs.attrs.get("position") is written:
                continue
            given = _floats(dofs.attrs["position"], f"{dofs.path}.position").reshape(-1, 3)
            if len(bindings.bodies) == 1:
                positions = given.copy()
                break
            positions = state.positions.copy() if positions is None else positions
            if given.shape != positions[rows].shape:
                raise SceneError(
                    f"{dofs.path}.position: {len(given)} points set where the body has"
                    f" {len(positions[rows])}"
                )
            positions[rows] = given
        if positions is not None:
            state = dataclasses.replace(state, positions=positions)
        for hook in bindings.hooks:
            state = hook.read(state)
        return state

    def write_outputs(self, state: State) -> None:
        """The state into the data scripts read: the body's and the carried points'
        ``position``, actuators' ``displacement`` / ``force`` (cables) and ``pressure`` /
        ``volumeGrowth`` (cavities), rigid poses, and the root's ``time``."""
        bindings = self.bindings
        if bindings is None:
            return
        bindings.written = [_frozen(state.positions[rows]) for _, rows in bindings.bodies]
        for hook in bindings.hooks:
            hook.write(state)
        for (dofs, rows), written in zip(bindings.bodies, bindings.written, strict=True):
            dofs.attrs["position"] = written
            dofs.attrs["velocity"] = _frozen(state.velocities[rows])
        for dofs, points in bindings.mapped:
            dofs.attrs["position"] = _frozen(points.positions(state.positions))
        n = len(self.model.actuators)
        force = state.actuation if len(state.actuation) == n else np.zeros(n)
        shift = state.displacement if len(state.displacement) == n else np.zeros(n)
        done = set()  # a PositionConstraint's data hold its first row's
        for obj, f, d in zip(bindings.actuators, force, shift, strict=True):
            if id(obj) in done:
                continue
            done.add(id(obj))
            if obj.type in CAVITIES:
                obj.attrs["pressure"], obj.attrs["volumeGrowth"] = float(f), float(d)
            else:
                obj.attrs["force"], obj.attrs["displacement"] = float(f), float(d)
        for dofs, x, r in zip(
            bindings.rigid, state.rigid_positions, state.rigid_rotations, strict=False
        ):
            if not str(dofs.attrs.get("template", "")).startswith("Rigid3"):  # a particle ball
                dofs.attrs["position"] = _frozen(x[None])
                continue
            dofs.attrs["position"] = _frozen(np.concatenate([x, Rotation.from_matrix(r).as_quat()]))
        for dofs, i, local in bindings.carried:  # points on a rigid body (RigidMapping)
            x, r = state.rigid_positions[i], state.rigid_rotations[i]
            dofs.attrs["position"] = _frozen(x + local @ r.T)
        for dofs, frames in bindings.frames:  # Rigidify's frames: a rigid body's, or held
            poses = []
            for index, x, r in frames:
                if isinstance(index, Servo):
                    x, r = index.carrier.pose(state.time)
                elif index is not None:
                    x, r = state.rigid_positions[index], state.rigid_rotations[index]
                poses.append(np.concatenate([x, Rotation.from_matrix(r).as_quat()]))
            dofs.attrs["position"] = _frozen(poses)
        for servo in bindings.servos:
            servo.write(state.time)
        if self.root is not None:
            self.root.attrs["time"] = float(state.time)

    def goal_path(self, n_goals: int) -> np.ndarray:
        """(n_goals, 3) goals on the straight line from the first effector point's rest
        position to the goal the scene gives it (its PositionEffector's ``effectorGoal``), the
        last one the scene's; for ``pliant inverse``."""
        if not self.model.effectors:
            raise SceneError(f"{self.path.name} has no PositionEffector to control")
        effector = self.model.effectors[0]
        start = effector.position(self.model.body.rest_positions)[0]
        goal = np.asarray(effector.goals, dtype=float)[0]
        if np.linalg.norm(goal - start) <= 1e-12 * max(self.model.body.extent, 1e-300):
            raise SceneError(
                f"{self.path.name}: the effector {effector.name!r} has no goal away from its"
                " rest position (give PositionEffector an effectorGoal)"
            )
        return start + np.linspace(0.0, 1.0, n_goals + 1)[1:, None] * (goal - start)

    def commands(self) -> np.ndarray:
        """The actuators' commands as the scene sets them."""
        return np.array([a.value for a in self.model.actuators])

    def entry(self):
        """The scene as a registered robot (:class:`pliant.robots.RobotEntry`) for the
        command line: built once, its commands held constant, or set by its controllers
        (through :meth:`solver`)."""
        from pliant.robots import RobotEntry

        commands = None if self.controllers() else self.commands()  # None: the controllers'
        goals = {"goal": self.goal_path} if self.model.effectors else {}
        return RobotEntry(lambda: self.model, lambda t: commands, goals, (20.0, -60.0))

    def simulate(self, n_steps: int, state: State | None = None) -> State:
        """Run `n_steps` steps under the scene's commands (and its controllers); returns the
        last state."""
        solver = self.solver()
        state = self.model.rest_state() if state is None else state
        for _ in range(n_steps):
            state = solver.step(state)
        return state


@dataclass
class Bindings:
    """Which components of the scene hold the model's inputs and outputs: the actuators'
    and effectors' components (in the model's order), the MechanicalObject of each of the
    scene's deformable bodies with its rows of the model's nodes, those of the points they
    carry (with their embedding) and the rigid bodies'."""

    actuators: list[SceneObject] = dataclasses.field(default_factory=list)
    effectors: list[SceneObject] = dataclasses.field(default_factory=list)
    bodies: list[tuple[SceneObject, slice]] = dataclasses.field(default_factory=list)
    mapped: list[tuple[SceneObject, EmbeddedPoints]] = dataclasses.field(default_factory=list)
    rigid: list[SceneObject] = dataclasses.field(default_factory=list)
    # Points carried by a rigid body through a RigidMapping: their MechanicalObject, the
    # body's index and the points in its frame.
    carried: list[tuple[SceneObject, int, np.ndarray]] = dataclasses.field(default_factory=list)
    written: list[np.ndarray] = dataclasses.field(default_factory=list)  # as last written
    # Rigidify's frames: their MechanicalObject, and for each frame (rigid body index or None
    # where it is held, its initial position and rotation).
    frames: list[tuple[SceneObject, list]] = dataclasses.field(default_factory=list)
    servos: list[Servo] = dataclasses.field(default_factory=list)
    # Bodies whose data have their own reading and writing (pliant.sofa.rods.RodData):
    # read(state) -> state before a step, write(state) after it.
    hooks: list = dataclasses.field(default_factory=list)


class ControlledSolver:
    """A scene's solver with its Python controllers around each step (SOFA's animation
    events); every other attribute is the solver's."""

    def __init__(self, scene: SofaScene, solver) -> None:
        self.scene, self.solver = scene, solver

    def step(self, state: State, control=None) -> State:
        state = self.solver.step(self.scene.begin_step(state), control)
        self.scene.end_step(state)
        return state

    def __getattr__(self, key: str):
        return getattr(self.solver, key)


def _frozen(values: np.ndarray) -> np.ndarray:
    """A read-only copy, as SofaPython3 gives data arrays."""
    array = np.array(values, dtype=float)
    array.flags.writeable = False
    return array


@dataclass
class _Frames:
    """Rigidify's frames: their MechanicalObject, the body's nodes of each group, (index,
    (position, rotation)) of each frame, and which frames are held."""

    dofs: SceneObject
    groups: list[np.ndarray]
    poses: list
    fixed: np.ndarray
    # the servo turning each frame (its nodes are then held and driven), or None
    driven: list = dataclasses.field(default_factory=list)
    # the (MechanicalObject, index) each frame is read from (a free frame's source), or None
    origins: list = dataclasses.field(default_factory=list)


@dataclass(frozen=True)
class Choices:
    """Where SOFA and Pliant's defaults differ, which one a loaded scene makes."""

    rotation: Literal["scene", "polar"]  # "scene": the FEM's method ("large" by default)
    outside: Literal["keep", "project"]
    change_reference: Literal["lagged", "last"]
    inversion: Literal["tolerate", "refuse"] = "refuse"  # of "large" elements


SOFA_CHOICES = Choices("scene", "keep", "lagged", "tolerate")
PLIANT_CHOICES = Choices("polar", "project", "last", "refuse")


def sofa_data_path() -> list[Path]:
    """The folders SOFA finds its data files in: ``SOFA_DATA_PATH`` (separated by the
    system's path separator), then ``$SOFA_ROOT/share`` and ``$SOFA_ROOT/examples``."""
    folders = [Path(d) for d in os.environ.get("SOFA_DATA_PATH", "").split(os.pathsep) if d]
    if root := os.environ.get("SOFA_ROOT"):
        folders += [Path(root) / "share", Path(root) / "examples"]
    return folders


def load_scene(
    path: str | Path,
    *,
    sofa_compatible: bool = True,
    mesh_dirs: Sequence[str | Path] = (),
    rotation: Literal["scene", "polar"] | None = None,
    outside: Literal["keep", "project"] | None = None,
    change_reference: Literal["lagged", "last"] | None = None,
    inversion: Literal["tolerate", "refuse"] | None = None,
    config: Mapping | None = None,
) -> SofaScene:
    """Read a SOFA scene (``.scn`` XML or a ``createScene`` Python script) into a model.

    Args:
        path: the scene file.
        sofa_compatible: SOFA's choices where Pliant's defaults differ (see the module text);
            False takes Pliant's.
        mesh_dirs: folders where mesh files not found beside the scene are looked for (by their
            path as written, then by their file name); then, as SOFA looks, the folders of the
            ``SOFA_DATA_PATH`` environment variable and ``$SOFA_ROOT/share`` and
            ``$SOFA_ROOT/examples`` (SOFA's own meshes, e.g. ``mesh/floor.obj``).
        rotation, outside, change_reference: override one of those choices: the element
            rotation ("scene": the FEM's method; "polar"), points outside the mesh ("keep",
            "project"), what a cable's maxDispVariation is measured from ("lagged", "last"),
            what an inverted element of the "large" frame does ("tolerate": keeps its force,
            as in SOFA; "refuse": the step raises DivergenceError).
        config: the configuration a SofaGym scene's ``createScene(rootNode, config)`` is
            called with (without it: the scene's own default, or an empty one).

    Raises:
        SceneError: the scene cannot be read, uses components Pliant does not support (all
            of them named in one message), or misses what a simulation needs.
    """
    path = Path(path)
    base = SOFA_CHOICES if sofa_compatible else PLIANT_CHOICES
    choices = Choices(
        rotation or base.rotation,
        outside or base.outside,
        change_reference or base.change_reference,
        inversion or base.inversion,
    )
    if choices.inversion not in ("tolerate", "refuse"):
        raise SceneError(f"inversion is 'tolerate' or 'refuse', got {choices.inversion!r}")
    root = read_scene(path, config)
    try:
        return _Builder(
            root, path, choices, [Path(d) for d in mesh_dirs] + sofa_data_path()
        ).build()
    except SceneError:
        raise
    except ModelError as exc:  # what Pliant's model refuses in the scene, named with it
        raise SceneError(f"{path.name}: {exc}") from exc


def _floats(value, what: str) -> np.ndarray:
    """A scene value (string of numbers, number, or sequence) as a flat float array."""
    parts = value.replace(",", " ").split() if isinstance(value, str) else list(flatten(value))
    try:
        return np.array([float(p) for p in parts], dtype=float)
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{what}: expected numbers, got {value!r}") from exc


def _value_type(obj: SceneObject, options: tuple[str, ...]) -> str:
    """An option of the component's ``valueType``, by name or by index (SOFA's option groups
    take either)."""
    raw = str(obj.attrs.get("valueType", options[0])).strip()
    if raw.isdigit() and int(raw) < len(options):
        return options[int(raw)].lower()
    return raw.lower()


def _command(obj: SceneObject, options: tuple[str, str]) -> tuple[np.ndarray, int, str]:
    """A SoftRobots actuator's command: its ``value`` list, ``valueIndex`` and ``valueType``
    (one of `options`, lower-cased)."""
    values = _floats(obj.attrs.get("value", "0"), f"{obj.path}.value")
    index = int(_float(obj, "valueIndex", 0.0))
    kind = _value_type(obj, options)
    if kind not in tuple(o.lower() for o in options):
        raise SceneError(f"{obj.path}.valueType: {options[0]!r} or {options[1]!r}, not {kind!r}")
    return values, index, kind


def _actuator_bounds(obj: SceneObject) -> dict[str, float]:
    """A SoftRobots point actuator's bounds (CableConstraint, PositionConstraint), as Pliant's
    actuator keywords: SoftRobots bounds the tension and the course only where the scene sets
    them."""
    return {
        "min_force": _float(obj, "minForce", -math.inf),
        "max_force": _float(obj, "maxForce", math.inf),
        "min_displacement": -_float(obj, "maxNegativeDisp", math.inf),
        "max_displacement": _float(obj, "maxPositiveDisp", math.inf),
    }


def _float(obj: SceneObject, key: str, default: float) -> float:
    if key not in obj.attrs:
        return default
    values = _floats(obj.attrs[key], f"{obj.path}.{key}")
    if values.size != 1:
        raise SceneError(f"{obj.path}.{key}: one value expected, got {values.size}")
    return float(values[0])


def _flag(obj: SceneObject, key: str, default: bool) -> bool:
    value = obj.attrs.get(key, default)
    if isinstance(value, str):
        return value.strip().lower() in ("1", "true", "yes")
    return bool(value)


def _placed(obj: SceneObject, points: np.ndarray) -> np.ndarray:
    """Points under a component's scale (``scale3d`` or uniform ``scale``), rotation (Euler
    angles in degrees, Rz Ry Rx as SOFA composes them) and translation, in that order."""
    if not {"scale3d", "scale", "rotation", "translation"} & obj.attrs.keys():
        return np.array(points, dtype=float)
    scale = _floats(obj.attrs.get("scale3d", obj.attrs.get("scale", "1")), f"{obj.path}.scale")
    euler = _floats(obj.attrs.get("rotation", "0 0 0"), f"{obj.path}.rotation")
    shift = _floats(obj.attrs.get("translation", "0 0 0"), f"{obj.path}.translation")
    rot = Rotation.from_euler("xyz", euler, degrees=True).as_matrix()
    return (points * scale) @ rot.T + shift


def _in_oriented_box(points: np.ndarray, box: np.ndarray) -> np.ndarray:
    """Nodes in SOFA's oriented box: the parallelogram p0, p1, p2 (edges p1 - p0 and
    p2 - p1) extruded by half the depth on each side of its plane."""
    p0, p1, p2, depth = box[0:3], box[3:6], box[6:9], box[9]
    u, v = p1 - p0, p2 - p1
    n = np.cross(u, v)
    n /= np.linalg.norm(n)
    a, b, c = np.linalg.solve(np.column_stack([u, v, n]), (points - p0).T)
    eps = 1e-12
    inside = (a >= -eps) & (a <= 1 + eps) & (b >= -eps) & (b <= 1 + eps)
    return np.flatnonzero(inside & (np.abs(c) <= 0.5 * depth + eps))


def _sphere_nodes(roi: SceneObject, points: np.ndarray) -> np.ndarray:
    """Nodes in any of a SphereROI's spheres (``centers``, ``radii``: one radius for all or
    one each), their boundary included."""
    centres = _floats(roi.attrs.get("centers", ""), f"{roi.path}.centers").reshape(-1, 3)
    radii = _floats(roi.attrs.get("radii", ""), f"{roi.path}.radii")
    if centres.shape[0] == 0 or radii.size not in (1, centres.shape[0]):
        raise SceneError(
            f"{roi.path}: {centres.shape[0]} centers and {radii.size} radii (one, or one each)"
        )
    radii = np.broadcast_to(radii, centres.shape[0])
    distance = np.linalg.norm(points[:, None, :] - centres[None], axis=2)
    return np.flatnonzero((distance <= radii[None]).any(axis=1))


def _read_obj(file: Path) -> meshio.Mesh:
    """An OBJ file's vertices and faces (polygons fanned into triangles), for files meshio
    refuses (texture coordinates that do not match the vertices), and its lines (polylines
    cut into edges) where it has some."""
    points, faces, lines = [], [], []
    for line in file.read_text(errors="replace").splitlines():
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "v":
            points.append([float(x) for x in parts[1:4]])
        elif parts[0] == "f":
            ids = [int(p.split("/")[0]) for p in parts[1:]]
            ids = [i - 1 if i > 0 else len(points) + i for i in ids]
            faces += [[ids[0], ids[k], ids[k + 1]] for k in range(1, len(ids) - 1)]
        elif parts[0] == "l":
            ids = [int(p.split("/")[0]) for p in parts[1:]]
            ids = [i - 1 if i > 0 else len(points) + i for i in ids]
            lines += [[a, b] for a, b in zip(ids[:-1], ids[1:], strict=True)]
    cells = [("triangle", np.array(faces, dtype=np.int64))]
    if lines:
        cells.append(("line", np.array(lines, dtype=np.int64)))
    return meshio.Mesh(np.array(points), cells)


def _read_gid(file: Path) -> meshio.Mesh:
    """A GiD mesh (GIDMeshLoader): numbered ``Coordinates`` and tetrahedral ``Elements``
    (node numbers from 1, an optional material number after them)."""
    points, tets, section = {}, [], None
    for line in file.read_text().splitlines():
        words = line.split()
        if not words:
            continue
        head = words[0].lower()
        if head in ("coordinates", "elements"):
            section = head
        elif head in ("end", "mesh"):
            section = None
        elif section == "coordinates":
            points[int(words[0])] = [float(x) for x in words[1:4]]
        elif section == "elements":
            tets.append([int(n) for n in words[1:5]])
    order = {number: k for k, number in enumerate(sorted(points))}
    cells = np.array([[order[n] for n in tet] for tet in tets], dtype=np.int64)
    return meshio.Mesh(np.array([points[n] for n in sorted(points)]), [("tetra", cells)])


def _within(node: SceneNode, ancestor: SceneNode) -> bool:
    """Whether `node` is `ancestor` or lies under it."""
    at: SceneNode | None = node
    while at is not None:
        if at is ancestor:
            return True
        at = at.parent
    return False


def _is_link(value) -> bool:
    return isinstance(value, str) and value.strip().startswith("@")


# Data fields every SOFA component has.
_COMMON = frozenset({"name", "template", "printLog", "tags", "bbox", "listening", "src"})


class _Builder:
    loaders = MESH_LOADERS
    intersections = INTERSECTIONS
    point_constraints = POINT_CONSTRAINTS

    def __init__(self, root: SceneNode, path: Path, choices: Choices, mesh_dirs: list[Path]):
        self.root, self.path, self.choices, self.mesh_dirs = root, path, choices, mesh_dirs
        self.bindings = Bindings()
        self._part: Part | None = None  # the body whose points are read, of several
        self._springs_read: set[int] = set()  # MeshSpringForceFields read on a body
        # The collision surfaces of the bodies read so far (vertices, triangles), by node.
        self._surfaces: dict[int, tuple[EmbeddedPoints, np.ndarray]] = {}
        # Collision triangles carried by a moving frame: (node, frame dofs, index).
        self._carried: list[tuple[SceneNode, SceneObject, int]] = []
        self._carried_friction = 0.5

    # --- scene-wide ------------------------------------------------------------------------
    def build(self) -> SofaScene:
        if reduced.has_reduction(self.root):
            changes = reduced.full_order(self)
            warnings.warn(
                f"{self.path.name}: its reduced-order model is read as the full model it"
                f" reduces ({'; '.join(changes)})",
                reduced.ReducedOrderWarning,
                stacklevel=3,
            )
        self._check_supported()
        # A slender body as the scene's one body, with its own data hook: a Cosserat rod,
        # BeamAdapter's deployed instruments, a BeamAdapter beam.
        slender = None
        if rods.has_rods(self.root) and rods.moving_rods(self):
            _refuse_on_rods(self.root)
            slender = rods.rod_model
        elif instruments.has_instruments(self.root):
            slender = instruments.instrument_model
        elif beams.has_beams(self.root):
            _refuse_on_rods(self.root)
            slender = beams.beam_model
        if slender is not None:
            model, dt, solver_kind, hook = slender(self)
            scene = SofaScene(model, dt, solver_kind, self.path, self.root, Bindings(hooks=[hook]))
            scene.write_outputs(model.rest_state())
            return scene
        if rigid_scene.is_rigid_scene(self):  # rigid bodies alone
            return self._rigid_scene()
        joints = [
            f"{o.type} (at {n.path})"
            for n in self.root.walk()
            for o in n.objects
            if o.type in rigid_scene.JOINTS
        ]
        if joints:
            raise SceneError(
                f"{self.path.name}: joints between rigid bodies are read in scenes of rigid"
                " bodies alone (no deformable body), not beside a deformable body: "
                + "; ".join(joints)
            )
        self._servos = read_servos(self.root)
        nodes = self._body_nodes()
        body_node = nodes[0]
        dt, gravity = self._scene_time()
        parts = [Part(n, *self._body(n, gravity)) for n in nodes]
        body, mesh, solver_kind = parts[0].body, parts[0].mesh, parts[0].solver_kind
        unread = [
            o.path
            for n in self.root.walk()
            for o in n.objects
            if o.type == "MeshSpringForceField" and id(o) not in self._springs_read
        ]
        if unread:
            raise SceneError(
                f"{unread[0]}: springs on points carried by a deformable body of tetrahedra only"
                " (a child node of its node with a BarycentricMapping)"
            )
        if len(parts) > 1:  # the scene's bodies side by side in one (pliant.sofa.bodies)
            body = join(parts, self.path.name)
            mesh = body.mesh
        actuators, effectors, carried = [], [], []
        for part in parts:
            self._part = part if len(parts) > 1 else None
            before = len(actuators), len(effectors)
            inside = [n for n in part.node.walk() if n is not part.node]
            carried += inside
            for obj in part.node.objects:  # on the body's own nodes
                if obj.type == "PositionConstraint":
                    idx = self._indices(part.node, obj, "indices", part.mesh.points)
                    at = np.arange(part.mesh.n_nodes) if idx is None else np.asarray(idx)
                    at = EmbeddedPoints.at_nodes(at + part.offset)
                    actuators += self._position_constraint(obj, at, body)
            for child in inside:
                acts, effs = self._embedded(child, body, mesh)
                actuators += acts
                effectors += effs
            if self._part is not None:  # named after their body, unique among the bodies'
                for c in actuators[before[0] :] + effectors[before[1] :]:
                    c.name = f"{part.label}/{c.name}"
        self._part = None
        stray = [
            f"{obj.type} (at {node.path})"
            for node in self.root.walk()
            if not any(node is p.node for p in parts) and not any(node is c for c in carried)
            for obj in node.objects
            if obj.type in POINT_CONSTRAINTS
        ]
        if stray:
            raise SceneError(
                f"{self.path.name}: actuators and effectors act on points carried by the body"
                f" (a node under {' or '.join(n.path for n in nodes)} with a"
                " BarycentricMapping): " + "; ".join(stray)
            )
        contacts, rigid = self._collisions(parts, body, mesh)
        frames, attachments = self._free_frames(body_node, body, mesh)
        if frames and solver_kind == "static":
            raise SceneError(
                f"{self.path.name}: Rigidify's free frame {frames[0].name} is a rigid body in"
                " Pliant, which the static solver cannot balance: use an EulerImplicitSolver"
                " (or hold the frame with a FixedConstraint)"
            )
        planes = self._planes(body_node, carried, body, mesh)
        if planes is not None:  # solved with the contacts, whether the scene detects any
            contacts = Contacts([], planes=planes) if contacts is None else contacts
            contacts.planes = planes
        drivers = [
            DrivenNodes(g.groups[j], servo.carrier, name=f"{g.dofs.node.name}[{j}]")
            for g in self._rigidified
            for j, servo in enumerate(g.driven)
            if servo is not None
        ]
        model = Model(
            body,
            actuators=actuators,
            effectors=effectors,
            contacts=contacts,
            drivers=drivers,
            rigid_bodies=rigid + frames,
            attachments=attachments,
            name=self.path.stem,
        )
        carriers = [f for f in frames if isinstance(f.shape, TriangleMesh)]
        if carriers and contacts is not None:  # the body's points near its own frame's mesh
            contacts.keep_apart(carriers)
        self.bindings.bodies = [
            (dofs, slice(p.offset, p.offset + p.body.n_nodes))
            for p in parts
            if (dofs := self._one(p.node, {"MechanicalObject"}, "MechanicalObjects")) is not None
        ]
        self.bindings.hooks += self._recorded_states(parts, dt)
        self.bindings.rigid = [
            self._one(n, {"MechanicalObject"}, "MechanicalObjects")
            for n in self.root.walk()
            if self._is_rigid(n)
        ]
        self.bindings.carried = self._rigidly_carried(rigid)
        self.bindings.servos = list(self._servos.values())
        self.bindings.frames, k = [], len(rigid)
        for g in self._rigidified:  # the rigid bodies of the free frames follow the others
            entries = []
            for j, (x, r) in g.poses:
                servo = g.driven[j] if g.driven else None
                entries.append((servo if servo is not None else None if g.fixed[j] else k, x, r))
                k += not g.fixed[j]
            self.bindings.frames.append((g.dofs, entries))
        scene = SofaScene(model, dt, solver_kind, self.path, self.root, self.bindings)
        scene.write_outputs(model.rest_state())
        self._default_positions()
        for obj in [o for n in self.root.walk() for o in n.objects if o.type in MESH_LOADERS]:
            try:  # SOFA initialises them: their outputs, for the scripts (Maze's path edges)
                init_loader(obj)
            except SceneError:
                continue  # a mesh the model does not read, not found: as before, unread
        return scene

    def _rigidly_carried(self, rigid: list[RigidBody]) -> list[tuple[SceneObject, int, np.ndarray]]:
        """The points that the rigid bodies' child nodes carry by a ``RigidMapping`` (a
        Goal, a collision surface), each body's in its frame: the child's MechanicalObject's
        points (SOFA's one point at the origin when it gives none and no mesh sizes it, then
        its transform), taken as offsets in the frame, or, with the mapping's
        ``globalToLocalCoords``, as world points brought into the body's first pose."""
        found = []
        for i, dofs in enumerate(self.bindings.rigid[: len(rigid)]):
            if dofs is None or not str(dofs.attrs.get("template", "")).startswith("Rigid3"):
                continue
            for child in dofs.node.children:
                mappings = [o for o in child.objects if o.type == "RigidMapping"]
                points = [o for o in child.objects if o.type == "MechanicalObject"]
                if not mappings or len(points) != 1 or "rigidIndexPerPoint" in mappings[0].attrs:
                    continue
                if not str(points[0].attrs.get("template", "Vec3")).startswith("Vec3"):
                    continue  # a frame carried by the body (Rigid3 to Rigid3): not points
                if int(_float(mappings[0], "index", 0)) != 0:
                    raise SceneError(
                        f"{mappings[0].path}: a rigid body has one frame (index 0), not"
                        f" {mappings[0].attrs['index']}"
                    )
                local = self._own_points(child, points[0])
                if _flag(mappings[0], "globalToLocalCoords", False):
                    local = (local - rigid[i].position) @ rigid[i].rotation
                found.append((points[0], i, local))
        return found

    def _own_points(self, node: SceneNode, dofs: SceneObject) -> np.ndarray:
        """A MechanicalObject's points as SOFA initialises them: its own positions (or its
        mesh's), else ``size`` points (SOFA's default: one) at the origin, transformed."""
        sized = "position" in dofs.attrs or "src" in dofs.attrs
        if sized or any(o.type in MESH_LOADERS for o in node.objects):
            return self._positions(node, dofs)
        if any(o.type in TOPOLOGIES and "position" in o.attrs for o in node.objects):
            raise SceneError(f"{dofs.path}: points given by a topology's position are not read")
        size = int(_float(dofs, "size", 0)) if "size" in dofs.attrs else 0
        return _placed(dofs, np.zeros((max(size, 1), 3)))

    def _default_positions(self) -> None:
        """SOFA's default positions for the Vec3 MechanicalObjects the scene gives none (nor a
        mesh to read): ``size`` points (one unless given) at the origin under the object's
        transform, as scripts then read them (after the model is built: nothing in it reads
        them)."""
        for node in self.root.walk():
            if any(o.type in MESH_LOADERS or o.type in TOPOLOGIES for o in node.objects):
                continue
            for dofs in node.objects:
                if (
                    dofs.type == "MechanicalObject"
                    and "position" not in dofs.attrs
                    and "src" not in dofs.attrs
                    and str(dofs.attrs.get("template", "Vec3")).startswith("Vec3")
                ):
                    dofs.attrs["position"] = _frozen(self._own_points(node, dofs))

    def _scene_time(self) -> tuple[float, np.ndarray]:
        """The root's dt and gravity."""
        dt = float(_floats(self.root.attrs.get("dt", 0.01), "root.dt")[0])
        gravity = _floats(self.root.attrs.get("gravity", "0 -9.81 0"), "root.gravity")
        if gravity.size != 3:
            raise SceneError(f"root.gravity: three values expected, got {gravity.size}")
        return dt, gravity

    def _rigid_scene(self) -> SofaScene:
        """A scene of rigid bodies alone (pliant.sofa.rigid_scene)."""
        dt, gravity = self._scene_time()
        model, dofs, hook = rigid_scene.rigid_model(self, dt, gravity)
        for obj in [o for n in self.root.walk() for o in n.objects if o.type in MESH_LOADERS]:
            init_loader(obj)  # SOFA initialises them: their outputs, for the scripts
        bindings = Bindings(rigid=dofs, hooks=[hook])
        scene = SofaScene(model, dt, "dynamic", self.path, self.root, bindings)
        scene.write_outputs(model.rest_state())
        return scene

    def _check_supported(self) -> None:
        """One error for everything the scene holds that Pliant cannot simulate: components
        it does not have and attributes that are no field of their component (a misspelt
        name, close to one of its fields)."""
        problems = []
        detects = self._detects()
        handled = HANDLED | (rods.COMPONENTS if rods.has_rods(self.root) else frozenset())
        handled |= beams.COMPONENTS if beams.has_beams(self.root) else frozenset()
        if instruments.has_instruments(self.root):  # BeamAdapter's deployed instruments
            handled = handled | instruments.COMPONENTS
        for node in self.root.walk():
            for obj in node.objects:
                if not detects and obj.type.endswith("CollisionModel"):
                    continue
                if obj.type not in handled and obj.type not in IGNORED and not is_visual(obj.type):
                    why = UNSUPPORTED.get(obj.type, "")
                    problems.append(f"{obj.type} (at {node.path}{': ' + why if why else ''})")
                    if not why:  # a component Pliant knows has its data checked too
                        continue
                fields = FIELDS.get(obj.type)
                if fields is None:
                    continue
                for key in obj.attrs:
                    if key in fields or key in _COMMON:
                        continue
                    # A misspelling: a field's name within an edit or two; any other unknown
                    # attribute SOFA only warns about, and so does Pliant: it ignores it.
                    near = [f for f in fields if abs(len(f) - len(key)) <= 2]
                    hint = close_match(key, near, cutoff=0.85)
                    if hint:
                        problems.append(f"{obj.type}.{key} (at {node.path}): no such data{hint}")
        if detects:
            touching = contact_problem(self._deformable_nodes(), COLLISION_MODELS)
            problems += [touching] if touching else []
        if problems:
            raise SceneError(
                f"{self.path.name} uses what Pliant does not support: "
                + "; ".join(problems)
                + " (docs/sofa-reference.md lists what it does)"
            )

    # --- collisions ----------------------------------------------------------------------------
    def _detects(self) -> bool:
        """Whether SOFA detects any collision: it needs an intersection method and collision
        models on two nodes at least (a model does not collide with itself unless asked).
        Otherwise collision models of any shape are inert (SofaGym's goal markers carry a
        sphere model)."""
        if not any(o.type in INTERSECTIONS for n in self.root.walk() for o in n.objects):
            return False
        carriers = [
            [o for o in n.objects if o.type.endswith("CollisionModel")] for n in self.root.walk()
        ]
        carriers = [models for models in carriers if models]
        return len(carriers) >= 2 or any(
            _flag(o, "selfCollision", False) for models in carriers for o in models
        )

    def _collisions(self, parts: list[Part], body: TetBody, mesh: TetMesh):
        """Contacts and rigid bodies from the collision pipeline: the body's collision points
        (a child node with a PointCollisionModel mapped on it), static triangle obstacles (a
        plane where their triangles are coplanar, else a closed triangle mesh; a still
        sphere), and rigid bodies (pliant.sofa.rigids: a Rigid3 MechanicalObject with a
        sphere, a box or a mesh, or a particle ball).
        ``alarmDistance`` is the contact margin, ``contactDistance`` the points' thickness,
        the response's ``mu`` the friction everywhere. Of several deformable bodies, the
        points of one touch the triangles of another (SurfaceContact) where SOFA tests the
        two models against each other (:func:`pliant.sofa.bodies.surface_pairs`), and the
        points (or sphere) of a rigid body touch a body's TriangleCollisionModel
        (RigidSurfaceContact) where they share no ``group``."""
        intersection = [o for n in self.root.walk() for o in n.objects if o.type in INTERSECTIONS]
        models = [o for n in self.root.walk() for o in n.objects if o.type in COLLISION_MODELS]
        if not models or not self._detects():
            return None, []
        proximity = intersection[0]
        margin = _float(proximity, "alarmDistance", 1.0)
        thickness = _float(proximity, "contactDistance", 0.5)
        friction = self._friction()
        self._carried_friction = friction
        rigid_nodes = [n for n in self.root.walk() if self._is_rigid(n)]
        rigid = [self._rigid_body(n, friction) for n in rigid_nodes]
        inside_rigid = {id(c) for n in rigid_nodes for c in n.walk()}
        rigid_models = [
            [o for c in n.walk() for o in c.objects if o.type in COLLISION_MODELS]
            for n in rigid_nodes
        ]
        points, obstacles, joined = [], [], []
        on_bodies: list[tuple[int, SceneObject]] = []  # (part, model) of the bodies' models
        embedded_at: dict[int, EmbeddedPoints] = {}  # a node's collision points
        for node in self.root.walk():
            types = {o.type for o in node.objects}
            if not types & COLLISION_MODELS or id(node) in inside_rigid:
                continue
            part = next((p for p in parts if p.owns(node)), None)
            if part is not None:
                k = parts.index(part)
                on_bodies += [(k, o) for o in node.objects if o.type in COLLISION_MODELS]
                if "PointCollisionModel" not in types:
                    touched = len(parts) > 1 or any(
                        _touches(m, o) for ms in rigid_models for m in ms for o in node.objects
                    )
                    if touched and "TriangleCollisionModel" in types:
                        continue  # another body's or a rigid body's points may touch them
                    raise SceneError(
                        f"{node.path}: the body collides by points only (PointCollisionModel),"
                        f" not by {', '.join(sorted(types & COLLISION_MODELS))}"
                    )
                if node is part.node:  # the body's own nodes collide
                    points.append(part.body.rest_positions)
                    ends = part.offset + np.arange(part.body.n_nodes)
                    joined.append(EmbeddedPoints.at_nodes(ends))
                    embedded_at[id(node)] = joined[-1]
                    continue
                if not types & MAPPINGS:
                    raise SceneError(f"{node.path}: collision points not mapped on the body")
                dofs = self._one(node, {"MechanicalObject"}, "MechanicalObjects")
                points.append(np.unique(self._positions(node, dofs), axis=0))
                self._part = part
                joined.append(self._embed(mesh, points[-1], body))
                self._part = None
                embedded_at[id(node)] = joined[-1]
            elif (carrier := self._moving_carrier(node)) is not None:
                self._carried.append((node, *carrier))  # on a free frame: _free_frames
            else:
                obstacles.append(self._obstacle(node))
        rigid_surfaces = [
            RigidSurfaceContact(
                rigid[r],
                _rigid_points(rigid[r].shape)[0],
                *self._surface(b.node, parts[k], mesh),
                friction=friction,
                distance=thickness,
                radius=_rigid_points(rigid[r].shape)[1],
                name=f"{rigid_nodes[r].path} on {b.node.path}",
            )
            for r, models in enumerate(rigid_models)
            for k, b in on_bodies
            if any(_touches(m, b) for m in models)
        ]
        if not points and rigid_surfaces:  # the body is touched by its triangles only
            joined = [EmbeddedPoints.at_nodes(np.zeros(0, dtype=np.int64))]
            points = [np.zeros((0, 3))]
        if not points:
            models = ", ".join(o.path for _, o in on_bodies)
            raise SceneError(
                f"{self.path.name}: the body has no collision points"
                + (
                    f" (its collision models: {models}; Pliant's bodies touch obstacles and"
                    " rigid bodies by their points)"
                    if models
                    else ""
                )
            )
        surfaces = [
            SurfaceContact(
                embedded_at[id(a.node)],
                *self._surface(b.node, parts[k], mesh),
                friction=friction,
                distance=thickness,
                name=f"{a.node.path} on {b.node.path}",
            )
            for a, b in surface_pairs(on_bodies)
            for k in [next(k for k, o in on_bodies if o is b)]
        ]
        if not obstacles and not rigid and not surfaces:  # SOFA detects nothing: no contact
            return None, []
        if rigid and not obstacles and not rigid_surfaces and not self._carried:
            raise SceneError(f"{self.path.name}: rigid bodies need a static obstacle too")
        embedded = (
            EmbeddedPoints.stack(joined)  # each body's points in its own mesh (or none)
            if len(parts) > 1 or not any(len(p) for p in points)
            else EmbeddedPoints(
                mesh,
                np.vstack(points),
                tolerance=SOFA_REACH * body.extent,
                outside=self.choices.outside,
            )
        )
        contacts = Contacts(
            obstacles,
            friction=friction,
            margin=margin,
            points=embedded,
            thickness=thickness,
            surfaces=surfaces,
            rigid_surfaces=rigid_surfaces,
        )
        return contacts, rigid

    def _surface(
        self, node: SceneNode, part: Part, mesh: TetMesh
    ) -> tuple[EmbeddedPoints, np.ndarray]:
        """The triangles of a body's TriangleCollisionModel, outward, and their vertices as
        points of the body: its own boundary where the model sits on the body's node, else
        the node's mesh carried by a mapping."""
        if id(node) in self._surfaces:  # one surface, touched by several bodies' points
            return self._surfaces[id(node)]
        if node is part.node:
            self._surfaces[id(node)] = (
                EmbeddedPoints.at_nodes(part.offset + np.arange(part.body.n_nodes)),
                part.body.boundary_triangles,
            )
            return self._surfaces[id(node)]
        if not any(o.type in MAPPINGS for o in node.objects):
            raise SceneError(f"{node.path}: collision triangles not mapped on the body")
        dofs = self._one(node, {"MechanicalObject"}, "MechanicalObjects")
        vertices = self._positions(node, dofs)
        faces = self._faces(node)
        if faces.max() >= len(vertices):
            raise SceneError(
                f"{node.path}: triangles index {faces.max()} of {len(vertices)} points"
            )
        tri = vertices[faces]
        if np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() < 0.0:
            faces = faces[:, ::-1]  # a closed surface's triangles turned inwards
        self._part = part
        try:
            embedded = self._embed(mesh, vertices, part.body)
        finally:
            self._part = None
        self._surfaces[id(node)] = (embedded, np.ascontiguousarray(faces))
        return self._surfaces[id(node)]

    def _friction(self) -> float:
        responses = [o for n in self.root.walk() for o in n.objects if o.type in RESPONSES]
        if not responses:
            return 0.0
        params = str(responses[0].attrs.get("responseParams", ""))
        for part in params.replace("&", " ").split():
            key, _, value = part.partition("=")
            if key == "mu":
                return float(_floats(value, f"{responses[0].path}.responseParams")[0])
        return 0.0

    @staticmethod
    def _is_rigid(node: SceneNode) -> bool:
        """A moving rigid body: a Rigid3 MechanicalObject, or a particle ball (a Vec3 one with
        a SphereCollisionModel), whose collision models move (STLIB marks a static one, a
        floor, moving=False and simulated=False)."""
        if is_particle_sphere(node) and not any(o.type in FEM for o in node.objects):
            return particle_moves(node)
        if not _Builder._rigid_dofs(node) or _Builder._is_frames(node):
            return False
        if _Builder._servo_part(node) or any(o.type.endswith("Mapping") for o in node.objects):
            return False  # a servo's part, or a frame carried by another (no state of its own)
        models = [o for n in node.walk() for o in n.objects if o.type in COLLISION_MODELS]
        return not models or any(
            _flag(o, "moving", True) or _flag(o, "simulated", True) for o in models
        )

    @staticmethod
    def _servo_part(node: SceneNode) -> bool:
        """A node of a servo (its body, wheel and arm) or a frame that Rigidify's frames map
        from (their mapping's input): kinematic in Pliant, no rigid body."""
        at: SceneNode | None = node
        while at is not None:
            if any(o.type in ARTICULATED for o in at.objects):
                return True
            siblings = at.parent.children if at.parent is not None else []
            if any(o.type == "ArticulatedHierarchyContainer" for s in siblings for o in s.objects):
                return True
            at = at.parent
        return any(
            o.type == "SubsetMultiMapping" and node.name in str(o.attrs.get("input", ""))
            for n in node.walk()
            for o in n.objects
        )

    @staticmethod
    def _rigid_dofs(node: SceneNode | None) -> SceneObject | None:
        if node is None:
            return None
        return next(
            (
                o
                for o in node.objects
                if o.type == "MechanicalObject"
                and str(o.attrs.get("template", "")).startswith("Rigid3")
            ),
            None,
        )

    @staticmethod
    def _pose(dofs: SceneObject) -> tuple[np.ndarray, np.ndarray]:
        """A Rigid3 MechanicalObject's position and rotation matrix: its `position` (x y z
        and the quaternion x y z w), then its ``rotation2`` (Euler angles, degrees) and
        ``translation2``."""
        pose = _floats(dofs.attrs.get("position", "0 0 0 0 0 0 1"), f"{dofs.path}.position")
        if pose.size != 7:
            raise SceneError(f"{dofs.path}.position: one Rigid3 pose (7 values) expected")
        rotation = Rotation.from_quat(pose[3:])  # SOFA: x y z w, as scipy
        turn = Rotation.from_euler(
            "xyz", _floats(dofs.attrs.get("rotation2", "0 0 0"), f"{dofs.path}.rotation2"), True
        )
        shift = _floats(dofs.attrs.get("translation2", "0 0 0"), f"{dofs.path}.translation2")
        return turn.apply(pose[:3]) + shift, (turn * rotation).as_matrix()

    def _rigid_body(self, node: SceneNode, friction: float) -> RigidBody:
        return rigid_body(self, node, friction)

    def _moving_carrier(self, node: SceneNode) -> tuple[SceneObject, int] | None:
        """The frame (MechanicalObject, index) whose RigidMapping carries a node's collision
        triangles, where that frame moves with the body (Rigidify's frames, or a frame they
        map from: the Tripod's free centre); None for a still frame's or no frame's."""
        parent = node.parent
        maps = [o for o in node.objects if o.type == "RigidMapping"]
        frame = self._rigid_dofs(parent)
        if (
            frame is None
            or len(maps) != 1
            or "TriangleCollisionModel" not in {o.type for o in node.objects}
        ):
            return None
        if not (self._is_frames(parent) or self._servo_part(parent)):
            return None
        link = maps[0].attrs.get("input")
        dofs = frame if link is None else self.link_dofs(node, str(link))
        return (dofs, int(_float(maps[0], "index", 0.0))) if dofs is not None else None

    def _carried_mesh(self, node: SceneNode, dofs: SceneObject, index: int, x, r):
        """The triangles a RigidMapping carries on frame (dofs, index), as a closed mesh in
        the coordinates of the rigid body at (x, r) that moves that frame (its inside read
        from its winding number: SofaGym's maze floor is two coincident sheets)."""
        points = self._positions(node, self._one(node, {"MechanicalObject"}, "MechanicalObjects"))
        position, rotation = rigid_pose(dofs, index)
        local = (points @ rotation.T + position - x) @ r
        faces = self._faces(node)
        if faces.size and faces.max() >= len(local):
            raise SceneError(f"{node.path}: triangles index {faces.max()} of {len(local)} points")
        tri = local[faces]
        if np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() < 0.0:
            faces = faces[:, ::-1]  # a closed surface's triangles turned inwards
        try:
            return TriangleMesh(local, faces, x, r, winding=True, per_face=True)
        except ContactError as exc:
            raise SceneError(f"{node.path}: {exc}") from exc

    def _obstacle(self, node: SceneNode):
        """A static obstacle: a plane where its triangles are coplanar, else a closed mesh."""
        types = {o.type for o in node.objects}
        if SPHERE_MODEL in types:
            return static_sphere(self, node)
        if "TriangleCollisionModel" not in types:
            raise SceneError(f"{node.path}: static obstacles collide by triangles or spheres")
        model = next(o for o in node.objects if o.type == "TriangleCollisionModel")
        if _flag(model, "moving", False) or _flag(model, "simulated", False):
            raise SceneError(f"{node.path}: a moving obstacle needs a body (not supported)")
        dofs = self._one(node, {"MechanicalObject"}, "MechanicalObjects")
        points = self._positions(node, dofs)
        frame = self._rigid_dofs(node.parent)
        if frame is not None and any(o.type == "RigidMapping" for o in node.objects):
            if self._is_frames(node.parent) or self._servo_part(node.parent):
                raise SceneError(
                    f"{node.path}: a collision model carried by a moving frame"
                    f" ({node.parent.path}, Rigidify's or a servo's) is not supported: Pliant's"
                    " moving shapes are rigid bodies (a Rigid3 MechanicalObject with a mass)"
                )
            position, rotation = self._pose(frame)  # a static rigid object: its frame's points
            points = points @ rotation.T + position
        faces = self._faces(node)
        a, b, c = (points[faces[:, k]] for k in range(3))
        normals = np.cross(b - a, c - a)
        normal = normals.sum(axis=0)
        normal /= np.linalg.norm(normal)
        spread = np.abs((points[np.unique(faces)] - a[0]) @ normal).max()
        if spread <= 1e-9 * np.ptp(points, axis=0).max():
            return Plane(normal=normal, point=a[0])
        return TriangleMesh(points, faces)

    def _faces(self, node: SceneNode) -> np.ndarray:
        """The triangles of a node's collision model: its MeshTopology's, or its loader's."""
        topology = self._one(node, {"MeshTopology"}, "topologies")
        given = None if topology is None else topology.attrs.get("triangles")
        if given is not None and not _is_link(given):  # a link: its node's loader's, below
            faces = _floats(topology.attrs["triangles"], f"{topology.path}.triangles")
            return faces.astype(np.int64).reshape(-1, 3)
        loaders = [o for o in node.objects if o.type in MESH_LOADERS]
        if len(loaders) != 1:
            raise SceneError(f"{node.path}: no triangles for its collision model")
        faces = self._loaded(loaders[0])[1].get("triangle")
        if faces is None:
            raise SceneError(f"{node.path}: its mesh holds no triangles")
        return np.asarray(faces, dtype=np.int64).reshape(-1, 3)

    @staticmethod
    def _is_layer(node: SceneNode) -> bool:
        """A second FEM on part of the body's elements (SoftRobots' stiffer layer): a child of
        the body's node with a FEM and a topology of its own but no MechanicalObject (it acts
        on its parent's nodes, SOFA's context)."""
        parent = node.parent
        return (
            parent is not None
            and any(o.type in FEM for o in parent.objects)
            and any(o.type in FEM for o in node.objects)
            and not any(o.type == "MechanicalObject" for o in node.objects)
            and any(o.type in TOPOLOGIES for o in node.objects)
        )

    def _deformable_nodes(self) -> list[SceneNode]:
        return [
            n
            for n in self.root.walk()
            if any(o.type in FEM for o in n.objects)
            and not self._is_layer(n)
            and not is_membrane(n, FEM)
        ]

    def _body_nodes(self) -> list[SceneNode]:
        """The nodes of the scene's deformable bodies; several are joined in one Pliant body
        (:mod:`pliant.sofa.bodies`), without STLIB's Rigidify or self-contact planes."""
        nodes = self._deformable_nodes()
        if not nodes:
            alone = any(self._is_rigid(n) for n in self.root.walk())
            raise SceneError(
                f"{self.path.name} has no deformable body (no TetrahedronFEMForceField or"
                " TetrahedronHyperelasticityFEMForceField)"
                + ("; a Pliant model needs one beside its rigid bodies" if alone else "")
            )
        if len(nodes) > 1:
            found = [
                f"{o.type} (at {n.path})"
                for n in self.root.walk()
                for o in n.objects
                if o.type == PLANE_CONSTRAINT
                or (o.type == "SubsetMultiMapping" and any(n is b for b in nodes))
            ]
            if found:
                raise SceneError(
                    f"{self.path.name} has {len(nodes)} deformable bodies"
                    f" ({', '.join(n.path for n in nodes)}), which Pliant joins in one body"
                    " without STLIB's Rigidify or UnilateralPlaneConstraint: " + "; ".join(found)
                )
        return nodes

    def _one(self, node: SceneNode, types: frozenset[str] | set[str], what: str):
        found = [o for o in node.objects if o.type in types]
        if len(found) > 1:
            raise SceneError(f"{node.path}: several {what} ({', '.join(o.name for o in found)})")
        return found[0] if found else None

    def _resolve_file(self, obj: SceneObject) -> Path:
        name = str(obj.attrs.get("filename", ""))
        if not name:
            raise SceneError(f"{obj.path}: no filename")
        candidates = [self.path.parent / name, Path(name)]
        for d in self.mesh_dirs:
            candidates += [d / name, d / Path(name).name]
        for c in candidates:
            if c.is_file():
                return c
        raise SceneError(
            f"{obj.path}: mesh file {name!r} not found beside the scene"
            + (f" nor in {', '.join(map(str, self.mesh_dirs))}" if self.mesh_dirs else "")
            + " (pass mesh_dirs, or set SOFA_DATA_PATH or SOFA_ROOT as for SOFA)"
        )

    # --- the deformable body ----------------------------------------------------------------
    def _body(self, node: SceneNode, gravity: np.ndarray) -> tuple[TetBody, TetMesh, str]:
        fem = self._one(node, FEM, "FEM force fields")
        membranes = [c for c in node.children if is_membrane(c, FEM)]
        if membranes and fem.type == HEXAHEDRA:
            raise SceneError(
                f"{membranes[0].path}: a membrane of triangles on a hexahedral body's nodes is"
                " not supported (on a body of tetrahedra it is)"
            )
        if fem.type == HEXAHEDRA:
            springs = [
                o for c in node.walk() for o in c.objects if o.type == "MeshSpringForceField"
            ]
            if springs:
                raise SceneError(f"{springs[0].path}: springs on a hexahedral body's points")
            return hex_body(self, node, fem, gravity)
        if fem.type == TRIANGLE_FEM:  # a shell of triangles (pliant.sofa.shells)
            return shell_body(self, node, fem, gravity)
        split = grid_tetrahedra(self, node)  # a grid's cells cut in tetrahedra
        points, tets = split if split is not None else self._read_mesh(self._mesh_loader(node))
        if fem.type == HYPERELASTIC:
            material: Material = self._hyperelastic(fem)
            rotation = "none"
        else:
            default = "qr" if fem.type == FAST_COROTATIONAL else "large"
            method = str(fem.attrs.get("method", default)).lower()
            if method not in ROTATIONS:
                raise SceneError(
                    f"{fem.path}: method {method!r} is not supported"
                    f" ({', '.join(sorted(ROTATIONS))})"
                )
            large = ROTATIONS[method] == "large" and self.choices.rotation == "scene"
            rotation = "large" if large else "polar"
            material = Corotational(
                _float(fem, "youngModulus", 5000.0),
                _float(fem, "poissonRatio", 0.45),
                rotation,
                # the polar frame of an inverted element is a reflection: refused whatever
                inversion=self.choices.inversion if large else "refuse",
            )
        # SOFA takes elements in either orientation; Pliant's are positive. The "large" frame
        # stays the file's first three nodes of each element.
        frame_nodes = tets[:, :3].copy()
        negative = signed_volumes(points, tets) < 0.0
        tets[negative] = tets[negative][:, [0, 2, 1, 3]]
        mesh = TetMesh(points, tets)
        layers = self._layers(node, fem, mesh)
        mass_kwargs = self._mass(node, points.shape[0])
        solver_kind, rayleigh = self._ode_solver(node)
        fixed = np.union1d(self._fixed_nodes(node, points), self._held_groups(node, points))
        springs, carried_mass = self._mesh_springs(node, mesh)
        body = TetBody(
            mesh,
            material,
            membranes=[membrane(self, c, mesh.points, mesh.tets) for c in membranes],
            fixed_nodes=fixed,
            fixed_dofs=self._fixed_components(node, points),
            frame_nodes=frame_nodes if rotation == "large" else None,
            loads=self._loads(node, points) + springs,
            projections=self._projections(node, points),
            gravity=tuple(gravity),
            rayleigh_mass=rayleigh[0],
            rayleigh_stiffness=rayleigh[1],
            **mass_kwargs,
        )
        check_held_if_massless(node, body)
        if carried_mass is not None:
            if body.massless:
                raise SceneError(
                    f"{node.path}: a mass on points mapped on a body that has none (no mass"
                    " component on the body's node): give the body a mass"
                )
            if body.mass_type == "consistent":
                raise SceneError(
                    f"{node.path}: a mass on points mapped on the body adds to its nodes' masses"
                    " (a diagonal mass): the body's MeshMatrixMass must be lumped"
                )
            body.set_node_masses(body.node_masses + carried_mass)
        for elements, (mu, lam) in layers:  # the same law: its parameters add up
            body.mu[elements] += mu
            body.lam[elements] += lam
        if layers:
            body.changed()
        return body, mesh, solver_kind

    def _recorded_states(self, parts: list[Part], dt: float) -> list[RecordedStates]:
        """A hook per ReadState on a body's node (pliant.sofa.states); one elsewhere is refused."""
        hooks = []
        for node in self.root.walk():
            for obj in node.objects:
                if obj.type != "ReadState":
                    continue
                part = next((p for p in parts if p.node is node), None)
                if part is None:
                    raise SceneError(
                        f"{obj.path}: Pliant reads a state file into a deformable body's node"
                        " only (its MechanicalObject)"
                    )
                if _float(obj, "interval", 0.0) != 0.0:
                    raise SceneError(f"{obj.path}.interval: only 0 (every record) is supported")
                n = part.body.n_nodes
                records = read_records(self._resolve_file(obj), n, obj.path)
                rows = slice(part.offset, part.offset + n)
                hooks.append(RecordedStates(records, _float(obj, "shift", 0.0), dt, rows))
        return hooks

    def _mesh_springs(self, node: SceneNode, mesh: TetMesh) -> tuple[list, np.ndarray | None]:
        """MeshSpringForceFields on points the body carries (nodes under `node` with a
        BarycentricMapping): springs on their topology's edges, rest lengths the edges' first
        lengths (:class:`~pliant.fem.loads.EmbeddedSprings`); and those points' UniformMass
        added to the body's nodes through their weights: the mapped mass m w w^T (SOFA's
        J^T M J) lumped by HRZ, w_a^2 / sum w^2 of m on node a, positive and summing to m
        where the weights of a point kept outside the mesh are negative (row sums would not)."""
        springs, extra = [], None
        for child in node.walk():
            fields = [o for o in child.objects if o.type == "MeshSpringForceField"]
            if child is node or not fields:
                continue
            mapping = next((o for o in child.objects if o.type in MAPPINGS), None)
            dofs = self._one(child, {"MechanicalObject"}, "MechanicalObjects")
            if mapping is None or mapping.type != "BarycentricMapping" or dofs is None:
                raise SceneError(
                    f"{fields[0].path}: springs on points without a BarycentricMapping to the"
                    f" body {node.path}"
                )
            self._springs_read.update(id(o) for o in fields)
            topology = next((o for o in child.objects if "edges" in o.attrs), None)
            if topology is None:
                raise SceneError(f"{fields[0].path}: no topology with edges in {child.path}")
            cells = [
                k for k in ("triangles", "quads", "tetrahedra", "hexahedra") if k in topology.attrs
            ]
            if cells:
                raise SceneError(
                    f"{fields[0].path}: springs on the edges of {cells[0]} too (SOFA adds them);"
                    " Pliant reads a topology of edges only"
                )
            source = dofs if "position" in dofs.attrs else topology
            points = self._positions(child, source)
            edges = _floats(topology.attrs["edges"], f"{topology.path}.edges").astype(np.int64)
            edges, lengths = _edge_lengths(points, edges, topology.path)
            extent = float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
            embedded = EmbeddedPoints(
                mesh, points, tolerance=SOFA_REACH * extent, outside=self.choices.outside
            )
            for obj in fields if _flag(mapping, "mapForces", True) else []:
                damping = _float(obj, "linesDamping", _float(obj, "damping", 0.0))
                if damping != 0.0:
                    raise SceneError(
                        f"{obj.path}: damping {damping:g}: Pliant's springs have none (give 0)"
                    )
                if "stiffness" not in obj.attrs and "linesStiffness" not in obj.attrs:
                    raise SceneError(f"{obj.path}: give the springs' stiffness")
                k = _float(obj, "linesStiffness", _float(obj, "stiffness", 0.0))
                try:
                    springs.append(
                        EmbeddedSprings(
                            embedded.nodes,
                            embedded.weights,
                            edges,
                            k,
                            rest_lengths=lengths,
                        )
                    )
                except ModelError as exc:
                    raise SceneError(f"{obj.path}: {exc}") from exc
            mass = next((o for o in child.objects if o.type == "UniformMass"), None)
            if mass is not None and _flag(mapping, "mapMasses", True):
                each = (
                    _float(mass, "totalMass", 0.0) / len(points)
                    if "totalMass" in mass.attrs
                    else _float(mass, "vertexMass", 1.0)
                )
                extra = np.zeros(mesh.n_nodes) if extra is None else extra
                np.add.at(extra, embedded.nodes.ravel(), each * _hrz_shares(embedded.weights))
        return springs, extra

    def _layers(self, node: SceneNode, fem: SceneObject, mesh: TetMesh) -> list:
        """The body's stiffer layers (see :meth:`_is_layer`): for each, its elements among
        the body's and the Lame parameters its FEM adds there. Two FEMs of the same law (and,
        corotational, the same frame) on an element sum to that law with the sum of their mu
        and lambda: every law Pliant has is linear in them (the corotational force is R K0
        (X - R^T x), K0 linear in mu and lambda; NeoHookean's and St Venant-Kirchhoff's
        energies are too). The layer's tetrahedra are its topology's (given, or a BoxROI's
        ``tetrahedraInROI``: those whose centre is in a box, or all of whose nodes are with
        ``strict``)."""
        layers = []
        for child in [c for c in node.children if self._is_layer(c)]:
            own = self._one(child, FEM, "FEM force fields")
            if own.type != fem.type or own.type == HEXAHEDRA:
                raise SceneError(f"{own.path}: a layer's FEM is the body's ({fem.type}) in Pliant")
            keys = ("method", "materialName")
            if any(
                str(own.attrs.get(k, "")).lower() != str(fem.attrs.get(k, "")).lower() for k in keys
            ):
                raise SceneError(f"{own.path}: a layer's method and material are the body's")
            topology = self._one(child, TOPOLOGIES, "topologies")
            tets = self._layer_tets(child, topology, mesh)
            index = {tuple(sorted(t)): k for k, t in enumerate(mesh.tets.tolist())}
            elements = np.array([index.get(tuple(sorted(t)), -1) for t in tets.tolist()], np.int64)
            if (elements < 0).any():
                raise SceneError(f"{topology.path}: the layer's tetrahedra are not the body's")
            if fem.type == HYPERELASTIC:
                material = self._hyperelastic(own)
            else:
                material = Corotational(
                    _float(own, "youngModulus", 5000.0), _float(own, "poissonRatio", 0.45)
                )
            layers.append((elements, (material.mu, material.lam)))
        return layers

    def _layer_tets(self, node: SceneNode, topology: SceneObject, mesh: TetMesh) -> np.ndarray:
        value = topology.attrs.get("tetrahedra", topology.attrs.get("tetras", ""))
        if not _is_link(value):
            return _floats(value, f"{topology.path}.tetrahedra").astype(np.int64).reshape(-1, 4)
        box = self.link(node, value)
        if box is None or box.type != "BoxROI" or not str(value).endswith("tetrahedraInROI"):
            raise SceneError(
                f"{topology.path}.tetrahedra: {value!r} is no BoxROI's tetrahedraInROI"
            )
        strict = _flag(box, "strict", True)
        if strict:
            inside = np.zeros(mesh.n_nodes, dtype=bool)
            inside[self._box_nodes(box, mesh.points)] = True
            chosen = inside[mesh.tets].all(axis=1)
        else:
            centres = mesh.points[mesh.tets].mean(axis=1)
            chosen = np.zeros(len(centres), dtype=bool)
            chosen[self._box_nodes(box, centres)] = True
        return mesh.tets[chosen]

    def _hyperelastic(self, fem: SceneObject) -> Material:
        """SOFA's TetrahedronHyperelasticityFEMForceField: ``materialName`` (SOFA's default
        is ArrudaBoyce) and ``ParameterSet``. SOFA's NeoHookean is Bonet and Wood's
        compressible law, psi = mu/2 (tr C - 3) - mu ln J + lambda/2 (ln J)^2, with
        ParameterSet = "mu lambda" (the Lame parameters): Pliant's NeoHookean, given the same
        mu and lambda through E = mu (3 lambda + 2 mu) / (lambda + mu), nu = lambda / (2
        (lambda + mu)). SOFA's StVenantKirchhoff, psi = lambda/2 tr(E)^2 + mu E:E with
        ParameterSet = "mu lambda", is Pliant's StVenantKirchhoff with the same mu and lambda."""
        name = str(fem.attrs.get("materialName", "ArrudaBoyce"))
        if name not in HYPERELASTIC_MATERIALS:
            raise SceneError(
                f"{fem.path}: materialName {name!r} has no Pliant law (supported:"
                f" {', '.join(HYPERELASTIC_MATERIALS)}; SOFA's default is ArrudaBoyce)"
            )
        law, wanted = HYPERELASTIC_MATERIALS[name]
        params = _floats(fem.attrs.get("ParameterSet", ""), f"{fem.path}.ParameterSet")
        if params.size != len(wanted):
            raise SceneError(
                f"{fem.path}.ParameterSet: {name} takes {len(wanted)} values"
                f" ({' '.join(wanted)}), got {params.size}"
            )
        mu, lam = params
        if not (mu > 0.0 and lam >= 0.0):
            raise SceneError(f"{fem.path}.ParameterSet: mu > 0 and lambda >= 0, got {mu}, {lam}")
        return law(mu * (3.0 * lam + 2.0 * mu) / (lam + mu), lam / (2.0 * (lam + mu)))

    def _mesh_loader(self, node: SceneNode) -> SceneObject:
        """The loader the body's topology reads (``src="@loader"``), or the node's only one;
        else the same in the nearest ancestor (SOFA's context: a topology above the body's
        node serves it)."""
        at: SceneNode | None = node
        while at is not None:
            for obj in at.objects:
                if obj.type not in ("MeshTopology", "TetrahedronSetTopologyContainer"):
                    continue
                for key in ("src", "tetrahedra", "tetras", "position"):
                    if _is_link(obj.attrs.get(key)):
                        found = self.link(at, obj.attrs[key])
                        if found is not None and found.type in MESH_LOADERS:
                            return found
            loader = self._one(at, MESH_LOADERS, "mesh loaders")
            if loader is not None:
                return loader
            at = at.parent
        raise SceneError(f"{node.path}: the body has no mesh loader (MeshVTKLoader, ...)")

    def link(self, node: SceneNode, link: str) -> SceneObject | None:
        """The component a link such as ``@loader``, ``@boxROI.indices``, ``@../loader`` or
        ``@../../goal/goalMO.position`` names: by its path from `node` (or from the root for
        ``@/...``) where the path leads to it, else by its name here or in an ancestor."""
        path = link.strip().lstrip("@")
        parts = path.split("/")
        target = parts[-1].split(".")[0]
        at: SceneNode | None = self.root if path.startswith("/") else node
        for part in parts[:-1]:
            if at is None:
                break
            if part == "..":
                at = at.parent
            elif part not in ("", "."):
                # a node a script moved elsewhere (SOFA's nodes may have several parents)
                at = next((c for c in at.children if c.name == part), None) or next(
                    (n for n in self.root.walk() if n.name == part), None
                )
        if at is not None and len(parts) > 1:
            found = next((o for o in at.objects if o.name == target), None)
            if found is not None:
                return found
        return node.find(target)

    def _loaded(self, loader: SceneObject) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The loader's points (transformed as SOFA's MeshLoader does: scale, then rotation,
        then translation) and its cells by type, in the file's order. A SOFA shared mesh
        (``mesh/cube.obj``, which SOFA finds in its own share folder) not beside the scene is
        the one STLIB's prefabs write out (:data:`pliant.sofa.prefabs.stlib.SHARED_MESHES`)."""
        try:
            file = self._resolve_file(loader)
        except SceneError:
            name = str(loader.attrs.get("filename", "")).replace("\\", "/")
            if name not in SHARED_MESHES:
                raise
            points, faces = SHARED_MESHES[name]
            triangles = np.asarray(faces, dtype=np.int64)
            return _placed(loader, np.asarray(points, dtype=float)), {"triangle": triangles}
        try:
            with warnings.catch_warnings():
                # meshio sniffs an ASCII STL as binary first, with an integer overflow warning.
                warnings.simplefilter("ignore", RuntimeWarning)
                # SOFA's MeshVTKLoader reads XML files (VTU) under the .vtk name too.
                xml = file.suffix == ".vtk" and file.read_bytes()[:64].lstrip().startswith(b"<")
                if file.suffix.lower() == ".obj":
                    raw = _read_obj(file)
                elif loader.type == "GIDMeshLoader":
                    raw = _read_gid(file)
                else:
                    raw = read_meshio(file, file_format="vtu" if xml else None)
        except Exception as exc:  # meshio reports malformed files with many exception types
            raise SceneError(f"{loader.path}: cannot read {str(file)!r}: {exc}") from exc
        cells: dict[str, list[np.ndarray]] = {}
        for block in raw.cells:
            cells.setdefault(block.type, []).append(np.asarray(block.data, dtype=np.int64))
        points = _placed(loader, np.asarray(raw.points, dtype=float))
        return points, {k: np.concatenate(v) for k, v in cells.items()}

    def _read_mesh(self, loader: SceneObject) -> tuple[np.ndarray, np.ndarray]:
        """The loader's points and tetrahedra, in the file's order."""
        points, cells = self._loaded(loader)
        file = Path(str(loader.attrs.get("filename", "")))
        tets = [cells["tetra"]] if "tetra" in cells else []
        if not tets:
            raise SceneError(f"{loader.path}: {file.name} holds no tetrahedra")
        tets = np.concatenate(tets).astype(np.int64)
        unused = points.shape[0] - np.unique(tets).size
        if unused:
            raise SceneError(
                f"{loader.path}: {unused} nodes of {file.name} belong to no tetrahedron (SOFA"
                " would simulate them as free particles); remove them from the mesh"
            )
        return points, tets

    def body_options(self, node: SceneNode, points: np.ndarray, gravity) -> tuple[dict, str]:
        """The keywords of a body of elements (BodyOptions) that a node's components give:
        held nodes and DoFs, loads, projections, gravity, its solver's Rayleigh damping and
        its mass; and the solver kind."""
        solver_kind, rayleigh = self._ode_solver(node)
        options = {
            "fixed_nodes": self._fixed_nodes(node, points),
            "fixed_dofs": self._fixed_components(node, points),
            "loads": self._loads(node, points),
            "projections": self._projections(node, points),
            "gravity": tuple(gravity),
            "rayleigh_mass": rayleigh[0],
            "rayleigh_stiffness": rayleigh[1],
            **self._mass(node, points.shape[0]),
        }
        return options, solver_kind

    def _mass(self, node: SceneNode, n_nodes: int) -> dict:
        mass = self._one(node, {"UniformMass", "MeshMatrixMass"}, "masses")
        if mass is None:
            # SOFA: no mass component, no mass term and no weight (the implicit step is then
            # a damped Newton step towards equilibrium; the static solve never reads a mass).
            return {"mass": "none"}
        if mass.type == "UniformMass":
            if "totalMass" in mass.attrs:
                return {"mass": "uniform", "total_mass": _float(mass, "totalMass", 1.0)}
            return {"mass": "uniform", "total_mass": n_nodes * _float(mass, "vertexMass", 1.0)}
        kind = "lumped" if _flag(mass, "lumping", False) else "consistent"
        if "totalMass" in mass.attrs:
            return {"mass": kind, "total_mass": _float(mass, "totalMass", 1.0)}
        return {"mass": kind, "density": _float(mass, "massDensity", 1.0)}

    def _ode_solver(self, node: SceneNode) -> tuple[str, tuple[float, float]]:
        """The solver of the body's node or of its nearest ancestor that has one."""
        at: SceneNode | None = node
        while at is not None:
            solver = self._one(at, {"EulerImplicitSolver", "StaticSolver"}, "ODE solvers")
            if solver is not None:
                if solver.type == "StaticSolver":
                    return "static", (0.0, 0.0)
                if _flag(solver, "firstOrder", False):
                    return "first-order", (0.0, 0.0)  # SOFA ignores Rayleigh damping there
                return "dynamic", (
                    _float(solver, "rayleighMass", 0.0),
                    _float(solver, "rayleighStiffness", 0.0),
                )
            at = at.parent
        raise SceneError(f"{node.path}: no ODE solver (EulerImplicitSolver or StaticSolver)")

    def _indices(self, node: SceneNode, obj: SceneObject, key: str, points: np.ndarray):
        value = obj.attrs.get(key)
        if value is None:
            return None
        if _is_link(value):
            source = self.link(node, value)
            if source is None or source.type not in ROIS:
                raise SceneError(f"{obj.path}.{key}: {value!r} names no BoxROI or SphereROI")
            owner = source.node
            dofs = self._one(owner, {"MechanicalObject"}, "MechanicalObjects")
            if dofs is not None and not _within(owner, node):
                # Another body's ROI (a gripper's fingers sharing the first's): SOFA selects
                # in its own node's points and uses the indices as they are.
                points = self._positions(owner, dofs)
            return self._roi_nodes(source, points)
        return _floats(value, f"{obj.path}.{key}").astype(np.int64)

    def _roi_nodes(self, roi: SceneObject, points: np.ndarray) -> np.ndarray:
        """The nodes a BoxROI or SphereROI selects."""
        return self._box_nodes(roi, points) if roi.type == "BoxROI" else _sphere_nodes(roi, points)

    def _box_nodes(self, box: SceneObject, points: np.ndarray) -> np.ndarray:
        """Nodes inside any of the BoxROI's boxes (xmin ymin zmin xmax ymax zmax each)."""
        oriented = _floats(box.attrs.get("orientedBox", ""), f"{box.path}.orientedBox")
        if oriented.size % 10:
            raise SceneError(f"{box.path}.orientedBox: groups of ten numbers expected")
        inside = [_in_oriented_box(points, o) for o in oriented.reshape(-1, 10)]
        values = _floats(box.attrs.get("box", ""), f"{box.path}.box")
        if values.size == 0 and inside:
            return np.unique(np.concatenate(inside))
        if values.size == 0 or values.size % 6:
            raise SceneError(f"{box.path}.box: groups of six numbers expected")
        # SOFA orders each axis of a box itself: corners may come max-first.
        boxes = np.sort(values.reshape(-1, 2, 3), axis=1)
        found = [nodes_in_box(points, b) for b in boxes] + inside
        return np.unique(np.concatenate(found))

    @staticmethod
    def _context(node: SceneNode) -> list[SceneObject]:
        """The components acting on `node`'s degrees of freedom: its own and those of its
        descendants that have no MechanicalObject of their own (SOFA's context: STLIB's
        FixedBox is such a child)."""
        found = list(node.objects)
        for child in node.children:
            if not any(o.type == "MechanicalObject" for o in child.objects):
                found += _Builder._context(child)
        return found

    def _fixed_nodes(self, node: SceneNode, points: np.ndarray) -> np.ndarray:
        fixed = [np.zeros(0, dtype=np.int64)]
        for obj in self._context(node):
            if obj.type in ("FixedConstraint", "FixedProjectiveConstraint"):
                if _flag(obj, "fixAll", False):
                    fixed.append(np.arange(points.shape[0]))
                    continue
                idx = self._indices(obj.node, obj, "indices", points)
                if idx is None:
                    raise SceneError(f"{obj.path}: no indices")
                fixed.append(idx)
        return np.unique(np.concatenate(fixed))

    def _fixed_components(self, node: SceneNode, points: np.ndarray) -> np.ndarray:
        dofs = [np.zeros(0, dtype=np.int64)]
        for obj in self._context(node):
            if obj.type in ("PartialFixedConstraint", "PartialFixedProjectiveConstraint"):
                idx = self._indices(obj.node, obj, "indices", points)
                if idx is None or _flag(obj, "fixAll", False):
                    idx = np.arange(points.shape[0])
                axes = _floats(obj.attrs.get("fixedDirections", "1 1 1"), f"{obj.path}")
                dofs.append(fixed_components(idx, tuple(bool(a) for a in axes)))
        return np.concatenate(dofs)

    def _projections(self, node: SceneNode, points: np.ndarray) -> list[Projection]:
        """ProjectToPlane/LineConstraint: nodes that slide on the plane through `origin` with
        `normal`, or on the line through it along `direction`. SOFA moves a node that is off
        it there at the start; Pliant asks for a mesh whose nodes lie on it."""
        found: list[Projection] = []
        size = float(np.linalg.norm(np.ptp(points, axis=0)))
        for obj in self._context(node):
            if obj.type not in PROJECTIONS:
                continue
            key, kind = PROJECTIONS[obj.type]
            idx = self._indices(obj.node, obj, "indices", points)
            if idx is None:
                raise SceneError(f"{obj.path}: no indices")
            default = "0 0 1" if key == "normal" else "1 0 0"
            axis = _floats(obj.attrs.get(key, default), f"{obj.path}.{key}")
            origin = _floats(obj.attrs.get("origin", "0 0 0"), f"{obj.path}.origin")
            try:
                projection = kind(idx, axis)
                projection.check_on(points, origin, tolerance=1e-9 * size)
            except ModelError as exc:
                raise SceneError(f"{obj.path}: {exc}") from exc
            found.append(projection)
        return found

    def _loads(self, node: SceneNode, points: np.ndarray) -> list[Load]:
        loads: list[Load] = []
        for obj in self._context(node):
            if obj.type not in ("ConstantForceField", "RestShapeSpringsForceField"):
                continue
            key = "indices" if obj.type == "ConstantForceField" else "points"
            idx = self._indices(obj.node, obj, key, points)
            idx = np.arange(points.shape[0]) if idx is None else idx
            if obj.type == "RestShapeSpringsForceField":
                if "external_rest_shape" in obj.attrs:
                    raise SceneError(f"{obj.path}: external_rest_shape is not supported")
                k = _floats(obj.attrs.get("stiffness", "1"), f"{obj.path}.stiffness")
                loads.append(RestShapeSprings(idx, points, k if k.size > 1 else k[0]))
            elif "forces" in obj.attrs:
                forces = _floats(obj.attrs["forces"], f"{obj.path}.forces").reshape(-1, 3)
                loads.append(NodalForces(idx, forces if len(forces) > 1 else forces[0]))
            elif "totalForce" in obj.attrs:
                total = _floats(obj.attrs["totalForce"], f"{obj.path}.totalForce")
                loads.append(NodalForces(idx, total / idx.size))
            else:
                force = _floats(obj.attrs.get("force", "0 0 0"), f"{obj.path}.force")
                loads.append(NodalForces(idx, force))
        return loads

    # --- STLIB's Rigidify ------------------------------------------------------------------------
    @staticmethod
    def _is_frames(node: SceneNode) -> bool:
        """Rigidify's ``RigidParts``: Rigid3 frames carrying a child's points by a RigidMapping
        with ``rigidIndexPerPoint``."""
        return any(
            o.type == "RigidMapping" and "rigidIndexPerPoint" in o.attrs
            for child in node.children
            for o in child.objects
        )

    def _groups(self, body_node: SceneNode, points: np.ndarray) -> list[_Frames]:
        """The rigidified groups of the body's nodes (STLIB's Rigidify), read once: its
        SubsetMultiMapping's second input is the groups' points, carried by the frames of
        their parent node. A frame's position is the group's barycentre unless given, its
        orientation Euler angles in degrees (x, y, z about fixed axes, as STLIB's
        ``Quat.createFromEuler``) or a quaternion x y z w; a frame with a FixedConstraint is
        held, with its nodes."""
        if hasattr(self, "_rigidified"):
            return self._rigidified
        self._rigidified: list[_Frames] = []
        for mapping in [o for o in body_node.objects if o.type == "SubsetMultiMapping"]:
            links = mapping.attrs.get("input", "")
            links = links.split() if isinstance(links, str) else [str(v) for v in links]
            carried = self.link(body_node, links[1]) if len(links) == 2 else None
            frames_node = None if carried is None else carried.node.parent
            rigid_map = (
                None
                if carried is None
                else self._one(carried.node, {"RigidMapping"}, "RigidMappings")
            )
            frames = self._rigid_dofs(frames_node)
            if rigid_map is None or frames is None:
                raise SceneError(
                    f"{mapping.path}.input: the free nodes, then nodes carried by Rigid3 frames"
                    f" (STLIB's Rigidify), got {links!r}"
                )
            owner = f"Rigidify (at {frames_node.parent.path})"
            per_point = _floats(
                rigid_map.attrs["rigidIndexPerPoint"], f"{rigid_map.path}.rigidIndexPerPoint"
            ).astype(np.int64)
            if "rigidified" in mapping.attrs:
                chosen = _floats(mapping.attrs["rigidified"], f"{owner}.groupIndices")
            else:  # SOFA's pairs (input, index) for each of the body's nodes
                pairs = _floats(mapping.attrs.get("indexPairs", ""), f"{mapping.path}.indexPairs")
                pairs = pairs.astype(np.int64).reshape(-1, 2)
                chosen = np.empty(int((pairs[:, 0] == 1).sum()))
                chosen[pairs[pairs[:, 0] == 1, 1]] = np.flatnonzero(pairs[:, 0] == 1)
            chosen = chosen.astype(np.int64)
            if chosen.size != per_point.size:
                raise SceneError(
                    f"{rigid_map.path}.rigidIndexPerPoint: {per_point.size} frames for"
                    f" {chosen.size} rigidified nodes"
                )
            if chosen.size and (chosen.min() < 0 or chosen.max() >= len(points)):
                bad = chosen[(chosen < 0) | (chosen >= len(points))][0]
                raise SceneError(
                    f"{owner}.groupIndices: node {bad} outside the body's {len(points)} nodes"
                )
            poses = self._frame_poses(frames, owner, chosen, per_point, points)
            held = np.zeros(len(poses), dtype=bool)
            driven: list = [None] * len(poses)
            origins: list = [None] * len(poses)
            for obj in frames_node.objects:
                if obj.type in ("SubsetMultiMapping", "RigidMapping"):  # from servos, frames
                    self._mapped_frames(obj, poses, held, driven, origins)
                elif obj.type in ("FixedConstraint", "FixedProjectiveConstraint"):
                    idx = _floats(obj.attrs.get("indices", ""), f"{obj.path}.indices")
                    held[idx.astype(np.int64)] = True
                    held |= _flag(obj, "fixAll", False)
                elif obj.type != "MechanicalObject" and not is_visual(obj.type):
                    raise SceneError(
                        f"{obj.path}: Rigidify's frames hold a FixedConstraint only in Pliant,"
                        f" not a {obj.type}"
                    )
            groups = [chosen[per_point == j] for j in range(len(poses))]
            self._rigidified.append(
                _Frames(frames, groups, list(enumerate(poses)), held, driven, origins)
            )
        return self._rigidified

    def _mapped_frames(
        self, mapping: SceneObject, poses: list, held, driven: list, origins: list
    ) -> None:
        """Rigidify's frames given by a SubsetMultiMapping (``input``: Rigid3 frames, in
        ``indexPairs`` (input, index) for each frame): the wheel of a servo (its frame 1) turns
        its frame, the servo's base (frame 0) holds it, and any other Rigid3 frame (the
        Tripod's free centre) places a free frame."""
        links = mapping.attrs.get("input", "")
        links = links.split() if isinstance(links, str) else [str(v) for v in links]
        sources = [self.link_dofs(mapping.node, link) for link in links]
        if mapping.type == "RigidMapping":  # every frame from the input's frame `index`
            index = int(_float(mapping, "index", 0.0))
            pairs = np.array([[0, index]] * len(poses), dtype=np.int64)
        else:
            pairs = _floats(mapping.attrs.get("indexPairs", ""), f"{mapping.path}.indexPairs")
            pairs = pairs.astype(np.int64).reshape(-1, 2)
        if len(pairs) != len(poses) or any(
            k < 0 or k >= len(sources) or sources[k] is None for k, _ in pairs
        ):
            raise SceneError(
                f"{mapping.path}: one (input, index) pair of indexPairs for each of the"
                f" {len(poses)} frames, each input a Rigid3 MechanicalObject"
            )
        for j, (k, i) in enumerate(pairs):
            dofs, i = self._frame_source(sources[k], int(i))
            servo = self._servos.get(id(dofs.node))
            if servo is not None and i == 1:
                driven[j], held[j] = servo, True
                poses[j] = servo.carrier.pose(0.0)
            elif servo is not None:
                held[j] = True
                poses[j] = servo._base_pose
            else:
                poses[j] = rigid_pose(dofs, int(i))
                origins[j] = (dofs, int(i))
                held[j] = any(
                    o.type in ("FixedConstraint", "FixedProjectiveConstraint")
                    for o in dofs.node.objects
                )

    def _frame_source(self, dofs: SceneObject, index: int) -> tuple[SceneObject, int]:
        """The frame that moves a Rigid3 frame: itself, or, through the RigidMappings that
        carry it (a servo's arm on its wheel), the frame they map it from. A constant offset
        changes nothing: the nodes follow the same rigid motion."""
        for _ in range(16):
            if id(dofs.node) in self._servos:
                return dofs, index
            mappings = [o for o in dofs.node.objects if o.type == "RigidMapping"]
            link = mappings[0].attrs.get("input") if mappings else None
            if link is None and mappings:
                link = "@.."  # SOFA's default input: the parent's state
            source = self.link_dofs(dofs.node, str(link)) if link is not None else None
            if source is None:
                return dofs, index
            dofs, index = source, int(_float(mappings[0], "index", 0.0))
        return dofs, index

    def link_dofs(self, node: SceneNode, link: str) -> SceneObject | None:
        """The MechanicalObject a mapping's input names: a node's, or a component. A path
        from the root of a part built apart ("@/Tripod/..." before the Tripod joined the
        scene) names the one node whose path ends so."""
        path = str(link).strip().lstrip("@")
        found = linked_dofs(node, path)
        if found is None and path.startswith("/"):
            tail = "/" + path.strip("/")
            ends = [n for n in self.root.walk() if n.sofa_path.endswith(tail)]
            if len(ends) == 1:
                return ends[0].getMechanicalState()
            head, _, name = tail.rpartition("/")  # a component's path
            ends = [n for n in self.root.walk() if n.sofa_path.endswith(head)]
            objects = [o for n in ends for o in n.objects if o.name == name]
            if len(objects) == 1 and objects[0].type == "MechanicalObject":
                return objects[0]
        return found

    def _frame_poses(self, frames, owner, chosen, per_point, points) -> list:
        """(index, position, rotation) of each frame (see :meth:`_groups`)."""
        if "position" in frames.attrs:
            pose = _floats(frames.attrs["position"], f"{frames.path}.position").reshape(-1, 7)
            given = [list(p[:3]) + list(p[3:]) for p in pose]
        else:
            given = frames.attrs.get("frames", [])
        poses = []
        for j, frame in enumerate(given):
            frame = np.asarray(frame, dtype=float).reshape(-1)
            members = chosen[per_point == j]
            if members.size == 0:
                raise SceneError(f"{owner}.groupIndices: frame {j} has no nodes")
            centre = points[members].mean(axis=0) if frame.size in (3, 4) else frame[:3]
            turn = frame[-4:] if frame.size in (4, 7) else None
            rotation = (
                Rotation.from_quat(turn)
                if turn is not None
                else Rotation.from_euler("xyz", frame[-3:], degrees=True)
            )
            poses.append((j, centre, rotation.as_matrix()))
        if per_point.size and per_point.max() >= len(poses):
            raise SceneError(f"{owner}.frames: {len(poses)} frames for group {per_point.max()}")
        return [(x, r) for _, x, r in poses]

    def _held_groups(self, body_node: SceneNode, points: np.ndarray) -> np.ndarray:
        """The nodes of the rigidified groups whose frames are held."""
        groups = self._groups(body_node, points)
        held = [g.groups[j] for g in groups for j in np.flatnonzero(g.fixed)]
        return np.unique(np.concatenate([np.zeros(0, dtype=np.int64), *held]))

    def _free_frames(self, body_node: SceneNode, body: TetBody, mesh: TetMesh):
        """A rigid body for each free frame (FRAME_MASS_SHARE of its nodes' mass, a box a
        thousandth of the body's extent, which nothing touches), its nodes attached to it."""
        bodies, attachments, carried = [], [], []
        for g in self._groups(body_node, body.rest_positions):
            for j, (x, r) in g.poses:
                if g.fixed[j]:
                    continue
                if body.massless:
                    raise SceneError(
                        f"{g.dofs.path}: a free rigidified frame of a body with no mass (Pliant"
                        " gives the frame a share of its nodes' mass); give the body a mass"
                    )
                mass = FRAME_MASS_SHARE * float(body.node_masses[g.groups[j]].sum())
                size = 1e-3 * body.extent
                box = Box(np.full(3, size), position=x, rotation=r)
                meshes = [
                    self._carried_mesh(n, d, i, x, r)
                    for n, d, i in self._carried
                    if g.origins[j] is not None and (d, i) == g.origins[j]
                ]
                if len(meshes) > 1:
                    raise SceneError(
                        f"{g.dofs.path}[{j}]: several collision meshes on one frame (a rigid"
                        " body has one shape in Pliant)"
                    )
                frame = RigidBody(
                    meshes[0] if meshes else box,
                    mass,
                    box_inertia(mass, box.half_extents),
                    friction=self._carried_friction if meshes else 0.5,
                    name=f"{g.dofs.node.name}[{j}]",
                )
                carried += [(n, d, i) for n, d, i in self._carried if (d, i) == g.origins[j]]
                bodies.append(frame)
                attachments.append(
                    Attachment(EmbeddedPoints.at_nodes(g.groups[j]), frame, name=frame.name)
                )
        stray = [n for n, _, _ in self._carried if not any(n is c for c, _, _ in carried)]
        if stray:
            raise SceneError(
                f"{stray[0].path}: a collision model carried by a moving frame"
                f" ({stray[0].parent.path}, Rigidify's held frame or a servo's) is not supported:"
                " Pliant's moving shapes are rigid bodies (a free frame of Rigidify's carries one)"
            )
        return bodies, attachments

    # --- self-contact planes -------------------------------------------------------------------
    def _planes(
        self, body_node: SceneNode, carried: list[SceneNode], body: TetBody, mesh: TetMesh
    ) -> PointPlanes | None:
        """SoftRobots' UnilateralPlaneConstraints: on the body's nodes, or on points a child
        node carries (BarycentricMapping); the first of their four ``indices`` is kept on the
        side of the plane of the three others that its normal (reversed by ``flipNormal``)
        points to (:class:`pliant.constraints.contact.PointPlanes`)."""
        parts, flips, names, stray = [], [], [], []
        inside = {id(body_node), *(id(n) for n in carried)}
        for node in self.root.walk():
            found = [o for o in node.objects if o.type == PLANE_CONSTRAINT]
            if not found:
                continue
            if id(node) not in inside:
                stray += [f"{o.path}" for o in found]
                continue
            if node is body_node:
                points = body.rest_positions
                embedded = None
            else:
                if not any(o.type in MAPPINGS for o in node.objects):
                    raise SceneError(
                        f"{node.path}: points without a BarycentricMapping to the body"
                    )
                dofs = self._one(node, {"MechanicalObject"}, "MechanicalObjects")
                if dofs is None:
                    raise SceneError(f"{found[0].path}: no MechanicalObject in its node")
                points = self._positions(node, dofs)
                embedded = self._embed(mesh, points, body)
            for obj in found:
                idx = _floats(obj.attrs.get("indices", ""), f"{obj.path}.indices")
                if idx.size != 4 or np.any(idx != np.round(idx)):
                    raise SceneError(
                        f"{obj.path}.indices: four point indices expected (the held point, then"
                        f" the plane's three), got {obj.attrs.get('indices', '')!r}"
                    )
                idx = idx.astype(np.int64)
                if idx.min() < 0 or idx.max() >= len(points):
                    raise SceneError(
                        f"{obj.path}.indices: {idx.tolist()} outside the {len(points)} points of"
                        f" {node.path}"
                    )
                if _float(obj, "endTime", -1.0) >= 0.0:
                    raise SceneError(f"{obj.path}.endTime: a plane that stops is not supported")
                parts.append(
                    EmbeddedPoints.at_nodes(idx) if embedded is None else embedded.subset(idx)
                )
                flips.append(_flag(obj, "flipNormal", False))
                names.append(obj.path)
        if stray:
            raise SceneError(
                f"{self.path.name}: UnilateralPlaneConstraint holds points of the body (on its"
                f" node or a node under {body_node.path} with a BarycentricMapping): "
                + "; ".join(stray)
            )
        if not parts:
            return None
        try:
            planes = PointPlanes(EmbeddedPoints.stack(parts), flips, names)
            planes.normals(body.rest_positions)
        except ContactError as exc:
            raise SceneError(f"{self.path.name}: {exc}") from exc
        return planes

    # --- points carried by the body: cables, effectors ---------------------------------------
    def _embedded(self, node: SceneNode, body: TetBody, mesh: TetMesh):
        dofs = self._one(node, {"MechanicalObject"}, "MechanicalObjects")
        constraints = [o for o in node.objects if o.type in ("CableConstraint", "CableActuator")]
        constraints += [o for o in node.objects if o.type in CAVITIES]
        constraints += [
            o for o in node.objects if o.type in ("PositionEffector", "PositionConstraint")
        ]
        if dofs is None or not constraints:
            return [], []
        if not any(o.type in MAPPINGS for o in node.objects):
            raise SceneError(f"{node.path}: points without a BarycentricMapping to the body")
        positions = self._positions(node, dofs)
        self.bindings.mapped.append(
            (
                dofs,
                self._embed(mesh, positions, body),
            )
        )
        actuators, effectors = [], []
        for obj in constraints:
            if obj.type in CAVITIES:
                embedded = self._embed(mesh, positions, body)
                actuators.append(self._cavity(node, obj, embedded, body))
                self.bindings.actuators.append(obj)
                continue
            idx = self._indices(node, obj, "indices", positions)
            pts = positions if idx is None else positions[idx]
            # SOFA maps a point wherever it lies; Pliant keeps a generous check against typos.
            embedded = self._embed(mesh, pts, body)
            if obj.type == "PositionEffector":
                effectors.append(self._effector(node, obj, embedded, body))
                self.bindings.effectors.append(obj)
            elif obj.type == "PositionConstraint":
                actuators += self._position_constraint(obj, embedded, body)
            else:
                actuators.append(self._cable(obj, embedded, body))
                self.bindings.actuators.append(obj)
        return actuators, effectors

    def _embed(self, mesh: TetMesh, points: np.ndarray, body: TetBody) -> EmbeddedPoints:
        """Points carried by the body (SOFA's BarycentricMapping); of several bodies, by the
        one being read, in its own mesh."""
        if self._part is not None:
            part, self._part = self._part, None
            try:
                return part.shifted(self._embed(part.mesh, points, part.body))
            finally:
                self._part = part
        return EmbeddedPoints(
            mesh, points, tolerance=SOFA_REACH * body.extent, outside=self.choices.outside
        )

    def _positions(self, node: SceneNode, dofs: SceneObject) -> np.ndarray:
        """The points of a MechanicalObject: its `position`, a link to positions, or the
        mesh of its `src` (a loader, or a topology reading one) or of its node's only loader;
        then its own transform (scale, rotation, translation), as SOFA's MechanicalObject
        applies it at initialisation."""
        value = dofs.attrs.get("position", dofs.attrs.get("src"))
        topology = next((o for o in node.objects if o.type in TOPOLOGIES), None)
        if (
            topology is not None
            and "position" in topology.attrs
            and value is not None
            and not _is_link(value)
            and _floats(value, f"{dofs.path}.position").size == 3
        ):
            value = None  # SOFA's MechanicalObject of one point takes its topology's points
        if value is None and topology is not None and "position" in topology.attrs:
            value = topology.attrs["position"]  # SOFA's MechanicalObject takes its topology's
            if not _is_link(value):
                pts = _floats(value, f"{topology.path}.position")
                if pts.size == 0 or pts.size % 3:
                    raise SceneError(f"{topology.path}.position: triples of numbers expected")
                return _placed(dofs, pts.reshape(-1, 3))
        if value is None:
            loaders = [o for o in node.objects if o.type in MESH_LOADERS]
            if len(loaders) != 1:
                raise SceneError(f"{dofs.path}: no position (and no single mesh loader)")
            return _placed(dofs, self._loaded(loaders[0])[0])
        if _is_link(value):
            source = self.link(node, value)
            for _ in range(4):  # a topology's src, or its position link, names the loader
                if source is None or source.type in MESH_LOADERS or "position" in source.attrs:
                    break
                if not _is_link(source.attrs.get("src")):
                    break
                source = self.link(source.node, source.attrs["src"])
            if source is not None and source.type in MESH_LOADERS:
                return _placed(dofs, self._loaded(source)[0])
            if source is None or "position" not in source.attrs:
                raise SceneError(f"{dofs.path}.position: {value!r} names no positions")
            if _is_link(source.attrs["position"]):
                return self._positions(source.node, source)
            value = source.attrs["position"]
        pts = _floats(value, f"{dofs.path}.position")
        if pts.size == 0 or pts.size % 3:
            raise SceneError(f"{dofs.path}.position: triples of numbers expected")
        return _placed(dofs, pts.reshape(-1, 3))

    def _cable(self, obj: SceneObject, points: EmbeddedPoints, body: TetBody) -> CableActuator:
        # SoftRobots: a pull point unless hasPullPoint is false, at the origin unless given.
        has_pull = _flag(obj, "hasPullPoint", True)
        pull_point = _floats(obj.attrs.get("pullPoint", "0 0 0"), f"{obj.path}.pullPoint")
        values, index, mode = _command(obj, ("displacement", "force"))
        change = obj.attrs.get("maxDispVariation")
        return CableActuator(
            points,
            body.rest_positions,
            pull_point=pull_point if has_pull else None,
            name=obj.node.name if obj.name == obj.type else obj.node.name + "/" + obj.name,
            mode=mode,
            value=float(values[index]) if values.size else 0.0,
            **_actuator_bounds(obj),
            max_displacement_change=None if change is None else _float(obj, "maxDispVariation", 0),
            change_reference=self.choices.change_reference,
        )

    def _position_constraint(
        self, obj: SceneObject, points: EmbeddedPoints, body: TetBody
    ) -> list[PointActuator]:
        """SoftRobots' PositionConstraint: one row for each point and each direction that
        ``useDirections`` selects (``directions``: the axes unless given, normalised), the
        point's displacement from rest along it times the direction's ``weight``; every row
        imposes the same ``value`` (a displacement or a force), within the scene's bounds."""
        directions = _floats(obj.attrs.get("directions", ""), f"{obj.path}.directions")
        directions = np.eye(3) if directions.size == 0 else directions.reshape(-1, 3)
        use = _floats(obj.attrs.get("useDirections", "1 1 1"), f"{obj.path}.useDirections")
        weight = _floats(obj.attrs.get("weight", "1"), f"{obj.path}.weight")
        weight = np.full(3, weight[0]) if weight.size != 3 else weight
        if directions.shape[0] != 3 or use.size != 3:
            raise SceneError(f"{obj.path}: directions and useDirections give three axes")
        if not use.any():  # SoftRobots then takes every direction
            use = np.ones(3)
        values, index, mode = _command(obj, ("displacement", "force"))
        name = obj.node.name if obj.name == obj.type else obj.node.name + "/" + obj.name
        rows = []
        for i in range(len(points)):
            one = points.subset(i)
            for axis in np.flatnonzero(use):
                rows.append(
                    PointActuator(
                        one,
                        body.rest_positions,
                        directions[axis],
                        weight=float(weight[axis]),
                        name=f"{name}[{i}]{'xyz'[axis]}",
                        mode=mode,
                        value=float(values[index]) if values.size else 0.0,
                        **_actuator_bounds(obj),
                    )
                )
                self.bindings.actuators.append(obj)
        return rows

    def _cavity(
        self, node: SceneNode, obj: SceneObject, points: EmbeddedPoints, body: TetBody
    ) -> CavityActuator:
        """SoftRobots' SurfacePressureConstraint: the closed surface of its node's mesh,
        carried by the body; a pressure (force mode) or a volume growth (displacement)."""
        value = obj.attrs.get("triangles")
        if value is None or _is_link(value):
            source = self.link(node, value) if value is not None else None
            if source is not None and source.type not in MESH_LOADERS:
                source = self.link(node, str(source.attrs.get("src", "")))
            if source is None:
                loaders = [o for o in node.objects if o.type in MESH_LOADERS]
                source = loaders[0] if len(loaders) == 1 else None
            if source is None:
                raise SceneError(f"{obj.path}.triangles: {value!r} names no surface mesh")
            cells = self._loaded(source)[1]
            if "triangle" not in cells:
                raise SceneError(f"{obj.path}: the cavity's mesh holds no triangles")
            triangles = cells["triangle"]
        else:
            triangles = _floats(value, f"{obj.path}.triangles").astype(np.int64).reshape(-1, 3)
        rest = points.positions(body.rest_positions)
        values, index, kind = _command(obj, ("pressure", "volumeGrowth"))
        change = obj.attrs.get("maxVolumeGrowthVariation")
        return CavityActuator(
            triangles,
            body.rest_positions,
            points=points,
            # The pressure inflates the cavity whichever way the file orients its faces.
            flip_normals=enclosed_volume(rest, triangles) < 0.0,
            name=node.name,
            mode="force" if kind == "pressure" else "displacement",
            value=float(values[index]) if values.size else 0.0,
            min_force=_float(obj, "minPressure", -math.inf),
            max_force=_float(obj, "maxPressure", math.inf),
            min_displacement=_float(obj, "minVolumeGrowth", -math.inf),
            max_displacement=_float(obj, "maxVolumeGrowth", math.inf),
            max_displacement_change=None
            if change is None
            else _float(obj, "maxVolumeGrowthVariation", 0.0),
            change_reference=self.choices.change_reference,
        )

    def _effector(
        self, node: SceneNode, obj: SceneObject, points: EmbeddedPoints, body: TetBody
    ) -> PositionEffector:
        goal = obj.attrs.get("effectorGoal")
        goals = None
        if goal is not None:
            if _is_link(goal):
                source = self.link(node, goal)
                if source is None or "position" not in source.attrs:
                    raise SceneError(f"{obj.path}.effectorGoal: {goal!r} names no positions")
                goal = source.attrs["position"]
            goals = _floats(goal, f"{obj.path}.effectorGoal").reshape(-1, 3)
            if goals.shape[0] == 1 and len(points) > 1:
                goals = np.repeat(goals, len(points), axis=0)
        axes = tuple(
            bool(v)
            for v in _floats(obj.attrs.get("useDirections", "1 1 1"), f"{obj.path}.useDirections")
        )
        return PositionEffector(
            points, body.rest_positions, goals=goals, axes=axes, name=obj.node.name
        )


# --- what a script's init() computes --------------------------------------------------------
def _refuse_on_rods(root: SceneNode) -> None:
    """SceneError for a ReadState or MeshSpringForceField in a scene whose body is a rod."""
    for node in root.walk():
        for obj in node.objects:
            if obj.type in ("ReadState", "MeshSpringForceField"):
                raise SceneError(f"{obj.path}: {obj.type} on a tetrahedral body only (not a rod)")


def _hrz_shares(weights: np.ndarray) -> np.ndarray:
    """Each point's shares w_a^2 / sum_b w_b^2 of its mass on its element's nodes (flat)."""
    squared = weights**2
    return (squared / squared.sum(axis=1, keepdims=True)).ravel()


def _edge_lengths(points: np.ndarray, edges: np.ndarray, where: str) -> tuple:
    """The edges (a flat list read as pairs) between `points` and their lengths. SOFA reads
    pairs from the list while two numbers remain: an odd last index makes no edge (SofaGym's
    TrunkCup gives 0..14, seven edges)."""
    pairs = edges[: edges.size - edges.size % 2].reshape(-1, 2)
    if pairs.size == 0 or pairs.min() < 0 or pairs.max() >= len(points):
        raise SceneError(f"{where}.edges: pairs of indices among the {len(points)} points expected")
    return pairs, np.linalg.norm(points[pairs[:, 1]] - points[pairs[:, 0]], axis=1)


def _script_builder(node: SceneNode) -> _Builder:
    """A builder for the tree a script is building (run in the script's folder)."""
    root = node
    while root.parent is not None:
        root = root.parent
    return _Builder(root, Path.cwd() / "scene.py", SOFA_CHOICES, [])


def _init_positions(dofs: SceneObject) -> None:
    """MechanicalObject.init(): its ``rest_position`` from its ``position`` (given, or linked
    to a mesh loader's), else from the node's mesh loader, as SOFA's takes its topology's."""
    if "rest_position" in dofs.attrs and not _is_link(dofs.attrs["rest_position"]):
        return
    given = dofs.attrs.get("position")
    builder = _script_builder(dofs.node)
    if given is not None and not _is_link(given):
        points = _floats(given, f"{dofs.path}.position")
    else:
        source = builder.link(dofs.node, given) if given is not None else None
        if source is None or source.type not in MESH_LOADERS:
            try:
                source = builder._mesh_loader(dofs.node)
            except SceneError:
                return  # nothing to read: SOFA's state stays empty too
        points = builder._loaded(source)[0]
    width = 7 if str(dofs.attrs.get("template", "")).startswith("Rigid3") else 3
    dofs.attrs["rest_position"] = _frozen(points.reshape(-1, width))


def _roi_points(roi: SceneObject) -> np.ndarray:
    """The points a ROI selects among: its ``position`` (given or linked), by default the
    rest positions of its node's MechanicalObject (SOFA links it so)."""
    given = roi.attrs.get("position")
    if given is not None and not _is_link(given) and np.size(given):
        return _floats(given, f"{roi.path}.position").reshape(-1, 3)
    builder = _script_builder(roi.node)
    dofs = builder.link(roi.node, given) if given is not None and _is_link(given) else None
    at = roi.node
    while dofs is None and at is not None:  # the context's, then the parent's
        dofs, at = at.getMechanicalState(), at.parent
    if dofs is None:
        raise SceneError(f"{roi.path}: no position to select from (no MechanicalObject here)")
    _init_positions(dofs)
    if "rest_position" not in dofs.attrs:
        raise SceneError(f"{roi.path}: {dofs.path} has no positions yet")
    rest = _floats(dofs.attrs["rest_position"], f"{dofs.path}.rest_position")
    width = 7 if str(dofs.attrs.get("template", "")).startswith("Rigid3") else 3
    return rest.reshape(-1, width)[:, :3]


def _init_roi(roi: SceneObject) -> None:
    """BoxROI.init() / SphereROI.init() in a script: the ``indices`` of the points inside."""
    points = _roi_points(roi)
    indices = _script_builder(roi.node)._roi_nodes(roi, points)
    roi.attrs["indices"] = _frozen(indices).astype(np.int64)


def _init_rigid_mass(obj: SceneObject) -> None:
    """GenerateRigidMass.init() in a script: its rigid mass (pliant.sofa.rigids)."""
    generate_rigid_mass(_script_builder(obj.node), obj)


def init_loader(loader: SceneObject) -> None:
    """A mesh loader's init(): its ``position`` (placed), ``edges`` and ``triangles`` outputs,
    where not set, as scripts read them (SofaGym's SimpleMaze walks its path's edges)."""
    points, cells = _script_builder(loader.node)._loaded(loader)
    outputs = {"position": points, "edges": cells.get("line"), "triangles": cells.get("triangle")}
    for key, value in outputs.items():
        if value is not None and (key not in loader.attrs or _is_link(loader.attrs[key])):
            loader.attrs[key] = _frozen(value) if key == "position" else _frozen(value).astype(int)


INITIALISERS.update(
    **dict.fromkeys(MESH_LOADERS - {"GIDMeshLoader"}, init_loader),
    MechanicalObject=_init_positions,
    BoxROI=_init_roi,
    SphereROI=_init_roi,
    GenerateRigidMass=_init_rigid_mass,
)


def _touches(model: SceneObject, triangles: SceneObject) -> bool:
    """Whether SOFA tests a rigid body's collision `model` (points, triangles or a sphere)
    against a deformable body's `triangles`: a TriangleCollisionModel, no group in common."""
    return triangles.type == "TriangleCollisionModel" and not (_groups(model) & _groups(triangles))


def _rigid_points(shape) -> tuple[np.ndarray, float]:
    """The points of a rigid body's shape that touch a deformable surface, in its frame, and
    their radius: a sphere's centre (its radius), a box's corners, a mesh's vertices."""
    if isinstance(shape, Box):
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        return signs * shape.half_extents, 0.0
    if isinstance(shape, TriangleMesh):
        return shape.vertices, 0.0
    return np.zeros((1, 3)), float(shape.radius)
