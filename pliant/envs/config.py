"""How an environment simulates, declared once: :class:`SimulationConfig` (time step, sub-steps,
action type, tangent policy, render mode), and the checks of the keyword arguments every
environment validates the same way.

Every environment takes ``config=SimulationConfig(...)`` or the config's fields as keywords
(``make("pliant/Diamond-v0", dt=0.02, substeps=3)``, as before the config existed); an
environment declares its own defaults once, as its class attribute ``default_config``, and no
environment re-declares the keywords: :meth:`SimulationConfig.updated` takes them out of the
constructor's keywords in :class:`pliant.envs.base.SoftRobotEnv`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any, Literal

import numpy as np

from pliant.errors import PliantError

ActionType = Literal["discrete", "continuous"]


class EnvConfigError(PliantError, ValueError):
    """An environment's keyword argument of the wrong kind or out of its range."""


@dataclass(frozen=True)
class SimulationConfig:
    """How an environment simulates its robot (frozen: an environment's config does not change).

    Attributes:
        dt: simulation time step (s).
        substeps: simulation steps per environment step (the commands are ramped over them).
        action_type: "discrete" or "continuous" (where the task offers both).
        tangent: the solver's factorisation policy (:mod:`pliant.solvers.system`).
        render_mode: None, "rgb_array" (offscreen frames) or "human" (a Matplotlib window).
    """

    dt: float = 0.01
    substeps: int = 5
    action_type: ActionType = "discrete"
    tangent: str = "lagged"
    render_mode: str | None = None

    def __post_init__(self) -> None:
        if not (isinstance(self.substeps, int | np.integer) and self.substeps >= 1):
            raise EnvConfigError(f"substeps must be an integer >= 1, got {self.substeps!r}")
        check_choice("action_type", self.action_type, ("discrete", "continuous"))
        object.__setattr__(self, "dt", float(self.dt))
        object.__setattr__(self, "substeps", int(self.substeps))

    @property
    def step_time(self) -> float:
        """Simulated seconds per environment step."""
        return self.dt * self.substeps


def with_keywords(group, keywords: dict[str, Any]):
    """The frozen dataclass `group` with the fields that `keywords` names, which are taken out
    of `keywords` (the rest are the environment's and its robot builder's)."""
    return replace(group, **taken(type(group), keywords))


def taken(group: type, keywords: dict[str, Any]) -> dict[str, Any]:
    """The keywords that name fields of the dataclass `group`, taken out of `keywords`."""
    return {f.name: keywords.pop(f.name) for f in fields(group) if f.name in keywords}


def check_choice(name: str, value, options: tuple) -> None:
    if value not in options:
        raise EnvConfigError(f"{name} must be one of {options}, got {value!r}")


def check_positive(name: str, value) -> float:
    """`value` as a float, or an error unless it is a finite number > 0."""
    if not (isinstance(value, int | float | np.number) and np.isfinite(value) and value > 0):
        raise EnvConfigError(f"{name} must be finite and > 0, got {value!r}")
    return float(value)


def check_interval(name: str, low, high, *, contains=None, floor=None, strict=True) -> None:
    """An error unless `name`_low <= `name`_high, with `contains` between them and `floor`
    below `name`_low (strictly unless ``strict=False``) when given."""
    ok = low <= high if contains is None else low <= contains <= high
    if floor is not None:
        ok = ok and (floor < low if strict else floor <= low)
    if not ok:
        bound = "" if floor is None else f"{floor:g} {'<' if strict else '<='} "
        middle = "" if contains is None else f" <= {contains:g}"
        raise EnvConfigError(f"need {bound}{name}_low{middle} <= {name}_high, got {low}, {high}")
