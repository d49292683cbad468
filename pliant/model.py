"""Model (built once) and State (what changes every step).

The model owns the deformable body, its constraints, the drivers that carry some of its held
nodes (a cart, a translating base) and the rigid bodies it touches; the state is a small value
that can be copied, saved, restored and compared, which planning, RL resets and trajectory
optimisation rely on.
"""

from __future__ import annotations

import dataclasses
import json
import math
import numbers
import os
import tempfile
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from pliant.constraints.attachment import Attachment
from pliant.constraints.base import Actuator, Constraint
from pliant.constraints.cable import CableActuator, CableBundle
from pliant.constraints.contact import Contacts
from pliant.constraints.control import commands
from pliant.constraints.friction import ContactForces
from pliant.constraints.rigid_joints import RigidJoint, check_joints
from pliant.errors import ModelError, StateError
from pliant.fem.body import TetBody
from pliant.fem.rigid import DrivenNodes, KinematicBody, RigidBody
from pliant.fem.rod import RodBody
from pliant.files import replace


@dataclass(frozen=True)
class ModelLayout:
    """What a state's arrays mean in the model that made it: its node count, its actuators
    (name and kind, in the order of the actuation vector), effectors, rigid bodies and the
    body's loads. A state made by one model and stepped by another whose layout differs
    (a state saved on a four-cable Diamond, stepped by the two-cable one) is refused with
    the difference named (:meth:`Model.check_state`). Actuator modes are not part of it: a
    controller may switch a cable from displacement to force between steps, and the state's
    actuator forces mean the same in both modes."""

    nodes: int
    actuators: tuple[str, ...] = ()
    effectors: tuple[str, ...] = ()
    rigid_bodies: tuple[str, ...] = ()
    loads: tuple[str, ...] = ()

    @classmethod
    def of(cls, model: Model) -> ModelLayout:
        def named(items) -> tuple[str, ...]:
            return tuple(f"{c.name} ({type(c).__name__})" for c in items)

        return cls(
            0 if model.body is None else int(model.body.n_nodes),
            named(model.actuators),
            named(model.effectors),
            tuple(b.name for b in model.rigid_bodies),
            tuple(type(a.load).__name__ for a in getattr(model.body, "loads", ())),
        )

    def differences(self, other: ModelLayout) -> list[str]:
        """What differs from `other` (the model's), in words."""
        out = []
        for name in ("nodes", "actuators", "effectors", "rigid_bodies", "loads"):
            mine, theirs = getattr(self, name), getattr(other, name)
            if mine != theirs:
                show = (lambda v: v) if name == "nodes" else (lambda v: list(v) or "none")
                label = name.replace("_", " ")
                out.append(f"{label} {show(mine)} where the model has {show(theirs)}")
        return out

    def to_json(self) -> str:
        return json.dumps(dataclasses.asdict(self))

    @classmethod
    def from_json(cls, text: str) -> ModelLayout:
        d = json.loads(text)
        return cls(
            int(d["nodes"]),
            *(tuple(d[k]) for k in ("actuators", "effectors", "rigid_bodies", "loads")),
        )


@dataclass
class State:
    """Positions and velocities of the nodes, time, step count and the last constraint forces.

    Attributes:
        positions, velocities: (n, 3).
        time: simulated time.
        step: number of steps taken.
        actuation: (n_actuators,) actuator forces lambda_a of the last step.
        displacement: (n_actuators,) actuator distances delta_a at the end of the last step.
        displacement_before: delta_a at the end of the step before the last (what an actuator
            with ``change_reference="lagged"`` limits its change against, as SoftRobots does);
            empty before the first step.
        contact_forces: the last step's contact forces by contact identity (the next step's
            warm start, so that a restored state replays exactly).
        rigid_positions, rigid_rotations, rigid_velocities, rigid_angular_velocities: the
            model's rigid bodies: centres of mass (b, 3), rotations body -> world (b, 3, 3),
            linear and angular velocities in the world (b, 3); empty without rigid bodies.
        layout: the :class:`ModelLayout` of the model that made the state (None for a state made
            by hand), checked where the state enters a solver step.

    The nodes carried by drivers are part of positions and velocities (their velocity is the
    one of the last step, (p(t) - p(t - h)) / h), so that a restored state replays exactly.
    """

    positions: np.ndarray
    velocities: np.ndarray
    time: float = 0.0
    step: int = 0
    actuation: np.ndarray = field(default_factory=lambda: np.zeros(0))
    displacement: np.ndarray = field(default_factory=lambda: np.zeros(0))
    contact_forces: ContactForces = field(default_factory=ContactForces.empty)
    rigid_positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    rigid_rotations: np.ndarray = field(default_factory=lambda: np.zeros((0, 3, 3)))
    rigid_velocities: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    rigid_angular_velocities: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    displacement_before: np.ndarray = field(default_factory=lambda: np.zeros(0))
    layout: ModelLayout | None = None

    _RIGID = ("rigid_positions", "rigid_rotations", "rigid_velocities", "rigid_angular_velocities")
    _FIELDS = (
        "positions",
        "velocities",
        "time",
        "step",
        "actuation",
        "displacement",
        "contact_keys",
        "contact_forces",
    )

    def copy(self) -> State:
        return State(
            self.positions.copy(),
            self.velocities.copy(),
            self.time,
            self.step,
            self.actuation.copy(),
            self.displacement.copy(),
            self.contact_forces.copy(),
            *(getattr(self, name).copy() for name in self._RIGID),
            self.displacement_before.copy(),
            self.layout,
        )

    def allclose(self, other: State, *, atol: float = 0.0) -> bool:
        pairs = [(self.positions, other.positions), (self.velocities, other.velocities)]
        pairs += [(getattr(self, name), getattr(other, name)) for name in self._RIGID]
        return self.step == other.step and all(
            a.shape == b.shape and np.allclose(a, b, rtol=0, atol=atol) for a, b in pairs
        )

    def save(self, path: str | os.PathLike) -> None:
        """Write the state to an .npz file atomically: a reader finds the old file or the whole
        new one, and a failed write leaves neither a partial file nor a temporary one.

        Raises:
            StateError: the folder does not exist or is not writable, or the disk is full.
        """
        path = Path(path)
        if path.is_dir():
            raise StateError(f"cannot save the state to {str(path)!r}: it is a folder")
        try:
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".npz")
        except OSError as exc:
            raise StateError(f"cannot save the state to {str(path)!r}: {exc}") from exc
        try:
            with os.fdopen(fd, "wb") as file:
                np.savez(
                    file,
                    positions=self.positions,
                    velocities=self.velocities,
                    time=self.time,
                    step=self.step,
                    actuation=self.actuation,
                    displacement=self.displacement,
                    displacement_before=self.displacement_before,
                    contact_keys=self.contact_forces.keys,
                    contact_forces=self.contact_forces.forces,
                    **{name: getattr(self, name) for name in self._RIGID},
                    **({} if self.layout is None else {"layout": self.layout.to_json()}),
                )
            replace(tmp, path)
        except OSError as exc:
            raise StateError(f"cannot save the state to {str(path)!r}: {exc}") from exc
        finally:
            if os.path.exists(tmp):
                os.remove(tmp)

    @classmethod
    def load(cls, path: str | os.PathLike, model: Model | None = None) -> State:
        """Read a state written by :meth:`save`; with `model`, check that it belongs to it.

        Raises:
            StateError: the file is missing, unreadable, truncated or not a state file, or
                the state does not fit `model` (see :meth:`Model.check_state`).
        """
        path = Path(path)
        if not path.is_file():
            raise StateError(f"no state file at {str(path)!r}")
        try:
            with np.load(path, allow_pickle=False) as d:
                missing = [k for k in cls._FIELDS if k not in d.files]
                if missing:
                    raise StateError(f"{str(path)!r} is not a state file: it lacks {missing}")
                state = cls(
                    d["positions"],
                    d["velocities"],
                    float(d["time"]),
                    int(d["step"]),
                    d["actuation"],
                    d["displacement"],
                    ContactForces(d["contact_keys"], d["contact_forces"]),
                    # States saved before rigid bodies (or the lagged displacement) existed
                    # have none.
                    **{
                        name: d[name]
                        for name in (*cls._RIGID, "displacement_before")
                        if name in d.files
                    },
                    layout=ModelLayout.from_json(str(d["layout"])) if "layout" in d.files else None,
                )
        except StateError:
            raise
        except (
            OSError,
            EOFError,
            ValueError,
            TypeError,
            KeyError,
            AttributeError,
            zipfile.BadZipFile,
        ) as exc:
            raise StateError(
                f"{str(path)!r} is not a readable state file (truncated or corrupt?): {exc}"
            ) from exc
        if model is not None:
            state = model.check_state(state, what=f"the state in {str(path)!r}", strict=True)
        return state


def _real_array(value, what: str, name: str) -> np.ndarray:
    """`value` as a float64 array (itself when it is one), finite; StateError naming
    "`what`: `name`" otherwise."""
    if type(value) is np.ndarray and value.dtype == np.float64:
        array = value  # the usual case, without a conversion
    else:
        try:
            array = np.asarray(value)
        except (ValueError, TypeError) as exc:  # ragged nested sequences
            raise StateError(f"{what}: {name} is not an array of numbers: {exc}") from None
        if array.dtype.kind not in "iuf":
            raise StateError(f"{what}: {name} must hold real numbers, got dtype {array.dtype}")
        array = array.astype(np.float64)
    # One pass: a finite sum shows every value finite (an overflowing one is told apart).
    if (
        array.size
        and not math.isfinite(np.add.reduce(array, axis=None))
        and not np.all(np.isfinite(array))
    ):
        raise StateError(f"{what}: {name} holds non-finite values (NaN or inf)")
    return array


@dataclass(frozen=True)
class ConstraintSpace:
    """All constraint rows at one configuration, in the order actuators, effectors, contacts.

    Attributes:
        distance: delta (r,).
        jacobian_t: H^T restricted to the free DoFs, dense (n_free, r).
        slices: role -> slice of rows.
    """

    distance: np.ndarray
    jacobian_t: np.ndarray
    slices: dict[str, slice]


class Model:
    """A simulated robot: one deformable body, its constraints, and what it is coupled to; or
    rigid bodies alone (no deformable body: `body` None).

    Args:
        body: the deformable body: tetrahedra, or a rod (:class:`pliant.fem.rod.RodBody`);
            None for a model of rigid bodies alone (a cart and pole, a ball in a maze): its
            state then has no nodes, and its bodies are stepped by the rigid bodies' scheme
            (:mod:`pliant.solvers.rigid`) with their joints and contacts.
        actuators: cables, cavities, ... in the order of the actuation vector.
        effectors: position effectors, used by inverse control.
        contacts: obstacles the body touches and the contact law (friction, margin).
        drivers: held nodes carried by kinematic bodies (a cart, a translating base); each
            node is one of the body's fixed nodes and belongs to one driver at most.
        rigid_bodies: dynamic rigid bodies the body touches (and that touch the obstacles of
            `contacts` and each other; `contacts` detects them) or carries (`attachments`).
        attachments: points of the body held at fixed places of rigid bodies of the model
            (:class:`pliant.constraints.attachment.Attachment`).
        joints: joints between the rigid bodies, or a body and the world
            (:mod:`pliant.constraints.rigid_joints`); a model without deformable body only.
        obstacles: kinematic bodies (a prescribed pose) moving shapes of `contacts`, which
            the others of its shapes stay still; a model without deformable body only.
        gravity: (3,) of a model without deformable body (default (0, 0, -9.81)); a body's
            model takes its body's.
    """

    def __init__(
        self,
        body: TetBody | RodBody | None,
        *,
        actuators: list[Actuator] | tuple = (),
        effectors: list[Constraint] | tuple = (),
        contacts: Contacts | None = None,
        drivers: list[DrivenNodes] | tuple = (),
        rigid_bodies: list[RigidBody] | tuple = (),
        attachments: list[Attachment] | tuple = (),
        joints: list[RigidJoint] | tuple = (),
        obstacles: list[KinematicBody] | tuple = (),
        gravity=None,
        name: str = "robot",
    ) -> None:
        self.body = body
        self.actuators = list(actuators)
        self.effectors = list(effectors)
        self.name = name
        self.contacts = contacts
        self.drivers = list(drivers)
        self.rigid_bodies = list(rigid_bodies)
        self.attachments = list(attachments)
        self.joints = list(joints)
        self.obstacles = list(obstacles)
        if body is None:
            self._rigid_only(gravity)
            return
        if self.joints or self.obstacles or gravity is not None:
            raise ModelError(
                f"{name}: joints, moving obstacles and a gravity of the model's own are those"
                " of a model of rigid bodies alone (body None); a deformable body's model"
                " takes its body's gravity, and couples its rigid bodies by contact or"
                " attachment"
            )
        self._check_drivers()
        if self.rigid_bodies and contacts is None and not self.attachments:
            raise ModelError(
                f"{name}: rigid bodies interact with the body by contact or attachment; give"
                " contacts=Contacts(...) (its shapes may be just the floor) or attachments"
            )
        for a in self.attachments:
            if not isinstance(a, Attachment):
                raise ModelError(f"{a!r} is not an Attachment")
            if not any(a.body is b for b in self.rigid_bodies):
                raise ModelError(
                    f"{a.name}: its body {a.body.name} is not one of the model's rigid_bodies"
                )
            a.bind(body.rest_positions)
        if contacts is not None:
            contacts.attach(body, self.rigid_bodies)
            if self.attachments:
                contacts.exclude_carried(self.attachments)
        for c in self.actuators:
            if c.role != "actuator":
                raise ModelError(f"{c.name} is a {c.role}, not an actuator")
        for c in self.effectors:
            if c.role != "effector":
                raise ModelError(f"{c.name} is a {c.role}, not an effector")
        self._groups = self._group(self.actuators) + self._group(self.effectors)
        self._n_actuator_groups = len(self._group(self.actuators))
        names = [c.name for c in self.actuators + self.effectors]
        if len(set(names)) != len(names):
            raise ModelError(f"constraint names must be unique, got {names}")
        self.layout = ModelLayout.of(self)

    def _rigid_only(self, gravity) -> None:
        """Check and complete a model of rigid bodies alone (no deformable body)."""
        name = self.name
        if not self.rigid_bodies:
            raise ModelError(f"{name}: a model without deformable body needs rigid bodies")
        what = [
            label
            for label, items in (
                ("actuators", self.actuators),
                ("effectors", self.effectors),
                ("drivers", self.drivers),
                ("attachments", self.attachments),
            )
            if items
        ]
        if what:
            raise ModelError(
                f"{name}: {', '.join(what)} act on a deformable body's nodes, and the model has"
                " none (body None)"
            )
        for b in self.rigid_bodies:
            if not isinstance(b, RigidBody):
                raise ModelError(f"{name}: {b!r} is not a RigidBody")
        shapes = {id(s) for s in self.contacts.shapes} if self.contacts is not None else set()
        for o in self.obstacles:
            if not isinstance(o, KinematicBody):
                raise ModelError(f"{name}: a moving obstacle is a KinematicBody, got {o!r}")
            if id(o.shape) not in shapes:
                raise ModelError(
                    f"{name}: the obstacle {o.name} moves a shape that is not one of the"
                    " contacts' (give it in Contacts too: its friction and margin are theirs)"
                )
        check_joints(self.joints, self.rigid_bodies)
        g = np.asarray((0.0, 0.0, -9.81) if gravity is None else gravity, dtype=float)
        if g.shape != (3,) or not np.all(np.isfinite(g)):
            raise ModelError(f"{name}: gravity must be a finite 3-vector, got {gravity!r}")
        self.gravity = g
        self._groups, self._n_actuator_groups = [], 0
        self.layout = ModelLayout.of(self)

    def geometric_pattern(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Free-DoF (rows, cols) of the actuators' load stiffness -lambda d^2 delta/dx^2 (the
        cables' geometric stiffness, a rotation actuator's torque turning with its node);
        None when no actuator has one."""
        parts = self._load_stiffness_parts()
        if parts is None:
            return None
        return self._geometric[0], self._geometric[1]

    def geometric_stiffness(self, positions: np.ndarray, actuation: np.ndarray) -> np.ndarray:
        """Values of the actuators' load stiffness at `positions` under the actuator forces
        `actuation` (cable tensions, torques), on :meth:`geometric_pattern`."""
        blocks = []
        for evaluate, index in self._load_stiffness_parts():
            blocks.append(evaluate(positions, actuation[index]))
        return np.concatenate(blocks).reshape(-1)[self._geometric[2]]

    def _load_stiffness_parts(self) -> list | None:
        """[(blocks(x, forces) -> (E, 3, 3), actuator indices)] of the actuators with a load
        stiffness (the cables bundled), or None; builds the pattern once."""
        if not hasattr(self, "_load_parts"):
            cables = [i for i, a in enumerate(self.actuators) if isinstance(a, CableActuator)]
            others = [
                i
                for i, a in enumerate(self.actuators)
                if not isinstance(a, CableActuator) and hasattr(a, "load_stiffness")
            ]
            parts, pairs = [], []
            if cables:
                bundle = CableBundle([self.actuators[i] for i in cables])
                # A slack cable has no tension: only a pulling one stiffens.
                parts.append(
                    (lambda x, f, b=bundle: b.geometric_stiffness(x, np.maximum(f, 0.0)), cables)
                )
                pairs.append(bundle.geometric_pairs())
            for i in others:
                act = self.actuators[i]
                parts.append((lambda x, f, a=act: a.load_stiffness(x, float(f[0])), [i]))
                pairs.append(act.load_stiffness_pairs())
            self._load_parts = parts or None
            if parts:
                ni = np.concatenate([p[0] for p in pairs])
                nj = np.concatenate([p[1] for p in pairs])
                free = self.body.free_index
                rows = free[3 * ni[:, None, None] + np.arange(3)[None, :, None]]
                cols = free[3 * nj[:, None, None] + np.arange(3)[None, None, :]]
                rows, cols = np.broadcast_arrays(rows, cols)
                keep = ((rows >= 0) & (cols >= 0)).reshape(-1)
                self._geometric = (rows.reshape(-1)[keep], cols.reshape(-1)[keep], keep)
        return self._load_parts

    def _check_drivers(self) -> None:
        body = self.body
        seen = np.zeros(body.n_nodes, dtype=bool)
        for driver in self.drivers:
            driver.attach(body.rest_positions)
            loose = np.setdiff1d(driver.nodes, body.fixed_nodes)
            if loose.size:
                raise ModelError(
                    f"{driver.name}: driven nodes must be fixed nodes of the body (held, not"
                    f" free DoFs); nodes {loose[:5].tolist()} are free"
                )
            if np.any(seen[driver.nodes]):
                raise ModelError(f"{driver.name}: a node is carried by two drivers")
            seen[driver.nodes] = True
        if self.drivers and body.mass_type == "consistent":
            raise ModelError(
                "driven nodes need a diagonal mass ('lumped' or 'uniform'): with a consistent"
                " mass their acceleration would load the free nodes through M_fp"
            )

    def drive(self, positions: np.ndarray, t: float) -> np.ndarray:
        """A copy of `positions` with every driven node at its prescribed position at t."""
        out = positions.copy()
        for driver in self.drivers:
            out[driver.nodes] = driver.positions(t)
        return out

    def trajectories_changed(self) -> None:
        """Tell the kinematic bodies that carry driven nodes that their trajectories were
        changed in place (their memoised poses are dropped)."""
        for driver in self.drivers:
            driver.carrier.forget()

    def drive_velocities(self, state: State, dt: float) -> np.ndarray:
        """(n, 3) velocity of each driven node over the step [t, t + h] from `state`,
        (p(t + h) - q) / h (for a rod's orientation, the spin from q to p(t + h) over h);
        zero on the other nodes."""
        velocities = np.zeros_like(state.positions)
        for driver in self.drivers:
            nodes = driver.nodes
            moved = self.body.difference(
                driver.positions(state.time + dt), state.positions[nodes], nodes
            )
            velocities[nodes] = moved / dt
        return velocities

    @staticmethod
    def _group(constraints: list[Constraint]) -> list:
        """Runs of consecutive constraints of one class, bundled when the class can."""
        groups, run = [], []
        for c in [*constraints, None]:
            if run and (c is None or type(c) is not type(run[0])):
                bundled = type(run[0]).bundle(run) if len(run) > 1 else None
                groups += [bundled] if bundled is not None else run
                run = []
            if c is not None:
                run.append(c)
        return groups

    def distances(self, positions: np.ndarray, *, actuators_only: bool = False) -> np.ndarray:
        """delta(x) of every constraint row (or only the actuators'), in row order."""
        groups = self._groups[: self._n_actuator_groups] if actuators_only else self._groups
        if not groups:
            return np.zeros(0)
        return np.concatenate([g.distance(positions) for g in groups])

    @property
    def constraints(self) -> list[Constraint]:
        return self.actuators + self.effectors

    @property
    def n_actuators(self) -> int:
        return len(self.actuators)

    def rest_state(self) -> State:
        """The body at rest (driven nodes at their t = 0 positions), rigid bodies at their
        initial poses and velocities."""
        q = np.zeros((0, 3)) if self.body is None else self.drive(self.body.rest_positions, 0.0)
        b = self.rigid_bodies
        return State(
            q,
            np.zeros_like(q),
            actuation=np.zeros(self.n_actuators),
            displacement=np.zeros(self.n_actuators),
            rigid_positions=np.array([x.position for x in b]).reshape(-1, 3),
            rigid_rotations=np.array([x.rotation for x in b]).reshape(-1, 3, 3),
            rigid_velocities=np.array([x.velocity for x in b]).reshape(-1, 3),
            rigid_angular_velocities=np.array([x.angular_velocity for x in b]).reshape(-1, 3),
            layout=self.layout,
        )

    def check_state(self, state: State, *, what: str = "the state", strict: bool = False) -> State:
        """`state` if it belongs to this model, else StateError naming what differs.

        The compiled kernels index the state's arrays by the model's nodes and elements: a
        state of another model (other node count, columns, rigid-body count) or with
        non-finite values must be refused before any of them runs. The last step's actuator
        forces and displacements only start the next step: those of another actuator count (a
        state of the same body under other actuators, released) are dropped, as for a state
        that records none, unless `strict` (a state file loaded for this model), which
        refuses them. A state that records the :class:`ModelLayout` of the model that made it
        (every solver step and ``rest_state`` do) is refused when that layout is not this
        model's (other actuators, effectors, rigid bodies or loads), the differences named: an
        identity test per step for the model's own states, a comparison of a few short tuples
        for one pickled or loaded. Arrays of another real dtype (integers, float32) are accepted and
        returned as float64 in a copy; the checks are O(1) but for one sum per array (a
        finite sum shows every value finite).
        """
        if not isinstance(state, State):
            raise StateError(f"{what} must be a pliant State, got {type(state).__name__}")
        layout = state.layout
        if layout is not None and layout is not self.layout and layout != self.layout:
            if not isinstance(layout, ModelLayout):
                raise StateError(
                    f"{what}: layout must be a ModelLayout, got {type(layout).__name__}"
                )
            raise StateError(
                f"{what} was made by another model than {self.name}: "
                + "; ".join(layout.differences(self.layout))
            )
        n = 0 if self.body is None else self.body.n_nodes
        b = len(self.rigid_bodies)
        cast = {}
        for name, shape in (
            ("positions", (n, 3)),
            ("velocities", (n, 3)),
            ("rigid_positions", (b, 3)),
            ("rigid_rotations", (b, 3, 3)),
            ("rigid_velocities", (b, 3)),
            ("rigid_angular_velocities", (b, 3)),
        ):
            value = getattr(state, name)
            array = _real_array(value, what, name)
            if array.shape != shape:
                whose = "nodes" if name in ("positions", "velocities") else "rigid bodies"
                raise StateError(
                    f"{what}: {name} has shape {array.shape}, {self.name} needs {shape} (its"
                    f" {whose}); was the state made for another model?"
                )
            if array is not value:
                cast[name] = array
        n_actuators = self.n_actuators
        for name in ("actuation", "displacement", "displacement_before"):
            value = getattr(state, name)
            array = _real_array(value, what, name)
            if array.ndim != 1 or array.size not in (0, n_actuators):
                if strict or array.ndim != 1:
                    raise StateError(
                        f"{what}: {name} has shape {array.shape}, {self.name} has"
                        f" {n_actuators} actuators; was the state made for another model?"
                    )
                array = np.zeros(0)
            if array is not value:
                cast[name] = array
        forces = state.contact_forces
        if not isinstance(forces, ContactForces):
            raise StateError(f"{what}: contact_forces must be ContactForces")
        keys = np.asarray(forces.keys)
        values = _real_array(forces.forces, what, "contact forces")
        if keys.ndim != 2 or keys.shape[1] != 3 or keys.dtype.kind not in "iu":
            raise StateError(f"{what}: contact keys must be (k, 3) integers, got {keys.shape}")
        if values.shape != keys.shape:
            raise StateError(
                f"{what}: {keys.shape[0]} contact keys but contact forces of shape {values.shape}"
            )
        if type(state.time) is not float and (
            isinstance(state.time, bool) or not isinstance(state.time, numbers.Real)
        ):
            raise StateError(f"{what}: time must be a real number, got {state.time!r}")
        if not math.isfinite(state.time):
            raise StateError(f"{what}: time must be finite, got {state.time!r}")
        if type(state.step) is not int and (
            isinstance(state.step, bool) or not isinstance(state.step, numbers.Integral)
        ):
            raise StateError(f"{what}: step must be an integer, got {state.step!r}")
        if state.step < 0:
            raise StateError(f"{what}: step must be >= 0, got {state.step}")
        if not cast and values is forces.forces:
            return state
        kept = ("positions", "velocities", "actuation", "displacement", "displacement_before")
        arrays = {name: getattr(state, name) for name in (*kept, *State._RIGID)}
        return State(
            time=float(state.time),
            step=int(state.step),
            contact_forces=ContactForces(keys.astype(np.int64), values),
            layout=layout,
            **(arrays | cast),
        )

    def set_actuation(self, values: np.ndarray | list[float], mode: str | None = None) -> None:
        """Set every actuator's command (and, optionally, mode)."""
        vals = commands(values)
        if vals.size != self.n_actuators:
            raise ModelError(
                f"{self.name} has {self.n_actuators} actuators, got {vals.size} commands"
            )
        for act, v in zip(self.actuators, vals, strict=True):
            if mode is not None:
                act.mode = mode
            act.value = v

    def actuator_distances(self, positions: np.ndarray) -> np.ndarray:
        return self.distances(positions, actuators_only=True)

    def constraint_space(
        self,
        positions: np.ndarray,
        constraints: list[Constraint] | None = None,
        *,
        roles: tuple[str, ...] | None = None,
        extra: tuple[Constraint, ...] = (),
        with_distance: bool = True,
    ) -> ConstraintSpace:
        """Jacobians (and distances) of the constraints (default: actuators then effectors).

        `roles` keeps only the constraints of those roles (a direct step needs no effector
        rows); `extra` are appended (the contacts detected for a step); `with_distance=False`
        skips the distances (then all zeros).
        """
        cons = self._groups if constraints is None else constraints
        if roles is not None:
            cons = [c for c in cons if c.role in roles]
        cons = [*cons, *extra]
        body = self.body
        rows = sum(c.n_rows for c in cons)
        delta = np.zeros(rows)
        slices: dict[str, slice] = {}
        index, weights = [], []
        start = 0
        for c in cons:
            stop = start + c.n_rows
            if with_distance:
                delta[start:stop], jac = c.distance_and_jacobian(positions)
            else:
                jac = c.jacobian(positions)
            # Entry (free DoF d, row r) of H^T, flattened as d * rows + r.
            free = body.free_index[3 * jac.nodes[:, :, None] + np.arange(3)]
            keep = free >= 0
            row = np.arange(start, stop)[:, None, None]
            index.append((free * rows + row)[keep])
            weights.append(jac.values[keep])
            role = slices.get(c.role)
            slices[c.role] = slice(start if role is None else role.start, stop)
            start = stop
        ht = np.bincount(
            np.concatenate(index) if index else np.zeros(0, dtype=np.int64),
            weights=np.concatenate(weights) if weights else None,
            minlength=body.n_free * rows,
        ).reshape(body.n_free, rows)
        for role in ("actuator", "effector", "contact"):
            slices.setdefault(role, slice(rows, rows))
        return ConstraintSpace(delta, ht, slices)
