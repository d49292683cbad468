"""Routing design: move a cable through the body so that an effector reaches further for the
same actuation, by L-BFGS-B on the exact gradient of the equilibrium (the implicit-function
theorem, :mod:`pliant.diff.static`) with respect to the cable's routing points
(:mod:`pliant.diff.routing`), each point kept in a box inside the body.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import optimize

from pliant.constraints.control import DirectControl
from pliant.diff.routing import rerouted, routing_points, routing_slices
from pliant.diff.static import static_gradient
from pliant.errors import DivergenceError, ModelError
from pliant.model import Model
from pliant.solvers.static import StaticSolver


class RoutingDesign:
    """How far an effector point travels along a direction, at static equilibrium, for a
    fixed actuation, as a function of the routing coordinates of one cable: the objective of
    a routing design.

    The design vector theta holds the coordinates `free` (a (k, 3) mask over the cable's
    points) of the cable's routing points; the others stay where `model` has them. Each
    evaluation reroutes the model (:func:`rerouted`), solves the equilibrium from rest under
    `commands` (:class:`pliant.solvers.StaticSolver`) and reads the reach
    e . (p - p_rest) of the effector's point `point` along the unit vector e of `direction`
    (default -z: how far a closing finger's tip comes down); :meth:`reach_and_gradient` adds
    its gradient by the implicit-function theorem (:func:`pliant.diff.static.static_gradient`).

    Attributes:
        solves: equilibria solved so far; adjoints: gradients taken so far.
    """

    def __init__(
        self,
        model: Model,
        cable: str,
        commands: np.ndarray,
        *,
        free: np.ndarray | None = None,
        effector: int = 0,
        point: int = 0,
        direction=(0.0, 0.0, -1.0),
    ) -> None:
        slices = routing_slices(model)
        if cable not in slices:
            raise ModelError(f"no cable named {cable!r}; the model's cables: {sorted(slices)}")
        self.model, self.rows = model, slices[cable]
        self.commands = np.asarray(commands, dtype=float)
        if self.commands.shape != (model.n_actuators,):
            raise ModelError(f"commands must be ({model.n_actuators},), got {self.commands.shape}")
        k = self.rows.stop - self.rows.start
        self.free = np.ones((k, 3), bool) if free is None else np.asarray(free, dtype=bool)
        if self.free.shape != (k, 3):
            raise ModelError(f"free must be a ({k}, 3) mask over {cable}'s points")
        self.points_now = routing_points(model)
        self.effector = model.effectors[effector].points
        self.point = point
        direction = np.asarray(direction, dtype=float)
        if direction.shape != (3,) or not np.linalg.norm(direction) > 0:
            raise ModelError(f"direction must be a non-zero 3-vector, got {direction!r}")
        self.direction = direction / np.linalg.norm(direction)
        self.rest_tip = self.effector.positions(model.body.rest_positions)[point]
        self.solves = 0
        self.adjoints = 0

    @property
    def initial(self) -> np.ndarray:
        """theta of `model`'s own routing."""
        return self.points_now[self.rows][self.free]

    def points(self, theta: np.ndarray) -> np.ndarray:
        """All routing points (P, 3) for the design vector `theta`."""
        out = self.points_now.copy()
        cable = out[self.rows]
        cable[self.free] = np.asarray(theta, dtype=float)
        out[self.rows] = cable
        return out

    def _solve(self, theta):
        model = rerouted(self.model, self.points(theta))
        solver = StaticSolver(model)
        equilibrium = solver.step(model.rest_state(), DirectControl(self.commands.copy()))
        self.solves += 1
        moved = self.effector.positions(equilibrium.positions)[self.point] - self.rest_tip
        return model, solver, equilibrium, moved

    def reach(self, theta: np.ndarray) -> float:
        """e . (p - p_rest) of the effector point at equilibrium (one static solve)."""
        return float(self.direction @ self._solve(theta)[3])

    def reach_and_gradient(self, theta: np.ndarray) -> tuple[float, np.ndarray]:
        """The reach and its gradient in theta (one static solve and its adjoint)."""
        model, solver, equilibrium, moved = self._solve(theta)
        reach = float(self.direction @ moved)
        grad_q = np.zeros_like(equilibrium.positions)
        weights = self.effector.weights[self.point]
        np.add.at(grad_q, self.effector.nodes[self.point], weights[:, None] * self.direction)
        grads = static_gradient(
            model, solver, equilibrium, self.commands, grad_q, wrt=("cable_routing",)
        )
        self.adjoints += 1
        return reach, grads["cable_routing"][self.rows][self.free]


@dataclass
class DesignResult:
    """An optimisation of a routing design.

    Attributes:
        theta: the best design vector found; reach: its reach.
        history: (solves so far, reach) after each evaluation, in order.
        solves, adjoints: equilibria solved and gradients taken in all.
        failed: evaluations whose equilibrium failed (counted as reach 0).
    """

    theta: np.ndarray
    reach: float
    history: list[tuple[int, float]] = field(default_factory=list)
    solves: int = 0
    adjoints: int = 0
    failed: int = 0


def optimise_routing(
    design: RoutingDesign,
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    method: str = "L-BFGS-B",
    max_solves: int = 50,
    initial: np.ndarray | None = None,
) -> DesignResult:
    """Maximise the design's reach within the box [lower, upper] by scipy's L-BFGS-B on the
    exact gradient (one solve and one adjoint per evaluation) or by Nelder-Mead (bounded,
    derivative-free), stopping after `max_solves` equilibria. An equilibrium that fails to
    converge (DivergenceError) counts as a solve of reach 0.

    Raises:
        ModelError: unknown method, lower > upper, a start outside the box.
    """
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    theta0 = design.initial if initial is None else np.asarray(initial, float)
    if lower.shape != theta0.shape or upper.shape != theta0.shape or np.any(lower > upper):
        raise ModelError(f"bounds must be {theta0.shape} with lower <= upper")
    if np.any(theta0 < lower) or np.any(theta0 > upper):
        raise ModelError("the initial design lies outside the bounds")
    if method not in ("L-BFGS-B", "Nelder-Mead"):
        raise ModelError(f"method must be 'L-BFGS-B' or 'Nelder-Mead', got {method!r}")
    out = DesignResult(theta0.copy(), 0.0)
    start = (design.solves, design.adjoints)

    class Spent(Exception):
        pass

    def record(theta, value):
        out.history.append((design.solves - start[0], value))
        if value > out.reach:
            out.theta, out.reach = np.array(theta, float), value

    def evaluate(theta, gradient):
        if design.solves - start[0] >= max_solves:
            raise Spent
        try:
            value, grad = (
                design.reach_and_gradient(theta) if gradient else (design.reach(theta), None)
            )
        except DivergenceError:
            design.solves += 1
            out.failed += 1
            value, grad = 0.0, np.zeros_like(theta)
        record(theta, value)
        return (-value, -grad) if gradient else -value

    bounds = list(zip(lower, upper, strict=True))
    try:
        if method == "L-BFGS-B":
            optimize.minimize(
                evaluate,
                theta0,
                args=(True,),
                jac=True,
                method=method,
                bounds=bounds,
                options={"maxfun": max_solves, "ftol": 1e-12, "gtol": 1e-9},
            )
        else:
            optimize.minimize(
                evaluate,
                theta0,
                args=(False,),
                method=method,
                bounds=bounds,
                options={"maxfev": max_solves, "xatol": 1e-6, "fatol": 1e-9},
            )
    except Spent:
        pass
    out.solves = design.solves - start[0]
    out.adjoints = design.adjoints - start[1]
    return out
