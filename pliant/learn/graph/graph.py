"""The configuration-space graph (thesis §4.2.1, Fig. 4.7).

A node is a configuration space S_i: the states that share one contact configuration; the
nodes cover the state space (⊔ S_i = S). Node i's neighbourhood V_i holds the nodes reachable
from S_i by a sequence of actions that crosses no third space. Which node a state belongs to is
given by a *partition function* on the observation (geometry, or a collision-detection callable)
or, where none is known, learned by the :class:`~pliant.learn.graph.agents.Selector`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import networkx as nx
import numpy as np

from pliant.errors import TrainingError

Partition = Callable[[np.ndarray], int]


class ConfigurationGraph:
    """Nodes (configuration spaces) and their neighbourhoods.

    Args:
        names: one name per node (its index is the node's label).
        neighbours: ``neighbours[i]`` = V_i, the nodes reachable from node i (i itself may be
            listed, as the thesis' CartStem edges [[0, 1], [0, 1, 2], [1, 2]] do; it is always
            reachable: choosing it means the internal agent).
        partition: observation -> node index, when the partition is known (geometry or
            collision detection); ``None`` when the Selector must learn it.
        start: the node episodes usually start in (informative only).
    """

    def __init__(
        self,
        names: Sequence[str],
        neighbours: Sequence[Sequence[int]],
        partition: Partition | None = None,
        start: int = 0,
    ) -> None:
        if len(names) != len(neighbours):
            raise TrainingError(f"{len(names)} names for {len(neighbours)} neighbourhoods")
        self.graph = nx.DiGraph()
        for i, name in enumerate(names):
            self.graph.add_node(i, name=name)
        for i, vi in enumerate(neighbours):
            for j in vi:
                if not 0 <= j < len(names):
                    raise TrainingError(f"node {i} lists neighbour {j}, not a node")
                if j != i:
                    self.graph.add_edge(i, j)
        self.partition = partition
        self.start = start

    @property
    def n_nodes(self) -> int:
        return self.graph.number_of_nodes()

    @property
    def names(self) -> list[str]:
        return [self.graph.nodes[i]["name"] for i in range(self.n_nodes)]

    def neighbours(self, i: int) -> list[int]:
        """V_i without i: the targets of node i's external agent."""
        return sorted(self.graph.successors(i))

    def reachable(self, i: int) -> list[int]:
        """V_i ∪ {i}: the Evaluator's choices in node i."""
        return sorted({i, *self.graph.successors(i)})

    def reachable_mask(self) -> np.ndarray:
        """(N, N) booleans, row i = V_i ∪ {i}."""
        mask = np.eye(self.n_nodes, dtype=bool)
        for i, j in self.graph.edges:
            mask[i, j] = True
        return mask

    def path(self, source: int, target: int) -> list[int]:
        """Shortest chain of configuration spaces from source to target."""
        return nx.shortest_path(self.graph, source, target)

    def node_of(self, obs: np.ndarray) -> int:
        if self.partition is None:
            raise TrainingError("this graph has no partition function: train a Selector")
        return int(self.partition(np.asarray(obs)))


def cartstem_partition(obs: np.ndarray) -> int:
    """CartStemContact's contact configuration from its observation, thesis Eq. 4.7:
    ``x_left + ½√(l_x² + l_z²) < x_cart < x_right − ½√(l_x² + l_z²)`` ⇒ no contact (node 1);
    at or left of the left bound ⇒ left contact (node 0); at or right of the right one ⇒ right
    contact (node 2). The observation is [x_cart, x_tip, x_left, x_right, l_x, l_z, x_goal]
    (all divided by the beam length: the test is scale free)."""
    x_cart, _, x_left, x_right, l_x, l_z = np.asarray(obs, dtype=float)[:6]
    half_diagonal = 0.5 * np.hypot(l_x, l_z)
    if x_cart <= x_left + half_diagonal:
        return 0
    if x_cart >= x_right - half_diagonal:
        return 2
    return 1


def cartstem_graph(partition: Partition | None = cartstem_partition) -> ConfigurationGraph:
    """The thesis' CartStemContact graph: left contact, no contact, right contact; edges
    [[0, 1], [0, 1, 2], [1, 2]]; episodes start in node 1 (D.2)."""
    return ConfigurationGraph(
        ["left contact", "no contact", "right contact"],
        [[0, 1], [0, 1, 2], [1, 2]],
        partition=partition,
        start=1,
    )
