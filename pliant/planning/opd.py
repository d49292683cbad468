"""Optimistic planning for deterministic systems, OPD (Hren & Munos 2008; thesis §2.2.2 L184).

For every node of depth d reached by the rewards r_0 .. r_{d-1}, the discounted sum along its
path u = Σ_{k<d} γ^k r_k is a lower bound of the value of any sequence that starts with that
path (rewards are >= 0), and b = u + γ^d/(1-γ) an upper bound (rewards are <= 1). An inner node
carries the largest bounds of the leaves below it, so the root's upper bound is the best b of
the tree. Sampling is optimistic: the leaf with the largest upper bound is expanded, all its
children at once. Recommendation is conservative: the root child with the largest lower bound.

This is the rl-agents ``OptimisticDeterministicPlanner`` that SofaGym runs (wave2_facts A.3),
with a finite horizon as an option: with a maximum depth D the tail γ^d/(1-γ) becomes
Σ_{k=d}^{D-1} γ^k, which is exact for the D-step return.
"""

from __future__ import annotations

from dataclasses import dataclass

from pliant.errors import PlanningError
from pliant.planning.planner import Planner
from pliant.planning.simulator import Simulator
from pliant.planning.tree import Node, check_gamma, discounted_tail


@dataclass(eq=False, slots=True)
class OPDNode(Node):
    """A node with its depth d, its path value u and the bounds of the best sequence below it.

    Attributes:
        depth: d, the number of actions from the root.
        path_value: u = Σ_{k<d} γ^k r_k along the path from the root (Hren & Munos' u(i)).
        lower: the largest lower bound of the leaves below (a leaf: u, plus the terminal tail
            when the episode ended).
        upper: the largest upper bound of the leaves below (a leaf: b = u + Σ_{k=d}^{D-1} γ^k).
    """

    depth: int = 0
    path_value: float = 0.0
    lower: float = 0.0
    upper: float = 0.0


class OPD(Planner):
    """Optimistic planning for deterministic systems over saved states.

    The budget counts simulated environment steps, as in rl-agents: each expansion plays every
    action once, so a decision makes ``budget // n_actions`` expansions (and stops early when
    the leaf to expand has equal bounds: the best sequence is then known exactly).

    Args:
        budget: environment steps simulated per decision (at least the number of actions).
        gamma: discount factor γ.
        max_depth: D, the horizon of the return (None: infinite, γ < 1 then).
        terminal_reward: the reward (in [0, 1]) counted at every step after the episode ends:
            0 when ending is neutral, 1 when the end is an absorbing goal.
        reuse_tree: keep the played child's subtree for the next decision.

    Raises:
        PlanningError: γ outside (0, 1], γ = 1 without max_depth, terminal_reward outside
            [0, 1]; in ``plan``: a budget below the number of actions, or a reward outside
            [0, 1] (the bounds need it).
    """

    def __init__(
        self,
        *,
        budget: int = 200,
        gamma: float = 0.9,
        max_depth: int | None = None,
        terminal_reward: float = 0.0,
        reuse_tree: bool = True,
    ) -> None:
        super().__init__(budget=budget, gamma=gamma, reuse_tree=reuse_tree)
        check_gamma(self.gamma, max_depth)
        if max_depth is not None and max_depth < 1:
            raise PlanningError(f"max_depth must be >= 1 (or None), got {max_depth}")
        if not 0.0 <= terminal_reward <= 1.0:
            raise PlanningError(f"terminal_reward must lie in [0, 1], got {terminal_reward}")
        self.max_depth = max_depth
        self.terminal_reward = float(terminal_reward)

    def _new_root(self, state: object) -> OPDNode:
        root = OPDNode(parent=None, action=None, reward=0.0, done=False, state=state)
        self._bound_leaf(root)
        return root

    def _search(self, sim: Simulator) -> int:
        expansions = self.budget // sim.n_actions
        if expansions == 0:
            raise PlanningError(
                f"OPD's budget of {self.budget} simulated steps is below the {sim.n_actions}"
                " steps one expansion takes"
            )
        for spent in range(expansions):
            leaf = self._optimistic_leaf()
            if leaf.done or leaf.depth == self.max_depth:
                # Its bounds are equal and no other leaf's upper bound exceeds them: the best
                # sequence within the horizon is found, further steps would be wasted.
                return spent
            self._expand(sim, leaf)
            self._back_up(leaf)
        return expansions

    def _optimistic_leaf(self) -> OPDNode:
        """The leaf with the largest upper bound, found down the path of largest upper bounds
        (each inner node carries the largest bound below it)."""
        node = self.root
        while node.children:
            node = max(node.children.values(), key=lambda child: child.upper)
        return node

    def _expand(self, sim: Simulator, leaf: OPDNode) -> None:
        for action in sim.actions:
            sim.restore(leaf.state)
            transition = sim.step(action)
            if not 0.0 <= transition.reward <= 1.0:
                raise PlanningError(
                    f"OPD needs rewards in [0, 1] (its bounds assume them), action {action} gave"
                    f" {transition.reward}: clip or rescale the environment's reward"
                )
            child = OPDNode.reached(
                leaf,
                action,
                transition,
                sim.save(),
                depth=leaf.depth + 1,
                path_value=leaf.path_value + self.gamma**leaf.depth * transition.reward,
            )
            self._bound_leaf(child)
            leaf.children[action] = child
        leaf.state = None  # OPD never expands a node twice: only leaves need their snapshot

    def _bound_leaf(self, leaf: OPDNode) -> None:
        tail = discounted_tail(self.gamma, leaf.depth, self.max_depth)
        if leaf.done:  # nothing more to learn below: both bounds are the value
            leaf.lower = leaf.upper = leaf.path_value + self.terminal_reward * tail
        else:
            leaf.lower, leaf.upper = leaf.path_value, leaf.path_value + tail

    def _back_up(self, node: OPDNode | None) -> None:
        while node is not None:
            node.lower = max(child.lower for child in node.children.values())
            node.upper = max(child.upper for child in node.children.values())
            node = node.parent

    def _recommend(self) -> int:
        return max(self.root.children.values(), key=lambda child: child.lower).action

    def _reroot(self) -> None:
        """Recompute depths, path values and bounds from the new root.

        With an infinite horizon this is rl-agents' shift v <- (v - r_root)/γ of every value;
        recomputing keeps the finite horizon D receding with the root instead of shrinking.
        """
        nodes = list(self.root.subtree())
        self.root.depth, self.root.path_value = 0, 0.0
        for node in nodes[1:]:  # parents before children
            parent = node.parent
            node.depth = parent.depth + 1
            node.path_value = parent.path_value + self.gamma**parent.depth * node.reward
        for node in reversed(nodes):  # children before parents
            if node.children:
                node.lower = max(child.lower for child in node.children.values())
                node.upper = max(child.upper for child in node.children.values())
            else:
                self._bound_leaf(node)
