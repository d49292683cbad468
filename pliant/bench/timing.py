"""Timed runs of a scene under each solver policy: steps per second, factorisations and the
contact solver's work per step (``pliant bench``)."""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from pliant.model import Model

# Solver options of each policy measured. "sofa-algorithm" is SOFA's scheme run by Pliant: a
# factorisation at every step, every contact within the margin in the constraint problem, and
# every constraint column solved (SOFA's LinearSolverConstraintCorrection builds W from one
# solve per constraint row).
POLICY_OPTIONS = {
    "pcg": {"tangent": "pcg"},
    "lagged": {"tangent": "lagged"},
    "fresh": {"tangent": "fresh"},
    "sofa-algorithm": {"tangent": "fresh", "point_compliance": False, "contact_screening": False},
}


@dataclass
class Measurement:
    scene: str
    tets: int
    policy: str
    steps_per_s: float
    repeats: list[float]
    factorisations_per_step: float
    sofa: float | None = None
    extra: dict = field(default_factory=dict)

    @property
    def speedup(self) -> float | None:
        return self.steps_per_s / self.sofa if self.sofa else None


@dataclass
class Timing:
    """Timed runs of one scene: steps/s of each, and per step the median factorisations, the
    mean contact-solver sweeps and Newton steps, the mean contacts, all of them, those of the
    body's points on rigid bodies and those solved (not screened out), and the mean contact
    solves (screening's rounds); 0 without contacts."""

    rates: list[float]
    factorisations_per_step: float
    sweeps_per_step: float
    newton_steps_per_step: float
    contacts_per_step: float
    body_contacts_per_step: float
    solved_contacts_per_step: float = 0.0
    contact_rounds_per_step: float = 0.0


def _contact_counts(model: Model, state) -> tuple[int, int]:
    """Contacts of the step that gave `state`, all and the body's points on rigid bodies."""
    contacts, keys = model.contacts, state.contact_forces.keys
    if contacts is None:
        return 0, 0
    on_bodies = (keys[:, 0] < len(contacts.points)) & (keys[:, 1] >= len(contacts.shapes))
    return len(keys), int(np.count_nonzero(on_bodies))


def time_steps(
    make_solver: Callable[[], object],
    state,
    control: Callable[[object], object],
    steps: int,
    repeats: int,
    warmup: int,
    *,
    from_rest: bool = False,
) -> Timing:
    """`repeats` runs of `steps` steps, each from the state after the warm-up; the contact
    figures are counted in the timer's pauses, after each step. With `from_rest`, as SOFA's
    batch runner times a scene: the warm-up steps are taken by a solver of their own (they warm
    the process: compilation, caches) and each run starts from `state` with a new solver, its
    first factorisation timed."""
    solver = make_solver()
    warm = state
    for _ in range(warmup):
        warm = solver.step(warm, control(warm))
    if not from_rest:
        state = warm
    rates, facts, sweeps, newton, counts = [], [], [], [], []
    for _ in range(repeats):
        if from_rest:
            solver = make_solver()
        s = state.copy()
        f0 = solver.system.factorisations
        elapsed = 0.0
        for _ in range(steps):
            t0 = time.perf_counter()
            s = solver.step(s, control(s))
            elapsed += time.perf_counter() - t0
            report = solver.last_report.contact
            sweeps.append(report.iterations if report is not None else 0)
            newton.append(report.newton_steps if report is not None else 0)
            total, on_bodies = _contact_counts(solver.model, s)
            screened = report.screened if report is not None else 0
            rounds = report.rounds if report is not None else 0
            counts.append((total, on_bodies, total - screened, rounds))
        rates.append(steps / elapsed)
        facts.append((solver.system.factorisations - f0) / steps)
    total, on_bodies, solved, rounds = np.mean(counts, axis=0)
    return Timing(
        rates,
        statistics.median(facts),
        float(np.mean(sweeps)),
        float(np.mean(newton)),
        float(total),
        float(on_bodies),
        float(solved),
        float(rounds),
    )
