"""Closed-loop planning: plan a decision, play it on the real environment, re-root, repeat."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

from pliant.planning.planner import Planner, PlanStats


@dataclass
class EpisodeReport:
    """What an episode played by a planner did and cost.

    Attributes:
        actions: the actions played on the real environment.
        rewards: the rewards it returned (through its wrappers).
        terminated: the episode ended in a terminal state.
        truncated: the episode was cut (time limit) before that.
        wall_time: seconds for the whole episode: planning, real steps and ``on_step``.
        decisions: the planner's cost at each decision.
    """

    actions: list[int] = field(default_factory=list)
    rewards: list[float] = field(default_factory=list)
    terminated: bool = False
    truncated: bool = False
    wall_time: float = 0.0
    decisions: list[PlanStats] = field(default_factory=list)

    @property
    def total_reward(self) -> float:
        return float(sum(self.rewards))

    def discounted_return(self, gamma: float) -> float:
        """Σ_t γ^t r_t of the real rewards."""
        return float(sum(gamma**t * r for t, r in enumerate(self.rewards)))

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready summary: totals first, then the per-decision costs."""
        return {
            "steps": len(self.actions),
            "total_reward": self.total_reward,
            "terminated": self.terminated,
            "truncated": self.truncated,
            "wall_time": self.wall_time,
            "planning_time": sum(d.wall_time for d in self.decisions),
            "expansions": sum(d.expansions for d in self.decisions),
            "simulated_steps": sum(d.simulated_steps for d in self.decisions),
            "actions": self.actions,
            "rewards": self.rewards,
            "decisions": [asdict(d) for d in self.decisions],
        }


def run_episode(
    env: Any,
    planner: Planner,
    *,
    max_steps: int,
    seed: int | None = None,
    options: dict | None = None,
    on_step: Callable[[Any], None] | None = None,
) -> EpisodeReport:
    """Reset ``env`` (with ``seed`` and ``options``, e.g. a goal) and play up to ``max_steps``
    decisions of ``planner``.

    The planner's tree is cleared first and re-rooted on each played action.
    ``on_step(env)`` is called after the reset and after every real step (to render frames).
    """
    start = time.perf_counter()
    env.reset(seed=seed, options=options)
    planner.reset()
    report = EpisodeReport()
    if on_step is not None:
        on_step(env)
    for _ in range(max_steps):
        action = planner.plan(env)
        report.decisions.append(planner.last)
        _, reward, terminated, truncated, _ = env.step(action)
        planner.step(action)
        report.actions.append(int(action))
        report.rewards.append(float(reward))
        if on_step is not None:
            on_step(env)
        if terminated or truncated:
            report.terminated, report.truncated = bool(terminated), bool(truncated)
            break
    report.wall_time = time.perf_counter() - start
    return report
