"""Upper confidence bounds applied to trees, UCT (Kocsis & Szepesvári 2006; thesis §2.2.2).

Each iteration walks down the tree choosing, at every fully expanded node, the child j that
maximises the UCB1 index (Auer et al. 2002; KS06 Eq. 1, with C_p = c/√2)

    Q̄_j / S + c √(2 ln N / n_j),

where Q̄_j is the mean discounted return observed after playing j, n_j its visits, N the
parent's, and S = Σ_{k<H} γ^k the largest return of rewards in [0, 1] over the horizon H (the
index needs returns in [0, 1]; other rewards still work, with a differently weighted c). The
first node with an untried action gets one child, a rollout estimates the rest of the return up
to the horizon, and the discounted return is added to every node on the path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from pliant.errors import PlanningError
from pliant.planning.planner import Planner
from pliant.planning.simulator import Simulator
from pliant.planning.tree import Node, check_gamma, discounted_tail


@dataclass(eq=False, slots=True)
class UCTNode(Node):
    """A node with its visit count and the sum of the returns observed from it.

    Attributes:
        visits: iterations that passed through this node.
        return_sum: sum of the returns r + γ r' + ... observed from the transition into it
            (at the root: unused).
        untried: actions not yet played from it, in the random order they will be; None until
            the node is first reached.
    """

    visits: int = 0
    return_sum: float = 0.0
    untried: list[int] | None = None

    @property
    def mean(self) -> float:
        return self.return_sum / self.visits if self.visits else 0.0


class UCT(Planner):
    """UCT over saved states.

    The budget counts simulated environment steps, rollouts included: the search runs
    iterations until it has spent them (the last one may overrun by its rollout), and at most
    ``budget`` iterations, since one that ends on an ended node or at the horizon simulates
    nothing (a small tree searched to the horizon spends less).

    Args:
        budget: environment steps simulated per decision.
        gamma: discount factor γ.
        horizon: H, the depth (from the current root) below which nothing is simulated.
        exploration: c, the weight of UCB1's exploration term (1: UCB1 as Auer et al. state it).
        rollout: "random" plays uniformly random actions from a new node to the horizon;
            "none" counts nothing beyond the tree (a new node is worth its reward alone).
        recommend: "visits", the most visited root child (robust), or "mean", the best mean
            return.
        terminal_reward: the reward counted at every step after the episode ends, up to H.
        seed: seed of the random generator (the order of untried actions and the rollouts).
        reuse_tree: keep the played child's subtree, with its statistics, for the next decision.
    """

    def __init__(
        self,
        *,
        budget: int = 200,
        gamma: float = 0.9,
        horizon: int = 20,
        exploration: float = 1.0,
        rollout: Literal["random", "none"] = "random",
        recommend: Literal["visits", "mean"] = "visits",
        terminal_reward: float = 0.0,
        seed: int | None = None,
        reuse_tree: bool = True,
    ) -> None:
        super().__init__(budget=budget, gamma=gamma, reuse_tree=reuse_tree)
        check_gamma(self.gamma, horizon)
        if horizon < 1:
            raise PlanningError(f"the horizon must be >= 1, got {horizon}")
        if not exploration >= 0.0:
            raise PlanningError(f"the exploration constant must be >= 0, got {exploration}")
        if rollout not in ("random", "none"):
            raise PlanningError(f"rollout must be 'random' or 'none', got {rollout!r}")
        if recommend not in ("visits", "mean"):
            raise PlanningError(f"recommend must be 'visits' or 'mean', got {recommend!r}")
        self.horizon = int(horizon)
        self.exploration = float(exploration)
        self.rollout = rollout
        self.recommend = recommend
        self.terminal_reward = float(terminal_reward)
        self.rng = np.random.default_rng(seed)
        self._scale = discounted_tail(self.gamma, 0, self.horizon)

    def _new_root(self, state: object) -> UCTNode:
        return UCTNode(parent=None, action=None, reward=0.0, done=False, state=state)

    def _search(self, sim: Simulator) -> int:
        expansions = 0
        for _ in range(self.budget):
            if sim.steps >= self.budget:
                break
            path, tail, added = self._descend(sim)
            expansions += added
            self._back_up(path, tail)
        return expansions

    def _descend(self, sim: Simulator) -> tuple[list[UCTNode], float, bool]:
        """Select down to a new node (or a terminal one, or the horizon); returns the path from
        the root, the value estimated beyond its last node and whether that node is new."""
        node, path = self.root, [self.root]
        while not node.done and len(path) <= self.horizon:
            if node.untried is None:
                node.untried = [sim.actions[i] for i in self.rng.permutation(sim.n_actions)]
            if node.untried:
                child = self._add_child(sim, node, node.untried.pop())
                path.append(child)
                return path, self._estimate(sim, child, depth=len(path) - 1), True
            node = max(node.children.values(), key=lambda child: self._index(node, child))
            path.append(node)
        return path, self._end_value(node, depth=len(path) - 1), False

    def _add_child(self, sim: Simulator, node: UCTNode, action: int) -> UCTNode:
        sim.restore(node.state)
        transition = sim.step(action)
        child = UCTNode.reached(node, action, transition, sim.save())
        node.children[action] = child
        if not node.untried:
            node.state = None  # every action tried: no search starts from this node again
        return child

    def _index(self, parent: UCTNode, child: UCTNode) -> float:
        """UCB1 (KS06 Eq. 1) on returns scaled to [0, 1]."""
        return child.mean / self._scale + self.exploration * math.sqrt(
            2.0 * math.log(parent.visits) / child.visits
        )

    def _estimate(self, sim: Simulator, node: UCTNode, depth: int) -> float:
        """The return after ``node``, whose state the environment is in, up to the horizon:
        a random rollout, or nothing."""
        if node.done or self.rollout == "none" or depth >= self.horizon:
            return self._end_value(node, depth)
        value, weight = 0.0, 1.0
        for step in range(depth, self.horizon):
            transition = sim.step(int(self.rng.choice(sim.actions)))
            value += weight * transition.reward
            weight *= self.gamma
            if transition.done:
                return value + weight * self.terminal_reward * discounted_tail(
                    self.gamma, 0, self.horizon - step - 1
                )
        return value

    def _end_value(self, node: UCTNode, depth: int) -> float:
        """What follows a node the search stops at: the terminal reward to the horizon after an
        ended episode, nothing at the horizon (or without rollouts)."""
        if node.done:
            return self.terminal_reward * discounted_tail(self.gamma, 0, self.horizon - depth)
        return 0.0

    def _back_up(self, path: list[UCTNode], tail: float) -> None:
        value = tail
        for node in reversed(path[1:]):
            value = node.reward + self.gamma * value
            node.visits += 1
            node.return_sum += value
        path[0].visits += 1

    def _reroot(self) -> None:
        """Nothing to do: a node's statistics are returns from that node on, and the horizon is
        counted from whichever node is the root as the search descends."""

    def _recommend(self) -> int:
        children = self.root.children.values()
        if self.recommend == "visits":  # ties to the better mean
            return max(children, key=lambda child: (child.visits, child.mean)).action
        return max(children, key=lambda child: child.mean if child.visits else -math.inf).action
