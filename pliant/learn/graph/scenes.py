"""The scenes the graph method is set up for: an environment, its graph, and the convex
controllers that may replace its internal agents."""

from __future__ import annotations

import numbers
from collections.abc import Callable
from dataclasses import dataclass, field

import gymnasium as gym
import numpy as np

from pliant.errors import ModelError
from pliant.learn.graph.agents import ExpertOption
from pliant.learn.graph.graph import ConfigurationGraph, cartstem_graph
from pliant.learn.graph.toy import CorridorEnv, corridor_controller, corridor_graph


@dataclass
class Scene:
    env: gym.Env
    graph: ConfigurationGraph
    #: node -> controller for ``--method convex`` (empty: the scene has none).
    controllers: dict[int, Callable[[np.ndarray], np.ndarray]]
    #: expert trajectories, more options of the Evaluator.
    experts: list[ExpertOption] = field(default_factory=list)
    #: node -> a controller kept inside that node's configuration space (empty: none).
    node_controllers: dict[int, Callable[[np.ndarray], np.ndarray]] = field(default_factory=dict)


def cartstem_controller(env: gym.Env) -> Callable[[np.ndarray], np.ndarray]:
    """Cart target that puts the tip over the goal if the beam's tip followed the cart rigidly
    (∂x_tip/∂x_cart = 1): argmin over |target| ≤ max_move of (x_tip + target − x_cart − x_goal)²,
    in closed form from the observation. Exact with no contact; wrong where the beam is bent
    over an obstacle (the tip then moves against the cart). :class:`CartStemStaticInverse` is
    the scene's convex agent; this one is kept as the reference it is compared with."""
    base = env.unwrapped

    def controller(obs: np.ndarray) -> np.ndarray:
        x_cart, x_tip, x_goal = obs[0], obs[1], obs[6]
        target = (x_cart + x_goal - x_tip) * base.length
        return np.clip([target / base.max_move], -1.0, 1.0)

    return controller


class CartStemStaticInverse:
    """The convex internal agent of CartStemContact on the FEM: the cart position that puts
    the beam's tip over the goal at static equilibrium, with the obstacles' contacts.

    The issue's inverse QP with the cart as the one actuator and the tip's x as the effector:
    min_c (x_tip(c) - x_goal)^2 over |c| <= max_move, by Gauss-Newton on the FEM statics.
    Each iteration solves the equilibrium (:class:`pliant.solvers.StaticSolver`, Signorini
    contacts with the obstacles) at the cart's position and ``probe`` mm further, which gives
    the tip's sensitivity dx_tip/dc there, contact response included (about 2 on the far side
    of an obstacle the beam is bent over, 1 with no contact); the step of the linearised,
    box-bounded least squares (a one-variable QP) is halved until the tip gets closer to the
    goal. It reads the environment's state (the FEM positions it starts each solve from), so
    it acts on the environment it was made for; ``iterations`` equilibria pairs a decision.
    Returned as the environment's action: the cart's target over ``max_move``."""

    def __init__(self, env: gym.Env, *, iterations: int = 3, probe: float = 0.5) -> None:
        from pliant.robots.cartstem import cartstem_contact
        from pliant.solvers import StaticSolver

        if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 0:
            raise ModelError(f"iterations must be an integer >= 0, got {iterations!r}")
        if not (np.isfinite(probe) and probe > 0):
            raise ModelError(f"probe must be a finite distance > 0 (mm), got {probe!r}")
        self.base = env.unwrapped
        self.iterations, self.probe = iterations, float(probe)
        self._cart = [0.0]  # the planning model's cart, set before each solve
        base = self.base
        self.model = cartstem_contact(cart_motion=lambda t: self._cart[0], **base.robot_kwargs)
        self.solver = StaticSolver(self.model)

    def equilibrium(self, cart: float, positions: np.ndarray) -> tuple[float, np.ndarray] | None:
        """The tip's x and the positions at equilibrium with the cart at `cart`, Newton started
        from `positions`; None where the solve fails (the step is then refused)."""
        from pliant.errors import DivergenceError

        self._cart[0] = float(cart)
        for mine, theirs in zip(
            self.model.contacts.shapes, self.base.model.contacts.shapes, strict=True
        ):  # the environment's obstacles, wherever its episode put them
            mine.position[:] = theirs.position
        self.model.trajectories_changed()
        state = self.model.rest_state()
        state.positions[:] = positions
        try:
            out = self.solver.step(state)
        except DivergenceError:
            return None
        return float(self.model.effectors[0].position(out.positions)[0, 0]), out.positions

    def target(
        self,
        goal: float,
        low: float | None = None,
        high: float | None = None,
        sweep: float | None = None,
    ) -> float:
        """The cart position this decision chooses for a tip goal `goal` (mm), within [low,
        high] (default: the cart's whole course, ±max_move). With ``sweep`` (mm), the
        Gauss-Newton starts from the best of the equilibria met on a continuation from the
        cart's position to both ends of [low, high] in steps of at most ``sweep`` (each solve
        started from the last): the tip's static response to the cart is not monotonic where
        the beam bends over an obstacle, and the local step alone stops at the near end."""
        base = self.base
        bound = base.max_move
        low = -bound if low is None else low
        high = bound if high is None else high
        cart = float(np.clip(base.cart_x(), low, high))
        found = self.equilibrium(cart, base.state.positions)
        if found is None:
            return cart
        tip, positions = found
        if sweep is not None:
            start = (cart, tip, positions)
            for end in (low, high):
                points = np.linspace(start[0], end, 1 + int(np.ceil(abs(end - start[0]) / sweep)))
                at = start[2]
                for point in points[1:]:
                    met = self.equilibrium(point, at)
                    if met is None:
                        break
                    at = met[1]
                    if abs(met[0] - goal) < abs(tip - goal):
                        cart, (tip, positions) = float(point), met
        for _ in range(self.iterations):
            error = tip - goal
            if abs(error) < 0.25 * base.goal_tolerance:
                break
            direction = -np.sign(error) or 1.0
            probe = self.equilibrium(cart + direction * self.probe, positions)
            if probe is None:
                break
            slope = (probe[0] - tip) / (direction * self.probe)
            if abs(slope) < 1e-3:  # the tip does not follow the cart here
                break
            step = float(np.clip(cart - error / slope, low, high)) - cart
            for _ in range(5):  # halve the step until the tip gets closer to the goal
                trial = self.equilibrium(cart + step, positions)
                if trial is not None and abs(trial[0] - goal) < abs(error):
                    cart, (tip, positions) = cart + step, trial
                    break
                step *= 0.5
            else:
                break
        return cart

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        goal = float(obs[6]) * self.base.length
        return np.array([self.target(goal) / self.base.max_move], dtype=np.float32)

    #: how far inside a node's cart interval its bounded inverse stays (mm), and the step of
    #: its continuation sweep (mm; see :meth:`target`)
    node_margin = 0.05
    node_sweep = 4.0

    def cart_range(self, obs: np.ndarray, node: int) -> tuple[float, float]:
        """The cart positions (mm) of node `node`'s configuration space by Eq. 4.7 (left
        contact, none, right contact), ``node_margin`` inside its boundaries and within the
        cart's course."""
        length, bound, margin = self.base.length, self.base.max_move, self.node_margin
        _, _, x_left, x_right, l_x, l_z = np.asarray(obs, dtype=float)[:6]
        half_diagonal = 0.5 * np.hypot(l_x, l_z)
        left, right = (x_left + half_diagonal) * length, (x_right - half_diagonal) * length
        low, high = {
            0: (-bound, left - margin),
            1: (left + margin, right - margin),
            2: (right + margin, bound),
        }[node]
        return max(low, -bound), min(high, bound)

    def in_node(self, node: int) -> Callable[[np.ndarray], np.ndarray]:
        """The inverse kept inside node `node`: its cart bounded to :meth:`cart_range`, as a QP
        of the node's contact configuration would be (the node's contact stays as it is), and
        started from the best point of a sweep over that interval (``node_sweep``), so that it
        solves the task from where the Evaluator sent the state instead of leaving the node by
        the nearest local step (a departure: the scene's default controllers are unbounded
        and local; docs/graph.md)."""
        if node not in (0, 1, 2):
            raise ModelError(f"CartStemContact has nodes 0, 1 and 2, got {node!r}")

        def controller(obs: np.ndarray) -> np.ndarray:
            low, high = self.cart_range(obs, node)
            goal = float(obs[6]) * self.base.length
            if low > high:  # no such interval on this observation: the whole course
                low, high = None, None
            cart = self.target(goal, low, high, sweep=self.node_sweep)
            return np.array([cart / self.base.max_move], dtype=np.float32)

        return controller


#: RodManipulator's settings for the graph: the base may go down to 20 mm (the pinch lowers
#: the fingertips beside the rod) and an episode lasts 60 steps (two re-contacts and their
#: strokes take 50 steps to 280°; the thesis' episodes have 30 steps of different fingers).
ROD_DEFAULTS = {"base_low": -20.0, "max_episode_steps": 60}


def make_scene(name: str, **env_kwargs) -> Scene:
    """``Corridor`` (the toy of the tests), ``CartStemContact`` (3 nodes by Eq. 4.7) or
    ``RodManipulator`` (3 nodes by collision detection, two re-contact experts; environment
    keywords over :data:`ROD_DEFAULTS`; ``expert_penalty`` charges each expert's use)."""
    if name == "Corridor":
        return Scene(
            CorridorEnv(**env_kwargs),
            corridor_graph(),
            dict.fromkeys(range(3), corridor_controller()),
        )
    if name == "CartStemContact":
        from pliant.envs import make

        env = make("pliant/CartStemContact-v0", **env_kwargs)
        inverse = CartStemStaticInverse(env)  # one planning model for the three nodes
        bounded = {node: inverse.in_node(node) for node in range(3)}
        return Scene(env, cartstem_graph(), dict.fromkeys(range(3), inverse), [], bounded)
    if name == "RodManipulator":
        from pliant.envs import make
        from pliant.learn.graph.rod import BendTable, RodGeometry, rod_experts, rod_graph

        penalty = env_kwargs.pop("expert_penalty", -1.0)
        if isinstance(penalty, bool) or not isinstance(penalty, numbers.Real):
            raise ModelError(f"expert_penalty must be a real number, got {penalty!r}")
        env = make("pliant/RodManipulator-v0", **{**ROD_DEFAULTS, **env_kwargs})
        # The fingers' bending, measured once (the experts' fingertip inverse); every episode
        # starts with a reset.
        table = BendTable.measure(env)
        geometry = RodGeometry.of(env)
        experts = rod_experts(env, geometry, table, float(penalty))
        return Scene(env, rod_graph(geometry), {}, experts)
    raise ModelError(f"no graph for scene {name!r}: Corridor, CartStemContact or RodManipulator")
