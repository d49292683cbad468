"""The search tree the planners grow (thesis §2.2.2, Fig. 2.5).

The root c_0 is the configuration the real system is in; a node c_i is the configuration reached
from its parent c_p(i) by the action a^i, and it keeps the saved simulation state so the search
can start from it again without replaying the path.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field

from pliant.errors import PlanningError


@dataclass(eq=False, slots=True)
class Node:
    """A configuration in the tree and the transition that reached it.

    Attributes:
        parent: the node this one was reached from; None at the root.
        action: the action played from the parent; None at a root built from the real state.
        reward: the reward received on that transition.
        done: that transition ended the episode (terminated or truncated): nothing follows.
        state: the snapshot from ``env.unwrapped.get_state()``; a planner drops it (None) once
            no search will start from this node again, since a FEM state weighs as much as its
            mesh.
        children: the nodes reached from this one, keyed by action, in the order they were
            added.
    """

    parent: Node | None
    action: int | None
    reward: float
    done: bool
    state: object | None
    children: dict[int, Node] = field(default_factory=dict)

    @classmethod
    def reached(cls, parent: Node, action: int, transition, state: object, **extra) -> Node:
        """The node that `transition` (its reward and done) from `parent` by `action` reached,
        with the snapshot `state` after it; `extra`: a planner's own fields."""
        reward, done = transition.reward, transition.done
        return cls(parent=parent, action=action, reward=reward, done=done, state=state, **extra)

    def subtree(self) -> Iterator[Node]:
        """This node and its descendants, parents before children (breadth first); iterative,
        since a search in a narrow tree can go deeper than Python's recursion limit."""
        level = [self]
        while level:
            yield from level
            level = [child for node in level for child in node.children.values()]

    def detach(self) -> Node:
        """Make this node a root (its parent forgets it); returns it."""
        self.parent = None
        return self


def discounted_tail(gamma: float, start: int, stop: int | None) -> float:
    """Σ_{k=start}^{stop-1} γ^k: the most discounted reward steps start..stop-1 can add when each
    reward is at most 1 (Hren & Munos 2008, the b-value's γ^d/(1-γ) for stop = ∞ = None)."""
    if stop is not None and stop <= start:
        return 0.0
    if gamma == 1.0:  # only reachable with a finite stop (the planners check)
        return float(stop - start)
    far = 0.0 if stop is None else gamma**stop
    return (gamma**start - far) / (1.0 - gamma)


def check_gamma(gamma: float, horizon: int | None) -> None:
    """γ must lie in (0, 1]; γ = 1 only with a finite horizon, where the sums stay finite."""
    if not 0.0 < gamma <= 1.0:  # NaN fails this too
        raise PlanningError(f"the discount factor gamma must lie in (0, 1], got {gamma}")
    if gamma == 1.0 and horizon is None:
        raise PlanningError("gamma = 1 needs a finite depth: the returns are unbounded otherwise")
