"""What every tree-search planner shares: plan from the real state, leave it untouched, keep the
chosen subtree for the next decision, and count what the search cost."""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Any

from pliant.errors import PlanningError
from pliant.planning.simulator import Simulator
from pliant.planning.tree import Node


@dataclass(frozen=True, slots=True)
class PlanStats:
    """The cost of one call to ``plan``.

    Attributes:
        expansions: nodes expanded in this call (OPD: leaves given all their children; UCT:
            nodes added).
        simulated_steps: environment steps simulated in this call (UCT's rollouts included).
        wall_time: seconds spent in ``plan``, saving and restoring included.
        reused_nodes: nodes kept from the previous decisions when the call started.
        tree_size: nodes in the tree when the call returned.
    """

    expansions: int
    simulated_steps: int
    wall_time: float
    reused_nodes: int
    tree_size: int


class Planner(ABC):
    """Receding-horizon tree search over saved simulation states.

    Use: ``action = planner.plan(env)``, play ``action`` on the real environment, then
    ``planner.step(action)`` so the next search starts from the subtree it already built.

    Args:
        budget: environment steps the search may simulate per decision.
        gamma: discount factor γ of the return Σ γ^t r_t.
        reuse_tree: keep the chosen child's subtree between decisions (else start afresh).
    """

    def __init__(self, *, budget: int, gamma: float, reuse_tree: bool = True) -> None:
        if budget < 1:
            raise PlanningError(
                f"the budget (simulated steps per decision) must be >= 1, got {budget}"
            )
        self.budget = int(budget)
        self.gamma = float(gamma)
        self.reuse_tree = reuse_tree
        self.root: Node | None = None
        self.last: PlanStats | None = None

    def plan(self, env: Any) -> int:
        """Search from the environment's current state and return the recommended action.

        The environment is put back in the state it was in, whatever happens in the search.

        Raises:
            PlanningError: the environment cannot be planned over (see ``Simulator``), or the
                search met what its algorithm excludes.
        """
        start = time.perf_counter()
        sim = Simulator(env)
        real = sim.save()
        if self.root is None:
            self.root = self._new_root(real)
        reused = sum(1 for _ in self.root.subtree()) - 1
        try:
            expansions = self._search(sim)
        except BaseException:
            self.root = None  # a search cut short can leave a node half expanded
            raise
        finally:
            sim.restore(real)
        if not self.root.children:
            raise PlanningError("the search expanded nothing: the episode has ended at the root")
        action = self._recommend()
        self.last = PlanStats(
            expansions=expansions,
            simulated_steps=sim.steps,
            wall_time=time.perf_counter() - start,
            reused_nodes=reused,
            tree_size=sum(1 for _ in self.root.subtree()),
        )
        return action

    def step(self, action: int) -> None:
        """The real environment played ``action``: the matching child becomes the root.

        Its subtree stays valid because the environment is deterministic; without that child
        (or with ``reuse_tree=False``) the next ``plan`` starts a new tree.
        """
        child = self.root.children.get(action) if self.root is not None else None
        if child is None or not self.reuse_tree:
            self.root = None
        else:
            self.root = child.detach()
            self._reroot()

    def reset(self) -> None:
        """Forget the tree (a new episode)."""
        self.root = None
        self.last = None

    @abstractmethod
    def _new_root(self, state: object) -> Node:
        """A root holding the real state ``state``."""

    @abstractmethod
    def _search(self, sim: Simulator) -> int:
        """Grow the tree within the budget; returns the number of expansions."""

    @abstractmethod
    def _recommend(self) -> int:
        """The action to play, read from the root's children."""

    @abstractmethod
    def _reroot(self) -> None:
        """Bring the statistics of the new root's subtree to the new root."""
