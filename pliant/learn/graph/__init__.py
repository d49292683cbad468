"""Hierarchical RL over contact configurations (thesis §4.2): a graph of configuration spaces,
a Selector, an Evaluator, and external and internal agents per node."""

from pliant.learn.graph.agents import (
    EXTERNAL_REWARDS,
    ControllerAgent,
    Evaluator,
    ExpertOption,
    ExternalAgent,
    InternalAgent,
    Selector,
    boundary_values,
    external_reward,
    option_transitions,
)
from pliant.learn.graph.baseline import FlatSAC
from pliant.learn.graph.graph import ConfigurationGraph, cartstem_graph, cartstem_partition
from pliant.learn.graph.hierarchy import GraphAgent, GraphConfig
from pliant.learn.graph.sac import SAC, ReplayBuffer

__all__ = [
    "EXTERNAL_REWARDS",
    "SAC",
    "ConfigurationGraph",
    "ControllerAgent",
    "Evaluator",
    "ExpertOption",
    "ExternalAgent",
    "FlatSAC",
    "GraphAgent",
    "GraphConfig",
    "InternalAgent",
    "ReplayBuffer",
    "Selector",
    "boundary_values",
    "cartstem_graph",
    "cartstem_partition",
    "external_reward",
    "option_transitions",
]
