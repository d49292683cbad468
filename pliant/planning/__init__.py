"""Tree search over saved simulation states (thesis §2.2.2): OPD and UCT.

A planner sees an environment only through its Gymnasium API and ``env.unwrapped``'s
``get_state``/``set_state``; it needs discrete actions and a deterministic simulation.
"""

from pliant.planning.opd import OPD
from pliant.planning.planner import Planner, PlanStats
from pliant.planning.run import EpisodeReport, run_episode
from pliant.planning.simulator import Simulator, check_restorable
from pliant.planning.uct import UCT

__all__ = [
    "OPD",
    "UCT",
    "EpisodeReport",
    "PlanStats",
    "Planner",
    "Simulator",
    "check_restorable",
    "run_episode",
]
