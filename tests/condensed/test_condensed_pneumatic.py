"""The learned condensed model of a pneumatic robot (thesis §5.1.5, the Stiff-Flop): W is the
compliance to a change of pressure, collection imposes the cavities' volume changes, the plant
is driven in pressure, and Algorithm 2 runs on the model's own volumes
delta_a = W_aa lambda_a + delta_a_free. On a coarse PneuNet (one
cavity, 329 nodes) at pressures below 4 kPa, where its unreinforced chambers still converge."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

pytest.importorskip("torch")
pytest.importorskip("h5py")

from typer.testing import CliRunner  # noqa: E402

from pliant import robots  # noqa: E402
from pliant.cli import app  # noqa: E402
from pliant.condensed.collect import collect  # noqa: E402
from pliant.condensed.control import (  # noqa: E402
    PID,
    EmbeddedController,
    ExactCondensed,
    effector_positions,
    follow_embedded,
    follow_trajectory,
)
from pliant.condensed.dataset import CollectionPlan, Dataset  # noqa: E402
from pliant.condensed.equilibrium import load_step, rest_equilibrium  # noqa: E402
from pliant.condensed.learned import OutOfBoundsWarning  # noqa: E402
from pliant.condensed.train import TrainConfig, train_condensed  # noqa: E402
from pliant.solvers import StaticSolver  # noqa: E402

COARSE = {"mesh_size": 12.0, "n_chambers": 3}
# volume growth (mm^3) of the cavity: about 0.2 to 3.5 kPa on this PneuNet
PLAN = CollectionPlan(
    "pneunet",
    ((200.0, 1400.0),),
    12,
    robot_kwargs=COARSE,
    max_increment=1200.0,
    chunk_size=6,
)
MAX_PRESSURE_STEP = 4.0  # kPa, the plant's force load steps


@pytest.fixture(scope="module")
def dataset(tmp_path_factory) -> Dataset:
    return collect(PLAN, tmp_path_factory.mktemp("pneumatic") / "pneunet.h5", workers=1)


def test_pressure_load_step_holds_the_pressure_and_w_predicts_the_motion() -> None:
    model = robots.build("pneunet", **COARSE)
    # the consistent tangent, with the pressure's load stiffness -lambda d^2V/dx^2 (SOFA's
    # material tangent leaves it out and misses 4 % of the tip's motion here)
    solver = StaticSolver(model)
    pressure, step = 1.0, 0.02
    state = load_step(
        model, solver, rest_equilibrium(model, solver), np.array([pressure]), 4.0, mode="force"
    )
    np.testing.assert_allclose(state.actuation, [pressure])
    problem = solver.condense(state)
    # delta(lambda + d) - delta(lambda) = W d + O(d^2) (Eq. 2.14 linearised at the state)
    nudged = load_step(model, solver, state, np.array([pressure + step]), 4.0, mode="force")
    np.testing.assert_allclose(nudged.actuation, [pressure + step])
    sa, se = problem.slices["actuator"], problem.slices["effector"]
    volume = nudged.displacement - state.displacement
    np.testing.assert_allclose(volume, problem.compliance[sa, sa] @ [step], rtol=1e-3)
    moved = (effector_positions(model, nudged) - effector_positions(model, state)).ravel()
    np.testing.assert_allclose(
        moved, problem.compliance[se, sa] @ [step], atol=1e-3 * np.abs(moved).max()
    )


def test_collection_imposes_the_volumes(dataset) -> None:
    for split in (dataset.train, dataset.test):
        assert split.converged.all()
        np.testing.assert_allclose(split.delta_a, split.command, atol=1e-6)
        assert np.all(split.w_triangle[:, 0] > 0)  # W_aa: volume per pressure
        np.testing.assert_array_equal(
            split.w0_triangle, split.w0_triangle[:1].repeat(len(split), 0)
        )


def test_pressure_controlled_tracking_learned_close_to_exact(dataset) -> None:
    config = TrainConfig(
        epochs=300, batch_size=4, learning_rate=1e-3, hidden=(64, 64), progress=False
    )
    learned = train_condensed(dataset, config)[0]
    model = robots.build("pneunet", **COARSE)
    solver = StaticSolver(model)
    rest = rest_equilibrium(model, solver)
    # goals the robot reaches at pressures inside the data's volumes
    goals = np.vstack(
        [
            effector_positions(
                model, load_step(model, solver, rest, np.array([p]), 4.0, mode="force")
            )
            for p in (1.0, 2.5)
        ]
    )
    motion = np.linalg.norm(goals - effector_positions(model, rest), axis=1).min()
    exact = follow_trajectory(
        model,
        goals,
        ExactCondensed(model, StaticSolver(model)),
        iterations=4,
        regularisation=1e-6,
        max_increment=MAX_PRESSURE_STEP,
        drive="force",
    )
    assert exact.errors.max() < 0.05 * motion, (exact.errors, motion)
    controller = EmbeddedController(learned, pid=PID(0.5, 0.1), regularisation=1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OutOfBoundsWarning)  # it starts at the rest volume
        by_learned = follow_embedded(
            model,
            goals,
            controller,
            iterations=8,
            closed_loop=True,
            max_increment=MAX_PRESSURE_STEP,
        )
    assert by_learned.errors.max() < 0.1 * motion, (by_learned.errors, motion)
    # its pressures hold the volumes it predicts (no volume sensing)
    np.testing.assert_allclose(controller.displacement, by_learned.displacements[-1], rtol=0.05)


def test_control_command_drives_the_stiff_flop_in_pressure(tmp_path) -> None:
    """`pliant condensed control MODEL --pressure` on a Stiff-Flop model of 8 samples: both
    controllers run the spiral in pressure and report their distance to the goals."""
    plan = CollectionPlan("stiff_flop", ((0.0, 30.0),) * 6, 8, max_increment=30.0, chunk_size=8)
    dataset = collect(plan, tmp_path / "stiff_flop.h5", workers=1)
    config = TrainConfig(epochs=20, batch_size=4, learning_rate=1e-3, hidden=(32,), progress=False)
    train_condensed(dataset, config)[0].save(tmp_path / "stiff_flop.pt")
    result = CliRunner().invoke(
        app,
        [
            "condensed",
            "control",
            str(tmp_path / "stiff_flop.pt"),
            "--trajectory",
            "spiral",
            "--goals",
            "2",
            "--iterations",
            "1",
            "--pid",
            "0.5,0.1,0",
            "--pressure",
            "--out",
            str(tmp_path),
        ],
    )
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "stiff_flop_spiral" / "report.json").read_text())
    for source in ("learned", "exact"):
        assert len(report[source]["errors"]) == 2
        assert np.all(np.isfinite(report[source]["errors"]))
    assert (tmp_path / "stiff_flop_spiral" / "reached.png").is_file()
