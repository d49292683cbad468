"""Design optimisation of the parametric Soft Finger through its condensed model (thesis
§5.1.6, Eq. 5.17-5.20, Fig. 5.14-5.17).

Two objectives are built from the predicted matrices at a fixed pull of the cable:

* dexterity, O_dext = |alpha_max - alpha| (Eq. 5.17): alpha is the bending angle, the angle
  between the fingertip's chord from the finger's root at rest and pulled. (Eq. 5.17 writes it
  arccos(delta_e^z / |delta_e(0)|) for a finger along z whose chord keeps its length; the
  angle between the chords is the same angle without that assumption.)
* strength, O_str = |beta_max - beta| (Eq. 5.19): beta is the force the fingertip exerts,
  across the finger, on an object that holds it at its rest position (Eq. 5.18, the effector's
  row on that axis standing for the contact row). The object holds the tip across the finger
  only: held on all three axes, the tip of a pulled finger would have to be stretched back
  along the finger, against the held cables, and the force would measure that stretch.

Both are minimised: a grid search over the design box picks the start (the objectives are not
convex), then gradient descent through G and F refines it (Adam, kept in the box). The
weighted sum of the normalised objectives (Eq. 5.20) trades them along the Pareto front.
"""

from __future__ import annotations

import inspect
import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import torch
from torch import Tensor

from pliant.condensed.mechanics import blocked_force
from pliant.condensed.parametric import DesignMechanics, descend_in_design_box, effector_rows
from pliant.errors import LearnedModelError
from pliant.robots import soft_finger

Objective = Callable[[DesignMechanics, Tensor], Tensor]
"""(model, designs (n, P)) -> objective per design (n,), differentiable."""

_FINGER_HEIGHT = inspect.signature(soft_finger).parameters["height"].default


def _tip_rows(model: DesignMechanics) -> slice:
    """The effector rows, which must be one point on all three axes (a fingertip)."""
    effectors = model.layout.effectors
    if len(effectors) != 1 or len(effectors[0].goals) != 1 or effectors[0].axes != (0, 1, 2):
        raise LearnedModelError(
            "the design objectives need one effector point on the x, y and z axes (the"
            f" fingertip); the model has {[(e.name, e.axes, len(e.goals)) for e in effectors]}"
        )
    return model.layout.slices["effector"]


def _positions(model: DesignMechanics, rows: Tensor) -> Tensor:
    """Effector rows -> positions: p = rows / weight + training goal."""
    effector = model.layout.effectors[0]
    goal = torch.tensor(effector.goals[0], dtype=rows.dtype)
    return rows / effector.weight + goal


def finger_root(model: DesignMechanics, design: Tensor) -> Tensor:
    """The parametric Soft Finger's root, the centre of its fixed base face, (0, 0, height/2),
    (n, 3), its height a design parameter or the plan's."""
    names = model.design_names
    if "height" in names:
        height = design[:, names.index("height")]
    else:
        fixed = getattr(model, "plan", None)
        value = fixed.robot_kwargs.get("height", _FINGER_HEIGHT) if fixed else _FINGER_HEIGHT
        height = design.new_full((design.shape[0],), float(value))
    zero = torch.zeros_like(height)
    return torch.stack([zero, zero, 0.5 * height], dim=1)


@dataclass(frozen=True)
class FingerObjectives:
    """The two objectives of Fig. 5.14 at the cable displacements `command`.

    Args:
        command: actuator displacements delta_a of the pull (thesis: the cable by 10 mm; here
            cable 1 is held at its length, as in the design dataset).
        max_angle: alpha_max of Eq. 5.17 (pi/2, the finger at a right angle).
        max_force: beta_max of Eq. 5.19, out of reach (thesis 10 kN, here in mN).
        force_axis: the axis across the finger on which the tip force counts (z: cable 0 bends
            the finger towards -z).
    """

    command: tuple[float, ...] = (10.0, 0.0)
    max_angle: float = math.pi / 2
    max_force: float = 1e7
    force_axis: int = 2

    def _pull(self, design: Tensor) -> Tensor:
        return design.new_tensor(self.command).expand(design.shape[0], -1)

    def bending_angle(self, model: DesignMechanics, design: Tensor) -> Tensor:
        """alpha of Eq. 5.17 [rad], per design."""
        tip = _tip_rows(model)
        root = finger_root(model, design)
        _, rest_free = model.rest(design)
        at_rest = _positions(model, rest_free[:, tip]) - root
        pulled = _positions(model, effector_rows(model, self._pull(design), design)) - root
        cosine = torch.nn.functional.cosine_similarity(pulled, at_rest, dim=1)
        return torch.arccos(cosine.clamp(-1.0, 1.0 - 1e-12))

    def tip_force(self, model: DesignMechanics, design: Tensor) -> Tensor:
        """beta of Eq. 5.19, |lambda_c| of the tip held on `force_axis` (Eq. 5.18), per
        design."""
        row = _tip_rows(model).start + self.force_axis
        contact = slice(row, row + 1)
        w, free = model.matrices(self._pull(design), design)
        _, rest_free = model.rest(design)
        force = blocked_force(
            w,
            free,
            self._pull(design),
            model.layout.slices["actuator"],
            contact,
            rest_free[:, contact],
        )
        # a row weighted w has Jacobian w dp/dq: the force on the point is w lambda
        return force[:, 0].abs() * model.layout.effectors[0].weight

    def dexterity(self, model: DesignMechanics, design: Tensor) -> Tensor:
        """O_dext = |alpha_max - alpha| (Eq. 5.17)."""
        return (self.max_angle - self.bending_angle(model, design)).abs()

    def strength(self, model: DesignMechanics, design: Tensor) -> Tensor:
        """O_str = |beta_max - beta| (Eq. 5.19)."""
        return (self.max_force - self.tip_force(model, design)).abs()


def design_grid(model: DesignMechanics, counts: Sequence[int]) -> np.ndarray:
    """A regular grid over the design box, `counts` values per parameter, (prod, P)."""
    box = model.design_box
    if len(counts) != box.dim:
        raise LearnedModelError(f"{box.dim} design parameters, got {len(counts)} grid counts")
    axes = [np.linspace(lo, hi, n) for lo, hi, n in zip(box.low, box.high, counts, strict=True)]
    return np.array(list(itertools.product(*axes)))


def evaluate(model: DesignMechanics, objective: Objective, designs: np.ndarray) -> np.ndarray:
    """The objective at each design (n, P), without gradients."""
    with torch.no_grad():
        return objective(model, torch.as_tensor(designs, dtype=torch.float64)).numpy()


def normalised(objective: Objective, low: float, high: float) -> Objective:
    """O_norm = (O - low) / (high - low), low and high its extremes on a grid (Eq. 5.20)."""
    span = high - low if high > low else 1.0
    return lambda model, design: (objective(model, design) - low) / span


def weighted(objectives: Sequence[Objective], weights: Sequence[float]) -> Objective:
    """O_mult = sum gamma_i O_i (Eq. 5.20)."""
    return lambda model, design: sum(
        g * o(model, design) for g, o in zip(weights, objectives, strict=True)
    )


@dataclass
class Refinement:
    """The design gradient descent reached, and its history (objective and design)."""

    design: np.ndarray
    objective: float
    history: list[dict] = field(default_factory=list)


def refine(
    model: DesignMechanics,
    objective: Objective,
    start: np.ndarray,
    *,
    learning_rate: float = 0.01,
    iterations: int = 200,
    lr_factor: float = 0.5,
    lr_patience: int = 10,
) -> Refinement:
    """Gradient descent on the objective from `start` through G and F: Adam in the unit box
    of the design space, projected back into it, the rate cut on plateaus (§5.1.2)."""
    history = descend_in_design_box(
        model,
        start,
        lambda design: objective(model, design)[0],
        learning_rate=learning_rate,
        iterations=iterations,
        lr_factor=lr_factor,
        lr_patience=lr_patience,
    )
    best = min(history, key=lambda h: h["objective"])
    return Refinement(np.array([best[k] for k in model.design_names]), best["objective"], history)


def landscape(
    model: DesignMechanics,
    objective: Objective,
    centre: np.ndarray,
    pair: tuple[int, int],
    n: int = 25,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The objective on an n x n grid of two design parameters over the box, the others at
    `centre` (Fig. 5.15): (values of the first, values of the second, objective (n, n))."""
    box = model.design_box
    i, j = pair
    a = np.linspace(box.low[i], box.high[i], n)
    b = np.linspace(box.low[j], box.high[j], n)
    designs = np.repeat(np.asarray(centre, dtype=float)[None], n * n, axis=0)
    grid_a, grid_b = np.meshgrid(a, b, indexing="ij")
    designs[:, i], designs[:, j] = grid_a.ravel(), grid_b.ravel()
    return a, b, evaluate(model, objective, designs).reshape(n, n)


def pareto_front(objectives: np.ndarray) -> np.ndarray:
    """Mask of the non-dominated rows of (n, k) objectives, all minimised: no other row is at
    least as good on every objective and better on one."""
    values = np.asarray(objectives, dtype=float)
    dominated = np.zeros(len(values), dtype=bool)
    for k, row in enumerate(values):
        dominated[k] = np.any(np.all(values <= row, axis=1) & np.any(values < row, axis=1))
    return ~dominated


@dataclass
class DesignStudy:
    """Grid search, refinements, landscapes and Pareto front of the two objectives
    (Fig. 5.15-5.17).

    Attributes:
        grid: the designs searched (n, P); angle [rad] and force [mN] are alpha and beta there.
        refined: "dexterity", "strength" and "combined" (Eq. 5.20) refinements, each started
            from the best design of the grid.
        landscapes: objective -> [(pair of parameter indices, values of the first, values of
            the second, objective (n, n))] around that objective's start.
        pareto: mask of the grid designs on the Pareto front of (O_dext, O_str).
    """

    names: tuple[str, ...]
    objectives: FingerObjectives
    weights: tuple[float, float]
    grid: np.ndarray
    angle: np.ndarray
    force: np.ndarray
    dexterity: np.ndarray
    strength: np.ndarray
    pareto: np.ndarray
    refined: dict[str, Refinement]
    landscapes: dict[str, list[tuple[tuple[int, int], np.ndarray, np.ndarray, np.ndarray]]]

    def summary(self) -> dict:
        """The results as JSON-ready values (no landscapes)."""

        def design(values: np.ndarray) -> dict[str, float]:
            return {k: float(v) for k, v in zip(self.names, values, strict=True)}

        return {
            "command": list(self.objectives.command),
            "weights": list(self.weights),
            "grid_designs": len(self.grid),
            "pareto_designs": [design(d) for d in self.grid[self.pareto]],
            "refined": {
                name: {
                    "start": design(np.array([r.history[0][k] for k in self.names])),
                    "start_objective": r.history[0]["objective"],
                    "design": design(r.design),
                    "objective": r.objective,
                    "iterations": len(r.history) - 1,
                }
                for name, r in self.refined.items()
            },
            "grid_range": {
                "angle_rad": [float(self.angle.min()), float(self.angle.max())],
                "force_mN": [float(self.force.min()), float(self.force.max())],
            },
        }


def design_study(
    model: DesignMechanics,
    objectives: FingerObjectives | None = None,
    *,
    counts: Sequence[int] = (10, 6, 10),
    weights: tuple[float, float] = (0.5, 0.5),
    iterations: int = 200,
    learning_rate: float = 0.01,
    landscape_points: int = 25,
) -> DesignStudy:
    """Grid search of the design box (`counts` values per parameter, the thesis' 600
    designs by default), gradient refinement of each objective and of their weighted sum
    (Eq. 5.20, normalised by the grid's extremes) from the grid's best, and the landscapes
    around the single-objective starts."""
    objectives = objectives or FingerObjectives()
    grid = design_grid(model, counts)
    dexterity = evaluate(model, objectives.dexterity, grid)
    strength = evaluate(model, objectives.strength, grid)
    combined = weighted(
        [
            normalised(objectives.dexterity, dexterity.min(), dexterity.max()),
            normalised(objectives.strength, strength.min(), strength.max()),
        ],
        weights,
    )
    single = {"dexterity": objectives.dexterity, "strength": objectives.strength}
    grid_values = {"dexterity": dexterity, "strength": strength}
    grid_values["combined"] = evaluate(model, combined, grid)
    refined = {
        name: refine(
            model,
            objective,
            grid[int(np.argmin(grid_values[name]))],
            learning_rate=learning_rate,
            iterations=iterations,
        )
        for name, objective in {**single, "combined": combined}.items()
    }
    pairs = list(itertools.combinations(range(len(model.design_names)), 2))
    landscapes = {
        name: [
            (
                pair,
                *landscape(
                    model,
                    objective,
                    grid[int(np.argmin(grid_values[name]))],
                    pair,
                    landscape_points,
                ),
            )
            for pair in pairs
        ]
        for name, objective in single.items()
    }
    return DesignStudy(
        model.design_names,
        objectives,
        weights,
        grid,
        evaluate(model, objectives.bending_angle, grid),
        evaluate(model, objectives.tip_force, grid),
        dexterity,
        strength,
        pareto_front(np.column_stack([dexterity, strength])),
        refined,
        landscapes,
    )
