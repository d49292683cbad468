"""The scenes the graph method is set up for: an environment, its graph, and the convex
controllers that may replace its internal agents."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import gymnasium as gym
import numpy as np

from pliant.errors import ModelError
from pliant.learn.graph.graph import ConfigurationGraph, cartstem_graph
from pliant.learn.graph.toy import CorridorEnv, corridor_controller, corridor_graph


@dataclass
class Scene:
    env: gym.Env
    graph: ConfigurationGraph
    #: node -> controller for ``--internal convex``.
    controllers: dict[int, Callable[[np.ndarray], np.ndarray]]


def cartstem_controller(env: gym.Env) -> Callable[[np.ndarray], np.ndarray]:
    """Cart target that puts the tip over the goal if the beam's tip followed the cart rigidly
    (∂x_tip/∂x_cart = 1): argmin over |target| ≤ max_move of (x_tip + target − x_cart − x_goal)²,
    in closed form. A stand-in for the inverse QP/QPCC (which needs the model, not the
    observation the learners see)."""
    base = env.unwrapped

    def controller(obs: np.ndarray) -> np.ndarray:
        x_cart, x_tip, x_goal = obs[0], obs[1], obs[6]
        target = (x_cart + x_goal - x_tip) * base.length
        return np.clip([target / base.max_move], -1.0, 1.0)

    return controller


def make_scene(name: str, **env_kwargs) -> Scene:
    """``Corridor`` (the toy of the tests) or ``CartStemContact`` (3 nodes by Eq. 4.7)."""
    if name == "Corridor":
        return Scene(
            CorridorEnv(**env_kwargs),
            corridor_graph(),
            dict.fromkeys(range(3), corridor_controller()),
        )
    if name == "CartStemContact":
        from pliant.envs import make

        env = make("pliant/CartStemContact-v0", **env_kwargs)
        return Scene(env, cartstem_graph(), dict.fromkeys(range(3), cartstem_controller(env)))
    raise ModelError(f"no graph for scene {name!r}: Corridor or CartStemContact")
