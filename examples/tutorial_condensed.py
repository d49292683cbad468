"""Tutorial: the learned condensed model (thesis §5.1). Collect a small dataset of the Soft
Finger's condensed matrices (W and delta_free at sampled cable displacements), train the network
F on it, then close the finger along goals with the learned matrices beside the exact ones."""

import tempfile
import time
import warnings
from pathlib import Path

from _common import QUICK, out

from pliant import StaticSolver, robots
from pliant.condensed import (
    CollectionPlan,
    ExactCondensed,
    OutOfBoundsWarning,
    TrainConfig,
    evaluate,
    follow_trajectory,
    train_condensed,
)
from pliant.condensed.collect import collect
from pliant.condensed.plots import plot_reached

# 1. Collect: each sample is a static equilibrium of the finger at cable displacements drawn
# from a scrambled Halton sequence in the box; W = H K^-1 H^T and delta_free are recorded.
plan = CollectionPlan(
    robot="finger",
    actuator_bounds=((-10.0, 10.0), (-10.0, 10.0)),  # mm, both cables
    n_train=24 if QUICK else 400,
)
start = time.perf_counter()
with tempfile.TemporaryDirectory() as folder:
    # workers=1 solves in this process; more spawn worker processes, which import the
    # script again: put the calls under `if __name__ == "__main__":` then.
    dataset = collect(plan, Path(folder) / "finger.h5", workers=1)
print(
    f"collected {len(dataset.train)} + {len(dataset.test)} samples"
    f" in {time.perf_counter() - start:.1f} s"
)

# 2. Train F: (delta_a, W0, delta0_free) -> (W upper triangle, delta_free), Eq. 5.4-5.5.
config = TrainConfig(
    epochs=30 if QUICK else 1000,
    hidden=(64, 64) if QUICK else (256, 256, 256),
    learning_rate=1e-3,
    progress=False,
)
learned, fit = train_condensed(dataset, config)
scores = evaluate(learned, dataset.test)
print(
    f"test loss {scores['loss']:.2e} (constant-W0 baseline {scores['baseline_loss']:.2e}),"
    f" best epoch {fit.best_epoch}"
)

# 3. Control: for each goal, W and delta_free at the robot's state from the network (or the
# FEM), the inverse QP, and the displacements it chose imposed on the FEM finger.
goals = robots.entry("finger").trajectories["closing"](3 if QUICK else 15)
finger = robots.build("finger")
with warnings.catch_warnings():
    warnings.simplefilter("ignore", OutOfBoundsWarning)  # goals near the box's edge
    reached = {
        "learned": follow_trajectory(finger, goals, learned, course=learned.input_box),
        "exact": follow_trajectory(
            finger, goals, ExactCondensed(finger, StaticSolver(finger)), course=learned.input_box
        ),
    }
for name, result in reached.items():
    print(
        f"{name}: distance to the goals mean {result.errors.mean():.3f} mm,"
        f" max {result.errors.max():.3f} mm"
    )
plot_reached(
    goals,
    {name: result.reached[:, 0] for name, result in reached.items()},
    out("condensed_finger.png"),
    plane=(0, 2),
    title="Soft Finger closing: learned vs exact condensed model",
)
