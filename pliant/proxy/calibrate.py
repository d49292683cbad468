"""Calibration of a proxy on its FEM robot (thesis §4.1.1, L637, L692-696): the max
curvature, stiffness and mass of each beam group, chosen by Bayesian optimisation (Optuna's
TPE) to minimise the distance between matched points of the two models following one
actuation trajectory.

The trajectory's recorded positions are split: every 5th is an optimisation position, the
others validation positions, which check that the proxy interpolates between them (the
authors' code). The loss is the mean over positions and matched points of the Euclidean
distance. The study lives in a SQLite file when given one, and a run resumes it: it adds
trials until the study holds the number asked for. A resumed study draws what an uninterrupted
one would have, bit for bit, even after a SIGKILL: the sampler's generators are seeded before
each trial from the seed and the number of finished trials (:class:`ResumableTPE`), and a
trial left running by a killed process is marked failed and run again. The proxy then uses
its calibrated max curvatures times a safety factor < 1, under-using the actuation range it
was fitted on (thesis L694).

Positions identify the mass poorly (a heavier proxy sags a little more, and the loss barely
sees it), so a search may also hold the proxy's mass within a tolerance of the FEM robot's: a
constraint of the trial (Optuna's ``Trial.set_constraint``, which TPE honours), under which a
trial outside the tolerance ranks below every feasible one and is not simulated.

Positions also weigh a walking robot's travel little: the Multigait's points are mostly its
legs' shape, and a proxy within 4 mm of them may gain on an action where the FEM loses, which a
policy learnt on the proxy then exploits. A search may therefore add the travel to the loss:
the matched points' centroid moves over the floor during each action (an interval of the
trajectory), and the mean distance between the FEM's and the proxy's moves, weighted, joins
the point distance (Pliant's addition, not the thesis'). A search may also start from known
parameters (a previous calibration's), its first trial.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import optuna
from sqlalchemy.exc import SQLAlchemyError

from pliant.errors import CorruptFileError, ModelError, PliantError
from pliant.model import State
from pliant.proxy.builders import Proxy
from pliant.solvers import ImplicitEuler

# What a trial whose proxy diverged scores: worse than any finite distance it could reach.
_FAILED = 1e9


class ResumableTPE(optuna.samplers.TPESampler):
    """Optuna's TPE whose draws for a trial depend on `seed` and the study's finished trials
    only, not on what this process drew before: its generators are seeded before each trial
    from (`seed`, number of finished trials). A study resumed in a fresh process (after a
    kill) then goes on as the uninterrupted one did."""

    def __init__(self, *, seed: int = 0, **options) -> None:
        super().__init__(seed=seed, **options)
        self._base_seed = seed

    def before_trial(self, study: optuna.Study, trial: optuna.trial.FrozenTrial) -> None:
        finished = study.get_trials(deepcopy=False, states=_FINISHED)
        words = np.random.SeedSequence([self._base_seed, len(finished)]).generate_state(2)
        self._rng.rng.seed(int(words[0]))
        self._random_sampler._rng.rng.seed(int(words[1]))
        super().before_trial(study, trial)


_FINISHED = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)


def split(n_positions: int, *, every: int = 5) -> tuple[np.ndarray, np.ndarray]:
    """(optimisation, validation) indices of recorded positions: every `every`-th position
    (0, 5, 10, ...) for the optimisation, the others for validation."""
    index = np.arange(n_positions)
    return index[index % every == 0], index[index % every != 0]


def mean_distance(reference: np.ndarray, proxy: np.ndarray) -> float:
    """Mean over positions and points of |reference - proxy| ((T, K, 3) each)."""
    if reference.shape != proxy.shape:
        raise ModelError(f"matched points differ in shape: {reference.shape} vs {proxy.shape}")
    return float(np.linalg.norm(reference - proxy, axis=-1).mean())


def travel(points: np.ndarray, interval: int) -> np.ndarray:
    """(n, 2) how far the centroid of the matched points (T, K, 3) moved over the floor (x,
    y; gravity is along -z, and the centroid's height is the body's shape, which the points
    already weigh) over each interval of `interval` steps: from the end of the previous
    interval (the first from the first position) to the end of this one; a last, incomplete
    interval is left out."""
    if interval < 1 or interval > len(points):
        raise ModelError(f"a travel interval of {interval} steps does not fit {len(points)} steps")
    ends = np.arange(interval - 1, len(points), interval)
    centroid = points.mean(axis=1)[:, :2]
    return centroid[ends] - centroid[np.concatenate([[0], ends[:-1]])]


def travel_error(reference: np.ndarray, proxy: np.ndarray, interval: int) -> float:
    """Mean over intervals of |travel of reference - travel of proxy| (:func:`travel`)."""
    return float(
        np.linalg.norm(travel(reference, interval) - travel(proxy, interval), axis=-1).mean()
    )


def fitted_proxy(report: Mapping) -> dict:
    """The proxy builder's keywords of a calibration report (``pliant proxy calibrate``'s
    JSON): its fitted parameters, its contact where it is not the default node balls, and the
    layer its beams bend about where it is not their axis. ModelError if the report holds no
    numeric parameters, an unknown contact or an unknown layer."""
    try:
        keywords = {str(k): float(v) for k, v in report["parameters"].items()}
    except (KeyError, TypeError, ValueError, AttributeError):
        raise ModelError("not a calibration report: no numeric 'parameters'") from None
    for key, (default, other) in {
        "contact": ("nodes", "surface"),
        "neutral": ("axis", "underside"),
    }.items():
        value = report.get(key, default)
        if value not in (default, other):
            raise ModelError(
                f"a calibration report's {key} is {default!r} or {other!r}, got {value!r}"
            )
        if value != default:  # the builders' defaults are left out
            keywords[key] = value
    return keywords


def rollout(
    proxy: Proxy,
    commands: np.ndarray,
    points: Callable[[State], np.ndarray],
    *,
    dt: float = 0.01,
    settle: int = 0,
) -> np.ndarray:
    """(T, K, 3) matched points of `proxy` after each of the steps commanded by `commands`
    (T, n_controls), read from the state by `points`; first `settle` steps at zero commands
    from rest."""
    commands = np.atleast_2d(commands)
    solver, state = ImplicitEuler(proxy.model, dt), proxy.model.rest_state()
    proxy.apply(np.zeros(commands.shape[1]))
    for _ in range(settle):
        state = solver.step(state)
    out = []
    for u in commands:
        proxy.apply(u)
        state = solver.step(state)
        out.append(points(state))
    return np.array(out)


@dataclass(frozen=True)
class CalibrationResult:
    """The best trial's parameters, its errors (mm) on the optimisation and validation
    positions, how many finished trials the study holds, and the parameters the proxy is to use (max
    curvatures times the safety factor)."""

    parameters: dict[str, float]
    optimisation_error: float
    validation_error: float
    trials: int
    safety: float
    #: the proxy's mass with these parameters (when the search was given one), and how many
    #: of the study's trials met the mass constraint (all when there was none).
    mass: float | None = None
    feasible_trials: int | None = None
    #: with a travel term: the best trial's travel error (mm) and the loss it minimised
    #: (optimisation error + weight x travel error)
    travel_error: float | None = None
    loss: float | None = None

    @property
    def proxy_parameters(self) -> dict[str, float]:
        return {
            k: v * self.safety if k.endswith("curvature") else v for k, v in self.parameters.items()
        }


def calibrate(
    simulate: Callable[[dict[str, float]], np.ndarray],
    reference: np.ndarray,
    space: Mapping[str, tuple[float, float]],
    *,
    trials: int = 20,
    fixed: Mapping[str, float] | None = None,
    storage: str | None = None,
    study_name: str = "proxy",
    seed: int = 0,
    safety: float = 0.9,
    startup_trials: int = 10,
    every: int = 5,
    mass: Callable[[dict[str, float]], float] | None = None,
    target_mass: float | None = None,
    mass_tolerance: float | None = None,
    travel_weight: float = 0.0,
    travel_interval: int | None = None,
    start: Mapping[str, float] | None = None,
) -> CalibrationResult:
    """Fit the parameters in `space` (name -> (low, high), sampled uniformly) so that
    `simulate(parameters)` (T, K, 3) follows `reference` (T, K, 3) on the optimisation
    positions; `fixed` adds parameters held at a value.

    `storage`: an Optuna storage URL ("sqlite:///calibration.db") to keep and resume the
    study `study_name`; None keeps it in memory. The study is run until it holds `trials`
    finished trials. `safety` in (0, 1] scales the calibrated max curvatures
    (:attr:`CalibrationResult.proxy_parameters`).

    `mass(parameters)` is the proxy's mass; with `target_mass` (the FEM robot's) and
    `mass_tolerance` (a fraction) the search is constrained to |mass - target| <= tolerance *
    target, and the result is the best trial that meets it (ModelError if none does).

    `travel_weight` > 0 adds that weight times :func:`travel_error` over intervals of
    `travel_interval` steps (an action's) to the loss; the errors reported stay the points'.
    `start`: parameters the study tries first (those of `space` it names, inside its box), when
    it holds no trial yet.
    """
    reference = np.asarray(reference, dtype=float)
    if reference.ndim != 3 or reference.shape[-1] != 3 or len(reference) < every:
        raise ModelError(f"reference must be (T >= {every}, K, 3) points, got {reference.shape}")
    for name, (low, high) in space.items():
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise ModelError(f"search interval of {name} must be finite, low < high")
    if not 0.0 < safety <= 1.0:
        raise ModelError(f"the safety factor must lie in (0, 1], got {safety}")
    constrained = mass_tolerance is not None
    if constrained and (
        mass is None
        or target_mass is None
        or not (math.isfinite(target_mass) and target_mass > 0.0)
        or not (math.isfinite(mass_tolerance) and mass_tolerance > 0.0)
    ):
        raise ModelError(
            "a mass constraint needs the proxy's mass function, the FEM's mass (positive, got"
            f" {target_mass}) and a positive tolerance (got {mass_tolerance})"
        )
    if not (math.isfinite(travel_weight) and travel_weight >= 0.0):
        raise ModelError(f"the travel weight must be finite and >= 0, got {travel_weight}")
    if travel_weight > 0.0:
        if travel_interval is None:
            raise ModelError("a travel term needs the interval (steps) it is measured over")
        travel(reference, travel_interval)  # the interval fits the trajectory
    optimisation, validation = split(len(reference), every=every)
    fixed = dict(fixed or {})

    def parameters(trial: optuna.trial.BaseTrial) -> dict[str, float]:
        chosen = {name: trial.suggest_float(name, *bounds) for name, bounds in space.items()}
        return {**fixed, **chosen}

    def objective(trial: optuna.Trial) -> float:
        chosen = parameters(trial)
        if constrained:
            trial.set_user_attr("mass", float(mass(chosen)))
            excess = abs(trial.user_attrs["mass"] / target_mass - 1.0) - mass_tolerance
            trial.set_constraint("mass", excess)  # feasible when <= 0
            if excess > 0.0:  # ranked below every feasible trial by TPE: not simulated
                return _FAILED
        try:
            points = simulate(chosen)
        except PliantError as error:  # a diverging proxy: a bad corner of the box
            trial.set_user_attr("failure", str(error))
            return _FAILED
        trial.set_user_attr(
            "validation_error", mean_distance(reference[validation], points[validation])
        )
        error = mean_distance(reference[optimisation], points[optimisation])
        trial.set_user_attr("optimisation_error", error)
        if travel_weight == 0.0:
            return error
        trial.set_user_attr("travel_error", travel_error(reference, points, travel_interval))
        return error + travel_weight * trial.user_attrs["travel_error"]

    optuna.logging.set_verbosity(optuna.logging.WARNING)
    try:
        study = optuna.create_study(
            study_name=study_name,
            storage=storage,
            load_if_exists=True,
            direction="minimize",
            sampler=ResumableTPE(seed=seed, n_startup_trials=startup_trials),
        )
    except SQLAlchemyError as exc:  # a damaged SQLite file: "file is not a database", ...
        where = storage.removeprefix("sqlite:///") if storage else storage
        raise CorruptFileError(
            f"{where}: not a readable Optuna study ({type(exc).__name__}: {exc.args[0]});"
            " delete it to start the calibration again",
            where,
        ) from exc
    # Trials left running by a process that was killed: failed, and run again (their number
    # is skipped; TPE draws from the finished trials only).
    for trial in study.get_trials(deepcopy=False, states=(optuna.trial.TrialState.RUNNING,)):
        study.tell(trial.number, state=optuna.trial.TrialState.FAIL)
    begun = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.WAITING)
    if start is not None and not study.get_trials(deepcopy=False, states=begun):
        first = {k: float(v) for k, v in start.items() if k in space}
        outside = [k for k, v in first.items() if not space[k][0] <= v <= space[k][1]]
        if outside:
            raise ModelError(f"start values outside the search box: {sorted(outside)}")
        study.enqueue_trial(first)
    done = sum(t.state == optuna.trial.TrialState.COMPLETE for t in study.trials)
    if trials > done:
        study.optimize(objective, n_trials=trials - done)
    complete = [t for t in study.trials if t.state == optuna.trial.TrialState.COMPLETE]
    # Studies made before Optuna 5 hold the constraint as a list (read as key "0").
    feasible = [t for t in complete if all(v <= 0.0 for v in t.constraints.values())]
    if not feasible:
        raise ModelError(
            f"none of the {len(complete)} trials kept the proxy's mass within"
            f" {mass_tolerance:.0%} of {target_mass}: widen the tolerance or the density box"
        )
    best = min(feasible, key=lambda t: t.value)
    found = {**fixed, **best.params}
    return CalibrationResult(
        found,
        float(best.user_attrs.get("optimisation_error", best.value)),
        float(best.user_attrs.get("validation_error", math.nan)),
        len(complete),
        safety,
        None if mass is None else float(mass(found)),  # the best trial's only
        len(feasible),
        best.user_attrs.get("travel_error"),
        float(best.value),
    )


def command_sequence(patterns: Sequence[Sequence[float]], steps: int) -> np.ndarray:
    """(len(patterns) * steps, n) commands: each pattern held for `steps` steps."""
    return np.repeat(np.asarray(patterns, dtype=float), steps, axis=0)
