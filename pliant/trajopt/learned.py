"""MPC whose prediction is the learned condensed model (thesis §6.2.1), closed on the full FEM.

The learned model (:class:`pliant.condensed.LearnedCondensedModel`) gives, at an equilibrium
reached with actuator distances delta_a, the compliance W projected on the actuator and
effector rows and the free distances delta_free there (Eq. 5.2). At that equilibrium
delta = W lambda_eq + delta_free, so that forces u move the rows, to first order, to

    delta' = W(delta_a)[:, a] u + delta_free(delta_a)

(with W the consistent tangent's compliance, one Newton step of the static equilibrium under
u: the non-linearity is carried by delta_free and W, both functions of delta_a). The
prediction is this quasi-static map iterated over the horizon, on the state

    X = [p; p_dot; delta_a],   p = (delta_e + weight p_goal^train) / weight   (Eq. 5.6),

p_dot = (p' - p) / h a finite difference, so that the tasks' effector costs (position and
velocity) apply unchanged; no FEM is solved in the prediction. Its derivatives are those of
the network: the Jacobian with respect to delta_a is exact by forward-mode differentiation
through the layers (a product of the weight matrices scaled by the activations' derivatives,
for a ReLU MLP masked by the active units; the tests compare it with torch's autograd), a few
hundred microseconds for a whole horizon, where finite differences would need n_a + 1 network
calls per node and a step size against the kinks of the ReLUs.

The MPC loop (:class:`LearnedMPC`) measures the FEM state (p, p_dot and the actuator
distances of the state reached), solves the horizon with the box-DDP warm-started from the
last solution, and applies the first control to the FEM.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pliant.errors import DivergenceError, ModelError
from pliant.model import State
from pliant.trajopt.mpc import CondensedMPC
from pliant.trajopt.problem import QuadraticCost


class NetworkJacobian:
    """A learned model's network F as NumPy float64 operations, with its Jacobian with respect
    to the actuator distances (its first inputs); the other inputs are the rest values."""

    def __init__(self, learned) -> None:
        from torch import nn

        from pliant.condensed.networks import numpy_activation

        network = learned.network
        state = {k: v.detach().double().numpy().copy() for k, v in network.state_dict().items()}
        self.in_mean, self.in_scale = state["input_scale.mean"], state["input_scale.scale"]
        self.out_mean, self.out_scale = state["output_scale.mean"], state["output_scale.scale"]
        self.layers = [
            (m.weight.detach().double().numpy().T.copy(), m.bias.detach().double().numpy().copy())
            for m in network.net
            if isinstance(m, nn.Linear)
        ]
        self.activation, self.derivative = numpy_activation(network.activation)
        self.n_active = learned.input_box.dim
        self.rest = np.concatenate(learned.rest)

    def __call__(self, delta: np.ndarray, *, jacobian: bool = False):
        """Outputs (B, n_out) at actuator distances delta (B, n_a) and, with `jacobian`,
        d outputs / d delta (B, n_a, n_out)."""
        delta = np.atleast_2d(delta)
        x = np.hstack([delta, np.broadcast_to(self.rest, (delta.shape[0], self.rest.size))])
        h = (x - self.in_mean) / self.in_scale
        tangent = None
        if jacobian:
            first = np.zeros((self.n_active, x.shape[1]))
            first[:, : self.n_active] = np.diag(1.0 / self.in_scale[: self.n_active])
            tangent = np.broadcast_to(first, (delta.shape[0], *first.shape))
        last = len(self.layers) - 1
        for k, (weight, bias) in enumerate(self.layers):
            h = h @ weight + bias
            if tangent is not None:
                tangent = tangent @ weight
            if k < last:
                if tangent is not None:
                    tangent = tangent * self.derivative(h)[:, None, :]
                h = self.activation(h)
        y = h * self.out_scale + self.out_mean
        return (y, tangent * self.out_scale) if jacobian else y


@dataclass
class LearnedRollout:
    """A prediction: states (N + 1, 2m + n_a) and controls (N, n_a)."""

    xs: np.ndarray
    us: np.ndarray


class LearnedCondensedDynamics:
    """The quasi-static condensed dynamics predicted by a learned condensed model (see the
    module's docstring), with the DDP's interface (rollout, derivatives).

    Args:
        learned: a LearnedCondensedModel of a robot without contact rows.
        dt: the time step h of the velocity p_dot (the control period).
    """

    def __init__(self, learned, dt: float) -> None:
        layout = learned.layout
        if layout.counts["contact"]:
            raise ModelError(
                "the learned prediction takes a model of actuators and effectors only; this one"
                f" has {layout.counts['contact']} contact rows"
            )
        self.learned = learned
        self.network = NetworkJacobian(learned)
        self.dt = float(dt)
        self.n_controls = layout.counts["actuator"]
        self.n_positions = layout.counts["effector"]
        self.n_state = 2 * self.n_positions + self.n_controls
        self._weights = np.concatenate([np.full(e.n_rows, e.weight) for e in layout.effectors])
        self._goal_rows = layout.training_goal_rows
        # Columns of W's actuator block, rows in layout order, as indices into the triangle.
        n = layout.n_rows
        index = np.zeros((n, n), dtype=int)
        rows, cols = layout.triangle
        index[rows, cols] = index[cols, rows] = np.arange(rows.size)
        self._w_columns = index[:, : self.n_controls]
        self._n_triangle = layout.n_triangle

    def blocks(self, delta_a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """W[:, actuators] (n_rows, n_a) and delta_free (n_rows,) at actuator distances
        delta_a: actuator rows first, then effector rows (layout order)."""
        y = self.network(delta_a)[0]
        return y[self._w_columns], y[self._n_triangle :]

    def positions(self, delta_e: np.ndarray) -> np.ndarray:
        """Effector positions p of effector rows delta_e (Eq. 5.6 read backwards)."""
        return (delta_e + self._goal_rows) / self._weights

    def state(self, x: np.ndarray, delta_a: np.ndarray) -> np.ndarray:
        """X = [p; p_dot; delta_a] of a measured effector state x = [p; p_dot]."""
        return np.concatenate([x, delta_a])

    def next_state(self, x: np.ndarray, u: np.ndarray) -> np.ndarray:
        m, n_a = self.n_positions, self.n_controls
        w, free = self.blocks(x[2 * m :])
        delta = w @ u + free
        p = self.positions(delta[n_a:])
        return np.concatenate([p, (p - x[:m]) / self.dt, delta[:n_a]])

    def rollout(self, start: np.ndarray, us: np.ndarray, *, policy=None) -> LearnedRollout:
        us = np.array(us, dtype=float)
        n = us.shape[0]
        xs = np.zeros((n + 1, self.n_state))
        xs[0] = start
        for k in range(n):
            if policy is not None:
                us[k] = policy(k, xs[k], us[k])
            xs[k + 1] = self.next_state(xs[k], us[k])
            if not np.all(np.isfinite(xs[k + 1])):
                raise DivergenceError(
                    f"the learned prediction diverged at node {k}", step=k, cause="rollout"
                )
        return LearnedRollout(xs, us)

    def derivatives(self, rollout: LearnedRollout) -> tuple[np.ndarray, np.ndarray]:
        """Fx (N, n_x, n_x) and Fu (N, n_x, n_a) of the prediction along a rollout."""
        m, n_a, h = self.n_positions, self.n_controls, self.dt
        us = rollout.us
        n = us.shape[0]
        y, dy = self.network(rollout.xs[:n, 2 * m :], jacobian=True)
        w = y[:, self._w_columns]  # (N, n_rows, n_a)
        dw = dy[:, :, self._w_columns]  # (N, n_a (d delta_a), n_rows, n_a (u))
        # d delta' / d delta_a = dW/d delta_a u + d delta_free / d delta_a: (N, n_rows, n_a)
        g = np.einsum("kjru,ku->krj", dw, us) + np.transpose(
            dy[:, :, self._n_triangle :], (0, 2, 1)
        )
        scale = 1.0 / self._weights[:, None]
        fx = np.zeros((n, self.n_state, self.n_state))
        fx[:, :m, 2 * m :] = scale * g[:, n_a:]
        fx[:, m : 2 * m, :m] = -np.eye(m) / h
        fx[:, m : 2 * m, 2 * m :] = scale * g[:, n_a:] / h
        fx[:, 2 * m :, 2 * m :] = g[:, :n_a]
        fu = np.concatenate([scale * w[:, n_a:], scale * w[:, n_a:] / h, w[:, :n_a]], axis=1)
        return fx, fu


class LearnedMPC(CondensedMPC):
    """Receding-horizon control whose prediction is :class:`LearnedCondensedDynamics` and
    whose plant is the FEM of `dynamics` (a :class:`CondensedDynamics`: its steps, and the
    effector state it measures).

    Args:
        dynamics: the robot's condensed dynamics (the plant and its measurements).
        learned: the learned condensed model of the same robot (its layout is checked).
        cost, bounds, horizon, max_iterations: as :class:`CondensedMPC`.
    """

    def __init__(self, dynamics, learned, cost, bounds, *, horizon=20, max_iterations=5) -> None:
        super().__init__(dynamics, cost, bounds, horizon=horizon, max_iterations=max_iterations)
        learned.check(dynamics.model)
        self.prediction = LearnedCondensedDynamics(learned, dynamics.dt)
        self.box = learned.input_box
        self.extrapolation = 0.0  # the farthest a measured state was outside the data's box

    def _prediction(self, state: State, x: np.ndarray, w_ea, free):
        distances = self.dynamics.model.actuator_distances(state.positions)
        outside = float(self.box.distance(distances)[0])
        self.extrapolation = max(self.extrapolation, outside)
        return self.prediction, self.prediction.state(x, distances)

    def _window(self, k: int) -> QuadraticCost:
        """The task's window with the actuator distances in the state, unweighted."""
        window = super()._window(k)
        n_a = self.prediction.n_controls
        pad = np.zeros((window.state_reference.shape[0], n_a))
        return QuadraticCost(
            np.hstack([window.state_reference, pad]),
            np.hstack([window.state_weights, pad]),
            window.control_weights,
            window.control_reference,
        )
