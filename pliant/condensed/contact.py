"""Fixed contact points of the condensed model (thesis §5.1.4), held where an object puts them.

Contacts are points fixed in advance on the robot's surface (a mesh landmark), and the object
shares their locations (no Signorini or Coulomb law: the contact sticks). Their displacements
delta_c = p - p_ref are rows of the condensed problem after the actuators and the effectors,
and inputs of F beside delta_a (Eq. 5.2).

:class:`ContactRobot` solves the robot with its actuator *and* contact displacements imposed,
each contact row held by a displacement actuator of unbounded force (:class:`HeldRow`), whose
force is the contact force lambda_c: that is how the data are collected (the robot alone when
it has no contact points), and how the exact FEM plays the fingers of
:mod:`~pliant.condensed.manipulation`.
"""

from __future__ import annotations

import math

import numpy as np

from pliant.condensed.equilibrium import load_step, rest_equilibrium
from pliant.condensed.layout import Layout
from pliant.constraints.base import Actuator, EmbeddedPoints, JacobianRows
from pliant.constraints.condensed import CondensedProblem
from pliant.constraints.effector import PositionEffector
from pliant.errors import ModelError
from pliant.geometry.rotation import exp_map
from pliant.model import Model, State
from pliant.solvers import StaticSolver


class ContactPoints(PositionEffector):
    """Fixed contact points of §5.1.4: rows delta_c = p - p_ref, x, y and z of each point, with
    p_ref their positions in the undeformed mesh (the effector's goals)."""

    role = "contact"

    def __init__(self, points: EmbeddedPoints, rest_positions: np.ndarray, *, name: str) -> None:
        super().__init__(points, rest_positions, name=name)


class HeldRow(Actuator):
    """One row of contact points imposed like a cable in displacement, its force unbounded both
    ways: the force it takes is the contact force of that row."""

    def __init__(self, contact: ContactPoints, row: int) -> None:
        super().__init__(name=f"{contact.name}[{row}]", min_force=-math.inf, max_force=math.inf)
        self.contact = contact
        self.row = row

    def distance(self, x: np.ndarray) -> np.ndarray:
        return self.contact.distance(x)[self.row : self.row + 1]

    def jacobian(self, x: np.ndarray) -> JacobianRows:
        rows = self.contact.jacobian(x)
        return JacobianRows(
            rows.nodes[self.row : self.row + 1], rows.values[self.row : self.row + 1]
        )


def contact_points(model: Model, landmark: str) -> ContactPoints:
    """The contact points of `model` at its mesh landmark `landmark`."""
    mesh = model.body.mesh
    if landmark not in mesh.landmarks:
        raise ModelError(
            f"{model.name}'s mesh has no landmark {landmark!r} for contact points; it has"
            f" {sorted(mesh.landmarks)}"
        )
    points = np.atleast_2d(np.asarray(mesh.landmarks[landmark], dtype=float))
    return ContactPoints(EmbeddedPoints(mesh, points), model.body.rest_positions, name=landmark)


class ContactRobot:
    """A robot whose fixed contact points are held at imposed displacements with its actuators.

    Its exact condensed problem has the rows of its :attr:`layout`: actuators, effectors, then
    contacts. Without contact points (`contacts=""`) it is the robot alone, driven by its
    actuators; :func:`pliant.condensed.collect.collect` solves every plan through it.

    Args:
        model: the robot (no obstacles, drivers or rigid bodies).
        contacts: mesh landmark of its fixed contact points; "" for none.
        tolerance, max_iterations: Newton's (StaticSolver), the tolerance relative to the
            body size.
        max_increment: largest change of an imposed displacement in one static step.
        consistent: the tangent of W: the consistent one (with the cables' geometric
            stiffness) or SOFA's material tangent, the thesis' W (see
            CollectionPlan.consistent_tangent). The equilibria are solved on the consistent
            tangent either way (the same states, reached in fewer iterations).
    """

    @classmethod
    def for_plan(cls, model: Model, plan) -> ContactRobot:
        """The robot as a collection plan (:class:`pliant.condensed.dataset.CollectionPlan`)
        solves it: its contact points and static-solver settings."""
        return cls(
            model,
            plan.contacts,
            tolerance=plan.tolerance,
            max_iterations=plan.newton_iterations,
            max_increment=plan.max_increment,
            consistent=plan.consistent_tangent,
        )

    def __init__(
        self,
        model: Model,
        contacts: str = "",
        *,
        tolerance: float = 1e-8,
        max_iterations: int = 60,
        max_increment: float = 8.0,
        consistent: bool = True,
    ) -> None:
        self.model = model
        self.contact = contact_points(model, contacts) if contacts else None
        if self.contact is not None and (model.contacts or model.drivers or model.rigid_bodies):
            raise ModelError(
                f"{model.name}: fixed contact points are for a robot without obstacles, drivers"
                " or rigid bodies (the static solver holds them)"
            )
        held = [] if self.contact is None else [HeldRow(self.contact, r) for r in range(self.n_c)]
        self.held = (
            Model(
                model.body,
                actuators=[*model.actuators, *held],
                effectors=model.effectors,
                name=model.name,
            )
            if held
            else model
        )
        # Equilibria by Newton on the consistent tangent (quadratic, and robust where the
        # material tangent converges linearly or not at all); W from the tangent asked for.
        settings = {"tolerance": tolerance, "max_iterations": max_iterations}
        self.solver = StaticSolver(self.held, **settings)
        self._free_solver = StaticSolver(model, **settings) if held else self.solver
        self._compliance = (
            self.solver if consistent else StaticSolver(self.held, **settings, consistent=False)
        )
        self.max_increment = max_increment
        self.layout = Layout.of(model, () if self.contact is None else (self.contact,))
        na, ne, nc = (self.layout.counts[r] for r in ("actuator", "effector", "contact"))
        # the held model's rows are actuators, held contacts, effectors; the layout's
        # actuators, effectors, contacts
        self._order = np.r_[0:na, na + nc : na + nc + ne, na : na + nc]

    @property
    def n_a(self) -> int:
        return self.model.n_actuators

    @property
    def n_c(self) -> int:
        return 0 if self.contact is None else self.contact.n_rows

    @property
    def reference(self) -> np.ndarray:
        """p_ref of the contact points, (points, 3)."""
        return np.zeros((0, 3)) if self.contact is None else self.contact.goals

    def rest(self) -> State:
        """The equilibrium with every actuator and contact force zero, where W0 is taken."""
        return rest_equilibrium(self.held, self.solver)

    def solve(self, state: State, delta_a: np.ndarray, delta_c: np.ndarray | None = None) -> State:
        """The equilibrium for imposed actuator (and contact) displacements, load-stepped from
        `state`; DivergenceError where no step gets there."""
        target = np.concatenate([np.ravel(delta_a), np.zeros(0) if delta_c is None else delta_c])
        return load_step(self.held, self.solver, state, target, self.max_increment)

    def problem(self, state: State) -> CondensedProblem:
        """The exact W and delta_free at `state`, rows in layout order."""
        held = self._compliance.condense(state)
        order = self._order
        return CondensedProblem(
            held.compliance[np.ix_(order, order)], held.free_distance[order], self.layout.slices
        )

    def split(self, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(actuator part, contact part) of the held actuators' values."""
        return values[: self.n_a], values[self.n_a :]

    def contact_positions(self, state: State) -> np.ndarray:
        return self.reference + self.split(state.displacement)[1].reshape(-1, 3)

    def contact_stiffness(self, state: State) -> np.ndarray:
        """d lambda_c / d delta_c at `state` with the taut actuators' displacements held (slack
        ones at their force bound stay there): the inverse of W over those rows, its contact
        block."""
        problem = self.problem(state)
        lam_a = self.split(state.actuation)[0]
        taut = lam_a > np.array([a.min_force for a in self.model.actuators])
        rows = np.concatenate(
            [
                np.flatnonzero(taut),
                np.arange(self.layout.slices["contact"].start, problem.free_distance.size),
            ]
        )
        inverse = np.linalg.inv(problem.compliance[np.ix_(rows, rows)])
        return inverse[taut.sum() :, taut.sum() :]

    def release(self, state: State, delta_a: np.ndarray) -> State:
        """The equilibrium for actuator displacements delta_a with the contact points free
        (lambda_c = 0), from `state`, as a state of the held robot."""
        n_a = self.n_a
        free = State(
            state.positions,
            state.velocities,
            state.time,
            state.step,
            state.actuation[:n_a],
            state.displacement[:n_a],
        )
        free = load_step(self.model, self._free_solver, free, delta_a, self.max_increment)
        # load_step returns a state already at delta_a untouched, its contacts still held: one
        # more static step at delta_a releases them
        self.model.set_actuation(delta_a, mode="displacement")
        free = self._free_solver.step(free)
        return State(
            free.positions,
            free.velocities,
            free.time,
            free.step,
            np.concatenate([free.actuation, np.zeros(self.n_c)]),
            self.held.actuator_distances(free.positions),
        )

    def object_rows(self, state: State, displacement: np.ndarray) -> np.ndarray:
        """delta_c of the contact points moved rigidly from where they are at `state` by
        `displacement`: a translation, then optionally a rotation vector about their centroid."""
        points = self.contact_positions(state)
        center = points.mean(axis=0)
        motion = np.resize(np.append(displacement, np.zeros(6)), 6)
        moved = center + motion[:3] + (points - center) @ exp_map(motion[3:]).T
        return (moved - self.reference).ravel()


def sample_row(
    robot: ContactRobot,
    state: State,
    command: np.ndarray,
    params: np.ndarray,
    rest: tuple[np.ndarray, np.ndarray],
) -> dict[str, np.ndarray]:
    """One converged sample: what was imposed, what was reached, W and delta_free there."""
    w, free = robot.layout.pack(robot.problem(state))
    delta_a, delta_c = robot.split(state.displacement)
    return {
        "command": command,
        "design": params,
        "delta_a": delta_a,
        "delta_c": delta_c,
        "w_triangle": w,
        "free_distance": free,
        "w0_triangle": rest[0],
        "free_distance0": rest[1],
        "converged": np.array(True),
    }


def failed_row(command: np.ndarray, params: np.ndarray, layout: Layout) -> dict[str, np.ndarray]:
    """A sample whose static solve failed: NaN where a converged one has values."""
    nan = {
        "delta_a": layout.counts["actuator"],
        "delta_c": layout.counts["contact"],
        "w_triangle": layout.n_triangle,
        "free_distance": layout.n_rows,
        "w0_triangle": layout.n_triangle,
        "free_distance0": layout.n_rows,
    }
    row = {key: np.full(n, np.nan) for key, n in nan.items()}
    return {**row, "command": command, "design": params, "converged": np.array(False)}
